/* Private to the database module (db.c, db_recover.c, db_limits.c): the statement numbers, the
 * connection pool and the helpers every part of it uses. Nothing outside those files includes it.
 * A conn belongs to the pool; srv_dbi_acquire lends one (waiting while all are lent or the pool
 * is being reopened) and srv_dbi_release returns it. */
#ifndef OBSCURAD_DB_INTERNAL_H
#define OBSCURAD_DB_INTERNAL_H

#include <sqlite3.h>
#include <stdatomic.h>
#include <sys/types.h>

#include "store_impl.h"

typedef struct srv_sq srv_sq;

/* Every statement the daemon runs. Bound parameters only: no SQL is ever built from input. */
enum {
  ST_BEGIN,
  ST_COMMIT,
  ST_ROLLBACK,
  ST_INSERT,
  ST_GET,
  ST_OUTPUTS,
  ST_LIST_DESC,
  ST_LIST_ASC,
  ST_CLAIM,
  ST_SET_BACKEND,
  ST_SUCCESS,
  ST_OUT_CLEAR,
  ST_OUT_INSERT,
  ST_FINISH,
  ST_REQUEUE,
  ST_STATE,
  ST_CANCEL_QUEUED,
  ST_CANCEL_RUNNING,
  ST_DELETE,
  ST_GET_OUTPUT,
  ST_COUNTS,
  ST_RUNNING_LIST,
  ST_QUEUED_LIST,
  ST_SET_LANE,
  ST_END_ANY,
  ST_REQUEUE_CRASH,
  ST_CHECKPOINT,
  ST_MIGRATION_MAX,
  ST_MIGRATION_PUT,
  ST_RUN_INSERT,
  ST_MACHINE_INSERT,
  ST_MACHINE_GET,
  ST_MACHINE_KIND,
  ST_CMP_INSERT,
  ST_CAND_INSERT,
  ST_SET_METRICS,
  ST_OUT_UPSERT,
  ST_RETRY,
  ST_CMP_ACTIVE,
  ST_CMP_JOBS,
  ST_CMP_DELETE,
  ST_JOB_DELETE_ANY,
  ST_HEARTBEAT,
  ST_QUERY, /* first of the SRV_NQUERIES read-only queries */
  ST_COUNT = ST_QUERY + SRV_NQUERIES
};

#define JOB_COLS                                                                                  \
  "id, state, priority, label, scene, technique, backend_requested, backend, lane, width, "      \
  "height, spp, attempts, cancel_requested, created_ms, started_ms, finished_ms, error, summary, " \
  "progress, repeats, warmup, backend_reason, (SELECT comparison FROM comparison_candidates "      \
  "WHERE job = jobs.id OR reference_job = jobs.id LIMIT 1), scene_name, notes, ranks, node"
/* How many columns JOB_COLS selects: a statement's further columns start there. */
#define JOB_NCOLS 28
#define LIST_WHERE                                                                                \
  "(?1 IS NULL OR state = ?1) AND (?2 IS NULL OR technique = ?2) AND "                           \
  "(?3 IS NULL OR coalesce(backend, backend_requested) = ?3) "

typedef struct conn {
  sqlite3 *db;
  sqlite3_stmt *st[ST_COUNT];
  int in_use;
  struct srv_sq *owner;
} conn;

struct srv_sq {
  conn *c;
  int n;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  int exclusive;               /* the pool is being reopened: acquire waits */
  char *path;
  srv_node node;               /* this daemon: the worker its claims record */
  dev_t dev, wal_dev;          /* identity of the files opened */
  ino_t ino, wal_ino;
  int wal_known;
  atomic_int corrupt_seen;     /* a statement met SQLITE_CORRUPT / SQLITE_NOTADB */
  char refuse[1024];           /* under mu: why inserts are refused, "" = accepted */
  char recovered[4200];        /* the copy written aside when the file was replaced */
};


/* An error from c as OBS_ETRANSIENT (full, busy, read-only, I/O: the environment's fault) or
 * OBS_EIO, with `what` and SQLite's message. */
int srv_dbi_fail(conn *c, obs_err *err, const char *what);
conn *srv_dbi_acquire(srv_sq *db);
void srv_dbi_release(srv_sq *db, conn *c);
/* Statement `which` (ST_*), prepared once per connection; NULL after filling err. */
sqlite3_stmt *srv_dbi_stmt(conn *c, int which, obs_err *err);
/* Resets a statement for reuse and clears its bindings. */
void srv_dbi_done(sqlite3_stmt *s);
/* Binds v, or NULL for a NULL pointer. */
void srv_dbi_bind_text(sqlite3_stmt *s, int i, const char *v);
/* Steps a statement that returns no rows (SQLITE_DONE is success), then resets it. */
int srv_dbi_exec_done(conn *c, sqlite3_stmt *s, obs_err *err, const char *what);
int srv_dbi_begin(conn *c, obs_err *err);
int srv_dbi_commit(conn *c, obs_err *err);
void srv_dbi_rollback(conn *c);
/* Column i as a new string, NULL for NULL. */
char *srv_dbi_col_str(sqlite3_stmt *s, int i);
int srv_dbi_open_conn(conn *c, const char *path, obs_err *err);
void srv_dbi_close_conn(conn *c);
/* Records st_dev/st_ino of the database file at `path`, for srv_db_check_identity. */
int srv_dbi_record_identity(srv_sq *db, const char *path, obs_err *err);
/* fsync of a file or directory by path. */
int srv_dbi_fsync_path(const char *path);
/* VACUUM INTO `target` on c, flushed: a consistent copy of everything committed. */
int srv_dbi_vacuum_into(conn *c, const char *target, obs_err *err);
/* Fills err and returns OBS_ETRANSIENT while work is refused (the database file was lost or is
 * corrupt): accepting a job that a restart would not find is losing it. */
int srv_dbi_refused(srv_sq *db, obs_err *err);
/* Inserts one job row on `c` (in autocommit or the caller's transaction). */
/* `extra`: bytes stored for the job beside its row (its candidate row; a comparison's row with
 * its first reference), added to its stored_bytes. */
int srv_dbi_insert_job(conn *c, const srv_new_job *nj, int64_t extra, int64_t *id, obs_err *err);
/* Inserts or replaces output rows of job `id` (statement `which`: ST_OUT_INSERT or UPSERT). */
int srv_dbi_put_outputs(conn *c, int which, int64_t id, const srv_output *outs, int nouts,
                        obs_err *err);

#endif
