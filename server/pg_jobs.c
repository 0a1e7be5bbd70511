/* The PostgreSQL store's jobs: inserting, reading and listing them, a lane's claim under a lease,
 * the end of an attempt (accepted only from the worker that holds it), cancellation, retry and
 * deletion, and the counts by state. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pg_internal.h"

void srv_pgi_read_job(const PGresult *r, int row, srv_job *j) {
  memset(j, 0, sizeof *j);
  j->id = srv_pgi_int(r, row, 0);
  srv_state st = SRV_FAILED;
  srv_state_parse(PQgetvalue(r, row, 1), &st);
  j->state = st;
  j->priority = (int)srv_pgi_int(r, row, 2);
  j->label = srv_pgi_str(r, row, 3);
  j->scene = srv_pgi_str(r, row, 4);
  j->technique = srv_pgi_str(r, row, 5);
  j->backend_requested = srv_pgi_str(r, row, 6);
  j->backend = srv_pgi_str(r, row, 7);
  j->lane = srv_lane_parse(PQgetvalue(r, row, 8));
  j->width = (int)srv_pgi_int(r, row, 9);
  j->height = (int)srv_pgi_int(r, row, 10);
  j->spp = (int)srv_pgi_int(r, row, 11);
  j->attempts = (int)srv_pgi_int(r, row, 12);
  j->cancel_requested = (int)srv_pgi_int(r, row, 13);
  j->created_ms = srv_pgi_int(r, row, 14);
  j->started_ms = srv_pgi_int(r, row, 15);
  j->finished_ms = srv_pgi_int(r, row, 16);
  j->error = srv_pgi_str(r, row, 17);
  j->summary = srv_pgi_str(r, row, 18);
  j->progress = srv_pgi_real(r, row, 19);
  j->repeats = (int)srv_pgi_int(r, row, 20);
  j->warmup = (int)srv_pgi_int(r, row, 21);
  j->backend_reason = srv_pgi_str(r, row, 22);
  j->comparison = srv_pgi_int(r, row, 23);
  j->scene_name = srv_pgi_str(r, row, 24);
  j->notes = srv_pgi_str(r, row, 25);
  j->ranks = (int)srv_pgi_int(r, row, 26);
  if (j->ranks < 1) j->ranks = 1;
  j->node = srv_pgi_str(r, row, 27);
}

/* Attaches the outputs of jobs[0..n) (one query for the page). */
static int read_outputs(struct srv_pg *pg, pgc *c, srv_job *jobs, int n, obs_err *err) {
  if (n == 0) return 0;
  pgbuf ids;
  srv_pgi_arr_open(&ids);
  for (int i = 0; i < n; i++) srv_pgi_arr_i64(&ids, jobs[i].id);
  const char *v[] = {srv_pgi_arr_close(&ids)};
  if (!v[0]) {
    srv_pgi_buf_free(&ids);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_OUTPUTS, 1, v, NULL, NULL, 0, &r, err);
  srv_pgi_buf_free(&ids);
  for (int k = 0; !rc && k < PQntuples(r); k++) {
    int64_t id = srv_pgi_int(r, k, 0);
    srv_job *j = NULL;
    for (int i = 0; i < n && !j; i++)
      if (jobs[i].id == id) j = &jobs[i];
    if (!j) continue;
    srv_output *o = realloc(j->outputs, (size_t)(j->noutputs + 1) * sizeof *o);
    if (!o) {
      rc = obs_err_set(err, OBS_ENOMEM, "out of memory");
      break;
    }
    j->outputs = o;
    o += j->noutputs++;
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "%s", PQgetvalue(r, k, 1));
    o->size = srv_pgi_int(r, k, 2);
    snprintf(o->sha256, sizeof o->sha256, "%s", PQgetvalue(r, k, 3));
    snprintf(o->content_type, sizeof o->content_type, "%s", PQgetvalue(r, k, 4));
  }
  if (!rc) PQclear(r);
  return rc;
}

/* ---- inserting ------------------------------------------------------------------------------- */

int srv_pgi_insert_jobs(struct srv_pg *pg, pgc *c, const srv_new_job *const *jobs,
                        const int64_t *extra, int n, int64_t comparison, int64_t *ids,
                        obs_err *err) {
  enum { NCOL = 19 };
  pgbuf a[NCOL];
  for (int k = 0; k < NCOL; k++) srv_pgi_arr_open(&a[k]);
  for (int i = 0; i < n; i++) {
    const srv_new_job *nj = jobs[i];
    srv_pgi_arr_i64(&a[0], nj->priority);
    srv_pgi_arr_text(&a[1], nj->label);
    srv_pgi_arr_text(&a[2], nj->scene);
    srv_pgi_arr_text(&a[3], nj->doc);
    srv_pgi_arr_text(&a[4], nj->technique);
    srv_pgi_arr_text(&a[5], nj->backend_requested);
    srv_pgi_arr_text(&a[6], srv_lane_name(nj->lane));
    srv_pgi_arr_i64(&a[7], nj->width);
    srv_pgi_arr_i64(&a[8], nj->height);
    srv_pgi_arr_i64(&a[9], nj->spp);
    srv_pgi_arr_i64(&a[10], nj->repeats > 0 ? nj->repeats : 1);
    srv_pgi_arr_i64(&a[11], nj->warmup ? 1 : 0);
    if (nj->work > 0) srv_pgi_arr_f64(&a[12], nj->work);
    else srv_pgi_arr_text(&a[12], NULL);
    srv_pgi_arr_text(&a[13], nj->backend_reason);
    srv_pgi_arr_text(&a[14], nj->scene_name);
    srv_pgi_arr_text(&a[15], nj->notes);
    srv_pgi_arr_i64(&a[16], nj->ranks > 1 ? nj->ranks : 1);
    srv_pgi_arr_i64(&a[17], srv_job_stored_bytes(nj) + (extra ? extra[i] : 0));
    srv_pgi_arr_text(&a[18], nj->choice);
  }
  const char *v[NCOL + 1];
  int oom = 0;
  for (int k = 0; k < NCOL; k++) oom |= !(v[k] = srv_pgi_arr_close(&a[k]));
  char cmp[24];
  v[NCOL] = comparison > 0 ? srv_pgi_i64(cmp, comparison) : NULL;
  PGresult *r = NULL;
  int rc = oom ? obs_err_set(err, OBS_ENOMEM, "out of memory")
               : srv_pgi_exec(pg, c, PGS_INSERT_JOBS, NCOL + 1, v, NULL, NULL, 0, &r, err);
  for (int k = 0; k < NCOL; k++) srv_pgi_buf_free(&a[k]);
  if (rc) return rc;
  if (PQntuples(r) != n) {
    PQclear(r);
    return obs_err_set(err, OBS_EINTERNAL, "database %s: inserted %d jobs of %d", pg->shown,
                       PQntuples(r), n);
  }
  /* Ids come from the sequence in the rows' order (ORDER BY ord): ascending is input order. */
  for (int i = 0; i < n; i++) {
    int64_t id = srv_pgi_int(r, i, 0);
    int k = i;
    while (k > 0 && ids[k - 1] > id) {
      ids[k] = ids[k - 1];
      k--;
    }
    ids[k] = id;
  }
  PQclear(r);
  return 0;
}

typedef struct insert_ctx {
  const srv_new_job *nj;
  int64_t *id;
} insert_ctx;

static int insert_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  insert_ctx *x = ctx;
  return srv_pgi_insert_jobs(pg, c, &x->nj, NULL, 1, 0, x->id, err);
}

int srv_pg_insert_job(struct srv_pg *pg, const srv_new_job *nj, int64_t *id, obs_err *err) {
  if (srv_pgi_refused(pg, err)) return OBS_ETRANSIENT;
  insert_ctx x = {nj, id};
  return srv_pgi_run(pg, 0, insert_op, &x, err);
}

/* ---- reading --------------------------------------------------------------------------------- */

typedef struct get_ctx {
  int which, nv;
  const char *v[5];
  int limit; /* rows kept (list: limit + 1) */
  srv_job *jobs;
  int n;
} get_ctx;

static int get_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  get_ctx *x = ctx;
  srv_jobs_free(x->jobs, x->n);
  x->jobs = NULL;
  x->n = 0;
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, x->which, x->nv, x->v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int n = PQntuples(r) < x->limit ? PQntuples(r) : x->limit;
  x->jobs = calloc((size_t)n + 1, sizeof *x->jobs);
  if (!x->jobs) {
    PQclear(r);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  for (int i = 0; i < n; i++) srv_pgi_read_job(r, i, &x->jobs[i]);
  x->n = n;
  PQclear(r);
  return read_outputs(pg, c, x->jobs, n, err);
}

int srv_pg_get_job(struct srv_pg *pg, int64_t id, srv_job *j, obs_err *err) {
  memset(j, 0, sizeof *j);
  char sid[24];
  get_ctx x = {PGS_GET, 1, {srv_pgi_i64(sid, id)}, 1, NULL, 0};
  int rc = srv_pgi_run(pg, 1, get_op, &x, err);
  if (!rc && x.n == 0) rc = OBS_ENOTFOUND;
  if (!rc) {
    *j = x.jobs[0];
    free(x.jobs);
  } else {
    srv_jobs_free(x.jobs, x.n);
  }
  return rc;
}

int srv_pg_list_jobs(struct srv_pg *pg, const srv_job_filter *f, srv_job **jobs, int *n,
                     obs_err *err) {
  *jobs = NULL;
  *n = 0;
  get_ctx x = {0};
  x.which = PGS_LIST + srv_pgi_list_variant(f->has_state, f->technique != NULL,
                                            f->backend != NULL, f->ascending);
  if (f->has_state) x.v[x.nv++] = srv_state_name(f->state);
  if (f->technique) x.v[x.nv++] = f->technique;
  if (f->backend) x.v[x.nv++] = f->backend;
  char after[24], limit[24];
  x.v[x.nv++] = srv_pgi_i64(after, f->ascending || f->after > 0 ? f->after : INT64_MAX);
  x.v[x.nv++] = srv_pgi_i64(limit, (int64_t)f->limit + 1);
  x.limit = f->limit + 1;
  /* One snapshot for the page and its outputs. */
  int rc = srv_pgi_run(pg, 1, get_op, &x, err);
  if (rc) {
    srv_jobs_free(x.jobs, x.n);
    return rc;
  }
  *jobs = x.jobs;
  *n = x.n;
  return 0;
}

int srv_pg_claim(struct srv_pg *pg, srv_lane lane, srv_job *j, obs_err *err) {
  memset(j, 0, sizeof *j);
  char lease[32];
  const char *v[] = {srv_lane_name(lane), pg->node.name, pg->node.worker,
                     srv_pgi_f64(lease, pg->node.lease_seconds)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_CLAIM, 4, v, &r, err);
  if (rc) return rc;
  if (PQntuples(r) == 0) {
    PQclear(r);
    return 1;
  }
  srv_pgi_read_job(r, 0, j);
  j->doc = srv_pgi_str(r, 0, PG_JOB_NCOLS);
  PQclear(r);
  return 0;
}

int srv_pg_set_backend(struct srv_pg *pg, int64_t id, const char *backend, obs_err *err) {
  char sid[24];
  const char *v[] = {backend, srv_pgi_i64(sid, id), pg->node.worker};
  return srv_pgi_one(pg, PGS_SET_BACKEND, 3, v, NULL, err);
}

/* ---- the end of an attempt ------------------------------------------------------------------- */

static int conflict(int64_t id, obs_err *err) {
  return obs_err_set(err, OBS_ECONFLICT, "job %lld is no longer held by this node", (long long)id);
}

typedef struct success_ctx {
  int64_t id;
  int attempt;
  const char *backend, *summary;
  const srv_output *outs;
  int nouts;
  const srv_run *runs;
  int nruns;
  int64_t machine;
} success_ctx;

int srv_pgi_put_outputs(struct srv_pg *pg, pgc *c, int which, int64_t id, const srv_output *outs,
                        int nouts, obs_err *err) {
  if (nouts == 0) return 0;
  pgbuf a[4];
  for (int k = 0; k < 4; k++) srv_pgi_arr_open(&a[k]);
  for (int i = 0; i < nouts; i++) {
    srv_pgi_arr_text(&a[0], outs[i].name);
    srv_pgi_arr_i64(&a[1], outs[i].size);
    srv_pgi_arr_text(&a[2], outs[i].sha256);
    srv_pgi_arr_text(&a[3], outs[i].content_type);
  }
  char sid[24];
  const char *v[5] = {srv_pgi_i64(sid, id)};
  int oom = 0;
  for (int k = 0; k < 4; k++) oom |= !(v[k + 1] = srv_pgi_arr_close(&a[k]));
  int rc = oom ? obs_err_set(err, OBS_ENOMEM, "out of memory")
               : srv_pgi_exec(pg, c, which, 5, v, NULL, NULL, 0, NULL, err);
  for (int k = 0; k < 4; k++) srv_pgi_buf_free(&a[k]);
  return rc;
}

static int success_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  success_ctx *x = ctx;
  char sid[24], att[24], mach[24];
  const char *v[] = {x->backend, x->summary, srv_pgi_i64(sid, x->id), pg->node.worker,
                     srv_pgi_i64(att, x->attempt)};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_SUCCESS, 5, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int held = PQntuples(r) == 1;
  PQclear(r);
  if (!held) return conflict(x->id, err);
  rc = srv_pgi_exec(pg, c, PGS_OUT_CLEAR, 1, &v[2], NULL, NULL, 0, NULL, err);
  if (!rc) rc = srv_pgi_put_outputs(pg, c, PGS_OUT_INSERT, x->id, x->outs, x->nouts, err);
  if (!rc && x->nruns > 0) {
    pgbuf a[4];
    for (int k = 0; k < 4; k++) srv_pgi_arr_open(&a[k]);
    for (int i = 0; i < x->nruns; i++) {
      srv_pgi_arr_f64(&a[0], x->runs[i].build_ms);
      srv_pgi_arr_f64(&a[1], x->runs[i].render_ms);
      srv_pgi_arr_f64(&a[2], x->runs[i].post_ms);
      srv_pgi_arr_f64(&a[3], x->runs[i].total_ms);
    }
    const char *rv[6] = {v[2]};
    int oom = 0;
    for (int k = 0; k < 4; k++) oom |= !(rv[k + 1] = srv_pgi_arr_close(&a[k]));
    rv[5] = x->machine > 0 ? srv_pgi_i64(mach, x->machine) : NULL;
    rc = oom ? obs_err_set(err, OBS_ENOMEM, "out of memory")
             : srv_pgi_exec(pg, c, PGS_RUN_INSERT, 6, rv, NULL, NULL, 0, NULL, err);
    for (int k = 0; k < 4; k++) srv_pgi_buf_free(&a[k]);
  }
  return rc;
}

int srv_pg_finish_success(struct srv_pg *pg, int64_t id, int attempt, const char *backend,
                          const char *summary, const srv_output *outs, int nouts,
                          const srv_run *runs, int nruns, int64_t machine, obs_err *err) {
  success_ctx x = {id, attempt, backend, summary, outs, nouts, runs, nruns, machine};
  return srv_pgi_run(pg, 1, success_op, &x, err);
}

int srv_pg_finish(struct srv_pg *pg, int64_t id, int attempt, srv_state state, const char *error,
                  double progress, obs_err *err) {
  char sid[24], att[24], prog[32];
  const char *v[] = {srv_state_name(state), error, srv_pgi_f64(prog, progress),
                     srv_pgi_i64(sid, id), pg->node.worker, srv_pgi_i64(att, attempt)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_FINISH, 6, v, &r, err);
  if (rc) return rc;
  int held = PQntuples(r) == 1;
  PQclear(r);
  return held ? 0 : conflict(id, err);
}

int srv_pg_requeue(struct srv_pg *pg, int64_t id, int attempt, obs_err *err) {
  char sid[24], att[24];
  const char *v[] = {srv_pgi_i64(sid, id), pg->node.worker, srv_pgi_i64(att, attempt)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_REQUEUE, 3, v, &r, err);
  if (rc) return rc;
  int held = PQntuples(r) == 1;
  PQclear(r);
  return held ? 0 : conflict(id, err);
}

/* ---- cancel, delete, retry ------------------------------------------------------------------- */

/* The state of job id (locked when `which` is PGS_STATE_LOCK): 0, OBS_ENOTFOUND or an error. */
static int state_of(struct srv_pg *pg, pgc *c, int which, const char *sid, srv_state *st,
                    obs_err *err) {
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, which, 1, &sid, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  if (PQntuples(r) == 0) rc = OBS_ENOTFOUND;
  else if (srv_state_parse(PQgetvalue(r, 0, 0), st)) *st = SRV_FAILED;
  PQclear(r);
  return rc;
}

typedef struct cancel_ctx {
  int64_t id;
  srv_cancel_result *res;
} cancel_ctx;

static int cancel_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  cancel_ctx *x = ctx;
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, x->id)};
  srv_state st = SRV_FAILED;
  /* The row stays locked to the commit, so no claim slips between the read and the update. */
  int rc = state_of(pg, c, PGS_STATE_LOCK, v[0], &st, err);
  if (rc) return rc;
  if (st == SRV_QUEUED) {
    *x->res = SRV_CANCEL_DONE;
    return srv_pgi_exec(pg, c, PGS_CANCEL_QUEUED, 1, v, NULL, NULL, 0, NULL, err);
  }
  if (st != SRV_RUNNING) {
    *x->res = SRV_CANCEL_FINISHED;
    return 0;
  }
  *x->res = SRV_CANCEL_RUNNING;
  rc = srv_pgi_exec(pg, c, PGS_CANCEL_RUNNING, 1, v, NULL, NULL, 0, NULL, err);
  /* The node running it hears at the commit, without waiting for its next heartbeat. */
  if (!rc) rc = srv_pgi_exec(pg, c, PGS_NOTIFY_CANCEL, 1, v, NULL, NULL, 0, NULL, err);
  return rc;
}

int srv_pg_cancel(struct srv_pg *pg, int64_t id, srv_cancel_result *res, obs_err *err) {
  cancel_ctx x = {id, res};
  return srv_pgi_run(pg, 1, cancel_op, &x, err);
}

typedef struct delete_ctx {
  int64_t id;
  srv_state *state; /* retry: filled when not failed or cancelled */
} delete_ctx;

static int delete_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  delete_ctx *x = ctx;
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, x->id)};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_DELETE, 1, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int gone = PQntuples(r) > 0;
  PQclear(r);
  if (gone) return 0;
  /* No such job (404), not finished (409), or finished but part of a comparison (409). */
  srv_state st = SRV_QUEUED;
  rc = state_of(pg, c, PGS_STATE, v[0], &st, err);
  if (!rc) rc = st == SRV_QUEUED || st == SRV_RUNNING ? OBS_EINVAL : OBS_EUNSUPPORTED;
  return rc;
}

int srv_pg_delete(struct srv_pg *pg, int64_t id, obs_err *err) {
  delete_ctx x = {id, NULL};
  return srv_pgi_run(pg, 0, delete_op, &x, err);
}

static int retry_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  delete_ctx *x = ctx;
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, x->id)};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_RETRY, 1, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  int done = PQntuples(r) > 0;
  PQclear(r);
  if (done) return 0;
  rc = state_of(pg, c, PGS_STATE, v[0], x->state, err);
  return rc ? rc : OBS_EINVAL;
}

int srv_pg_retry(struct srv_pg *pg, int64_t id, srv_state *state, obs_err *err) {
  if (srv_pgi_refused(pg, err)) return OBS_ETRANSIENT;
  delete_ctx x = {id, state};
  return srv_pgi_run(pg, 0, retry_op, &x, err);
}

int srv_pg_get_output(struct srv_pg *pg, int64_t id, const char *name, srv_output *o,
                      obs_err *err) {
  memset(o, 0, sizeof *o);
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, id), name};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_GET_OUTPUT, 2, v, &r, err);
  if (rc) return rc;
  if (PQntuples(r) == 0) {
    PQclear(r);
    return OBS_ENOTFOUND;
  }
  snprintf(o->name, sizeof o->name, "%s", name);
  o->size = srv_pgi_int(r, 0, 0);
  snprintf(o->sha256, sizeof o->sha256, "%s", PQgetvalue(r, 0, 1));
  snprintf(o->content_type, sizeof o->content_type, "%s", PQgetvalue(r, 0, 2));
  PQclear(r);
  return 0;
}

int srv_pg_counts(struct srv_pg *pg, int64_t counts[SRV_NSTATES], obs_err *err) {
  memset(counts, 0, sizeof(int64_t) * SRV_NSTATES);
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_COUNTS, 0, NULL, &r, err);
  if (rc) return rc;
  for (int i = 0; i < PQntuples(r); i++) {
    srv_state st;
    if (!srv_state_parse(PQgetvalue(r, i, 0), &st)) counts[st] = srv_pgi_int(r, i, 1);
  }
  PQclear(r);
  return 0;
}

int srv_pg_job_exists(struct srv_pg *pg, int64_t id, srv_state *state, obs_err *err) {
  char sid[24];
  const char *v[] = {srv_pgi_i64(sid, id)};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_STATE, 1, v, &r, err);
  if (rc) return rc;
  int found = PQntuples(r) > 0;
  if (found && state && srv_state_parse(PQgetvalue(r, 0, 0), state)) *state = SRV_FAILED;
  PQclear(r);
  return found;
}
