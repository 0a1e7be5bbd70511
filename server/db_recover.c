/* The database's recovery paths: jobs a dead process left running, and queued jobs moved to the
 * lane the scheduler picks (at start); and a database file lost, replaced or corrupted under the
 * running daemon (identity checks, quick_check, write-back with VACUUM INTO, reopening the pool,
 * the write probe). */
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "db_internal.h"

/* The name of an SQLite result code, for the fault a failed probe raises. */
static const char *sqlite_code_name(int code) {
  switch (code & 0xff) {
    case SQLITE_FULL: return "SQLITE_FULL";
    case SQLITE_BUSY: return "SQLITE_BUSY";
    case SQLITE_LOCKED: return "SQLITE_LOCKED";
    case SQLITE_IOERR: return "SQLITE_IOERR";
    case SQLITE_READONLY: return "SQLITE_READONLY";
    case SQLITE_CANTOPEN: return "SQLITE_CANTOPEN";
    case SQLITE_PERM: return "SQLITE_PERM";
    case SQLITE_CORRUPT: return "SQLITE_CORRUPT";
    case SQLITE_NOTADB: return "SQLITE_NOTADB";
    default: return "SQLITE_ERROR";
  }
}

typedef struct pending {
  int64_t id;
  int attempts, cancel;
  char *error;
  char *technique, *backend;
  srv_lane lane;
} pending;

static void free_pending(pending *p, int n) {
  for (int i = 0; i < n; i++) {
    free(p[i].error);
    free(p[i].technique);
    free(p[i].backend);
  }
  free(p);
}

/* Collects the rows of a recovery query (running or queued). */
static int collect(conn *c, int which, pending **out, int *n, obs_err *err) {
  *out = NULL;
  *n = 0;
  sqlite3_stmt *s = srv_dbi_stmt(c, which, err);
  if (!s) return OBS_EIO;
  int step, cap = 0;
  while ((step = sqlite3_step(s)) == SQLITE_ROW) {
    if (*n == cap) {
      cap = cap ? cap * 2 : 16;
      pending *p = realloc(*out, (size_t)cap * sizeof *p);
      if (!p) {
        srv_dbi_done(s);
        return obs_err_set(err, OBS_ENOMEM, "out of memory");
      }
      *out = p;
    }
    pending *p = &(*out)[(*n)++];
    memset(p, 0, sizeof *p);
    p->id = sqlite3_column_int64(s, 0);
    if (which == ST_RUNNING_LIST) {
      p->attempts = sqlite3_column_int(s, 1);
      p->cancel = sqlite3_column_int(s, 2);
      p->error = srv_dbi_col_str(s, 3);
    } else {
      p->technique = srv_dbi_col_str(s, 1);
      p->backend = srv_dbi_col_str(s, 2);
      p->lane = srv_lane_parse((const char *)sqlite3_column_text(s, 3));
    }
  }
  int rc = step == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "recovery scan");
  srv_dbi_done(s);
  return rc;
}

static int end_job(conn *c, int64_t id, srv_state st, const char *msg, obs_err *err) {
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_END_ANY, err);
  if (!s) return OBS_EIO;
  srv_dbi_bind_text(s, 1, srv_state_name(st));
  srv_dbi_bind_text(s, 2, msg);
  sqlite3_bind_int64(s, 3, srv_now_unix_ms());
  sqlite3_bind_int64(s, 4, id);
  return srv_dbi_exec_done(c, s, err, "recovery");
}

int srv_sq_recover(srv_sq *db,
                   int (*pick)(void *user, const char *technique, const char *backend_requested,
                               srv_lane stored, srv_lane *lane, obs_err *err),
                   void (*clean)(void *, int64_t), void *user, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  pending *run = NULL, *queued = NULL;
  int nrun = 0, nq = 0;
  int rc = srv_dbi_begin(c, err);
  if (!rc) rc = collect(c, ST_RUNNING_LIST, &run, &nrun, err);
  for (int i = 0; !rc && i < nrun; i++) {
    pending *p = &run[i];
    char msg[1024];
    if (p->cancel) {
      rc = end_job(c, p->id, SRV_CANCELLED, "cancelled by request (the daemon stopped first)", err);
      srv_log("job %lld: running -> cancelled (cancel was pending when the daemon stopped)",
              (long long)p->id);
    } else if (p->attempts >= SRV_MAX_ATTEMPTS) {
      snprintf(msg, sizeof msg, "gave up after %d attempts: attempt %d was interrupted by a "
               "daemon crash", p->attempts, p->attempts);
      rc = end_job(c, p->id, SRV_FAILED, msg, err);
      srv_log("job %lld: running -> failed (%s)", (long long)p->id, msg);
    } else {
      snprintf(msg, sizeof msg, "attempt %d was interrupted by a daemon crash; requeued",
               p->attempts);
      sqlite3_stmt *s = srv_dbi_stmt(c, ST_REQUEUE_CRASH, err);
      if (!s) rc = OBS_EIO;
      else {
        srv_dbi_bind_text(s, 1, msg);
        sqlite3_bind_int64(s, 2, p->id);
        rc = srv_dbi_exec_done(c, s, err, "recovery");
      }
      srv_log("job %lld: running -> queued (%s)", (long long)p->id, msg);
    }
  }
  if (!rc) rc = collect(c, ST_QUEUED_LIST, &queued, &nq, err);
  for (int i = 0; !rc && i < nq; i++) {
    pending *p = &queued[i];
    srv_lane lane = p->lane;
    obs_err e = OBS_ERR_INIT;
    if (pick(user, p->technique, p->backend, p->lane, &lane, &e)) {
      rc = end_job(c, p->id, SRV_FAILED, obs_err_message(&e), err);
      srv_log("job %lld: queued -> failed (%s)", (long long)p->id, obs_err_message(&e));
    } else if (lane != p->lane) {
      sqlite3_stmt *s = srv_dbi_stmt(c, ST_SET_LANE, err);
      if (!s) rc = OBS_EIO;
      else {
        srv_dbi_bind_text(s, 1, srv_lane_name(lane));
        sqlite3_bind_int64(s, 2, p->id);
        rc = srv_dbi_exec_done(c, s, err, "recovery");
      }
    }
    obs_err_free(&e);
  }
  if (!rc) rc = srv_dbi_commit(c, err);
  if (rc) srv_dbi_rollback(c);
  srv_dbi_release(db, c);
  /* Half-written outputs go only after the commit: a crash here just repeats the sweep. */
  for (int i = 0; !rc && clean && i < nrun; i++) clean(user, run[i].id);
  free_pending(run, nrun);
  free_pending(queued, nq);
  return rc;
}

/* ---- identity, integrity and write-back of a lost file ---------------------------------------- */

srv_db_identity srv_sq_check_identity(srv_sq *db, char *detail, size_t n) {
  struct stat st;
  if (stat(db->path, &st)) {
    /* Only a missing file is a loss; EACCES on the directory and the like change nothing the
     * open connections use. */
    if (errno != ENOENT) return SRV_DB_SAME;
    snprintf(detail, n, "%s no longer exists", db->path);
    return SRV_DB_DELETED;
  }
  if (st.st_dev != db->dev || st.st_ino != db->ino) {
    snprintf(detail, n, "%s is another file than the one opened (inode %llu, was %llu)", db->path,
             (unsigned long long)st.st_ino, (unsigned long long)db->ino);
    return SRV_DB_REPLACED;
  }
  char wal[4200];
  snprintf(wal, sizeof wal, "%s-wal", db->path);
  int have = !stat(wal, &st);
  if (!db->wal_known) {
    /* The log appears with the first write after open; from then on it stays while we run. */
    if (have) {
      db->wal_known = 1;
      db->wal_dev = st.st_dev;
      db->wal_ino = st.st_ino;
    }
    return SRV_DB_SAME;
  }
  if (!have || st.st_dev != db->wal_dev || st.st_ino != db->wal_ino) {
    snprintf(detail, n, "%s was %s while the daemon had it open", wal,
             have ? "replaced" : "deleted");
    return SRV_DB_WAL_LOST;
  }
  return SRV_DB_SAME;
}

/* Takes every connection (waiting for those in use): nothing else touches the pool meanwhile. */
static void acquire_all(srv_sq *db) {
  pthread_mutex_lock(&db->mu);
  while (db->exclusive) pthread_cond_wait(&db->cv, &db->mu);
  db->exclusive = 1;
  for (;;) {
    int busy = 0;
    for (int i = 0; i < db->n; i++) busy |= db->c[i].in_use;
    if (!busy) break;
    pthread_cond_wait(&db->cv, &db->mu);
  }
  pthread_mutex_unlock(&db->mu);
}

static void release_all(srv_sq *db) {
  pthread_mutex_lock(&db->mu);
  db->exclusive = 0;
  pthread_cond_broadcast(&db->cv);
  pthread_mutex_unlock(&db->mu);
}

/* Closes the old pool and opens a fresh one on db->path. Closing first matters: the last old
 * connection removes the -wal and -shm names, which must not be a new file's by then. */
static int reopen_pool(srv_sq *db, obs_err *err) {
  conn *fresh = calloc((size_t)db->n, sizeof *fresh);
  if (!fresh) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  for (int i = 0; i < db->n; i++) srv_dbi_close_conn(&db->c[i]);
  int rc = 0;
  for (int i = 0; !rc && i < db->n; i++) rc = srv_dbi_open_conn(&fresh[i], db->path, err);
  if (rc) {
    /* The old pool is gone and the data is on disk: a restart is the safe way on. */
    srv_log("database %s: cannot reopen after writing it back (%s); exiting so that a restart "
            "recovers from the file", db->path, obs_err_message(err));
    _exit(70);
  }
  free(db->c);
  db->c = fresh;
  return srv_dbi_record_identity(db, db->path, err);
}

/* Writes the open database to a temporary name beside db->path and links it into place only
 * when nothing is there: a failed copy never leaves a partial file at the path, and a file that
 * appeared meanwhile is never overwritten (the copy then stays as <path>.recovered-<time>).
 * Returns 0 with the copy at the path, 1 with it elsewhere (named in `where`), or <0. */
static int write_back(srv_sq *db, conn *c, char *where, size_t n, obs_err *err) {
  /* Everything the log holds goes into the (unlinked) file first, so no stale log frames
   * outlive the old pool under the path's -wal name. */
  int log = 0, done = 0;
  sqlite3_wal_checkpoint_v2(c->db, "main", SQLITE_CHECKPOINT_TRUNCATE, &log, &done);
  char tmp[4200];
  snprintf(tmp, sizeof tmp, "%s.restoring-%ld", db->path, (long)getpid());
  unlink(tmp);
  int rc = srv_dbi_vacuum_into(c, tmp, err);
  if (rc) {
    unlink(tmp);
    return rc;
  }
  if (!link(tmp, db->path)) {
    unlink(tmp);
    snprintf(where, n, "%s", db->path);
    return 0;
  }
  if (errno != EEXIST) {
    rc = obs_err_set(err, OBS_ETRANSIENT, "%s: cannot link the written-back copy %s: %s",
                     db->path, tmp, strerror(errno));
    unlink(tmp);
    return rc;
  }
  char t[32];
  srv_format_time(srv_now_unix_ms(), t, sizeof t);
  snprintf(where, n, "%s.recovered-%s", db->path, t);
  if (rename(tmp, where)) {
    rc = obs_err_set(err, OBS_ETRANSIENT, "%s: cannot keep the copy: %s", where, strerror(errno));
    unlink(tmp);
    return rc;
  }
  return 1;
}

int srv_sq_restore(srv_sq *db, srv_db_identity what, char *where, size_t n, obs_err *err) {
  acquire_all(db);
  conn *c = &db->c[0];
  int rc, elsewhere = 0;
  if (what == SRV_DB_WAL_LOST) {
    /* The open connections still read the unlinked log: move its frames into the database file
     * (still the one at the path), then start again with a new log. */
    snprintf(where, n, "%s", db->path);
    int log = 0, done = 0;
    rc = sqlite3_wal_checkpoint_v2(c->db, "main", SQLITE_CHECKPOINT_TRUNCATE, &log, &done);
    rc = rc == SQLITE_OK ? 0 : srv_dbi_fail(c, err, "checkpoint of the lost WAL");
    if (!rc && srv_dbi_fsync_path(db->path))
      rc = obs_err_set(err, OBS_ETRANSIENT, "%s: cannot flush: %s", db->path, strerror(errno));
    if (!rc) rc = reopen_pool(db, err);
  } else if (what == SRV_DB_DELETED) {
    rc = write_back(db, c, where, n, err);
    if (rc == 1) {
      elsewhere = 1;
      rc = 0;
    } else if (rc == 0) {
      rc = reopen_pool(db, err);
    }
    if (elsewhere) snprintf(db->recovered, sizeof db->recovered, "%s", where);
  } else {
    char t[32];
    srv_format_time(srv_now_unix_ms(), t, sizeof t);
    snprintf(where, n, "%s.recovered-%s", db->path, t);
    elsewhere = 1;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.partial", where);
    rc = srv_dbi_vacuum_into(c, tmp, err);
    if (!rc && rename(tmp, where))
      rc = obs_err_set(err, OBS_ETRANSIENT, "%s: cannot keep the copy: %s", where,
                       strerror(errno));
    if (rc) unlink(tmp);
    if (!rc) snprintf(db->recovered, sizeof db->recovered, "%s", where);
  }
  release_all(db);
  return rc ? rc : elsewhere;
}

int srv_sq_quick_check(srv_sq *db, obs_err *err) {
  sqlite3 *q = NULL;
  /* Its own connection: the pool's page caches could hold a good copy of a page that is bad on
   * disk. Read-only and without CREATE, so a missing file is never made anew here. */
  int rc = sqlite3_open_v2(db->path, &q, SQLITE_OPEN_READONLY, NULL);
  if (rc != SQLITE_OK) {
    obs_err_set(err, OBS_ETRANSIENT, "database %s: quick_check: %s", db->path,
                q ? sqlite3_errmsg(q) : sqlite3_errstr(rc));
    sqlite3_close(q);
    return OBS_ETRANSIENT;
  }
  sqlite3_busy_timeout(q, 5000);
  sqlite3_stmt *s = NULL;
  int out = 0;
  if (sqlite3_prepare_v2(q, "PRAGMA quick_check(20)", -1, &s, NULL) != SQLITE_OK) {
    int code = sqlite3_extended_errcode(q) & 0xff;
    out = code == SQLITE_CORRUPT || code == SQLITE_NOTADB ? 1 : OBS_ETRANSIENT;
    obs_err_set(err, out > 0 ? OBS_EIO : OBS_ETRANSIENT, "database %s: %s", db->path,
                sqlite3_errmsg(q));
  } else {
    int step;
    while ((step = sqlite3_step(s)) == SQLITE_ROW) {
      const char *t = (const char *)sqlite3_column_text(s, 0);
      if (t && strcmp(t, "ok")) {
        if (!out) obs_err_set(err, OBS_EIO, "database %s: quick_check:", db->path);
        obs_err_set(err, OBS_EIO, "%s", t);
        out = 1;
      }
    }
    if (step != SQLITE_DONE && !out) {
      int code = sqlite3_extended_errcode(q) & 0xff;
      out = code == SQLITE_CORRUPT || code == SQLITE_NOTADB ? 1 : OBS_ETRANSIENT;
      obs_err_set(err, OBS_EIO, "database %s: quick_check: %s", db->path, sqlite3_errmsg(q));
    }
  }
  sqlite3_finalize(s);
  sqlite3_close(q);
  return out;
}

int srv_sq_probe(srv_sq *db, char *code, size_t n, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  /* A write that changes nothing still dirties the page and appends it to the WAL: it needs the
   * same disk and permissions as a real commit. */
  char *msg = NULL;
  int rc = sqlite3_exec(c->db,
                        "BEGIN IMMEDIATE; UPDATE schema_migrations SET applied_ms = applied_ms "
                        "WHERE version = (SELECT max(version) FROM schema_migrations); COMMIT;",
                        NULL, NULL, &msg);
  if (rc != SQLITE_OK) {
    snprintf(code, n, "%s", sqlite_code_name(sqlite3_extended_errcode(c->db)));
    obs_err_set(err, OBS_ETRANSIENT, "database %s: %s", db->path,
                msg ? msg : sqlite3_errmsg(c->db));
    srv_dbi_rollback(c);
  }
  sqlite3_free(msg);
  srv_dbi_release(db, c);
  return rc == SQLITE_OK ? 0 : OBS_ETRANSIENT;
}

