/* The scheduler's private state, shared by its two files: jobs.c (the workers' loop, the render
 * gate, the maintenance thread, the API other modules call) and outcome.c (what a worker does at
 * the end of an attempt: publish the outputs, record the outcome, or drop it). */
#ifndef SRV_SCHED_INTERNAL_H
#define SRV_SCHED_INTERNAL_H

#include <pthread.h>

#include "obscurad.h"

/* Why a slot's cancel flag was raised. STOP_LEASE: the store no longer gives this node the job
 * (its lease lapsed or was lost): nothing is recorded, the outputs are dropped, and another node
 * runs it. */
enum { STOP_NONE, STOP_USER, STOP_TIMEOUT, STOP_SHUTDOWN, STOP_LEASE };

/* One worker's current job. `id` and `progress_ppm` are read without the lock by GET handlers
 * (a stale read only shows a progress value a moment old); `stop` is written under the lock. */
typedef struct slot {
  atomic_llong id;           /* 0 = idle */
  atomic_int attempt;        /* the attempt of `id` this slot holds (the store's guard) */
  atomic_int cancel;         /* the render's cancel flag */
  atomic_int progress_ppm;   /* millionths */
  atomic_int render_index;   /* which of render_count renders of the attempt is running */
  atomic_int render_count;
  int stop;                  /* why cancel was raised (STOP_*) */
  int paused;                /* holds a finished job while a fault is cleared (under mu) */
  int settled;               /* the store took this attempt's outcome (under mu) */
  double deadline_ms;        /* obs_now_ms() clock */
  srv_lane lane;
  int index;
  srv_app *app;
  pthread_t thread;
} slot;

struct srv_sched {
  pthread_mutex_t mu;
  pthread_cond_t work;       /* a job was queued, or stopping */
  pthread_cond_t maint_cv;
  pthread_cond_t fault_cv;   /* a fault was cleared, or stopping */
  /* Renders of different lanes share the cores, so a comparison job's timed renders run alone:
   * they take the render gate exclusively, every other render shares it. Waiting exclusive
   * renders hold back new shared ones, so a busy lane cannot starve a comparison. */
  pthread_cond_t gate_cv;
  int gate_shared, gate_exclusive, gate_waiting;
  unsigned long generation;  /* bumped by notify, so a wake-up between claim and wait is kept */
  int stopping;
  int nslots;
  slot *slots;
  pthread_t maint;
  int maint_started;
  atomic_int finished_since_checkpoint;
  atomic_int metrics_due;    /* a database fault cleared: metrics it kept from storing are due */
};


/* outcome.c: the end of an attempt. Each records through the store's guarded completion (an
 * attempt this node no longer holds is refused, and its outputs go). */
/* Records job j failed or cancelled with msg. */
void srv_slot_fail(slot *sl, srv_job *j, srv_state state, const char *msg);
/* The render stopped for `why` (STOP_*): records it (or requeues, or drops it for STOP_LEASE). */
void srv_slot_stopped(slot *sl, srv_job *j, int why);
/* The slot's stop reason, read under the scheduler's lock. */
int srv_slot_stop_reason(slot *sl);
/* The staging directory of job j's current attempt. */
void srv_slot_stage_path(const srv_app *app, const srv_job *j, char *buf, size_t n);
/* Publishes a finished render and records it; returns 1 when the job succeeded. `res` NULL: an
 * mpirun job, whose outputs are in the staging directory and whose summary.json text is
 * `mpi_summary` (taken). */
int srv_slot_finish(slot *sl, srv_job *j, obs_result *res, const obs_scene *sc, char *mpi_summary,
                    const srv_run *runs, int nruns, obs_err *err);

#endif
