/* The PostgreSQL store's operations for several daemons sharing it: a restarted node's recovery
 * of what its previous boot left running, heartbeats that extend leases and carry cancellations,
 * the reaper of expired leases, wake-ups by LISTEN/NOTIFY, content-addressed result blobs, and
 * retention. Every lease is judged by the database's clock. */
#include <limits.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "pg_internal.h"

/* Jobs and comparisons one srv_pg_prune call deletes at most: short transactions. */
#define PRUNE_JOBS 1000
#define PRUNE_COMPARISONS 50

/* Queued jobs keep the lane they were stored with: on a shared queue the node that can run a lane
 * claims it, so no single node's devices decide (pick is the SQLite store's). */
int srv_pg_recover(struct srv_pg *pg,
                   int (*pick)(void *user, const char *technique, const char *backend_requested,
                               srv_lane stored, srv_lane *lane, obs_err *err),
                   void (*clean)(void *, int64_t), void *user, obs_err *err) {
  (void)pick;
  const char *v[] = {pg->node.name, pg->node.worker};
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_RECOVER, 2, v, &r, err);
  if (rc) return rc;
  int requeued = 0;
  for (int i = 0; i < PQntuples(r); i++) {
    const char *state = PQgetvalue(r, i, 1);
    requeued |= !strcmp(state, "queued");
    srv_log("job %s: running -> %s (%s)", PQgetvalue(r, i, 0), state, PQgetvalue(r, i, 2));
  }
  /* Half-written outputs go only after the commit: a crash here just repeats the sweep. */
  for (int i = 0; clean && i < PQntuples(r); i++) clean(user, srv_pgi_int(r, i, 0));
  PQclear(r);
  if (requeued) rc = srv_pgi_one(pg, PGS_NOTIFY_JOBS, 0, NULL, NULL, err);
  return rc;
}

int srv_pg_heartbeat(struct srv_pg *pg, const int64_t *ids, const int *attempts, int n, int *held,
                     int *cancel, obs_err *err) {
  for (int i = 0; i < n; i++) held[i] = cancel[i] = 0;
  if (n == 0) return 0;
  pgbuf a[2];
  srv_pgi_arr_open(&a[0]);
  srv_pgi_arr_open(&a[1]);
  for (int i = 0; i < n; i++) {
    srv_pgi_arr_i64(&a[0], ids[i]);
    srv_pgi_arr_i64(&a[1], attempts[i]);
  }
  char lease[32];
  const char *v[] = {srv_pgi_arr_close(&a[0]), srv_pgi_arr_close(&a[1]), pg->node.worker,
                     srv_pgi_f64(lease, pg->node.lease_seconds)};
  PGresult *r = NULL;
  int rc = !v[0] || !v[1] ? obs_err_set(err, OBS_ENOMEM, "out of memory")
                          : srv_pgi_one(pg, PGS_HEARTBEAT, 4, v, &r, err);
  srv_pgi_buf_free(&a[0]);
  srv_pgi_buf_free(&a[1]);
  if (rc) return rc;
  for (int k = 0; k < PQntuples(r); k++) {
    int64_t id = srv_pgi_int(r, k, 0);
    for (int i = 0; i < n; i++) {
      if (ids[i] == id) {
        held[i] = 1;
        cancel[i] = srv_pgi_int(r, k, 1) != 0;
      }
    }
  }
  PQclear(r);
  return 0;
}

int srv_pg_reap(struct srv_pg *pg, int *requeued, int *failed, obs_err *err) {
  *requeued = *failed = 0;
  PGresult *r;
  int rc = srv_pgi_one(pg, PGS_REAP, 0, NULL, &r, err);
  if (rc) return rc;
  *requeued = (int)srv_pgi_int(r, 0, 0);
  *failed = (int)srv_pgi_int(r, 0, 1);
  PQclear(r);
  if (*requeued || *failed)
    srv_log("database %s: %d expired leases requeued, %d jobs ended", pg->shown, *requeued,
            *failed);
  return 0;
}

/* ---- wake-ups -------------------------------------------------------------------------------- */

static PGconn *listen_conn(struct srv_pg *pg, obs_err *err) {
  PGconn *l = srv_pgi_connect(pg, err);
  if (l) {
    PGresult *r = PQexec(l, "LISTEN obscura_jobs; LISTEN obscura_cancel");
    if (PQresultStatus(r) != PGRES_COMMAND_OK) {
      obs_err_set(err, OBS_ETRANSIENT, "database %s: LISTEN: %s", pg->shown, PQerrorMessage(l));
      PQfinish(l);
      l = NULL;
    }
    PQclear(r);
  }
  return l;
}

int srv_pg_wait(struct srv_pg *pg, int timeout_ms, int *what, obs_err *err) {
  *what = 0;
  pthread_mutex_lock(&pg->lmu);
  int rc = 0;
  if (!pg->listener || PQstatus(pg->listener) != CONNECTION_OK) {
    PQfinish(pg->listener);
    pg->listener = listen_conn(pg, err);
    if (!pg->listener) {
      pthread_mutex_unlock(&pg->lmu);
      /* No spinning while the server is away: the caller's loop comes back after the wait. */
      if (timeout_ms > 0) usleep((useconds_t)timeout_ms * 1000);
      return OBS_ETRANSIENT;
    }
    /* What was notified while no one listened is unknown: look at the queue once. */
    *what = SRV_WAKE_JOBS;
    pthread_mutex_unlock(&pg->lmu);
    return 1;
  }
  PGconn *l = pg->listener;
  PGnotify *n = PQnotifies(l);
  /* Input that holds no notification (a notice, the server's last words before closing) is read
   * and the wait goes on to its end: a closed socket stays readable and fails the next read. */
  struct timespec t0;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  while (!n) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    long spent = (t.tv_sec - t0.tv_sec) * 1000L + (t.tv_nsec - t0.tv_nsec) / 1000000L;
    if (spent >= timeout_ms && spent > 0) break;
    struct pollfd p = {PQsocket(l), POLLIN, 0};
    int ready = poll(&p, 1, timeout_ms - (int)spent);
    if (ready <= 0) break;
    if (!PQconsumeInput(l) || PQstatus(l) != CONNECTION_OK) {
      rc = obs_err_set(err, OBS_ETRANSIENT, "database %s: the listener was lost: %s", pg->shown,
                       PQerrorMessage(l));
      PQfinish(l);
      pg->listener = NULL;
      break;
    }
    n = PQnotifies(l);
  }
  if (n) {
    *what = !strcmp(n->relname, "obscura_cancel") ? SRV_WAKE_CANCEL : SRV_WAKE_JOBS;
    PQfreemem(n);
    rc = 1;
  }
  pthread_mutex_unlock(&pg->lmu);
  return rc;
}

/* ---- results --------------------------------------------------------------------------------- */

static int check_sha(const char *sha256, obs_err *err) {
  size_t n = sha256 ? strspn(sha256, "0123456789abcdef") : 0;
  if (n != 64 || sha256[64])
    return obs_err_set(err, OBS_EINVAL, "blob name '%s' is not a SHA-256 in lowercase hex",
                       sha256 ? sha256 : "(null)");
  return 0;
}

typedef struct blob_ctx {
  const char *sha256;
  const void *in;
  size_t n;
  void **out;
  size_t *nout;
} blob_ctx;

static int blob_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  blob_ctx *x = ctx;
  if (x->in) {
    const char *v[] = {x->sha256, x->in};
    const int lens[] = {0, (int)x->n};
    const int fmts[] = {0, 1};
    return srv_pgi_exec(pg, c, PGS_BLOB_PUT, 2, v, lens, fmts, 0, NULL, err);
  }
  free(*x->out);
  *x->out = NULL;
  *x->nout = 0;
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_BLOB_GET, 1, &x->sha256, NULL, NULL, 1, &r, err);
  if (rc) return rc;
  if (PQntuples(r) == 0) {
    PQclear(r);
    return OBS_ENOTFOUND;
  }
  size_t n = (size_t)PQgetlength(r, 0, 0);
  *x->out = malloc(n ? n : 1);
  if (!*x->out) rc = obs_err_set(err, OBS_ENOMEM, "out of memory");
  else {
    memcpy(*x->out, PQgetvalue(r, 0, 0), n);
    *x->nout = n;
  }
  PQclear(r);
  return rc;
}

int srv_pg_put_blob(struct srv_pg *pg, const char *sha256, const void *data, size_t n,
                    obs_err *err) {
  int rc = check_sha(sha256, err);
  if (rc) return rc;
  if (n > (size_t)INT_MAX / 2)
    return obs_err_set(err, OBS_EINVAL, "blob %s: %zu bytes is more than the store takes",
                       sha256, n);
  blob_ctx x = {sha256, data ? data : "", n, NULL, NULL};
  return srv_pgi_run(pg, 0, blob_op, &x, err);
}

int srv_pg_get_blob(struct srv_pg *pg, const char *sha256, void **data, size_t *n, obs_err *err) {
  *data = NULL;
  *n = 0;
  int rc = check_sha(sha256, err);
  if (rc) return rc;
  blob_ctx x = {sha256, NULL, 0, data, n};
  rc = srv_pgi_run(pg, 0, blob_op, &x, err);
  if (rc == OBS_ENOTFOUND) obs_err_set(err, rc, "no blob %s", sha256);
  return rc;
}

/* ---- retention ------------------------------------------------------------------------------- */

typedef struct prune_ctx {
  const char *v[3];
  int64_t **ids;
  int *nids;
} prune_ctx;

static int append_ids(PGresult *r, int64_t **ids, int *nids, obs_err *err) {
  int n = PQntuples(r);
  int64_t *g = realloc(*ids, ((size_t)*nids + (size_t)n + 1) * sizeof *g);
  if (!g) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  *ids = g;
  for (int i = 0; i < n; i++) g[(*nids)++] = srv_pgi_int(r, i, 0);
  return 0;
}

static int prune_op(struct srv_pg *pg, pgc *c, void *ctx, obs_err *err) {
  prune_ctx *x = ctx;
  free(*x->ids);
  *x->ids = NULL;
  *x->nids = 0;
  char lim[24];
  const char *v[] = {x->v[0], x->v[1], srv_pgi_i64(lim, PRUNE_JOBS)};
  PGresult *r;
  int rc = srv_pgi_exec(pg, c, PGS_PRUNE_JOBS, 3, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  rc = append_ids(r, x->ids, x->nids, err);
  PQclear(r);
  v[2] = srv_pgi_i64(lim, PRUNE_COMPARISONS);
  if (!rc) rc = srv_pgi_exec(pg, c, PGS_PRUNE_CMPS, 3, v, NULL, NULL, 0, &r, err);
  if (rc) return rc;
  pgbuf cmps;
  srv_pgi_arr_open(&cmps);
  for (int i = 0; i < PQntuples(r); i++) srv_pgi_arr_i64(&cmps, srv_pgi_int(r, i, 0));
  int ncmp = PQntuples(r);
  PQclear(r);
  const char *cv[] = {srv_pgi_arr_close(&cmps)};
  if (!cv[0]) rc = obs_err_set(err, OBS_ENOMEM, "out of memory");
  else if (ncmp) rc = srv_pgi_exec(pg, c, PGS_PRUNE_CMP_JOBS, 1, cv, NULL, NULL, 0, &r, err);
  if (!rc && ncmp) {
    rc = append_ids(r, x->ids, x->nids, err);
    PQclear(r);
  }
  srv_pgi_buf_free(&cmps);
  if (!rc) rc = srv_pgi_exec(pg, c, PGS_PRUNE_BLOBS, 0, NULL, NULL, NULL, 0, NULL, err);
  return rc;
}

int srv_pg_prune(struct srv_pg *pg, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err) {
  *ids = NULL;
  *nids = 0;
  if (keep_jobs < 0 || !(keep_days >= 0))
    return obs_err_set(err, OBS_EINVAL, "retention: keep_jobs %lld and keep_days %g must be >= 0",
                       (long long)keep_jobs, keep_days);
  char kj[24], kd[32];
  prune_ctx x = {{srv_pgi_i64(kj, keep_jobs), srv_pgi_f64(kd, keep_days)}, ids, nids};
  int rc = srv_pgi_run(pg, 1, prune_op, &x, err);
  if (rc) {
    free(*ids);
    *ids = NULL;
    *nids = 0;
  }
  return rc;
}
