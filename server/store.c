/* The store's dispatcher (db.h): every srv_db_* call goes to the SQLite implementation (db.c and
 * db_*.c) or the PostgreSQL one (pg*.c), chosen once when the store is opened; plus what both
 * share: the names of states and lanes, a job row's release and the node's identity. */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "store_impl.h"

struct srv_db {
  struct srv_sq *sq; /* exactly one of the two is set */
  struct srv_pg *pg;
  srv_node node;
};

/* The call on whichever implementation the store is. */
#define DISPATCH(fn, ...) \
  (db->pg ? srv_pg_##fn(db->pg, __VA_ARGS__) : srv_sq_##fn(db->sq, __VA_ARGS__))
/* The same for a call that takes only the store. */
#define DISPATCH0(fn) (db->pg ? srv_pg_##fn(db->pg) : srv_sq_##fn(db->sq))

static int is_url(const char *where) {
  return !strncmp(where, "postgresql://", 13) || !strncmp(where, "postgres://", 11);
}

int srv_db_open(srv_db **out, const char *where, int nconn, const srv_node *node, obs_err *err) {
  *out = NULL;
  srv_db *db = calloc(1, sizeof *db);
  if (!db) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  if (node)
    db->node = *node;
  else
    srv_node_init(&db->node, "local", 0);
  int rc = is_url(where) ? srv_pg_open(&db->pg, where, nconn, &db->node, err)
                         : srv_sq_open(&db->sq, where, nconn, &db->node, err);
  if (rc) {
    free(db);
    return rc;
  }
  *out = db;
  return 0;
}

void srv_db_close(srv_db *db) {
  if (!db) return;
  DISPATCH0(close);
  free(db);
}

srv_store_kind srv_db_kind(const srv_db *db) {
  return db->pg ? SRV_STORE_POSTGRESQL : SRV_STORE_SQLITE;
}
const srv_node *srv_db_node(const srv_db *db) { return &db->node; }

int srv_db_recover(srv_db *db,
                   int (*pick)(void *user, const char *technique, const char *backend_requested,
                               srv_lane stored, srv_lane *lane, obs_err *err),
                   void (*clean)(void *, int64_t), void *user, obs_err *err) {
  return DISPATCH(recover, pick, clean, user, err);
}
int srv_db_insert_job(srv_db *db, const srv_new_job *nj, int64_t *id, obs_err *err) {
  return DISPATCH(insert_job, nj, id, err);
}
int srv_db_get_job(srv_db *db, int64_t id, srv_job *j, obs_err *err) {
  return DISPATCH(get_job, id, j, err);
}
int srv_db_list_jobs(srv_db *db, const srv_job_filter *f, srv_job **jobs, int *n, obs_err *err) {
  return DISPATCH(list_jobs, f, jobs, n, err);
}
int srv_db_claim(srv_db *db, srv_lane lane, srv_job *j, obs_err *err) {
  return DISPATCH(claim, lane, j, err);
}
int srv_db_set_backend(srv_db *db, int64_t id, const char *backend, obs_err *err) {
  return DISPATCH(set_backend, id, backend, err);
}
int srv_db_finish_success(srv_db *db, int64_t id, int attempt, const char *backend,
                          const char *summary, const srv_output *outs, int nouts,
                          const srv_run *runs, int nruns, int64_t machine, obs_err *err) {
  return DISPATCH(finish_success, id, attempt, backend, summary, outs, nouts, runs, nruns, machine,
                  err);
}
int srv_db_machine(srv_db *db, const char *cpu_model, int cores, const char *vulkan_device,
                   const char *vulkan_kind, int64_t *id, obs_err *err) {
  return DISPATCH(machine, cpu_model, cores, vulkan_device, vulkan_kind, id, err);
}
int srv_db_insert_comparison(srv_db *db, const srv_new_comparison *c, int64_t *id, obs_err *err) {
  return DISPATCH(insert_comparison, c, id, err);
}
int srv_db_set_metrics(srv_db *db, int64_t comparison, int idx, int64_t job, const char *metrics,
                       const char *error, const srv_output *outs, int nouts, obs_err *err) {
  return DISPATCH(set_metrics, comparison, idx, job, metrics, error, outs, nouts, err);
}
int srv_db_query(srv_db *db, srv_query q, const srv_arg *args, int nargs, json_t **rows,
                 obs_err *err) {
  return DISPATCH(query, q, args, nargs, rows, err);
}
int srv_db_finish(srv_db *db, int64_t id, int attempt, srv_state state, const char *error,
                  double progress, obs_err *err) {
  return DISPATCH(finish, id, attempt, state, error, progress, err);
}
int srv_db_requeue(srv_db *db, int64_t id, int attempt, obs_err *err) {
  return DISPATCH(requeue, id, attempt, err);
}
int srv_db_cancel(srv_db *db, int64_t id, srv_cancel_result *res, obs_err *err) {
  return DISPATCH(cancel, id, res, err);
}
int srv_db_delete(srv_db *db, int64_t id, obs_err *err) { return DISPATCH(delete, id, err); }
int srv_db_retry(srv_db *db, int64_t id, srv_state *state, obs_err *err) {
  return DISPATCH(retry, id, state, err);
}
int srv_db_delete_comparison(srv_db *db, int64_t id, int64_t **ids, int *nids, obs_err *err) {
  return DISPATCH(delete_comparison, id, ids, nids, err);
}
int srv_db_get_output(srv_db *db, int64_t id, const char *name, srv_output *o, obs_err *err) {
  return DISPATCH(get_output, id, name, o, err);
}
int srv_db_counts(srv_db *db, int64_t counts[SRV_NSTATES], obs_err *err) {
  return DISPATCH(counts, counts, err);
}
int srv_db_job_exists(srv_db *db, int64_t id, srv_state *state, obs_err *err) {
  return DISPATCH(job_exists, id, state, err);
}
int srv_db_queued(srv_db *db, const char *client, srv_load *mine, srv_load *total, obs_err *err) {
  return DISPATCH(queued, client, mine, total, err);
}
int srv_db_job_load(srv_db *db, int64_t id, srv_load *load, srv_state *state, obs_err *err) {
  return DISPATCH(job_load, id, load, state, err);
}
int srv_db_set_job_client(srv_db *db, int64_t job, int64_t comparison, const char *client,
                          obs_err *err) {
  return DISPATCH(set_job_client, job, comparison, client, err);
}
int srv_db_run_rates(srv_db *db, const char *technique, const char *backend, int64_t machine,
                     double min_work, double **rates, size_t *n, obs_err *err) {
  return DISPATCH(run_rates, technique, backend, machine, min_work, rates, n, err);
}
int srv_db_heartbeat(srv_db *db, const int64_t *ids, const int *attempts, int n, int *held,
                     int *cancel, obs_err *err) {
  return DISPATCH(heartbeat, ids, attempts, n, held, cancel, err);
}
int srv_db_reap(srv_db *db, int *requeued, int *failed, obs_err *err) {
  return DISPATCH(reap, requeued, failed, err);
}
int srv_db_wait(srv_db *db, int timeout_ms, int *what, obs_err *err) {
  return DISPATCH(wait, timeout_ms, what, err);
}
int srv_db_results_shared(const srv_db *db) { return db->pg ? srv_pg_results_shared(db->pg) : 0; }
int srv_db_put_blob(srv_db *db, const char *sha256, const void *data, size_t n, obs_err *err) {
  return DISPATCH(put_blob, sha256, data, n, err);
}
int srv_db_get_blob(srv_db *db, const char *sha256, void **data, size_t *n, obs_err *err) {
  return DISPATCH(get_blob, sha256, data, n, err);
}
int srv_db_prune(srv_db *db, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err) {
  return DISPATCH(prune, keep_jobs, keep_days, ids, nids, err);
}
int srv_db_admit_lock(srv_db *db, obs_err *err) { return DISPATCH(admit_lock, err); }
void srv_db_admit_unlock(srv_db *db) { DISPATCH0(admit_unlock); }
void srv_db_refuse(srv_db *db, const char *msg) { DISPATCH(refuse, msg); }
const char *srv_db_path(const srv_db *db) { return DISPATCH0(path); }

/* ---- the SQLite file's own integrity checks: a PostgreSQL server has nothing to do here ------ */

int srv_db_checkpoint(srv_db *db, obs_err *err) {
  return db->sq ? srv_sq_checkpoint(db->sq, err) : 0;
}
srv_db_identity srv_db_check_identity(srv_db *db, char *detail, size_t n) {
  return db->sq ? srv_sq_check_identity(db->sq, detail, n) : SRV_DB_SAME;
}
int srv_db_restore(srv_db *db, srv_db_identity what, char *where, size_t n, obs_err *err) {
  return db->sq ? srv_sq_restore(db->sq, what, where, n, err) : 0;
}
int srv_db_quick_check(srv_db *db, obs_err *err) {
  return db->sq ? srv_sq_quick_check(db->sq, err) : 0;
}
int srv_db_probe(srv_db *db, char *code, size_t n, obs_err *err) {
  return db->sq ? srv_sq_probe(db->sq, code, n, err) : 0;
}
int srv_db_take_corrupt_flag(srv_db *db) { return db->sq ? srv_sq_take_corrupt_flag(db->sq) : 0; }
