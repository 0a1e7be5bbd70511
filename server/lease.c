/* The node loop of obscurad: one thread that keeps this node's claims alive in the store. Every
 * third of a lease it heartbeats the jobs the scheduler's slots run (a job the store no longer
 * gives this node is stopped and its outputs dropped; a cancel requested through another node
 * stops its render); every half lease it runs the reaper, which gives expired leases of any node
 * back to the queue; in between it waits on the store's wake-ups (jobs queued by another node
 * wake the workers, a cancel heartbeats at once). With a shared store, a node that could not
 * heartbeat for two thirds of a lease stops every render and drops its outputs, since the reaper
 * of another node is about to requeue them. It calls the scheduler's small API and the store
 * only. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "obscurad.h"

/* Heartbeats of one attempt are written to its job's log at the 1st, 2nd, 4th, 8th ... beat:
 * enough to see the loop at work on a long render without a line every few seconds. */
typedef struct beat {
  int64_t id;
  int attempt;
  int count;
} beat;

struct srv_lease {
  pthread_t thread;
  pthread_mutex_t mu;
  pthread_cond_t cv; /* stopping */
  int stopping;
  int nslots;
  int64_t *ids;
  int *attempts, *held, *cancel;
  beat *beats;      /* the previous round's attempts and their beat counts */
  beat *next;       /* this round's */
  int nbeats;
  double last_ok_ms; /* the last heartbeat the store answered (obs_now_ms clock) */
  int failing;       /* heartbeats fail: said once in the log */
  int dropped;       /* renders stopped for want of a heartbeat: said once */
};

static int is_stopping(struct srv_lease *l) {
  pthread_mutex_lock(&l->mu);
  int s = l->stopping;
  pthread_mutex_unlock(&l->mu);
  return s;
}

/* The beat count of (id, attempt) this round, carried over from the previous round. */
static int count_beat(struct srv_lease *l, beat *next, int n, int64_t id, int attempt) {
  int c = 1;
  for (int k = 0; k < l->nbeats; k++)
    if (l->beats[k].id == id && l->beats[k].attempt == attempt) c = l->beats[k].count + 1;
  next[n] = (beat){id, attempt, c};
  return c;
}

static int power_of_two(int c) { return c > 0 && !(c & (c - 1)); }

/* One heartbeat round over the busy slots. */
static void heartbeat(srv_app *app, struct srv_lease *l) {
  int shared = srv_db_kind(app->db) == SRV_STORE_POSTGRESQL;
  int lease_ms = srv_db_node(app->db)->lease_seconds * 1000;
  int n = srv_sched_busy(app, l->ids, l->attempts, l->nslots);
  double now = obs_now_ms();
  if (!n) {
    l->last_ok_ms = now; /* nothing held: nothing to lose */
    l->nbeats = 0;
    return;
  }
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_heartbeat(app->db, l->ids, l->attempts, n, l->held, l->cancel, &err);
  if (rc) {
    /* A SQLite store's leases never lapse (no other node takes its jobs), and its faults are the
     * maintenance thread's to report: only a shared store's failing heartbeats matter here. */
    if (shared && !l->failing)
      srv_log("heartbeat: the store does not answer (%s); renders stop if it stays so for %.1f s",
              obs_err_message(&err), (2.0 * lease_ms / 3 - (now - l->last_ok_ms)) / 1e3);
    l->failing = 1;
    obs_err_free(&err);
    if (shared && now - l->last_ok_ms >= 2.0 * lease_ms / 3) {
      int stopped = 0;
      for (int i = 0; i < n; i++)
        stopped += srv_sched_stop_job(app, l->ids[i], l->attempts[i], SRV_STOP_LEASE);
      if (stopped && !l->dropped)
        srv_log("heartbeat: none for %.1f s (2/3 of the lease): %d render(s) stopped, their "
                "outputs dropped; the store's reaper requeues them",
                (now - l->last_ok_ms) / 1e3, stopped);
      l->dropped = 1;
    }
    return;
  }
  if (l->failing && shared) srv_log("heartbeat: the store answers again");
  l->failing = l->dropped = 0;
  l->last_ok_ms = now;
  beat *next = l->next;
  for (int i = 0; i < n; i++) {
    if (!l->held[i]) {
      /* The worker logs it and drops the outputs (outcome.c). */
      srv_sched_stop_job(app, l->ids[i], l->attempts[i], SRV_STOP_LEASE);
      next[i] = (beat){0, 0, 0};
      continue;
    }
    if (l->cancel[i] && srv_sched_stop_job(app, l->ids[i], l->attempts[i], SRV_STOP_CANCEL))
      srv_job_log(app, l->ids[i], "cancel requested through another node: stopping the render");
    int c = count_beat(l, next, i, l->ids[i], l->attempts[i]);
    if (power_of_two(c))
      srv_job_log(app, l->ids[i], "heartbeat %d: lease of attempt %d held for %d s more", c,
                  l->attempts[i], lease_ms / 1000);
  }
  memcpy(l->beats, next, (size_t)n * sizeof *next);
  l->nbeats = n;
}

static void reap(srv_app *app) {
  int requeued = 0, failed = 0;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_reap(app->db, &requeued, &failed, &err);
  if (rc && srv_db_kind(app->db) == SRV_STORE_POSTGRESQL)
    srv_log("reaper: %s", obs_err_message(&err));
  else if (!rc && (requeued || failed))
    srv_log("reaper: %d job(s) whose lease expired requeued, %d failed (attempts used up)",
            requeued, failed);
  obs_err_free(&err);
  if (!rc && requeued) srv_sched_notify(app);
}

static void *loop(void *arg) {
  srv_app *app = arg;
  struct srv_lease *l = app->lease;
  int lease_ms = srv_db_node(app->db)->lease_seconds * 1000;
  double next_beat = obs_now_ms() + lease_ms / 3.0, next_reap = obs_now_ms();
  l->last_ok_ms = obs_now_ms();
  while (!is_stopping(l)) {
    double now = obs_now_ms();
    if (now >= next_reap) {
      reap(app);
      next_reap = now + lease_ms / 2.0;
    }
    if (now >= next_beat) {
      heartbeat(app, l);
      next_beat = now + lease_ms / 3.0;
    }
    now = obs_now_ms();
    double until = next_beat < next_reap ? next_beat : next_reap;
    /* Short waits, so stopping the daemon never waits out a long one. */
    int wait_ms = (int)(until - now);
    if (wait_ms > 250) wait_ms = 250;
    if (wait_ms < 1) wait_ms = 1;
    int what = 0;
    obs_err err = OBS_ERR_INIT;
    int rc = srv_db_wait(app->db, wait_ms, &what, &err);
    obs_err_free(&err);
    if (rc == 1 && (what & SRV_WAKE_JOBS)) srv_sched_notify(app);
    if (rc == 1 && (what & SRV_WAKE_CANCEL)) next_beat = 0; /* heartbeat now: it carries cancels */
    if (rc < 0) {
      /* The listener was lost; the next call reconnects. Meanwhile the workers poll. */
      pthread_mutex_lock(&l->mu);
      if (!l->stopping) {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        ts.tv_nsec += 250 * 1000000L;
        if (ts.tv_nsec >= 1000000000L) ts.tv_sec++, ts.tv_nsec -= 1000000000L;
        pthread_cond_timedwait(&l->cv, &l->mu, &ts);
      }
      pthread_mutex_unlock(&l->mu);
    }
  }
  return NULL;
}

static void free_lease(struct srv_lease *l) {
  if (!l) return;
  free(l->ids);
  free(l->attempts);
  free(l->held);
  free(l->cancel);
  free(l->beats);
  free(l->next);
  free(l);
}

int srv_lease_start(srv_app *app, obs_err *err) {
  struct srv_lease *l = calloc(1, sizeof *l);
  int n = srv_sched_slots(app);
  if (n < 1) n = 1;
  if (l) {
    l->nslots = n;
    l->ids = calloc((size_t)n, sizeof *l->ids);
    l->attempts = calloc((size_t)n, sizeof *l->attempts);
    l->held = calloc((size_t)n, sizeof *l->held);
    l->cancel = calloc((size_t)n, sizeof *l->cancel);
    l->beats = calloc((size_t)n, sizeof *l->beats);
    l->next = calloc((size_t)n, sizeof *l->next);
  }
  if (!l || !l->ids || !l->attempts || !l->held || !l->cancel || !l->beats || !l->next) {
    free_lease(l);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  pthread_mutex_init(&l->mu, NULL);
  pthread_cond_init(&l->cv, NULL);
  app->lease = l;
  if (pthread_create(&l->thread, NULL, loop, app)) {
    app->lease = NULL;
    pthread_mutex_destroy(&l->mu);
    pthread_cond_destroy(&l->cv);
    free_lease(l);
    return obs_err_set(err, OBS_EINTERNAL, "cannot start the node loop's thread");
  }
  return 0;
}

void srv_lease_stop(srv_app *app) {
  struct srv_lease *l = app->lease;
  if (!l) return;
  pthread_mutex_lock(&l->mu);
  l->stopping = 1;
  pthread_cond_broadcast(&l->cv);
  pthread_mutex_unlock(&l->mu);
  pthread_join(l->thread, NULL);
  pthread_mutex_destroy(&l->mu);
  pthread_cond_destroy(&l->cv);
  free_lease(l);
  app->lease = NULL;
}
