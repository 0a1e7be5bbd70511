/* obscurad's SQLite store, what the store contract asks for several nodes, answered for the one
 * daemon that owns a SQLite file: heartbeats extend leases and report cancels, admission needs no
 * lock beyond the daemon's own, nothing is ever reaped (the start-up recovery requeues what a previous process left), there is no other node to
 * wait for, and outputs stay local files instead of blobs. */
#include <sqlite3.h>
#include <stdlib.h>
#include <time.h>

#include "db_internal.h"

int srv_sq_heartbeat(srv_sq *db, const int64_t *ids, const int *attempts, int n, int *held,
                     int *cancel, obs_err *err) {
  int rc = 0;
  conn *c = srv_dbi_acquire(db);
  for (int i = 0; i < n && !rc; i++) {
    sqlite3_stmt *s = srv_dbi_stmt(c, ST_HEARTBEAT, err);
    if (!s) {
      rc = OBS_EIO;
      break;
    }
    sqlite3_bind_int64(s, 1, srv_now_unix_ms() + (int64_t)db->node.lease_seconds * 1000);
    sqlite3_bind_int64(s, 5, ids[i]);
    sqlite3_bind_int(s, 6, attempts[i]);
    srv_dbi_bind_text(s, 7, db->node.worker);
    int step = sqlite3_step(s);
    held[i] = step == SQLITE_ROW;
    cancel[i] = held[i] && sqlite3_column_int(s, 0);
    if (step == SQLITE_ROW) step = sqlite3_step(s);
    if (step != SQLITE_DONE) rc = srv_dbi_fail(c, err, "extending a lease");
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}

int srv_sq_reap(srv_sq *db, int *requeued, int *failed, obs_err *err) {
  (void)db, (void)err;
  *requeued = *failed = 0;
  return 0;
}

int srv_sq_wait(srv_sq *db, int timeout_ms, int *what, obs_err *err) {
  (void)db, (void)err;
  *what = 0;
  struct timespec ts = {timeout_ms / 1000, (long)(timeout_ms % 1000) * 1000000L};
  nanosleep(&ts, NULL);
  return 0;
}

int srv_sq_admit_lock(srv_sq *db, obs_err *err) {
  (void)db, (void)err;
  return 0;
}

void srv_sq_admit_unlock(srv_sq *db) { (void)db; }

int srv_sq_put_blob(srv_sq *db, const char *sha256, const void *data, size_t n, obs_err *err) {
  (void)db, (void)sha256, (void)data, (void)n, (void)err;
  return 0;
}

int srv_sq_get_blob(srv_sq *db, const char *sha256, void **data, size_t *n, obs_err *err) {
  (void)db, (void)data, (void)n;
  return obs_err_set(err, OBS_ENOTFOUND, "output %s: a SQLite store keeps outputs as local files",
                     sha256);
}

int srv_sq_prune(srv_sq *db, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err) {
  (void)db, (void)keep_jobs, (void)keep_days;
  *ids = NULL;
  *nids = 0;
  return obs_err_set(err, OBS_EUNSUPPORTED, "retention is not built yet");
}
