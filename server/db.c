/* obscurad's SQLite store: a pool of connections (WAL, synchronous=NORMAL, busy timeout, foreign
 * keys), the migrations of schema/db.sql, and every query as a prepared statement. The jobs
 * (db_jobs.c), comparisons and machines (db_compare.c), recovery (db_recover.c) and the limits'
 * reads (db_limits.c) use these statements through db_internal.h. */
#include <errno.h>
#include <limits.h>
#include <fcntl.h>
#include <pthread.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "db_internal.h"

extern const char srv_db_sql[];
extern const size_t srv_db_sql_len;


#define CMP_JOBS                                                                                  \
  "(SELECT job FROM comparison_candidates WHERE comparison = ?1 UNION "                           \
  "SELECT reference_job FROM comparison_candidates WHERE comparison = ?1)"

static const char *const sql[ST_COUNT] = {
    [ST_BEGIN] = "BEGIN IMMEDIATE",
    [ST_COMMIT] = "COMMIT",
    [ST_ROLLBACK] = "ROLLBACK",
    [ST_INSERT] = "INSERT INTO jobs (priority, label, scene, doc, technique, backend_requested, "
                  "lane, width, height, spp, created_ms, repeats, warmup, work, backend_reason, "
                  "scene_name, notes, ranks, stored_bytes, choice) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                  "?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
    [ST_GET] = "SELECT " JOB_COLS " FROM jobs WHERE id = ?",
    [ST_OUTPUTS] = "SELECT name, size, sha256, content_type FROM outputs WHERE job_id = ? "
                   "ORDER BY name",
/* The list, one statement per filter combination (bit 1 state, 2 technique, 4 backend, 8
 * ascending) so that each plan walks the index of its filters (migration 12) in id order and
 * stops after the page, whatever the history holds. */
#define LW_S "state = ?1 AND "
#define LW_T "technique = ?2 AND "
#define LW_B "coalesce(backend, backend_requested) = ?3 AND "
#define LIST_D(w) "SELECT " JOB_COLS " FROM jobs WHERE " w "id < ?4 ORDER BY id DESC LIMIT ?5"
#define LIST_A(w) "SELECT " JOB_COLS " FROM jobs WHERE " w "id > ?4 ORDER BY id ASC LIMIT ?5"
#define LIST_VARIANTS(L)                                                                          \
  L(""), L(LW_S), L(LW_T), L(LW_S LW_T), L(LW_B), L(LW_S LW_B), L(LW_T LW_B), L(LW_S LW_T LW_B)
    [ST_LIST] = LIST_VARIANTS(LIST_D), LIST_VARIANTS(LIST_A),
    /* One statement, so one transaction: two workers can never claim the same job. */
    [ST_CLAIM] = "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = ?2, "
                 "finished_ms = NULL, progress = 0, backend = NULL, worker = ?3, node = ?4, "
                 "lease_expires_ms = ?2 + ?5 WHERE id = (SELECT id FROM jobs WHERE lane = ?1 AND "
                 "state = 'queued' AND (run_after IS NULL OR run_after <= ?2) AND NOT EXISTS "
                 "(SELECT 1 FROM job_node_failures f WHERE f.job = jobs.id AND f.node = ?4 AND "
                 "f.failures >= 3) ORDER BY priority DESC, id LIMIT 1) "
                 "RETURNING " JOB_COLS ", doc",
    [ST_SET_BACKEND] = "UPDATE jobs SET backend = ? WHERE id = ? AND state = 'running'",
    /* Completion is accepted only from the worker that still holds this attempt. */
#define HELD "WHERE id = ?5 AND attempts = ?6 AND worker = ?7 AND state = 'running'"
    [ST_SUCCESS] = "UPDATE jobs SET state = 'succeeded', backend = ?1, summary = ?2, progress = 1, "
                   "finished_ms = ?3, error = NULL, worker = NULL, lease_expires_ms = NULL " HELD,
    [ST_OUT_CLEAR] = "DELETE FROM outputs WHERE job_id = ?",
    [ST_OUT_INSERT] = "INSERT INTO outputs (job_id, name, size, sha256, content_type) "
                      "VALUES (?, ?, ?, ?, ?)",
    [ST_FINISH] = "UPDATE jobs SET state = ?1, error = ?2, finished_ms = ?3, progress = ?4, "
                  "worker = NULL, lease_expires_ms = NULL " HELD,
    [ST_REQUEUE] = "UPDATE jobs SET state = 'queued', attempts = max(attempts - 1, 0), "
                   "started_ms = NULL, backend = NULL, worker = NULL, lease_expires_ms = NULL "
                   "WHERE id = ?5 AND attempts = ?6 AND worker = ?7 AND state = 'running'",
    [ST_HEARTBEAT] = "UPDATE jobs SET lease_expires_ms = ?1 " HELD " RETURNING cancel_requested",
    [ST_STATE] = "SELECT state FROM jobs WHERE id = ?",
    [ST_CANCEL_QUEUED] = "UPDATE jobs SET state = 'cancelled', cancel_requested = 1, "
                         "error = 'cancelled by request', finished_ms = ? "
                         "WHERE id = ? AND state = 'queued'",
    [ST_CANCEL_RUNNING] = "UPDATE jobs SET cancel_requested = 1 WHERE id = ? AND state = 'running'",
    [ST_DELETE] = "DELETE FROM jobs WHERE id = ?1 AND state IN ('succeeded', 'failed', 'cancelled') "
                  "AND NOT EXISTS (SELECT 1 FROM comparison_candidates WHERE job = ?1 OR "
                  "reference_job = ?1)",
    [ST_GET_OUTPUT] = "SELECT size, sha256, content_type FROM outputs WHERE job_id = ? AND name = ?",
    /* Kept by triggers (migration 12): five rows, however long the history. */
    [ST_COUNTS] = "SELECT state, n FROM job_counts",
    [ST_RUNNING_LIST] = "SELECT id, attempts, cancel_requested, error FROM jobs "
                        "WHERE state = 'running'",
    [ST_QUEUED_LIST] = "SELECT id, technique, backend_requested, lane FROM jobs "
                       "WHERE state = 'queued'",
    [ST_SET_LANE] = "UPDATE jobs SET lane = ? WHERE id = ?",
    [ST_END_ANY] = "UPDATE jobs SET state = ?, error = ?, finished_ms = ?, worker = NULL, "
                   "lease_expires_ms = NULL WHERE id = ?",
    [ST_REQUEUE_CRASH] = "UPDATE jobs SET state = 'queued', error = ?, started_ms = NULL, "
                         "backend = NULL, worker = NULL, lease_expires_ms = NULL WHERE id = ?",
    [ST_CHECKPOINT] = "PRAGMA wal_checkpoint(TRUNCATE)",
    [ST_MIGRATION_MAX] = "SELECT coalesce(max(version), 0) FROM schema_migrations",
    [ST_MIGRATION_PUT] = "INSERT INTO schema_migrations (version, applied_ms) VALUES (?, ?)",
    [ST_RUN_INSERT] = "INSERT INTO runs (job, run, build_ms, render_ms, post_ms, total_ms, machine) "
                      "VALUES (?, ?, ?, ?, ?, ?, ?)",
    [ST_MACHINE_INSERT] = "INSERT INTO machines (cpu_model, cores, vulkan_device, vulkan_kind) "
                          "VALUES (?, ?, ?, ?) ON CONFLICT DO NOTHING",
    /* A row recorded before kinds were gets this device's kind (same name, same device). */
    [ST_MACHINE_KIND] = "UPDATE machines SET vulkan_kind = ?2 WHERE id = ?1 AND vulkan_kind IS NULL "
                        "AND ?2 IS NOT NULL",
    [ST_MACHINE_GET] = "SELECT id FROM machines WHERE cpu_model = ?1 AND cores = ?2 AND "
                       "vulkan_device IS ?3",
    [ST_CMP_INSERT] = "INSERT INTO comparisons (label, scene, width, height, repeats, request, "
                      "created_ms, notes) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
    [ST_CAND_INSERT] = "INSERT INTO comparison_candidates (comparison, idx, job, reference_job, "
                       "technique, backend, params, reference_params, response, role, output) "
                       "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
    [ST_SET_METRICS] = "UPDATE comparison_candidates SET metrics = ?3, metrics_error = ?4 "
                       "WHERE comparison = ?1 AND idx = ?2 AND metrics IS NULL AND "
                       "metrics_error IS NULL",
    [ST_OUT_UPSERT] = "INSERT OR REPLACE INTO outputs (job_id, name, size, sha256, content_type) "
                      "VALUES (?, ?, ?, ?, ?)",
    /* The same row goes back to the queue: its id, document and comparison stay. */
    [ST_RETRY] = "UPDATE jobs SET state = 'queued', error = NULL, cancel_requested = 0, "
                 "started_ms = NULL, finished_ms = NULL, progress = 0, backend = NULL, "
                 "run_after = NULL WHERE id = ? AND state IN ('failed', 'cancelled')",
    /* A candidate whose jobs have succeeded but whose metrics are not stored yet is still being
     * measured: deleting it then would pull the rows from under the metrics being written. */
    [ST_CMP_ACTIVE] = "SELECT (SELECT count(*) FROM comparisons WHERE id = ?1), (SELECT count(*) "
                      "FROM jobs WHERE id IN " CMP_JOBS " AND state IN ('queued', 'running')) + "
                      "(SELECT count(*) FROM comparison_candidates cc JOIN jobs j ON j.id = cc.job "
                      "JOIN jobs r ON r.id = cc.reference_job WHERE cc.comparison = ?1 AND "
                      "cc.metrics IS NULL AND cc.metrics_error IS NULL AND j.state = 'succeeded' "
                      "AND r.state = 'succeeded')",
    [ST_CMP_JOBS] = "SELECT job FROM comparison_candidates WHERE comparison = ?1 UNION "
                    "SELECT reference_job FROM comparison_candidates WHERE comparison = ?1",
    [ST_CMP_DELETE] = "DELETE FROM comparisons WHERE id = ?",
    [ST_JOB_DELETE_ANY] = "DELETE FROM jobs WHERE id = ?",
/* Per comparison: jobs still to run, candidates that can no longer get metrics, and with them. */
#define CMP_COUNTS                                                                                \
  "(SELECT count(*) FROM jobs WHERE id IN (SELECT job FROM comparison_candidates WHERE "          \
  "comparison = c.id UNION SELECT reference_job FROM comparison_candidates WHERE comparison = "    \
  "c.id) AND state IN ('queued', 'running')) AS active, "                                         \
  "(SELECT count(*) FROM comparison_candidates x JOIN jobs j ON j.id = x.job JOIN jobs r ON "     \
  "r.id = x.reference_job WHERE x.comparison = c.id AND x.role = 'own' AND x.metrics IS NULL AND " \
  "(x.metrics_error IS NOT NULL OR j.state IN ('failed', 'cancelled') OR "                        \
  "r.state IN ('failed', 'cancelled'))) AS broken, "                                              \
  "(SELECT count(*) FROM comparison_candidates x WHERE x.comparison = c.id AND x.role = 'own' "   \
  "AND x.metrics IS NOT NULL) AS measured, "                                                      \
  "(SELECT count(*) FROM comparison_candidates x WHERE x.comparison = c.id AND x.role = 'own') "  \
  "AS candidates, "                                                                               \
  /* Further measurements still to come: the comparison runs until they have their figures. */   \
  "(SELECT count(*) FROM comparison_candidates x JOIN jobs j ON j.id = x.job JOIN jobs r ON "     \
  "r.id = x.reference_job WHERE x.comparison = c.id AND x.role <> 'own' AND x.metrics IS NULL "   \
  "AND x.metrics_error IS NULL AND j.state = 'succeeded' AND r.state NOT IN ('failed', "          \
  "'cancelled')) AS measuring"
    [ST_QUERY + SRV_Q_COMPARISON] = "SELECT c.id, c.label, c.scene, c.width, c.height, c.repeats, "
                                    "c.created_ms, c.notes, json_extract(c.request, '$.budget_ms') AS budget_ms, "
                                    CMP_COUNTS " FROM comparisons c WHERE c.id = ?1",
    [ST_QUERY + SRV_Q_CANDIDATES] =
        "SELECT cc.idx, cc.job, cc.reference_job, cc.technique, cc.backend, cc.params, "
        "cc.reference_params, cc.response, cc.role, cc.output, cc.metrics, cc.metrics_error, j.state, j.progress, "
        "r.state AS ref_state, r.progress AS ref_progress, r.summary AS ref_summary, "
        "r.technique AS ref_technique "
        "FROM comparison_candidates cc JOIN jobs j ON j.id = cc.job "
        "JOIN jobs r ON r.id = cc.reference_job WHERE cc.comparison = ?1 ORDER BY cc.idx",
    [ST_QUERY + SRV_Q_COMPARISON_RUNS] =
        "SELECT ru.job, ru.run, ru.build_ms, ru.render_ms, ru.post_ms, ru.total_ms, m.cpu_model, "
        "m.cores, m.vulkan_device, m.vulkan_kind, j.node AS host FROM runs ru LEFT JOIN machines m "
        "ON m.id = ru.machine JOIN jobs j ON j.id = ru.job WHERE ru.job IN " CMP_JOBS
        " ORDER BY ru.job, ru.run",
    [ST_QUERY + SRV_Q_COMPARISON_OUTPUTS] =
        "SELECT job_id AS job, name FROM outputs WHERE job_id IN " CMP_JOBS " ORDER BY job_id, name",
    [ST_QUERY + SRV_Q_COMPARISONS] = "SELECT c.id, c.label, c.scene, c.created_ms, " CMP_COUNTS
                                     " FROM comparisons c WHERE (?1 = 0 OR c.id < ?1) "
                                     "ORDER BY c.id DESC LIMIT ?2",
    [ST_QUERY + SRV_Q_JOB_DOC] = "SELECT doc, scene, scene_name, label, priority FROM jobs "
                                 "WHERE id = ?1",
    [ST_QUERY + SRV_Q_JOB_MACHINE] = "SELECT m.cpu_model, m.cores, m.vulkan_device, m.vulkan_kind "
                                     "FROM runs ru JOIN machines m ON m.id = ru.machine WHERE "
                                     "ru.job = ?1 ORDER BY ru.run DESC LIMIT 1",
    [ST_QUERY + SRV_Q_JOB_CHOICE] = "SELECT choice FROM jobs WHERE id = ?1",
    [ST_QUERY + SRV_Q_MACHINE] = "SELECT cpu_model, cores, vulkan_device, vulkan_kind FROM "
                                 "machines WHERE id = ?1",
    [ST_QUERY + SRV_Q_JOB_COMPARISON] = "SELECT comparison FROM comparison_candidates WHERE "
                                        "job = ?1 OR reference_job = ?1 LIMIT 1",
    [ST_QUERY + SRV_Q_METRICS_PENDING] =
        "SELECT cc.comparison, cc.idx, cc.job, cc.reference_job, cc.response, cc.role, cc.output "
        "FROM comparison_candidates cc JOIN jobs j ON j.id = cc.job "
        "JOIN jobs r ON r.id = cc.reference_job WHERE cc.metrics IS NULL AND "
        "cc.metrics_error IS NULL AND j.state = 'succeeded' AND r.state = 'succeeded' AND "
        "(?1 = 0 OR cc.job = ?1 OR cc.reference_job = ?1) ORDER BY cc.comparison, cc.idx",
    /* The newest 5000 runs are plenty for a median and bound the work of one submission. Runs
     * count on hosts of this one's kind only: the CPU model and threads of machine ?4. */
    [ST_QUERY + SRV_Q_AUTO_RUNS] =
        "SELECT j.backend, ru.total_ms FROM (" RECENT_SUCCEEDED("") ") j "
        "JOIN runs ru ON ru.job = j.id LEFT JOIN machines m ON m.id = ru.machine "
        "WHERE j.work BETWEEN ?2 / 2.0 AND ?2 * 2.0 AND j.backend IS NOT NULL AND "
        "(j.backend <> 'vulkan' OR m.vulkan_kind = ?3) AND (m.cpu_model, m.cores) = (SELECT "
        "cpu_model, cores FROM machines WHERE id = ?4) ORDER BY ru.job DESC LIMIT 5000",
    [ST_QUERY + SRV_Q_BUDGET] =
        "SELECT c.id AS comparison, c.scene, cc.idx, cc.job, cc.technique, cc.backend, cc.params, "
        "cc.metrics, cc.role, cc.reference_params, cc.response, rj.technique AS reference_technique, "
        "j.width * j.height * j.spp AS pixels, (SELECT m.vulkan_kind FROM runs ru "
        "JOIN machines m ON m.id = ru.machine WHERE ru.job = cc.job LIMIT 1) AS vulkan_kind "
        "FROM comparison_candidates cc "
        "JOIN comparisons c ON c.id = cc.comparison JOIN jobs j ON j.id = cc.job "
        "JOIN jobs rj ON rj.id = cc.reference_job "
        "WHERE cc.metrics IS NOT NULL AND cc.role IN ('own', 'common') AND j.state = 'succeeded' "
        "ORDER BY c.id DESC, cc.idx LIMIT 2000",
    [ST_QUERY + SRV_Q_JOB_RUNS] = "SELECT total_ms FROM runs WHERE job = ?1 ORDER BY run",
};

/* Faults of the environment (a full or read-only disk, a busy database) come back as
 * OBS_ETRANSIENT, so callers can wait for them instead of failing a job for good. */
int srv_dbi_fail(conn *c, obs_err *err, const char *what) {
  int code = sqlite3_extended_errcode(c->db) & 0xff;
  if ((code == SQLITE_CORRUPT || code == SQLITE_NOTADB) && c->owner)
    atomic_store(&c->owner->corrupt_seen, 1);
  int transient = code == SQLITE_FULL || code == SQLITE_BUSY || code == SQLITE_LOCKED ||
                  code == SQLITE_IOERR || code == SQLITE_READONLY || code == SQLITE_CANTOPEN ||
                  code == SQLITE_PERM;
  return obs_err_set(err, transient ? OBS_ETRANSIENT : OBS_EIO, "database: %s: %s", what,
                     sqlite3_errmsg(c->db));
}

conn *srv_dbi_acquire(srv_sq *db) {
  pthread_mutex_lock(&db->mu);
  for (;;) {
    for (int i = 0; !db->exclusive && i < db->n; i++) {
      if (!db->c[i].in_use) {
        db->c[i].in_use = 1;
        pthread_mutex_unlock(&db->mu);
        return &db->c[i];
      }
    }
    pthread_cond_wait(&db->cv, &db->mu);
  }
}

void srv_dbi_release(srv_sq *db, conn *c) {
  pthread_mutex_lock(&db->mu);
  c->in_use = 0;
  /* Broadcast: an exclusive reopen waits on the same condition for all to be free. */
  pthread_cond_broadcast(&db->cv);
  pthread_mutex_unlock(&db->mu);
}

/* The statement, prepared once per connection and reset for reuse. */
sqlite3_stmt *srv_dbi_stmt(conn *c, int which, obs_err *err) {
  if (!c->st[which]) {
    if (sqlite3_prepare_v3(c->db, sql[which], -1, SQLITE_PREPARE_PERSISTENT, &c->st[which],
                           NULL) != SQLITE_OK) {
      srv_dbi_fail(c, err, "prepare");
      c->st[which] = NULL;
      return NULL;
    }
  }
  return c->st[which];
}

void srv_dbi_done(sqlite3_stmt *s) {
  if (!s) return;
  sqlite3_reset(s);
  sqlite3_clear_bindings(s);
}

void srv_dbi_bind_text(sqlite3_stmt *s, int i, const char *v) {
  if (v) sqlite3_bind_text(s, i, v, -1, SQLITE_TRANSIENT);
  else sqlite3_bind_null(s, i);
}

/* Runs a statement that returns no rows; SQLITE_DONE is success. */
int srv_dbi_exec_done(conn *c, sqlite3_stmt *s, obs_err *err, const char *what) {
  int rc = sqlite3_step(s);
  int out = rc == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, what);
  srv_dbi_done(s);
  return out;
}

static int simple(conn *c, int which, obs_err *err) {
  sqlite3_stmt *s = srv_dbi_stmt(c, which, err);
  return s ? srv_dbi_exec_done(c, s, err, sql[which]) : OBS_EIO;
}

int srv_dbi_begin(conn *c, obs_err *err) { return simple(c, ST_BEGIN, err); }
int srv_dbi_commit(conn *c, obs_err *err) { return simple(c, ST_COMMIT, err); }
void srv_dbi_rollback(conn *c) {
  if (!sqlite3_get_autocommit(c->db)) simple(c, ST_ROLLBACK, NULL);
}

char *srv_dbi_col_str(sqlite3_stmt *s, int i) {
  const unsigned char *t = sqlite3_column_text(s, i);
  return t ? strdup((const char *)t) : NULL;
}

/* ---- opening and migrations ------------------------------------------------------------------ */

static const char *errno_name(int e) {
  switch (e) {
    case EACCES: return "EACCES";
    case EPERM: return "EPERM";
    case EROFS: return "EROFS";
    case ENOENT: return "ENOENT";
    case ENOTDIR: return "ENOTDIR";
    case ENOSPC: return "ENOSPC";
    case EDQUOT: return "EDQUOT";
    case EIO: return "EIO";
    case ELOOP: return "ELOOP";
    case ENAMETOOLONG: return "ENAMETOOLONG";
    default: return "errno";
  }
}

/* Why the file system refuses `path` for a read-write database (SQLite says only "unable to open
 * database file"), naming the path at fault; 0 when no cause is found. */
static int explain_open(const char *path, char *out, size_t n) {
  char dir[PATH_MAX];
  snprintf(dir, sizeof dir, "%s", path);
  char *slash = strrchr(dir, '/');
  if (!slash) snprintf(dir, sizeof dir, ".");
  else if (slash == dir) dir[1] = '\0';
  else *slash = '\0';
  struct stat st;
  struct statvfs vfs;
  int e;
  if (stat(dir, &st)) {
    e = errno;
    snprintf(out, n, "the directory %s cannot be reached: %s (%s)", dir, strerror(e),
             errno_name(e));
  } else if (!S_ISDIR(st.st_mode)) {
    snprintf(out, n, "%s is not a directory", dir);
  } else if (!statvfs(dir, &vfs) && (vfs.f_flag & ST_RDONLY)) {
    snprintf(out, n, "the directory %s is on a read-only file system (EROFS)", dir);
  } else if (!stat(path, &st) && S_ISDIR(st.st_mode)) {
    snprintf(out, n, "%s is a directory", path);
  } else if (!stat(path, &st) && access(path, R_OK | W_OK)) {
    e = errno;
    snprintf(out, n, "the file %s is not writable: %s (%s)", path, strerror(e), errno_name(e));
  } else if (access(dir, W_OK | X_OK)) {
    /* Even an existing database needs its directory: the -wal and -shm files live there. */
    e = errno;
    snprintf(out, n, "the directory %s is not writable: %s (%s)", dir, strerror(e),
             errno_name(e));
  } else {
    return 0;
  }
  return 1;
}

/* Reports a failure to open or set up the database, with the file system's reason when found. */
static int open_failed(const char *path, const char *sqlite_msg, obs_err *err) {
  char why[PATH_MAX + 200];
  if (explain_open(path, why, sizeof why))
    return obs_err_set(err, OBS_EIO, "cannot open database %s: %s (SQLite: %s)", path, why,
                       sqlite_msg);
  return obs_err_set(err, OBS_EIO, "database %s: cannot open: %s", path, sqlite_msg);
}

int srv_dbi_open_conn(conn *c, const char *path, obs_err *err) {
  memset(c, 0, sizeof *c);
  int rc = sqlite3_open_v2(path, &c->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, NULL);
  if (rc != SQLITE_OK) {
    open_failed(path, c->db ? sqlite3_errmsg(c->db) : sqlite3_errstr(rc), err);
    sqlite3_close(c->db);
    c->db = NULL;
    return OBS_EIO;
  }
  sqlite3_busy_timeout(c->db, 5000);
  /* journal_size_limit truncates the WAL back to 4 MiB whenever a checkpoint resets it, so even
   * the automatic PASSIVE checkpoints keep the file bounded between our TRUNCATE ones. */
  static const char pragmas[] = "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL; "
                                "PRAGMA foreign_keys = ON; PRAGMA journal_size_limit = 4194304;";
  char *msg = NULL;
  if (sqlite3_exec(c->db, pragmas, NULL, NULL, &msg) != SQLITE_OK) {
    /* A file SQLite could only open read-only fails here, at the first write (the WAL switch). */
    open_failed(path, msg ? msg : "cannot configure", err);
    sqlite3_free(msg);
    sqlite3_close(c->db);
    c->db = NULL;
    return OBS_EIO;
  }
  return 0;
}

void srv_dbi_close_conn(conn *c) {
  for (int i = 0; i < ST_COUNT; i++) sqlite3_finalize(c->st[i]);
  sqlite3_close(c->db);
  memset(c, 0, sizeof *c);
}

/* Applies every "-- migration N" section of schema/db.sql newer than the database. */
static int migrate(conn *c, const char *path, obs_err *err) {
  char *msg = NULL;
  if (sqlite3_exec(c->db,
                   "CREATE TABLE IF NOT EXISTS schema_migrations (version INTEGER PRIMARY KEY, "
                   "applied_ms INTEGER NOT NULL)",
                   NULL, NULL, &msg) != SQLITE_OK) {
    open_failed(path, msg ? msg : "?", err);
    sqlite3_free(msg);
    return OBS_EIO;
  }
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_MIGRATION_MAX, err);
  if (!s) return OBS_EIO;
  int64_t have = sqlite3_step(s) == SQLITE_ROW ? sqlite3_column_int64(s, 0) : -1;
  srv_dbi_done(s);
  if (have < 0) return srv_dbi_fail(c, err, "reading schema_migrations");
  static const char marker[] = "\n-- migration ";
  int64_t latest = 0;
  const char *p = strstr(srv_db_sql, marker);
  while (p) {
    const char *num = p + sizeof marker - 1;
    int64_t v = strtoll(num, NULL, 10);
    const char *body = strchr(num, '\n');
    const char *next = body ? strstr(body, marker) : NULL;
    if (v != latest + 1 || !body)
      return obs_err_set(err, OBS_EINTERNAL, "schema/db.sql: migrations must be numbered 1, 2, ...");
    latest = v;
    if (v > have) {
      size_t n = next ? (size_t)(next - body) : strlen(body);
      char *text = strndup(body, n);
      if (!text) return obs_err_set(err, OBS_ENOMEM, "out of memory");
      int rc = srv_dbi_begin(c, err);
      if (!rc && sqlite3_exec(c->db, text, NULL, NULL, &msg) != SQLITE_OK) {
        rc = obs_err_set(err, OBS_EIO, "database %s: migration %lld: %s", path, (long long)v,
                         msg ? msg : "?");
        sqlite3_free(msg);
        msg = NULL;
      }
      free(text);
      if (!rc) {
        sqlite3_stmt *put = srv_dbi_stmt(c, ST_MIGRATION_PUT, err);
        if (!put) rc = OBS_EIO;
        else {
          sqlite3_bind_int64(put, 1, v);
          sqlite3_bind_int64(put, 2, srv_now_unix_ms());
          rc = srv_dbi_exec_done(c, put, err, "recording migration");
        }
      }
      if (!rc) rc = srv_dbi_commit(c, err);
      if (rc) {
        srv_dbi_rollback(c);
        return rc;
      }
      srv_log("database %s: applied migration %lld", path, (long long)v);
    }
    p = next;
  }
  if (have > latest)
    return obs_err_set(err, OBS_EINVAL,
                       "database %s is at schema version %lld, newer than this obscurad (%lld)",
                       path, (long long)have, (long long)latest);
  return 0;
}

/* Remembers which files were opened, so that a deleted or replaced database is noticed. */
int srv_dbi_record_identity(srv_sq *db, const char *path, obs_err *err) {
  for (int i = 0; i < db->n; i++) db->c[i].owner = db;
  atomic_init(&db->corrupt_seen, 0);
  if (db->path != path) {
    free(db->path);
    db->path = strdup(path);
    if (!db->path) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  struct stat st;
  if (stat(path, &st))
    return obs_err_set(err, OBS_EIO, "database %s: cannot stat: %s", path, strerror(errno));
  db->dev = st.st_dev;
  db->ino = st.st_ino;
  char wal[4200];
  snprintf(wal, sizeof wal, "%s-wal", path);
  db->wal_known = !stat(wal, &st);
  db->wal_dev = st.st_dev;
  db->wal_ino = st.st_ino;
  return 0;
}

int srv_dbi_fsync_path(const char *path) {
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  int rc = fsync(fd);
  close(fd);
  return rc;
}

/* VACUUM INTO `target` on c: a consistent copy of everything committed, WAL included. */
int srv_dbi_vacuum_into(conn *c, const char *target, obs_err *err) {
  sqlite3_stmt *s = NULL;
  if (sqlite3_prepare_v2(c->db, "VACUUM INTO ?1", -1, &s, NULL) != SQLITE_OK)
    return srv_dbi_fail(c, err, "VACUUM INTO");
  sqlite3_bind_text(s, 1, target, -1, SQLITE_TRANSIENT);
  int rc = sqlite3_step(s) == SQLITE_DONE ? 0 : srv_dbi_fail(c, err, "VACUUM INTO");
  sqlite3_finalize(s);
  if (!rc && srv_dbi_fsync_path(target))
    rc = obs_err_set(err, OBS_ETRANSIENT, "%s: cannot flush: %s", target, strerror(errno));
  char dir[4200];
  snprintf(dir, sizeof dir, "%s", target);
  char *slash = strrchr(dir, '/');
  if (slash) *slash = 0;
  if (!rc) srv_dbi_fsync_path(slash ? (slash == dir ? "/" : dir) : ".");
  return rc;
}

int srv_sq_open(srv_sq **out, const char *path, int nconn, const srv_node *node, obs_err *err) {
  *out = NULL;
  srv_sq *db = calloc(1, sizeof *db);
  if (!db) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  db->node = *node;
  db->c = calloc((size_t)nconn, sizeof *db->c);
  if (!db->c) {
    free(db);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  pthread_mutex_init(&db->mu, NULL);
  pthread_cond_init(&db->cv, NULL);
  int rc = 0;
  for (int i = 0; i < nconn && !rc; i++) {
    rc = srv_dbi_open_conn(&db->c[i], path, err);
    if (!rc) db->n = i + 1;
    if (!rc && i == 0) rc = migrate(&db->c[0], path, err);
  }
  if (!rc) rc = srv_dbi_record_identity(db, path, err);
  if (rc) {
    srv_sq_close(db);
    return rc;
  }
  *out = db;
  return 0;
}


void srv_sq_close(srv_sq *db) {
  if (!db) return;
  if (db->recovered[0] && db->n) {
    /* Jobs may have finished into the unlinked file since the copy was written: refresh it. */
    char tmp[4300];
    snprintf(tmp, sizeof tmp, "%s.tmp", db->recovered);
    unlink(tmp);
    obs_err e = OBS_ERR_INIT;
    if (srv_dbi_vacuum_into(&db->c[0], tmp, &e) || rename(tmp, db->recovered))
      srv_log("database: cannot refresh %s: %s", db->recovered, obs_err_message(&e));
    else
      srv_log("database: %s holds this daemon's jobs; move it to %s to keep them",
              db->recovered, db->path);
    obs_err_free(&e);
  }
  for (int i = 0; i < db->n; i++) srv_dbi_close_conn(&db->c[i]);
  free(db->c);
  free(db->path);
  pthread_mutex_destroy(&db->mu);
  pthread_cond_destroy(&db->cv);
  free(db);
}

int srv_dbi_refused(srv_sq *db, obs_err *err) {
  pthread_mutex_lock(&db->mu);
  int r = db->refuse[0] != 0;
  if (r) obs_err_set(err, OBS_ETRANSIENT, "not accepting work: %s", db->refuse);
  pthread_mutex_unlock(&db->mu);
  return r ? OBS_ETRANSIENT : 0;
}

void srv_sq_refuse(srv_sq *db, const char *msg) {
  pthread_mutex_lock(&db->mu);
  snprintf(db->refuse, sizeof db->refuse, "%s", msg ? msg : "");
  pthread_mutex_unlock(&db->mu);
}

const char *srv_sq_path(const srv_sq *db) { return db->path; }

int srv_sq_take_corrupt_flag(srv_sq *db) { return atomic_exchange(&db->corrupt_seen, 0); }

int srv_sq_checkpoint(srv_sq *db, obs_err *err) {
  conn *c = srv_dbi_acquire(db);
  sqlite3_stmt *s = srv_dbi_stmt(c, ST_CHECKPOINT, err);
  int rc = OBS_EIO;
  if (s) {
    int step = sqlite3_step(s);
    /* Row: (busy, wal frames, frames checkpointed); busy = readers kept it from finishing. */
    if (step == SQLITE_ROW) rc = sqlite3_column_int(s, 0) ? 1 : 0;
    else rc = srv_dbi_fail(c, err, "checkpoint");
    srv_dbi_done(s);
  }
  srv_dbi_release(db, c);
  return rc;
}
