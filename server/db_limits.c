/* The database queries behind the admission limits (limits.c): the queue's work, jobs and stored
 * bytes per client and in total, what one job adds, the client of a job, and stored run rates. Prepared per call rather than kept with the
 * pool's statements: they run once per submission. */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "db_internal.h"


int srv_dbi_prepare(conn *c, const char *q, sqlite3_stmt **s, obs_err *err) {
  if (sqlite3_prepare_v2(c->db, q, -1, s, NULL) != SQLITE_OK) {
    *s = NULL;
    return srv_dbi_fail(c, err, "preparing a query");
  }
  return 0;
}

int srv_sq_queued(srv_sq *db, const char *client, srv_load *mine, srv_load *total,
                  obs_err *err) {
  memset(mine, 0, sizeof *mine);
  memset(total, 0, sizeof *total);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  /* Work times renders, renderer processes (a job on N ranks starts N), stored bytes. */
  int rc = srv_dbi_prepare(c,
                   "SELECT coalesce(sum(coalesce(work, 0) * (repeats + warmup)), 0), "
                   "coalesce(sum(ranks), 0), coalesce(sum(stored_bytes), 0), "
                   "coalesce(sum(CASE WHEN client = ?1 THEN coalesce(work, 0) * (repeats + warmup) "
                   "END), 0), coalesce(sum(CASE WHEN client = ?1 THEN ranks END), 0), "
                   "coalesce(sum(CASE WHEN client = ?1 THEN stored_bytes END), 0) "
                   "FROM jobs WHERE state IN ('queued', 'running')",
                   &s, err);
  if (!rc) {
    srv_dbi_bind_text(s, 1, client);
    if (sqlite3_step(s) == SQLITE_ROW) {
      total->work = sqlite3_column_double(s, 0);
      total->jobs = sqlite3_column_double(s, 1);
      total->bytes = sqlite3_column_double(s, 2);
      mine->work = sqlite3_column_double(s, 3);
      mine->jobs = sqlite3_column_double(s, 4);
      mine->bytes = sqlite3_column_double(s, 5);
    } else {
      rc = srv_dbi_fail(c, err, "summing the queue");
    }
    sqlite3_finalize(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_job_load(srv_sq *db, int64_t id, srv_load *load, srv_state *state, obs_err *err) {
  memset(load, 0, sizeof *load);
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(c,
                   "SELECT coalesce(work, 0) * (repeats + warmup), ranks, stored_bytes, state "
                   "FROM jobs WHERE id = ?1",
                   &s, err);
  if (!rc) {
    sqlite3_bind_int64(s, 1, id);
    int step = sqlite3_step(s);
    if (step == SQLITE_ROW) {
      load->work = sqlite3_column_double(s, 0);
      load->jobs = sqlite3_column_double(s, 1);
      load->bytes = sqlite3_column_double(s, 2);
      if (srv_state_parse((const char *)sqlite3_column_text(s, 3), state)) *state = SRV_FAILED;
    } else if (step == SQLITE_DONE) {
      rc = OBS_ENOTFOUND;
    } else {
      rc = srv_dbi_fail(c, err, "reading the job");
    }
    sqlite3_finalize(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_set_job_client(srv_sq *db, int64_t job, int64_t comparison, const char *client,
                          obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(c,
                   "UPDATE jobs SET client = ?3 WHERE id = ?1 OR id IN (SELECT job FROM "
                   "comparison_candidates WHERE comparison = ?2 UNION SELECT reference_job FROM "
                   "comparison_candidates WHERE comparison = ?2)",
                   &s, err);
  if (!rc) {
    sqlite3_bind_int64(s, 1, job);
    sqlite3_bind_int64(s, 2, comparison);
    srv_dbi_bind_text(s, 3, client);
    rc = sqlite3_step(s) == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "recording the client");
    sqlite3_finalize(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_run_rates(srv_sq *db, const char *technique, const char *backend, int64_t machine,
                     double min_work, double **rates, size_t *n, obs_err *err) {
  enum { MAX_RATES = 1000 };
  *rates = NULL;
  *n = 0;
  double *v = malloc(MAX_RATES * sizeof *v);
  if (!v) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(c,
                   "SELECT ru.total_ms / j.work FROM (" RECENT_SUCCEEDED("AND backend = ?2")
                   ") j JOIN runs ru ON ru.job = j.id WHERE ru.machine = ?3 AND j.work >= ?4 AND "
                   "j.work > 0 ORDER BY ru.job DESC, ru.run LIMIT 1000",
                   &s, err);
  if (!rc) {
    srv_dbi_bind_text(s, 1, technique);
    srv_dbi_bind_text(s, 2, backend);
    sqlite3_bind_int64(s, 3, machine);
    sqlite3_bind_double(s, 4, min_work);
    int step;
    while ((step = sqlite3_step(s)) == SQLITE_ROW && *n < MAX_RATES) {
      double r = sqlite3_column_double(s, 0);
      if (r >= 0 && r < 1e30) v[(*n)++] = r;
    }
    if (step != SQLITE_ROW && step != SQLITE_DONE) rc = srv_dbi_fail(c, err, "reading run rates");
    sqlite3_finalize(s);
  }
  srv_dbi_release(db, c);
  if (rc) {
    free(v);
    *n = 0;
    return rc;
  }
  *rates = v;
  return 0;
}
