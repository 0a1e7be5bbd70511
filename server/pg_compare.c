/* The PostgreSQL store's comparisons and machines: a comparison's fan-out (its row, every job in
 * one INSERT ... unnest, every candidate row in another, one wake-up), the machine a timed run is
 * recorded with, candidates' metrics, deleting a comparison whole, and the read-only queries of
 * srv_query as JSON rows shaped like the SQLite store's. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pg_internal.h"

/* Type OIDs (pg_type.h) the rows convert by. */
enum {
  OID_BOOL = 16,
  OID_INT8 = 20,
  OID_INT2 = 21,
  OID_INT4 = 23,
  OID_FLOAT4 = 700,
  OID_FLOAT8 = 701,
  OID_NUMERIC = 1700,
  OID_JSON = 114,
  OID_JSONB = 3802
};

typedef struct cmp_ctx {
  const srv_new_comparison *cmp;
  int64_t *id;
} cmp_ctx;

/* The candidate rows: the candidates' own, then the further measurements'. */
static int insert_candidates(struct srv_pg *pg, pgc *c, const srv_new_comparison *cmp,
                             int64_t id, const int64_t *ref_ids, const int64_t *cand_ids,
                             obs_err *err) {
  enum { NCOL = 10 };
  pgbuf a[NCOL];
  for (int k = 0; k < NCOL; k++) srv_pgi_arr_open(&a[k]);
  int rows = cmp->ncandidates + cmp->nmeasures;
  for (int i = 0; i < rows; i++) {
    const srv_new_measure *m = i < cmp->ncandidates ? NULL : &cmp->measures[i - cmp->ncandidates];
    const srv_new_candidate *cd = &cmp->candidates[m ? m->candidate : i];
    srv_pgi_arr_i64(&a[0], i);
    srv_pgi_arr_i64(&a[1], cand_ids[m ? m->candidate : i]);
    srv_pgi_arr_i64(&a[2], ref_ids[m ? m->reference : cd->reference]);
    srv_pgi_arr_text(&a[3], cd->technique);
    srv_pgi_arr_text(&a[4], cd->backend);
    srv_pgi_arr_text(&a[5], cd->params);
    srv_pgi_arr_text(&a[6], m ? m->reference_params : cd->reference_params);
    srv_pgi_arr_text(&a[7], m ? m->response : cd->response);
    srv_pgi_arr_text(&a[8], m ? m->role : "own");
    srv_pgi_arr_text(&a[9], m ? m->output : NULL);
  }
  char sid[24];
  const char *v[NCOL + 1] = {srv_pgi_i64(sid, id)};
  int oom = 0;
  for (int k = 0; k < NCOL; k++) oom |= !(v[k + 1] = srv_pgi_arr_close(&a[k]));
  int rc = oom ? obs_err_set(err, OBS_ENOMEM, "out of memory")
               : srv_pgi_exec(pg, c, PGS_CAND_INSERT, NCOL + 1, v, NULL, NULL, 0, NULL, err);
  for (int k = 0; k < NCOL; k++) srv_pgi_buf_free(&a[k]);
  return rc;
}

static int cmp_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  cmp_ctx *x = ctx;
  const srv_new_comparison *cmp = x->cmp;
  char w[24], h[24], rep[24];
  const char *v[] = {cmp->label, cmp->scene, srv_pgi_i64(w, cmp->width),
                     srv_pgi_i64(h, cmp->height), srv_pgi_i64(rep, cmp->repeats), cmp->request,
                     cmp->notes};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_CMP_INSERT, 7, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  *x->id = srv_pgi_int(r, 0, 0);
  PQclear(r);
  /* References first, so a scheduler taking jobs in id order renders a shared reference early. */
  int n = cmp->nreferences + cmp->ncandidates;
  const srv_new_job **jobs = calloc((size_t)n + 1, sizeof *jobs);
  int64_t *extra = calloc((size_t)n + 1, sizeof *extra);
  int64_t *ids = calloc((size_t)n + 1, sizeof *ids);
  if (!jobs || !extra || !ids) rc = obs_err_set(err, OBS_ENOMEM, "out of memory");
  for (int i = 0; !rc && i < cmp->nreferences; i++) {
    jobs[i] = &cmp->references[i];
    extra[i] = i ? 0 : srv_comparison_stored_bytes(cmp);
  }
  for (int i = 0; !rc && i < cmp->ncandidates; i++) {
    jobs[cmp->nreferences + i] = &cmp->candidates[i].job;
    extra[cmp->nreferences + i] = srv_candidate_row_bytes(&cmp->candidates[i]);
  }
  if (!rc) rc = srv_pgi_insert_jobs(pg, c, jobs, extra, n, *x->id, ids, err);
  if (!rc) rc = insert_candidates(pg, c, cmp, *x->id, ids, ids + cmp->nreferences, err);
  free(jobs);
  free(extra);
  free(ids);
  return rc;
}

int srv_pg_insert_comparison(struct srv_pg *pg, const srv_new_comparison *cmp, int64_t *id,
                             obs_err *err) {
  if (srv_pgi_refused(pg, err)) return OBS_ETRANSIENT;
  cmp_ctx x = {cmp, id};
  return srv_pgi_run(pg, 1, cmp_op, &x, err);
}

int srv_pg_machine(struct srv_pg *pg, const char *cpu_model, int cores, const char *vulkan_device,
                   const char *vulkan_kind, int64_t *id, obs_err *err) {
  char sc[24];
  const char *host = pg->node.name[0] ? pg->node.name : NULL;
  const char *v[] = {cpu_model, srv_pgi_i64(sc, cores), vulkan_device, vulkan_kind, host};
  int rc = 0;
  /* Twice at most: a row another node inserted after this statement's snapshot is seen by the
   * next one. */
  for (int tries = 0; tries < 2; tries++) {
    PGresult *r;
    rc = srv_pgi_one(pg, PGS_MACHINE_INSERT, 5, v, &r, err);
    if (rc) return rc;
    int found = PQntuples(r) > 0;
    if (found) *id = srv_pgi_int(r, 0, 0);
    PQclear(r);
    if (found) break;
    if (tries == 1)
      return obs_err_set(err, OBS_EIO, "database %s: the machine row could not be read",
                         pg->shown);
  }
  char sid[24];
  const char *k[] = {srv_pgi_i64(sid, *id), vulkan_kind};
  return srv_pgi_one(pg, PGS_MACHINE_KIND, 2, k, NULL, err);
}

typedef struct metrics_ctx {
  int64_t comparison, job;
  int idx;
  const char *metrics, *error;
  const srv_output *outs;
  int nouts;
} metrics_ctx;

static int metrics_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  metrics_ctx *x = ctx;
  char sc[24], si[24];
  const char *v[] = {srv_pgi_i64(sc, x->comparison), srv_pgi_i64(si, x->idx), x->metrics,
                     x->error};
  int rc = srv_pgi_exec(pg, c, PGS_SET_METRICS, 4, v, NULL, NULL, 0, NULL, err);
  if (!rc) rc = srv_pgi_put_outputs(pg, c, PGS_OUT_UPSERT, x->job, x->outs, x->nouts, err);
  return rc;
}

int srv_pg_set_metrics(struct srv_pg *pg, int64_t comparison, int idx, int64_t job,
                       const char *metrics, const char *error, const srv_output *outs, int nouts,
                       obs_err *err) {
  metrics_ctx x = {comparison, job, idx, metrics, error, outs, nouts};
  return srv_pgi_run(pg, 1, metrics_op, &x, err);
}

typedef struct delcmp_ctx {
  int64_t id;
  int64_t **ids;
  int *nids;
} delcmp_ctx;

static int delcmp_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  delcmp_ctx *x = ctx;
  free(*x->ids);
  *x->ids = NULL;
  *x->nids = 0;
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, x->id)};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_CMP_ACTIVE, 1, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  rc = !srv_pgi_int(r, 0, 0) ? OBS_ENOTFOUND : srv_pgi_int(r, 0, 1) ? OBS_EINVAL : 0;
  PQclear(r);
  /* The candidates go first (cascade): they are what keeps the jobs from being deleted. */
  if (!rc) rc = srv_pgi_exec(pg, c, PGS_CMP_DELETE, 1, v, NULL, NULL, 0, NULL, err);
  if (!rc) rc = srv_pgi_exec(pg, c, PGS_CMP_JOBS_DELETE, 1, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int n = PQntuples(r);
  *x->ids = malloc(((size_t)n + 1) * sizeof **x->ids);
  if (!*x->ids) rc = obs_err_set(err, OBS_ENOMEM, "out of memory");
  for (int i = 0; !rc && i < n; i++) (*x->ids)[i] = srv_pgi_int(r, i, 0);
  if (!rc) *x->nids = n;
  PQclear(r);
  return rc;
}

int srv_pg_delete_comparison(struct srv_pg *pg, int64_t id, int64_t **ids, int *nids,
                             obs_err *err) {
  *ids = NULL;
  *nids = 0;
  delcmp_ctx x = {id, ids, nids};
  int rc = srv_pgi_run(pg, 1, delcmp_op, &x, err);
  if (rc) {
    free(*ids);
    *ids = NULL;
    *nids = 0;
  }
  return rc;
}

/* A value as the SQLite store's rows show it: integers, reals, strings, JSON as its value. */
static json_t *value(const PGresult *r, int row, int col) {
  if (PQgetisnull(r, row, col)) return json_null();
  const char *t = PQgetvalue(r, row, col);
  switch (PQftype(r, col)) {
    case OID_INT2:
    case OID_INT4:
    case OID_INT8: return json_integer(strtoll(t, NULL, 10));
    case OID_BOOL: return json_integer(t[0] == 't');
    case OID_FLOAT4:
    case OID_FLOAT8:
    case OID_NUMERIC: return json_real(strtod(t, NULL));
    case OID_JSON:
    case OID_JSONB: return json_loads(t, JSON_DECODE_ANY, NULL);
    default: return json_string(t);
  }
}

typedef struct query_ctx {
  int which, n;
  const char *const *vals;
  json_t *rows;
} query_ctx;

static int query_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  query_ctx *x = ctx;
  json_array_clear(x->rows);
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, x->which, x->n, x->vals, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int ncol = PQnfields(r);
  for (int i = 0; i < PQntuples(r); i++) {
    json_t *row = json_object();
    for (int k = 0; row && k < ncol; k++) {
      json_t *v = value(r, i, k);
      /* A string that is not UTF-8 cannot be a JSON string: shown as null. */
      json_object_set_new(row, PQfname(r, k), v ? v : json_null());
    }
    if (!row || json_array_append_new(x->rows, row)) {
      PQclear(r);
      return obs_err_set(err, OBS_ENOMEM, "out of memory");
    }
  }
  PQclear(r);
  return 0;
}

int srv_pg_query(struct srv_pg *pg, srv_query q, const srv_arg *args, int nargs, json_t **rows,
                 obs_err *err) {
  *rows = NULL;
  if (q < 0 || q >= SRV_NQUERIES || nargs < 0 || nargs > 8)
    return obs_err_set(err, OBS_EINTERNAL, "no query %d", (int)q);
  char buf[8][32];
  const char *vals[8];
  for (int i = 0; i < nargs; i++) {
    if (args[i].kind == SRV_ARG_INT) vals[i] = srv_pgi_i64(buf[i], args[i].i);
    else if (args[i].kind == SRV_ARG_REAL) vals[i] = srv_pgi_f64(buf[i], args[i].d);
    else vals[i] = args[i].s;
  }
  query_ctx x = {PGS_QUERY + (int)q, nargs, vals, json_array()};
  if (!x.rows) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  int rc = srv_pgi_run(pg, 0, query_op, &x, err);
  if (rc) {
    json_decref(x.rows);
    return rc;
  }
  *rows = x.rows;
  return 0;
}
