/* Retention: under --keep-jobs / --keep-days, a thread prunes the store at start and every minute
 * (srv_db_prune deletes finished jobs past the limits, comparisons only whole) and removes the
 * results directory and log of every job it deleted. With both limits 0 nothing runs and the
 * history is kept whole. */
#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "obscurad.h"

#define PERIOD_S 60

static pthread_t thread;
static int running;
static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t cv = PTHREAD_COND_INITIALIZER;
static int stopping;

/* A pruned job's files. Not srv_outputs_remove: that also looks through the whole results
 * directory for the job's half-written attempts, a walk as long as the history, and a finished
 * job has none (the start-up sweep removes what a crash left). */
static void remove_files(const srv_app *app, int64_t id) {
  srv_job_log_remove(app, id);
  char path[8400];
  srv_results_path(app, id, path, sizeof path);
  if (srv_remove_tree(path))
    srv_log("retention: job %lld: cannot remove %s: %s", (long long)id, path, strerror(errno));
}

/* Between two batches of one pass: the lock is free this long for the requests and workers
 * waiting on it (SQLite's busy handler polls; back-to-back transactions could starve a claim). */
#define BATCH_PAUSE_MS 100

/* Waits ms or until stopped; returns 1 when stopping. */
static int pause_ms(long ms) {
  struct timespec until;
  clock_gettime(CLOCK_REALTIME, &until);
  until.tv_sec += ms / 1000;
  until.tv_nsec += (ms % 1000) * 1000000L;
  if (until.tv_nsec >= 1000000000L) {
    until.tv_sec++;
    until.tv_nsec -= 1000000000L;
  }
  pthread_mutex_lock(&mu);
  while (!stopping && pthread_cond_timedwait(&cv, &mu, &until) != ETIMEDOUT) {
  }
  int stop = stopping;
  pthread_mutex_unlock(&mu);
  return stop;
}

int srv_retention_pass(srv_app *app, obs_err *err) {
  int total = 0;
  for (int batch = 0; !batch || !pause_ms(BATCH_PAUSE_MS); batch++) {
    int64_t *ids = NULL;
    int n = 0;
    int rc = srv_db_prune(app->db, app->cfg.keep_jobs, app->cfg.keep_days, &ids, &n, err);
    if (rc) return rc;
    for (int i = 0; i < n; i++) remove_files(app, ids[i]);
    free(ids);
    total += n;
    if (!n) break;
  }
  return total;
}

static void *loop(void *arg) {
  srv_app *app = arg;
  do {
    obs_err err = OBS_ERR_INIT;
    int n = srv_retention_pass(app, &err);
    if (n < 0) srv_log("retention: %s (trying again in %d s)", obs_err_message(&err), PERIOD_S);
    else if (n > 0)
      srv_log("retention: removed %d finished job(s) past keep-jobs = %lld, keep-days = %g", n,
              (long long)app->cfg.keep_jobs, app->cfg.keep_days);
    obs_err_free(&err);
  } while (!pause_ms(PERIOD_S * 1000L));
  return NULL;
}

int srv_retention_start(srv_app *app, obs_err *err) {
  if (app->cfg.keep_jobs <= 0 && app->cfg.keep_days <= 0) return 0;
  stopping = 0;
  int e = pthread_create(&thread, NULL, loop, app);
  if (e) return obs_err_set(err, OBS_EIO, "retention: cannot start its thread: %s", strerror(e));
  running = 1;
  return 0;
}

void srv_retention_stop(srv_app *app) {
  (void)app;
  if (!running) return;
  pthread_mutex_lock(&mu);
  stopping = 1;
  pthread_cond_broadcast(&cv);
  pthread_mutex_unlock(&mu);
  pthread_join(thread, NULL);
  running = 0;
}
