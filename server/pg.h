/* obscurad's PostgreSQL store (server/pg*.c): the same operations as the SQLite store behind
 * db.h, each srv_pg_X taking the PostgreSQL handle where srv_db_X takes srv_db, plus the
 * operations only a store shared by several daemons needs (leases, heartbeats, the reaper,
 * wake-ups, content-addressed results, retention). Only the store's dispatcher includes it. */
#ifndef SRV_PG_H
#define SRV_PG_H

#include "obscurad.h"

#ifndef SRV_NODE_DEFINED
#define SRV_NODE_DEFINED
/* This daemon among those sharing a store: `name` is stable across restarts, `boot` random per
 * process start, and `worker` ("<name>/<boot>") what a running job's row holds. */
typedef struct srv_node {
  char name[128];
  char boot[40];
  char worker[170];
} srv_node;
#endif

#ifndef SRV_WAKE_DEFINED
#define SRV_WAKE_DEFINED
/* What srv_pg_wait woke for. */
enum { SRV_WAKE_JOBS = 1, SRV_WAKE_CANCEL = 2 };
#endif

#ifndef OBS_ECONFLICT
/* The row moved on: the job is no longer held by this node (its lease expired). */
#define OBS_ECONFLICT (-9)
#endif

struct srv_pg;

/* Connects `nconn` pooled connections and the listener to `url` (postgresql://...), applies the
 * migrations of schema/pg.sql (serialised between daemons by an advisory lock). */
int srv_pg_open(struct srv_pg **out, const char *url, int nconn, const srv_node *node,
                obs_err *err);
void srv_pg_close(struct srv_pg *pg);
/* The lease a claim or a heartbeat grants, in seconds (default 30). */
void srv_pg_set_lease(struct srv_pg *pg, double seconds);

int srv_pg_recover(struct srv_pg *pg,
                   int (*pick)(void *user, const char *technique, const char *backend_requested,
                               srv_lane stored, srv_lane *lane, obs_err *err),
                   void (*clean)(void *, int64_t), void *user, obs_err *err);
int srv_pg_insert_job(struct srv_pg *pg, const srv_new_job *nj, int64_t *id, obs_err *err);
int srv_pg_get_job(struct srv_pg *pg, int64_t id, srv_job *j, obs_err *err);
int srv_pg_list_jobs(struct srv_pg *pg, const srv_job_filter *f, srv_job **jobs, int *n,
                     obs_err *err);
int srv_pg_claim(struct srv_pg *pg, srv_lane lane, srv_job *j, obs_err *err);
int srv_pg_set_backend(struct srv_pg *pg, int64_t id, const char *backend, obs_err *err);
int srv_pg_finish_success(struct srv_pg *pg, int64_t id, int attempt, const char *backend,
                          const char *summary, const srv_output *outs, int nouts,
                          const srv_run *runs, int nruns, int64_t machine, obs_err *err);
int srv_pg_machine(struct srv_pg *pg, const char *cpu_model, int cores, const char *vulkan_device,
                   const char *vulkan_kind, int64_t *id, obs_err *err);
int srv_pg_insert_comparison(struct srv_pg *pg, const srv_new_comparison *c, int64_t *id,
                             obs_err *err);
int srv_pg_set_metrics(struct srv_pg *pg, int64_t comparison, int idx, int64_t job,
                       const char *metrics, const char *error, const srv_output *outs, int nouts,
                       obs_err *err);
int srv_pg_query(struct srv_pg *pg, srv_query q, const srv_arg *args, int nargs, json_t **rows,
                 obs_err *err);
int srv_pg_finish(struct srv_pg *pg, int64_t id, int attempt, srv_state state, const char *error,
                  double progress, obs_err *err);
int srv_pg_requeue(struct srv_pg *pg, int64_t id, int attempt, obs_err *err);
int srv_pg_cancel(struct srv_pg *pg, int64_t id, srv_cancel_result *res, obs_err *err);
int srv_pg_delete(struct srv_pg *pg, int64_t id, obs_err *err);
int srv_pg_retry(struct srv_pg *pg, int64_t id, srv_state *state, obs_err *err);
int srv_pg_delete_comparison(struct srv_pg *pg, int64_t id, int64_t **ids, int *nids,
                             obs_err *err);
int srv_pg_get_output(struct srv_pg *pg, int64_t id, const char *name, srv_output *o,
                      obs_err *err);
int srv_pg_counts(struct srv_pg *pg, int64_t counts[SRV_NSTATES], obs_err *err);
int srv_pg_job_exists(struct srv_pg *pg, int64_t id, srv_state *state, obs_err *err);
void srv_pg_refuse(struct srv_pg *pg, const char *msg);
/* The URL with any password shown as ***. */
const char *srv_pg_path(const struct srv_pg *pg);

/* The SQLite file's maintenance has nothing to do on a server: SAME, 0. */
int srv_pg_checkpoint(struct srv_pg *pg, obs_err *err);
srv_db_identity srv_pg_check_identity(struct srv_pg *pg, char *detail, size_t n);
int srv_pg_restore(struct srv_pg *pg, srv_db_identity what, char *where, size_t n, obs_err *err);
int srv_pg_quick_check(struct srv_pg *pg, obs_err *err);
int srv_pg_probe(struct srv_pg *pg, char *code, size_t n, obs_err *err);
int srv_pg_take_corrupt_flag(struct srv_pg *pg);

/* The admission limits' reads (obscurad.h). */
int srv_pg_queued(struct srv_pg *pg, const char *client, srv_load *mine, srv_load *total,
                  obs_err *err);
int srv_pg_job_load(struct srv_pg *pg, int64_t id, srv_load *load, srv_state *state,
                    obs_err *err);
int srv_pg_set_job_client(struct srv_pg *pg, int64_t job, int64_t comparison, const char *client,
                          obs_err *err);
int srv_pg_run_rates(struct srv_pg *pg, const char *technique, const char *backend,
                     int64_t machine, double min_work, double **rates, size_t *n, obs_err *err);

/* ---- the cluster's operations ---------------------------------------------------------------- */

/* Extends the lease of every job of ids[i] at attempt attempts[i] this worker still runs:
 * held[i] = 1 when the row is still ours, cancel[i] = its cancel_requested. */
int srv_pg_heartbeat(struct srv_pg *pg, const int64_t *ids, const int *attempts, int n, int *held,
                     int *cancel, obs_err *err);
/* Running jobs whose lease expired (by the database's clock) go back to the queue after a
 * back-off, or fail at max_attempts (cancelled when a cancel was pending); each records a
 * failure of its node. Idempotent; every node runs it. */
int srv_pg_reap(struct srv_pg *pg, int *requeued, int *failed, obs_err *err);
/* Waits on the listener: 1 with *what (SRV_WAKE_*) when notified, 0 after timeout_ms, <0 when
 * the listener is lost (the next call reconnects). */
int srv_pg_wait(struct srv_pg *pg, int timeout_ms, int *what);
int srv_pg_put_blob(struct srv_pg *pg, const char *sha256, const void *data, size_t n,
                    obs_err *err);
/* *data malloc'd; OBS_ENOTFOUND when absent. */
int srv_pg_get_blob(struct srv_pg *pg, const char *sha256, void **data, size_t *n, obs_err *err);
/* 1: outputs travel through the store (the caller overrides it with a shared results dir). */
int srv_pg_results_shared(struct srv_pg *pg);
/* Deletes finished jobs beyond the newest keep_jobs or finished more than keep_days ago (0: no
 * such limit), a comparison only whole (with all its jobs) once every job of it is past the
 * limits; the deleted job ids in *ids (malloc'd). At most a batch per call: call again while it
 * deletes something. */
int srv_pg_prune(struct srv_pg *pg, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err);

#endif
