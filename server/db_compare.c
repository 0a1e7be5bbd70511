/* obscurad's store, comparisons and machines: a comparison with its candidate and reference
 * jobs in one transaction, the machine a timed run is recorded with, candidates' metrics, and the
 * read-only queries of srv_query. */
#include <pthread.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "db_internal.h"

int srv_sq_insert_comparison(srv_sq *db, const srv_new_comparison *cmp, int64_t *id,
                             obs_err *err) {
  if (srv_dbi_refused(db, err)) return OBS_ETRANSIENT;
  int64_t *ref_ids = calloc((size_t)cmp->nreferences + 1, sizeof *ref_ids);
  int64_t *cand_ids = calloc((size_t)cmp->ncandidates + 1, sizeof *cand_ids);
  if (!ref_ids || !cand_ids) {
    free(ref_ids);
    free(cand_ids);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  conn *c = srv_dbi_acquire(db);
  int rc = srv_dbi_begin(c, err);
  sqlite3_stmt *s;
  if (!rc) {
    s = srv_dbi_stmt(c, ST_CMP_INSERT, err);
    if (!s) rc = OBS_EIO;
    else {
      srv_dbi_bind_text(s, 1, cmp->label);
      srv_dbi_bind_text(s, 2, cmp->scene);
      sqlite3_bind_int(s, 3, cmp->width);
      sqlite3_bind_int(s, 4, cmp->height);
      sqlite3_bind_int(s, 5, cmp->repeats);
      srv_dbi_bind_text(s, 6, cmp->request);
      sqlite3_bind_int64(s, 7, srv_now_unix_ms());
      srv_dbi_bind_text(s, 8, cmp->notes);
      rc = srv_dbi_exec_done(c, s, err, "inserting the comparison");
      if (!rc) *id = sqlite3_last_insert_rowid(c->db);
    }
  }
  /* References first, so a scheduler taking jobs in id order renders a shared reference early. */
  for (int i = 0; !rc && i < cmp->nreferences; i++)
    rc = srv_dbi_insert_job(c, &cmp->references[i], i ? 0 : srv_comparison_stored_bytes(cmp),
                            &ref_ids[i], err);
  for (int i = 0; !rc && i < cmp->ncandidates; i++) {
    const srv_new_candidate *cd = &cmp->candidates[i];
    int64_t job = 0;
    rc = srv_dbi_insert_job(c, &cd->job, srv_candidate_row_bytes(cd), &job, err);
    if (rc) break;
    s = srv_dbi_stmt(c, ST_CAND_INSERT, err);
    if (!s) {
      rc = OBS_EIO;
      break;
    }
    sqlite3_bind_int64(s, 1, *id);
    sqlite3_bind_int(s, 2, i);
    sqlite3_bind_int64(s, 3, job);
    sqlite3_bind_int64(s, 4, ref_ids[cd->reference]);
    srv_dbi_bind_text(s, 5, cd->technique);
    srv_dbi_bind_text(s, 6, cd->backend);
    srv_dbi_bind_text(s, 7, cd->params);
    srv_dbi_bind_text(s, 8, cd->reference_params);
    srv_dbi_bind_text(s, 9, cd->response);
    srv_dbi_bind_text(s, 10, "own");
    srv_dbi_bind_text(s, 11, NULL);
    rc = srv_dbi_exec_done(c, s, err, "inserting a candidate");
    if (!rc) cand_ids[i] = job;
  }
  for (int i = 0; !rc && i < cmp->nmeasures; i++) {
    const srv_new_measure *m = &cmp->measures[i];
    const srv_new_candidate *cd = &cmp->candidates[m->candidate];
    s = srv_dbi_stmt(c, ST_CAND_INSERT, err);
    if (!s) {
      rc = OBS_EIO;
      break;
    }
    sqlite3_bind_int64(s, 1, *id);
    sqlite3_bind_int(s, 2, cmp->ncandidates + i);
    sqlite3_bind_int64(s, 3, cand_ids[m->candidate]);
    sqlite3_bind_int64(s, 4, ref_ids[m->reference]);
    srv_dbi_bind_text(s, 5, cd->technique);
    srv_dbi_bind_text(s, 6, cd->backend);
    srv_dbi_bind_text(s, 7, cd->params);
    srv_dbi_bind_text(s, 8, m->reference_params);
    srv_dbi_bind_text(s, 9, m->response);
    srv_dbi_bind_text(s, 10, m->role);
    srv_dbi_bind_text(s, 11, m->output);
    rc = srv_dbi_exec_done(c, s, err, "inserting a measurement");
  }
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) srv_dbi_rollback(c);
  srv_dbi_release(db, c);
  free(ref_ids);
  free(cand_ids);
  return rc;
}

int srv_sq_machine(srv_sq *db, const char *cpu_model, int cores, const char *vulkan_device,
                   const char *vulkan_kind, int64_t *id, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_MACHINE_INSERT, err);
  int rc = OBS_EIO;
  if (s) {
    srv_dbi_bind_text(s, 1, cpu_model);
    sqlite3_bind_int(s, 2, cores);
    srv_dbi_bind_text(s, 3, vulkan_device);
    srv_dbi_bind_text(s, 4, vulkan_kind);
    rc = srv_dbi_exec_done(c, s, err, "recording the machine");
  }
  if (!rc) {
    s = srv_dbi_stmt(c, ST_MACHINE_GET, err);
    if (!s) rc = OBS_EIO;
    else {
      srv_dbi_bind_text(s, 1, cpu_model);
      sqlite3_bind_int(s, 2, cores);
      srv_dbi_bind_text(s, 3, vulkan_device);
      int step = sqlite3_step(s);
      if (step == SQLITE_ROW) *id = sqlite3_column_int64(s, 0);
      else rc = srv_dbi_fail(c, err, "reading the machine");
      srv_dbi_done(s);
    }
  }
  if (!rc && (s = srv_dbi_stmt(c, ST_MACHINE_KIND, err))) {
    sqlite3_bind_int64(s, 1, *id);
    srv_dbi_bind_text(s, 2, vulkan_kind);
    rc = srv_dbi_exec_done(c, s, err, "recording the machine's Vulkan kind");
  } else if (!rc) {
    rc = OBS_EIO;
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_set_metrics(srv_sq *db, int64_t comparison, int idx, int64_t job, const char *metrics,
                       const char *error, const srv_output *outs, int nouts, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  int rc = srv_dbi_begin(c, err);
  if (!rc) {
    sqlite3_stmt *s = srv_dbi_stmt(c, ST_SET_METRICS, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, comparison);
      sqlite3_bind_int(s, 2, idx);
      srv_dbi_bind_text(s, 3, metrics);
      srv_dbi_bind_text(s, 4, error);
      rc = srv_dbi_exec_done(c, s, err, "storing metrics");
    }
  }
  if (!rc) rc = srv_dbi_put_outputs(c, ST_OUT_UPSERT, job, outs, nouts, err);
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) srv_dbi_rollback(c);
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_query(srv_sq *db, srv_query q, const srv_arg *args, int nargs, json_t **rows,
                 obs_err *err) {
  *rows = NULL;
  if (q < 0 || q >= SRV_NQUERIES) return obs_err_set(err, OBS_EINTERNAL, "no query %d", (int)q);
  json_t *out = json_array();
  if (!out) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_QUERY + (int)q, err);
  int rc = OBS_EIO;
  if (s) {
    for (int i = 0; i < nargs; i++) {
      if (args[i].kind == SRV_ARG_INT) sqlite3_bind_int64(s, i + 1, args[i].i);
      else if (args[i].kind == SRV_ARG_REAL) sqlite3_bind_double(s, i + 1, args[i].d);
      else srv_dbi_bind_text(s, i + 1, args[i].s);
    }
    int step, ncol = sqlite3_column_count(s);
    while ((step = sqlite3_step(s)) == SQLITE_ROW) {
      json_t *row = json_object();
      for (int k = 0; k < ncol; k++) {
        json_t *v;
        switch (sqlite3_column_type(s, k)) {
          case SQLITE_INTEGER: v = json_integer(sqlite3_column_int64(s, k)); break;
          case SQLITE_FLOAT: v = json_real(sqlite3_column_double(s, k)); break;
          case SQLITE_TEXT: v = json_string((const char *)sqlite3_column_text(s, k)); break;
          default: v = json_null(); break;
        }
        /* A string that is not UTF-8 cannot be a JSON string: shown as null. */
        json_object_set_new(row, sqlite3_column_name(s, k), v ? v : json_null());
      }
      json_array_append_new(out, row);
    }
    rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "query");
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  if (rc) {
    json_decref(out);
    return rc;
  }
  *rows = out;
  return 0;
}
