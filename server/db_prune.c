/* obscurad's SQLite store, retention: deletes finished jobs beyond the newest keep_jobs or finished
 * more than keep_days ago, a comparison only whole, with their outputs rows, runs and candidate
 * rows, and returns the deleted ids so that the caller removes their files. One call deletes at
 * most PRUNE_JOBS jobs and PRUNE_COMPARISONS comparisons in one transaction, so the write lock is
 * held briefly (a batch of 1000 behind a million jobs held it past the 5 s busy timeout of a
 * worker's claim on a loaded 2-core VM); the retention pass (retention.c) calls again, with a
 * pause between calls, until nothing is left. */
#include <math.h>
#include <sqlite3.h>
#include <stdlib.h>

#include "db_internal.h"

#define PRUNE_JOBS 100
#define PRUNE_COMPARISONS 2
#define STR2(x) #x
#define STR(x) STR2(x)
#define FINISHED "('succeeded', 'failed', 'cancelled')"
/* A job past the limits: ?1 the oldest id kept by count (jobs below it are beyond the newest
 * keep_jobs), ?2 the finishing time before which a job is too old. */
#define PAST "(j.state IN " FINISHED " AND (j.id < ?1 OR j.finished_ms < ?2))"

/* The limits as the statements take them: *keep_from (0: no limit by count, or fewer jobs than
 * it), *cutoff (INT64_MIN: no limit by age), and *bound, the creation time up to which a
 * comparison can be past them (a comparison created later has jobs newer than both limits). */
static int limits(conn *c, int64_t keep_jobs, double keep_days, int64_t *keep_from,
                  int64_t *cutoff, int64_t *bound, obs_err *err) {
  *keep_from = 0;
  *cutoff = INT64_MIN;
  *bound = INT64_MIN;
  if (keep_days > 0) {
    *cutoff = srv_now_unix_ms() - (int64_t)llround(keep_days * 86400000.0);
    *bound = *cutoff;
  }
  if (keep_jobs <= 0) return 0;
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(c, "SELECT id, (SELECT created_ms FROM jobs k WHERE k.id = j.id) FROM "
                           "jobs j INDEXED BY jobs_ids ORDER BY id DESC LIMIT 1 OFFSET ?1", &s, err);
  if (rc) return rc;
  sqlite3_bind_int64(s, 1, keep_jobs - 1);
  int step = sqlite3_step(s);
  if (step == SQLITE_ROW) {
    *keep_from = sqlite3_column_int64(s, 0);
    int64_t created = sqlite3_column_int64(s, 1);
    if (created > *bound) *bound = created;
  } else if (step != SQLITE_DONE) {
    rc = srv_dbi_fail(c, err, "finding the oldest job kept");
  }
  sqlite3_finalize(s);
  return rc;
}

static int push_id(int64_t **ids, int *nids, int64_t id, obs_err *err) {
  int64_t *g = realloc(*ids, ((size_t)*nids + 1) * sizeof *g);
  if (!g) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  *ids = g;
  g[(*nids)++] = id;
  return 0;
}

/* Finished jobs past the limits that belong to no comparison: the oldest ids below keep_from
 * (walking the rowids) and the earliest finished before the cutoff (walking jobs_finished), so
 * that neither a first pass over a long history nor a pass with nothing to do sorts it. */
#define LONE "NOT EXISTS (SELECT 1 FROM comparison_candidates WHERE job = j.id OR reference_job = j.id)"
static int prune_jobs(conn *c, int64_t keep_from, int64_t cutoff, int64_t **ids, int *nids,
                      obs_err *err) {
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(
      c,
      "SELECT id FROM (SELECT j.id FROM jobs j NOT INDEXED WHERE j.id < ?1 AND j.state IN "
      FINISHED " AND " LONE " ORDER BY j.id LIMIT " STR(PRUNE_JOBS) ") UNION SELECT id FROM "
      "(SELECT j.id FROM jobs j INDEXED BY jobs_finished WHERE j.finished_ms < ?2 AND j.state IN "
      FINISHED " AND " LONE " ORDER BY j.finished_ms LIMIT " STR(PRUNE_JOBS) ") LIMIT "
      STR(PRUNE_JOBS),
      &s, err);
  if (rc) return rc;
  sqlite3_bind_int64(s, 1, keep_from);
  sqlite3_bind_int64(s, 2, cutoff);
  int first = *nids, step;
  while (!rc && (step = sqlite3_step(s)) == SQLITE_ROW)
    rc = push_id(ids, nids, sqlite3_column_int64(s, 0), err);
  if (!rc && step != SQLITE_DONE) rc = srv_dbi_fail(c, err, "finding jobs to prune");
  sqlite3_finalize(s);
  for (int i = first; !rc && i < *nids; i++) {
    sqlite3_stmt *d = srv_dbi_stmt(c, ST_JOB_DELETE_ANY, err);
    if (!d) return OBS_EIO;
    sqlite3_bind_int64(d, 1, (*ids)[i]);
    rc = srv_dbi_exec_done(c, d, err, "pruning a job");
  }
  return rc;
}

/* Comparisons every job of which is past the limits and none of whose candidates still waits
 * for its metrics, deleted whole. */
static int prune_comparisons(conn *c, int64_t keep_from, int64_t cutoff, int64_t bound,
                             int64_t **ids, int *nids, obs_err *err) {
  if (bound == INT64_MIN) return 0;
  sqlite3_stmt *s;
  int rc = srv_dbi_prepare(
      c,
      "SELECT c.id FROM comparisons c WHERE c.created_ms <= ?3 AND NOT EXISTS (SELECT 1 FROM "
      "comparison_candidates cc JOIN jobs j ON j.id = cc.job OR j.id = cc.reference_job WHERE "
      "cc.comparison = c.id AND NOT coalesce(" PAST ", 0)) AND NOT EXISTS (SELECT 1 FROM comparison_candidates "
      "cc JOIN jobs a ON a.id = cc.job JOIN jobs r ON r.id = cc.reference_job WHERE "
      "cc.comparison = c.id AND cc.metrics IS NULL AND cc.metrics_error IS NULL AND "
      "a.state = 'succeeded' AND r.state = 'succeeded') ORDER BY c.id LIMIT "
      STR(PRUNE_COMPARISONS),
      &s, err);
  if (rc) return rc;
  sqlite3_bind_int64(s, 1, keep_from);
  sqlite3_bind_int64(s, 2, cutoff);
  sqlite3_bind_int64(s, 3, bound);
  int64_t cmp[PRUNE_COMPARISONS];
  int ncmp = 0, step;
  while ((step = sqlite3_step(s)) == SQLITE_ROW && ncmp < PRUNE_COMPARISONS)
    cmp[ncmp++] = sqlite3_column_int64(s, 0);
  if (step != SQLITE_DONE && step != SQLITE_ROW) rc = srv_dbi_fail(c, err, "finding comparisons");
  sqlite3_finalize(s);
  for (int i = 0; !rc && i < ncmp; i++) rc = srv_dbi_drop_comparison(c, cmp[i], ids, nids, err);
  return rc;
}

int srv_sq_prune(srv_sq *db, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err) {
  *ids = NULL;
  *nids = 0;
  if (keep_jobs < 0 || !(keep_days >= 0) || !isfinite(keep_days))
    return obs_err_set(err, OBS_EINVAL, "retention: keep-jobs (%lld) and keep-days (%g) must be "
                       ">= 0", (long long)keep_jobs, keep_days);
  if (keep_jobs == 0 && keep_days == 0) return 0;
  conn *c = srv_dbi_acquire(db);
  int64_t keep_from, cutoff, bound;
  int rc = srv_dbi_begin(c, err);
  if (!rc) rc = limits(c, keep_jobs, keep_days, &keep_from, &cutoff, &bound, err);
  if (!rc) rc = prune_jobs(c, keep_from, cutoff, ids, nids, err);
  if (!rc) rc = prune_comparisons(c, keep_from, cutoff, bound, ids, nids, err);
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
