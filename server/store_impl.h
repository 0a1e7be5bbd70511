/* The contract each store implementation fulfils, written once: SRV_STORE_DECLARE(prefix, handle)
 * declares every function of db.h's interface as prefix_X(handle *, ...) with the public
 * signature's other parameters, so the compiler checks the SQLite (srv_sq, db*.c) and PostgreSQL
 * (srv_pg, pg*.c) implementations against the same list. Only store.c and the implementations
 * include it. */
#ifndef SRV_STORE_IMPL_H
#define SRV_STORE_IMPL_H

#include "obscurad.h"

#define SRV_STORE_DECLARE(P, H)                                                                    \
  int P##_open(H **out, const char *where, int nconn, const srv_node *node, obs_err *err);         \
  void P##_close(H *db);                                                                           \
  int P##_recover(H *db,                                                                           \
                  int (*pick)(void *user, const char *technique, const char *backend_requested,    \
                              srv_lane stored, srv_lane *lane, obs_err *err),                      \
                  void (*clean)(void *, int64_t), void *user, obs_err *err);                       \
  int P##_insert_job(H *db, const srv_new_job *nj, int64_t *id, obs_err *err);                     \
  int P##_get_job(H *db, int64_t id, srv_job *j, obs_err *err);                                    \
  int P##_list_jobs(H *db, const srv_job_filter *f, srv_job **jobs, int *n, obs_err *err);         \
  int P##_claim(H *db, srv_lane lane, srv_job *j, obs_err *err);                                   \
  int P##_set_backend(H *db, int64_t id, const char *backend, obs_err *err);                       \
  int P##_finish_success(H *db, int64_t id, int attempt, const char *backend, const char *summary, \
                         const srv_output *outs, int nouts, const srv_run *runs, int nruns,        \
                         int64_t machine, obs_err *err);                                           \
  int P##_machine(H *db, const char *cpu_model, int cores, const char *vulkan_device,              \
                  const char *vulkan_kind, int64_t *id, obs_err *err);                             \
  int P##_insert_comparison(H *db, const srv_new_comparison *c, int64_t *id, obs_err *err);        \
  int P##_set_metrics(H *db, int64_t comparison, int idx, int64_t job, const char *metrics,        \
                      const char *error, const srv_output *outs, int nouts, obs_err *err);         \
  int P##_query(H *db, srv_query q, const srv_arg *args, int nargs, json_t **rows, obs_err *err);  \
  int P##_finish(H *db, int64_t id, int attempt, srv_state state, const char *error,               \
                 double progress, obs_err *err);                                                   \
  int P##_requeue(H *db, int64_t id, int attempt, obs_err *err);                                   \
  int P##_cancel(H *db, int64_t id, srv_cancel_result *res, obs_err *err);                         \
  int P##_delete(H *db, int64_t id, obs_err *err);                                                 \
  int P##_retry(H *db, int64_t id, srv_state *state, obs_err *err);                                \
  int P##_delete_comparison(H *db, int64_t id, int64_t **ids, int *nids, obs_err *err);            \
  int P##_get_output(H *db, int64_t id, const char *name, srv_output *o, obs_err *err);            \
  int P##_counts(H *db, int64_t counts[SRV_NSTATES], obs_err *err);                                \
  int P##_job_exists(H *db, int64_t id, srv_state *state, obs_err *err);                           \
  int P##_queued(H *db, const char *client, srv_load *mine, srv_load *total, obs_err *err);        \
  int P##_job_load(H *db, int64_t id, srv_load *load, srv_state *state, obs_err *err);             \
  int P##_set_job_client(H *db, int64_t job, int64_t comparison, const char *client,               \
                         obs_err *err);                                                            \
  int P##_run_rates(H *db, const char *technique, const char *backend, int64_t machine,            \
                    double min_work, double **rates, size_t *n, obs_err *err);                     \
  int P##_heartbeat(H *db, const int64_t *ids, const int *attempts, int n, int *held, int *cancel, \
                    obs_err *err);                                                                 \
  int P##_reap(H *db, int *requeued, int *failed, obs_err *err);                                   \
  int P##_wait(H *db, int timeout_ms, int *what, obs_err *err);                                    \
  int P##_put_blob(H *db, const char *sha256, const void *data, size_t n, obs_err *err);           \
  int P##_get_blob(H *db, const char *sha256, void **data, size_t *n, obs_err *err);               \
  int P##_prune(H *db, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,              \
                obs_err *err);                                                                     \
  int P##_admit_lock(H *db, obs_err *err);                                                        \
  void P##_admit_unlock(H *db);                                                                   \
  void P##_refuse(H *db, const char *msg);                                                         \
  const char *P##_path(const H *db);

struct srv_sq;
struct srv_pg;
SRV_STORE_DECLARE(srv_sq, struct srv_sq)
SRV_STORE_DECLARE(srv_pg, struct srv_pg)

/* What only the SQLite file has (the maintenance thread's integrity checks); the PostgreSQL server
 * keeps its own files, so for it store.c answers "nothing to do". */
int srv_sq_checkpoint(struct srv_sq *db, obs_err *err);
srv_db_identity srv_sq_check_identity(struct srv_sq *db, char *detail, size_t n);
int srv_sq_restore(struct srv_sq *db, srv_db_identity what, char *where, size_t n, obs_err *err);
int srv_sq_quick_check(struct srv_sq *db, obs_err *err);
int srv_sq_probe(struct srv_sq *db, char *code, size_t n, obs_err *err);
int srv_sq_take_corrupt_flag(struct srv_sq *db);
/* A PostgreSQL store whose outputs live in a shared --results-dir rather than in blobs. */
int srv_pg_results_shared(const struct srv_pg *db);

#endif
