/* The database queries behind the admission limits (limits.c): queued work per client and in
 * total, the client of a job, and stored run rates. Prepared per call rather than kept with the
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


static int prepare(conn *c, const char *q, sqlite3_stmt **s, obs_err *err) {
  if (sqlite3_prepare_v2(c->db, q, -1, s, NULL) != SQLITE_OK) {
    *s = NULL;
    return srv_dbi_fail(c, err, "preparing a query");
  }
  return 0;
}

int srv_db_queued_work(srv_db *db, const char *client, double *mine, double *total,
                       obs_err *err) {
  *mine = *total = 0;
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = prepare(c,
                   "SELECT coalesce(sum(coalesce(work, 0) * (repeats + warmup)), 0), "
                   "coalesce(sum(CASE WHEN client = ?1 THEN coalesce(work, 0) * (repeats + warmup) "
                   "END), 0) FROM jobs WHERE state IN ('queued', 'running')",
                   &s, err);
  if (!rc) {
    srv_dbi_bind_text(s, 1, client);
    if (sqlite3_step(s) == SQLITE_ROW) {
      *total = sqlite3_column_double(s, 0);
      *mine = sqlite3_column_double(s, 1);
    } else {
      rc = srv_dbi_fail(c, err, "summing queued work");
    }
    sqlite3_finalize(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_db_set_job_client(srv_db *db, int64_t job, int64_t comparison, const char *client,
                          obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = prepare(c,
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

int srv_db_run_rates(srv_db *db, const char *technique, const char *backend, int64_t machine,
                     double min_work, double **rates, size_t *n, obs_err *err) {
  enum { MAX_RATES = 1000 };
  *rates = NULL;
  *n = 0;
  double *v = malloc(MAX_RATES * sizeof *v);
  if (!v) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s;
  int rc = prepare(c,
                   "SELECT ru.total_ms / j.work FROM runs ru JOIN jobs j ON j.id = ru.job "
                   "WHERE j.technique = ?1 AND j.backend = ?2 AND ru.machine = ?3 AND "
                   "j.work >= ?4 AND j.work > 0 AND j.state = 'succeeded' "
                   "ORDER BY ru.job DESC, ru.run LIMIT 1000",
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
