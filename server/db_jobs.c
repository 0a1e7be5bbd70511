/* obscurad's store, the jobs: inserting, reading and listing them, a lane's claim, the end of a
 * run (success with its outputs and timed runs, failure, requeue), cancellation and deletion. */
#include <pthread.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "db_internal.h"

static void read_job(sqlite3_stmt *s, srv_job *j) {
  memset(j, 0, sizeof *j);
  j->id = sqlite3_column_int64(s, 0);
  srv_state st = SRV_FAILED;
  srv_state_parse((const char *)sqlite3_column_text(s, 1), &st);
  j->state = st;
  j->priority = sqlite3_column_int(s, 2);
  j->label = srv_dbi_col_str(s, 3);
  j->scene = srv_dbi_col_str(s, 4);
  j->technique = srv_dbi_col_str(s, 5);
  j->backend_requested = srv_dbi_col_str(s, 6);
  j->backend = srv_dbi_col_str(s, 7);
  j->lane = srv_lane_parse((const char *)sqlite3_column_text(s, 8));
  j->width = sqlite3_column_int(s, 9);
  j->height = sqlite3_column_int(s, 10);
  j->spp = sqlite3_column_int(s, 11);
  j->attempts = sqlite3_column_int(s, 12);
  j->cancel_requested = sqlite3_column_int(s, 13);
  j->created_ms = sqlite3_column_int64(s, 14);
  j->started_ms = sqlite3_column_int64(s, 15);
  j->finished_ms = sqlite3_column_int64(s, 16);
  j->error = srv_dbi_col_str(s, 17);
  j->summary = srv_dbi_col_str(s, 18);
  j->progress = sqlite3_column_double(s, 19);
  j->repeats = sqlite3_column_int(s, 20);
  j->warmup = sqlite3_column_int(s, 21);
  j->backend_reason = srv_dbi_col_str(s, 22);
  j->comparison = sqlite3_column_int64(s, 23);
  j->scene_name = srv_dbi_col_str(s, 24);
  j->notes = srv_dbi_col_str(s, 25);
  j->ranks = sqlite3_column_int(s, 26);
  if (j->ranks < 1) j->ranks = 1;
  j->node = srv_dbi_col_str(s, 27);
}

static int read_outputs(conn *c, srv_job *j, obs_err *err) {
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_OUTPUTS, err);
  if (!s) return OBS_EIO;
  sqlite3_bind_int64(s, 1, j->id);
  int rc;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW) {
    srv_output *o = realloc(j->outputs, (size_t)(j->noutputs + 1) * sizeof *o);
    if (!o) {
      srv_dbi_done(s);
      return obs_err_set(err, OBS_ENOMEM, "out of memory");
    }
    j->outputs = o;
    o += j->noutputs++;
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "%s", (const char *)sqlite3_column_text(s, 0));
    o->size = sqlite3_column_int64(s, 1);
    snprintf(o->sha256, sizeof o->sha256, "%s", (const char *)sqlite3_column_text(s, 2));
    snprintf(o->content_type, sizeof o->content_type, "%s",
             (const char *)sqlite3_column_text(s, 3));
  }
  int out = rc == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "outputs");
  srv_dbi_done(s);
  return out;
}

/* ---- jobs ------------------------------------------------------------------------------------ */

int srv_dbi_insert_job(conn *c, const srv_new_job *nj, int64_t extra, int64_t *id,
                       obs_err *err) {
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_INSERT, err);
  if (!s) return OBS_EIO;
  sqlite3_bind_int(s, 1, nj->priority);
  srv_dbi_bind_text(s, 2, nj->label);
  srv_dbi_bind_text(s, 3, nj->scene);
  srv_dbi_bind_text(s, 4, nj->doc);
  srv_dbi_bind_text(s, 5, nj->technique);
  srv_dbi_bind_text(s, 6, nj->backend_requested);
  srv_dbi_bind_text(s, 7, srv_lane_name(nj->lane));
  sqlite3_bind_int(s, 8, nj->width);
  sqlite3_bind_int(s, 9, nj->height);
  sqlite3_bind_int(s, 10, nj->spp);
  sqlite3_bind_int64(s, 11, srv_now_unix_ms());
  sqlite3_bind_int(s, 12, nj->repeats > 0 ? nj->repeats : 1);
  sqlite3_bind_int(s, 13, nj->warmup ? 1 : 0);
  if (nj->work > 0) sqlite3_bind_double(s, 14, nj->work);
  else sqlite3_bind_null(s, 14);
  srv_dbi_bind_text(s, 15, nj->backend_reason);
  srv_dbi_bind_text(s, 16, nj->scene_name);
  srv_dbi_bind_text(s, 17, nj->notes);
  sqlite3_bind_int(s, 18, nj->ranks > 1 ? nj->ranks : 1);
  sqlite3_bind_int64(s, 19, srv_job_stored_bytes(nj) + extra);
  srv_dbi_bind_text(s, 20, nj->choice);
  int rc = srv_dbi_exec_done(c, s, err, "inserting the job");
  if (!rc) *id = sqlite3_last_insert_rowid(c->db);
  return rc;
}

int srv_sq_insert_job(srv_sq *db, const srv_new_job *nj, int64_t *id, obs_err *err) {
  if (srv_dbi_refused(db, err)) return OBS_ETRANSIENT;
  conn *c = srv_dbi_acquire(db);
  /* Autocommit: when the step returned DONE the row is committed to the WAL. */
  int rc = srv_dbi_insert_job(c, nj, 0, id, err);
  srv_dbi_release(db, c);
  return rc;
}

int srv_dbi_put_outputs(conn *c, int which, int64_t id, const srv_output *outs, int nouts,
                        obs_err *err) {
  int rc = 0;
  for (int i = 0; !rc && i < nouts; i++) {
    sqlite3_stmt *s = srv_dbi_stmt(c, which, err);
    if (!s) return OBS_EIO;
    sqlite3_bind_int64(s, 1, id);
    srv_dbi_bind_text(s, 2, outs[i].name);
    sqlite3_bind_int64(s, 3, outs[i].size);
    srv_dbi_bind_text(s, 4, outs[i].sha256);
    srv_dbi_bind_text(s, 5, outs[i].content_type);
    rc = srv_dbi_exec_done(c, s, err, "recording an output");
  }
  return rc;
}

int srv_sq_get_job(srv_sq *db, int64_t id, srv_job *j, obs_err *err) {
  memset(j, 0, sizeof *j);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_GET, err);
  int rc = OBS_EIO;
  if (s) {
    sqlite3_bind_int64(s, 1, id);
    int step = sqlite3_step(s);
    if (step == SQLITE_ROW) {
      read_job(s, j);
      rc = 0;
    } else {
      rc = step == SQLITE_DONE ? OBS_ENOTFOUND : srv_dbi_fail(c, err, "reading the job");
    }
    srv_dbi_done(s);
    if (!rc) rc = read_outputs(c, j, err);
    if (rc && rc != OBS_ENOTFOUND) srv_job_free(j);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_list_jobs(srv_sq *db, const srv_job_filter *f, srv_job **jobs, int *n, obs_err *err) {
  *jobs = NULL;
  *n = 0;
  srv_job *out = calloc((size_t)f->limit + 1, sizeof *out);
  if (!out) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  conn *c = srv_dbi_acquire(db);
  int variant = (f->has_state ? 1 : 0) | (f->technique ? 2 : 0) | (f->backend ? 4 : 0) |
                (f->ascending ? 8 : 0);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_LIST + variant, err);
  int rc = OBS_EIO, count = 0;
  if (s) {
    srv_dbi_bind_text(s, 1, f->has_state ? srv_state_name(f->state) : NULL);
    srv_dbi_bind_text(s, 2, f->technique);
    srv_dbi_bind_text(s, 3, f->backend);
    sqlite3_bind_int64(s, 4, f->after || f->ascending ? f->after : INT64_MAX);
    sqlite3_bind_int(s, 5, f->limit + 1);
    int step;
    while ((step = sqlite3_step(s)) == SQLITE_ROW && count <= f->limit) read_job(s, &out[count++]);
    rc = step == SQLITE_DONE || step == SQLITE_ROW ? 0 : srv_dbi_fail(c, err, "listing jobs");
    srv_dbi_done(s);
    for (int i = 0; !rc && i < count; i++) rc = read_outputs(c, &out[i], err);
  }
  srv_dbi_release(db, c);
  if (rc) {
    srv_jobs_free(out, count);
    return rc;
  }
  *jobs = out;
  *n = count;
  return 0;
}

int srv_sq_claim(srv_sq *db, srv_lane lane, srv_job *j, obs_err *err) {
  memset(j, 0, sizeof *j);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_CLAIM, err);
  int rc = OBS_EIO;
  if (s) {
    srv_dbi_bind_text(s, 1, srv_lane_name(lane));
    sqlite3_bind_int64(s, 2, srv_now_unix_ms());
    srv_dbi_bind_text(s, 3, db->node.worker);
    srv_dbi_bind_text(s, 4, db->node.name);
    sqlite3_bind_int64(s, 5, (int64_t)db->node.lease_seconds * 1000);
    int step = sqlite3_step(s);
    if (step == SQLITE_ROW) {
      read_job(s, j);
      j->doc = srv_dbi_col_str(s, JOB_NCOLS);
      /* Step to the end so the UPDATE's transaction commits before we let go. */
      step = sqlite3_step(s);
      rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "claiming a job");
      if (rc) srv_job_free(j);
    } else {
      rc = step == SQLITE_DONE ? 1 : srv_dbi_fail(c, err, "claiming a job");
    }
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_set_backend(srv_sq *db, int64_t id, const char *backend, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_SET_BACKEND, err);
  int rc = OBS_EIO;
  if (s) {
    srv_dbi_bind_text(s, 1, backend);
    sqlite3_bind_int64(s, 2, id);
    rc = srv_dbi_exec_done(c, s, err, "recording the backend");
  }
  srv_dbi_release(db, c);
  return rc;
}

/* Binds the guard of a completion (HELD in db.c): the job, the attempt and this worker. */
static void bind_held(srv_sq *db, sqlite3_stmt *s, int64_t id, int attempt) {
  sqlite3_bind_int64(s, 5, id);
  sqlite3_bind_int(s, 6, attempt);
  srv_dbi_bind_text(s, 7, db->node.worker);
}

static int not_held(obs_err *err, int64_t id, int attempt) {
  return obs_err_set(err, OBS_ECONFLICT,
                     "job %lld: attempt %d is no longer held by this node (its lease lapsed or it "
                     "was requeued); the result is refused",
                     (long long)id, attempt);
}

int srv_sq_finish_success(srv_sq *db, int64_t id, int attempt, const char *backend,
                          const char *summary, const srv_output *outs, int nouts,
                          const srv_run *runs, int nruns, int64_t machine, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  int rc = srv_dbi_begin(c, err);
  sqlite3_stmt *s;
  if (!rc) {
    s = srv_dbi_stmt(c, ST_SUCCESS, err);
    if (!s) rc = OBS_EIO;
    else {
      srv_dbi_bind_text(s, 1, backend);
      srv_dbi_bind_text(s, 2, summary);
      sqlite3_bind_int64(s, 3, srv_now_unix_ms());
      bind_held(db, s, id, attempt);
      rc = srv_dbi_exec_done(c, s, err, "marking the job succeeded");
      if (!rc && sqlite3_changes(c->db) != 1) rc = not_held(err, id, attempt);
    }
  }
  if (!rc) {
    s = srv_dbi_stmt(c, ST_OUT_CLEAR, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, id);
      rc = srv_dbi_exec_done(c, s, err, "clearing outputs");
    }
  }
  if (!rc) rc = srv_dbi_put_outputs(c, ST_OUT_INSERT, id, outs, nouts, err);
  for (int i = 0; !rc && i < nruns; i++) {
    s = srv_dbi_stmt(c, ST_RUN_INSERT, err);
    if (!s) {
      rc = OBS_EIO;
      break;
    }
    sqlite3_bind_int64(s, 1, id);
    sqlite3_bind_int(s, 2, i + 1);
    sqlite3_bind_double(s, 3, runs[i].build_ms);
    sqlite3_bind_double(s, 4, runs[i].render_ms);
    sqlite3_bind_double(s, 5, runs[i].post_ms);
    sqlite3_bind_double(s, 6, runs[i].total_ms);
    if (machine > 0) sqlite3_bind_int64(s, 7, machine);
    else sqlite3_bind_null(s, 7);
    rc = srv_dbi_exec_done(c, s, err, "recording a run");
  }
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) srv_dbi_rollback(c);
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_finish(srv_sq *db, int64_t id, int attempt, srv_state state, const char *error,
                  double progress, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_FINISH, err);
  int rc = OBS_EIO;
  if (s) {
    srv_dbi_bind_text(s, 1, srv_state_name(state));
    srv_dbi_bind_text(s, 2, error);
    sqlite3_bind_int64(s, 3, srv_now_unix_ms());
    sqlite3_bind_double(s, 4, progress);
    bind_held(db, s, id, attempt);
    rc = srv_dbi_exec_done(c, s, err, "finishing the job");
    if (!rc && sqlite3_changes(c->db) != 1) rc = not_held(err, id, attempt);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_requeue(srv_sq *db, int64_t id, int attempt, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_REQUEUE, err);
  int rc = OBS_EIO;
  if (s) {
    bind_held(db, s, id, attempt);
    rc = srv_dbi_exec_done(c, s, err, "requeueing the job");
    if (!rc && sqlite3_changes(c->db) != 1) rc = not_held(err, id, attempt);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_cancel(srv_sq *db, int64_t id, srv_cancel_result *res, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  /* One write transaction, so the state read and the update cannot be split by a claim. */
  int rc = srv_dbi_begin(c, err);
  sqlite3_stmt *s = NULL;
  srv_state st = SRV_FAILED;
  if (!rc) {
    s = srv_dbi_stmt(c, ST_STATE, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, id);
      int step = sqlite3_step(s);
      if (step == SQLITE_ROW) srv_state_parse((const char *)sqlite3_column_text(s, 0), &st);
      else rc = step == SQLITE_DONE ? OBS_ENOTFOUND : srv_dbi_fail(c, err, "reading the job");
      srv_dbi_done(s);
    }
  }
  if (!rc) {
    if (st == SRV_QUEUED || st == SRV_RUNNING) {
      s = srv_dbi_stmt(c, st == SRV_QUEUED ? ST_CANCEL_QUEUED : ST_CANCEL_RUNNING, err);
      if (!s) rc = OBS_EIO;
      else if (st == SRV_QUEUED) {
        sqlite3_bind_int64(s, 1, srv_now_unix_ms());
        sqlite3_bind_int64(s, 2, id);
      } else {
        sqlite3_bind_int64(s, 1, id);
      }
      if (s) rc = srv_dbi_exec_done(c, s, err, "cancelling the job");
      *res = st == SRV_QUEUED ? SRV_CANCEL_DONE : SRV_CANCEL_RUNNING;
    } else {
      *res = SRV_CANCEL_FINISHED;
    }
  }
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) srv_dbi_rollback(c);
  srv_dbi_release(db, c);
  return rc;
}

/* After a conditional write that changed no row: the job's state (0), OBS_ENOTFOUND when there is
 * no such job, or a database error. */
static int state_of(conn *c, int64_t id, srv_state *st, obs_err *err) {
  sqlite3_stmt *q = srv_dbi_stmt(c, ST_STATE, err);
  if (!q) return OBS_EIO;
  sqlite3_bind_int64(q, 1, id);
  int step = sqlite3_step(q);
  if (step == SQLITE_ROW) srv_state_parse((const char *)sqlite3_column_text(q, 0), st);
  int rc = step == SQLITE_ROW    ? 0
           : step == SQLITE_DONE ? OBS_ENOTFOUND
                                 : srv_dbi_fail(c, err, "reading the job");
  srv_dbi_done(q);
  return rc;
}

int srv_sq_delete(srv_sq *db, int64_t id, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_DELETE, err);
  int rc = OBS_EIO;
  if (s) {
    sqlite3_bind_int64(s, 1, id);
    rc = srv_dbi_exec_done(c, s, err, "deleting the job");
    if (!rc && sqlite3_changes(c->db) == 0) {
      /* No such job (404), not finished (409), or finished but part of a comparison (409). */
      srv_state st = SRV_QUEUED;
      rc = state_of(c, id, &st, err);
      if (!rc) rc = st == SRV_QUEUED || st == SRV_RUNNING ? OBS_EINVAL : OBS_EUNSUPPORTED;
    }
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_get_output(srv_sq *db, int64_t id, const char *name, srv_output *o, obs_err *err) {
  memset(o, 0, sizeof *o);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_GET_OUTPUT, err);
  int rc = OBS_EIO;
  if (s) {
    sqlite3_bind_int64(s, 1, id);
    srv_dbi_bind_text(s, 2, name);
    int step = sqlite3_step(s);
    if (step == SQLITE_ROW) {
      snprintf(o->name, sizeof o->name, "%s", name);
      o->size = sqlite3_column_int64(s, 0);
      snprintf(o->sha256, sizeof o->sha256, "%s", (const char *)sqlite3_column_text(s, 1));
      snprintf(o->content_type, sizeof o->content_type, "%s",
               (const char *)sqlite3_column_text(s, 2));
      rc = 0;
    } else {
      rc = step == SQLITE_DONE ? OBS_ENOTFOUND : srv_dbi_fail(c, err, "reading the output");
    }
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_counts(srv_sq *db, int64_t counts[SRV_NSTATES], obs_err *err) {
  memset(counts, 0, sizeof(int64_t) * SRV_NSTATES);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_COUNTS, err);
  int rc = OBS_EIO;
  if (s) {
    int step;
    while ((step = sqlite3_step(s)) == SQLITE_ROW) {
      srv_state st;
      if (!srv_state_parse((const char *)sqlite3_column_text(s, 0), &st))
        counts[st] = sqlite3_column_int64(s, 1);
    }
    rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "counting jobs");
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_job_exists(srv_sq *db, int64_t id, srv_state *state, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_STATE, err);
  int rc = OBS_EIO;
  if (s) {
    sqlite3_bind_int64(s, 1, id);
    int step = sqlite3_step(s);
    if (step == SQLITE_ROW) {
      srv_state st = SRV_FAILED;
      srv_state_parse((const char *)sqlite3_column_text(s, 0), &st);
      if (state) *state = st;
      rc = 1;
    } else {
      rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "reading the job");
    }
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_retry(srv_sq *db, int64_t id, srv_state *state, obs_err *err) {
  if (srv_dbi_refused(db, err)) return OBS_ETRANSIENT;
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_RETRY, err);
  int rc = OBS_EIO;
  if (s) {
    sqlite3_bind_int64(s, 1, id);
    rc = srv_dbi_exec_done(c, s, err, "requeueing the job");
    if (!rc && sqlite3_changes(c->db) == 0) {
      rc = state_of(c, id, state, err);
      if (!rc) rc = OBS_EINVAL;
    }
  }
  srv_dbi_release(db, c);
  return rc;
}

/* The comparison's job ids into *ids; 0 or an error. */
static int comparison_job_ids(conn *c, int64_t id, int64_t **ids, int *nids, obs_err *err) {
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_CMP_JOBS, err);
  if (!s) return OBS_EIO;
  sqlite3_bind_int64(s, 1, id);
  int step;
  while ((step = sqlite3_step(s)) == SQLITE_ROW) {
    int64_t *grown = realloc(*ids, (size_t)(*nids + 1) * sizeof **ids);
    if (!grown) {
      srv_dbi_done(s);
      return obs_err_set(err, OBS_ENOMEM, "out of memory");
    }
    *ids = grown;
    (*ids)[(*nids)++] = sqlite3_column_int64(s, 0);
  }
  int rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "listing the comparison's jobs");
  srv_dbi_done(s);
  return rc;
}

int srv_dbi_drop_comparison(conn *c, int64_t id, int64_t **ids, int *nids, obs_err *err) {
  int first = *nids;
  int rc = comparison_job_ids(c, id, ids, nids, err);
  if (!rc) {
    /* The candidates go first (cascade): they are what keeps the jobs from being deleted. */
    sqlite3_stmt *s = srv_dbi_stmt(c, ST_CMP_DELETE, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, id);
      rc = srv_dbi_exec_done(c, s, err, "deleting the comparison");
    }
  }
  for (int i = first; !rc && i < *nids; i++) {
    sqlite3_stmt *s = srv_dbi_stmt(c, ST_JOB_DELETE_ANY, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, (*ids)[i]);
      rc = srv_dbi_exec_done(c, s, err, "deleting a job of the comparison");
    }
  }
  return rc;
}

int srv_sq_delete_comparison(srv_sq *db, int64_t id, int64_t **ids, int *nids, obs_err *err) {
  *ids = NULL;
  *nids = 0;
  conn *c = srv_dbi_acquire(db);
  int rc = srv_dbi_begin(c, err);
  if (!rc) {
    sqlite3_stmt *s = srv_dbi_stmt(c, ST_CMP_ACTIVE, err);
    if (!s) rc = OBS_EIO;
    else {
      sqlite3_bind_int64(s, 1, id);
      if (sqlite3_step(s) == SQLITE_ROW)
        rc = !sqlite3_column_int(s, 0) ? OBS_ENOTFOUND : sqlite3_column_int(s, 1) ? OBS_EINVAL : 0;
      else
        rc = srv_dbi_fail(c, err, "reading the comparison");
      srv_dbi_done(s);
    }
  }
  if (!rc) rc = srv_dbi_drop_comparison(c, id, ids, nids, err);
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) {
    srv_dbi_rollback(c);
    free(*ids);
    *ids = NULL;
    *nids = 0;
  }
  srv_dbi_release(db, c);
  return rc;
}
