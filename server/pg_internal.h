/* Private to the PostgreSQL store (pg*.c): the statement numbers, the connection pool, the
 * runner that retries an operation once on a fresh connection, and the helpers every part of it
 * uses to pass parameters as text and read rows. Nothing outside those files includes it. */
#ifndef OBSCURAD_PG_INTERNAL_H
#define OBSCURAD_PG_INTERNAL_H

#include <libpq-fe.h>
#include <pthread.h>

#include "store_impl.h"

/* Every statement the store runs, prepared per connection. Bound parameters only. */
enum {
  PGS_INSERT_JOBS,
  PGS_GET,
  PGS_OUTPUTS,
  PGS_CLAIM,
  PGS_SET_BACKEND,
  PGS_SUCCESS,
  PGS_OUT_CLEAR,
  PGS_OUT_INSERT,
  PGS_OUT_UPSERT,
  PGS_RUN_INSERT,
  PGS_FINISH,
  PGS_REQUEUE,
  PGS_STATE,
  PGS_STATE_LOCK,
  PGS_CANCEL_QUEUED,
  PGS_CANCEL_RUNNING,
  PGS_NOTIFY_CANCEL,
  PGS_DELETE,
  PGS_GET_OUTPUT,
  PGS_COUNTS,
  PGS_RETRY,
  PGS_MACHINE_INSERT,
  PGS_MACHINE_KIND,
  PGS_CMP_INSERT,
  PGS_CAND_INSERT,
  PGS_SET_METRICS,
  PGS_CMP_ACTIVE,
  PGS_CMP_DELETE,
  PGS_CMP_JOBS_DELETE,
  PGS_QUEUED,
  PGS_JOB_LOAD,
  PGS_SET_CLIENT,
  PGS_RUN_RATES,
  PGS_RECOVER,
  PGS_NOTIFY_JOBS,
  PGS_HEARTBEAT,
  PGS_REAP,
  PGS_BLOB_PUT,
  PGS_BLOB_GET,
  PGS_PRUNE_JOBS,
  PGS_PRUNE_CMPS,
  PGS_PRUNE_CMP_JOBS,
  PGS_PRUNE_BLOBS,
  PGS_LIST,                          /* PGS_LIST_VARIANTS list statements (pg_sql.c) */
  PGS_LIST_VARIANTS = 16,
  PGS_QUERY = PGS_LIST + PGS_LIST_VARIANTS, /* first of the SRV_NQUERIES srv_query statements */
  PGS_COUNT = PGS_QUERY + SRV_NQUERIES
};

/* The columns srv_pgi_read_job reads, in its order; a statement's further columns follow. */
#define PG_JOB_COLS                                                                               \
  "jobs.id, jobs.state, jobs.priority, jobs.label, jobs.scene, jobs.technique, "                  \
  "jobs.backend_requested, jobs.backend, jobs.lane, jobs.width, jobs.height, jobs.spp, "          \
  "jobs.attempts, jobs.cancel_requested, jobs.created_ms, jobs.started_ms, jobs.finished_ms, "    \
  "jobs.error, jobs.summary, jobs.progress, jobs.repeats, jobs.warmup, jobs.backend_reason, "     \
  "jobs.comparison, jobs.scene_name, jobs.notes, jobs.ranks, jobs.node"
#define PG_JOB_NCOLS 28

/* The SQL of statement `which` (pg_sql.c). */
const char *srv_pgi_sql(int which);
/* The list statement for a filter: which of state, technique, backend are set (bits 0..2) and the
 * order (bit 3: ascending). */
int srv_pgi_list_variant(int has_state, int has_technique, int has_backend, int ascending);

typedef struct pgc {
  PGconn *pq;
  unsigned char prepared[PGS_COUNT];
  int in_use;
  int broken; /* the last failure lost the connection: reset before the next use */
  int retry;  /* the last failure is worth one more try (lost connection, deadlock, conflict) */
} pgc;

struct srv_pg {
  pgc *c;
  int n;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  char *url;       /* as given, with its password */
  char *shown;     /* the password as *** */
  char app[200];   /* application_name */
  srv_node node; /* its lease_seconds: what a claim or a heartbeat grants */
  char refuse[1024]; /* under mu */
  pthread_mutex_t lmu; /* the listener */
  PGconn *listener;
  pthread_mutex_t amu; /* held from srv_pg_admit_lock to srv_pg_admit_unlock */
  PGconn *admit;       /* the session that holds the admission lock */
};

/* A connection of the pool, connected (or reset after a loss) and ready; NULL after filling err
 * (OBS_ETRANSIENT: the server cannot be reached). srv_pgi_release returns it. */
pgc *srv_pgi_acquire(struct srv_pg *pg);
void srv_pgi_release(struct srv_pg *pg, pgc *c);
PGconn *srv_pgi_connect(struct srv_pg *pg, obs_err *err);

/* Runs statement `which` with n text parameters (NULL = SQL NULL; lens and fmts may be NULL,
 * else fmts[i] = 1 passes vals[i] as lens[i] binary bytes), results in binary when binres.
 * Returns 0 with *res (the caller PQclears it; may be NULL when res is), or a negative code with
 * err filled: OBS_ETRANSIENT for a lost connection, a timeout, a deadlock or a serialization
 * failure (c->broken set for the first), OBS_EIO otherwise. */
int srv_pgi_exec(struct srv_pg *pg, pgc *c, int which, int n, const char *const *vals,
                 const int *lens, const int *fmts, int binres, PGresult **res, obs_err *err);
/* Plain SQL without parameters (BEGIN, COMMIT, migrations). */
int srv_pgi_simple(struct srv_pg *pg, pgc *c, const char *sql, obs_err *err);

/* An operation on one connection; `ctx` its arguments and results. It must start by resetting
 * its results: the runner may run it twice. */
typedef int (*srv_pgi_op)(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err);
/* Runs op on a pooled connection (inside BEGIN ... COMMIT when txn), once more on a fresh
 * connection when the first try lost its connection or met a deadlock or serialization failure
 * (the transaction rolled back, so nothing of it stayed). */
int srv_pgi_run(struct srv_pg *pg, int txn, srv_pgi_op op, void *ctx, obs_err *err);
/* One statement through srv_pgi_run: 0 with *res, or an error. */
int srv_pgi_one(struct srv_pg *pg, int which, int n, const char *const *vals, PGresult **res,
                obs_err *err);
/* Fills err and returns OBS_ETRANSIENT while work is refused. */
int srv_pgi_refused(struct srv_pg *pg, obs_err *err);

/* Parameters as text. */
const char *srv_pgi_i64(char buf[24], int64_t v);
const char *srv_pgi_f64(char buf[32], double v);
/* A growable buffer for array literals ({1,2,"text"}). */
typedef struct pgbuf {
  char *s;
  size_t n, cap;
  int oom;
} pgbuf;
void srv_pgi_arr_open(pgbuf *b);
void srv_pgi_arr_i64(pgbuf *b, int64_t v);
void srv_pgi_arr_f64(pgbuf *b, double v);
void srv_pgi_arr_text(pgbuf *b, const char *v); /* NULL = NULL */
/* Closes the literal: its text, or NULL (out of memory). */
const char *srv_pgi_arr_close(pgbuf *b);
void srv_pgi_buf_free(pgbuf *b);

/* Values of a row: NULL for SQL NULL (text), 0 for numbers. */
char *srv_pgi_str(const PGresult *r, int row, int col);
int64_t srv_pgi_int(const PGresult *r, int row, int col);
double srv_pgi_real(const PGresult *r, int row, int col);
/* Inserts jobs[0..n) in one statement (extra[i]: bytes stored beside job i's row, or NULL),
 * belonging to `comparison` (0: none), and wakes the nodes at commit; ids[i] is job i's id. */
int srv_pgi_insert_jobs(struct srv_pg *pg, pgc *c, const srv_new_job *const *jobs,
                        const int64_t *extra, int n, int64_t comparison, int64_t *ids,
                        obs_err *err);
/* Inserts (PGS_OUT_INSERT) or replaces (PGS_OUT_UPSERT) output rows of job `id`. */
int srv_pgi_put_outputs(struct srv_pg *pg, pgc *c, int which, int64_t id, const srv_output *outs,
                        int nouts, obs_err *err);
/* A row of PG_JOB_COLS into *j (zeroed first). */
void srv_pgi_read_job(const PGresult *r, int row, srv_job *j);

#endif
