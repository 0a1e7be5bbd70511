/* The scheduler of obscurad: worker threads per lane (CPU, Vulkan) that claim queued jobs from the
 * database, render them through the renderer API, publish outputs and record the outcome; live
 * progress and cancel flags kept in memory; a maintenance thread for time limits and checkpoints. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "obscurad.h"

enum { STOP_NONE, STOP_USER, STOP_TIMEOUT, STOP_SHUTDOWN };

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

void srv_sched_notify(srv_app *app) {
  srv_sched *s = app->sched;
  if (!s) return;
  pthread_mutex_lock(&s->mu);
  s->generation++;
  pthread_cond_broadcast(&s->work);
  pthread_mutex_unlock(&s->mu);
}

int srv_sched_progress(srv_app *app, int64_t id, double *progress) {
  srv_sched *s = app->sched;
  for (int i = 0; s && i < s->nslots; i++) {
    if (atomic_load(&s->slots[i].id) == id) {
      *progress = atomic_load(&s->slots[i].progress_ppm) / 1e6;
      return 1;
    }
  }
  return 0;
}

int srv_sched_running(srv_app *app) {
  srv_sched *s = app->sched;
  int n = 0;
  for (int i = 0; s && i < s->nslots; i++) n += atomic_load(&s->slots[i].id) != 0;
  return n;
}

int srv_sched_paused(srv_app *app) {
  srv_sched *s = app->sched;
  int n = 0;
  if (!s) return 0;
  pthread_mutex_lock(&s->mu);
  for (int i = 0; i < s->nslots; i++) n += s->slots[i].paused;
  pthread_mutex_unlock(&s->mu);
  return n;
}

int srv_sched_cancel(srv_app *app, int64_t id, srv_cancel_result *res, obs_err *err) {
  srv_sched *s = app->sched;
  /* Under the scheduler lock: claims register their slot under it too, so a job the database
   * calls running always has its slot here. */
  pthread_mutex_lock(&s->mu);
  int rc = srv_db_cancel(app->db, id, res, err);
  if (!rc && *res == SRV_CANCEL_RUNNING) {
    for (int i = 0; i < s->nslots; i++) {
      slot *sl = &s->slots[i];
      if (atomic_load(&sl->id) == id && !sl->stop) {
        sl->stop = STOP_USER;
        atomic_store(&sl->cancel, 1);
      }
    }
    pthread_cond_broadcast(&s->gate_cv); /* the job may be waiting at the render gate */
  }
  pthread_mutex_unlock(&s->mu);
  if (!rc && *res == SRV_CANCEL_DONE) srv_job_log(app, id, "queued -> cancelled by request");
  if (!rc && *res == SRV_CANCEL_RUNNING) srv_job_log(app, id, "cancel requested");
  return rc;
}

static void on_progress(void *user, double f) {
  slot *sl = user;
  /* Warm-up and repeated renders each take an equal share of the job's progress. */
  int n = atomic_load(&sl->render_count), k = atomic_load(&sl->render_index);
  if (n > 1) f = (k + f) / n;
  int ppm = (int)(f * 1e6);
  if (ppm < 0) ppm = 0;
  if (ppm > 1000000) ppm = 1000000;
  atomic_store(&sl->progress_ppm, ppm);
}

/* Enters the render gate; with a slot, gives up (returns 0) as soon as the slot is asked to stop,
 * so a cancelled or shut-down waiter neither waits out another job's renders nor keeps holding
 * back shared renders. Returns 1 once entered. */
static int gate_enter(srv_sched *s, const slot *sl, int exclusive) {
  int entered = 0;
  pthread_mutex_lock(&s->mu);
  if (exclusive) {
    s->gate_waiting++;
    while ((s->gate_shared || s->gate_exclusive) && !(sl && sl->stop))
      pthread_cond_wait(&s->gate_cv, &s->mu);
    s->gate_waiting--;
    if (!(sl && sl->stop)) {
      s->gate_exclusive = 1;
      entered = 1;
    } else {
      pthread_cond_broadcast(&s->gate_cv); /* shared renders held back by this waiter may go */
    }
  } else {
    while ((s->gate_exclusive || s->gate_waiting) && !(sl && sl->stop))
      pthread_cond_wait(&s->gate_cv, &s->mu);
    if (!(sl && sl->stop)) {
      s->gate_shared++;
      entered = 1;
    }
  }
  pthread_mutex_unlock(&s->mu);
  return entered;
}

static void gate_leave(srv_sched *s, int exclusive) {
  pthread_mutex_lock(&s->mu);
  if (exclusive) s->gate_exclusive = 0;
  else s->gate_shared--;
  pthread_cond_broadcast(&s->gate_cv);
  pthread_mutex_unlock(&s->mu);
}

static void job_done(srv_sched *s) { atomic_fetch_add(&s->finished_since_checkpoint, 1); }

/* Waits, holding the finished job in its slot, until fault `k` is cleared (the maintenance
 * thread probes with back-off) or the slot is asked to stop. Returns 0 to retry, else the
 * stop reason. */
static int wait_fault(slot *sl, srv_fault_kind k, int only_shutdown) {
  srv_sched *s = sl->app->sched;
  pthread_mutex_lock(&s->mu);
  /* Waiting for a disk is not rendering: no time limit meanwhile. */
  sl->deadline_ms = INFINITY;
  sl->paused = 1;
  while (srv_fault_active(k) && !(sl->stop && !only_shutdown) && !s->stopping) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += 1;
    pthread_cond_timedwait(&s->fault_cv, &s->mu, &ts);
  }
  int why = s->stopping ? STOP_SHUTDOWN : only_shutdown ? 0 : sl->stop;
  sl->paused = 0;
  pthread_mutex_unlock(&s->mu);
  return why;
}

/* What a worker writes to the database at the end of an attempt. */
enum { OUT_SUCCESS, OUT_FINISH, OUT_REQUEUE };
typedef struct outcome {
  int kind;
  srv_state state;
  const char *msg;
  double progress;
  const char *backend, *summary;
  const srv_output *outs;
  int nouts;
  const srv_run *runs;
  int nruns;
} outcome;

/* Records `o`, retrying while the database has a transient fault: the job stays `running` in
 * this slot (never without a worker) until the write lands. A shutdown meanwhile leaves it to
 * the recovery at the next start. Returns 0 or the last error. */
static int record(slot *sl, int64_t id, const outcome *o, obs_err *err) {
  srv_app *app = sl->app;
  int attempt = atomic_load(&sl->attempt);
  for (;;) {
    obs_err_clear(err);
    int rc = o->kind == OUT_SUCCESS
                 ? srv_db_finish_success(app->db, id, attempt, o->backend, o->summary, o->outs,
                                         o->nouts, o->runs, o->nruns, app->machine_id, err)
             : o->kind == OUT_FINISH
                 ? srv_db_finish(app->db, id, attempt, o->state, o->msg, o->progress, err)
                 : srv_db_requeue(app->db, id, attempt, err);
    if (rc != OBS_ETRANSIENT) return rc;
    srv_fault_raise(SRV_FAULT_DB, srv_db_path(app->db), NULL, obs_err_message(err), NULL);
    if (o->kind == OUT_REQUEUE) return rc; /* stopping: recovery requeues it at the next start */
    srv_log("job %lld: cannot record the outcome yet (%s); the lanes wait for the database",
            (long long)id, obs_err_message(err));
    /* Only a shutdown ends this wait: a cancel or time limit changes nothing the database
     * could take now. */
    if (wait_fault(sl, SRV_FAULT_DB, 1) == STOP_SHUTDOWN) {
      srv_log("job %lld: stopping before the outcome was recorded; the next start requeues it",
              (long long)id);
      return rc;
    }
  }
}

static void fail_job(slot *sl, srv_job *j, srv_state state, const char *msg) {
  obs_err err = OBS_ERR_INIT;
  outcome o = {.kind = OUT_FINISH,
               .state = state,
               .msg = msg,
               .progress = atomic_load(&sl->progress_ppm) / 1e6};
  if (record(sl, j->id, &o, &err))
    srv_log("job %lld: cannot record the outcome: %s", (long long)j->id, obs_err_message(&err));
  else
    srv_job_log(sl->app, j->id, "running -> %s (%s)", srv_state_name(state), msg);
  obs_err_free(&err);
  job_done(sl->app->sched);
}

/* The render was stopped (or finished after a stop request): record why. */
static void stopped(slot *sl, srv_job *j, int why) {
  srv_app *app = sl->app;
  if (why == STOP_SHUTDOWN) {
    obs_err err = OBS_ERR_INIT;
    outcome o = {.kind = OUT_REQUEUE};
    if (record(sl, j->id, &o, &err))
      srv_log("job %lld: cannot requeue: %s", (long long)j->id, obs_err_message(&err));
    else
      srv_job_log(app, j->id, "running -> queued (daemon stopping; this attempt does not count)");
    obs_err_free(&err);
  } else if (why == STOP_TIMEOUT) {
    char msg[96];
    snprintf(msg, sizeof msg, "render time limit of %d s exceeded", app->cfg.max_render_seconds);
    fail_job(sl, j, SRV_FAILED, msg);
  } else {
    fail_job(sl, j, SRV_CANCELLED, "cancelled by request");
  }
}

static int stop_reason(slot *sl) {
  pthread_mutex_lock(&sl->app->sched->mu);
  int why = sl->stop;
  pthread_mutex_unlock(&sl->app->sched->mu);
  return why;
}

/* Waits `seconds` holding the finished job, or less when the slot is asked to stop or the daemon
 * stops. Returns the stop reason, 0 when the time is up. */
static int wait_space(slot *sl, double seconds) {
  srv_sched *s = sl->app->sched;
  struct timespec until;
  clock_gettime(CLOCK_REALTIME, &until);
  until.tv_sec += (time_t)seconds;
  pthread_mutex_lock(&s->mu);
  sl->deadline_ms = INFINITY; /* waiting for room is not rendering */
  while (!sl->stop && !s->stopping)
    if (pthread_cond_timedwait(&s->fault_cv, &s->mu, &until) == ETIMEDOUT) break;
  int why = s->stopping ? STOP_SHUTDOWN : sl->stop;
  pthread_mutex_unlock(&s->mu);
  return why;
}

/* Outputs that found no room while the results directory still takes a page: the disk is not
 * down for everyone, these files are too big for what is free. Other lanes keep running (no
 * fault is raised); this job keeps its render and tries again after 1, 2, 4 ... s (at most 60)
 * in case room is made, --output-space-retries times, then fails with the reason, so it never
 * holds its lane (or, as a fault, every lane) until someone frees the disk. Returns 0 to try
 * again, a stop reason (> 0), or OBS_EIO with `err` holding why the job fails. */
static int no_room(slot *sl, srv_job *j, int *tries, double since, const char *code,
                   obs_err *err) {
  srv_app *app = sl->app;
  double free_bytes = srv_outputs_free_bytes(app->results_dir);
  char room[64] = "";
  if (free_bytes >= 0) snprintf(room, sizeof room, ", %.4g MB free", free_bytes / 1e6);
  if (*tries >= app->cfg.output_space_retries) {
    char cause[1200];
    obs_path_err_relative(err, app->results_dir); /* the job's error is the client's to read */
    snprintf(cause, sizeof cause, "%s", obs_err_message(err));
    obs_err_clear(err);
    obs_err_set(err, OBS_EIO,
                "its outputs do not fit the free space of the results disk (%s%s after %d "
                "tries over %.0f s, while smaller files could still be written): %s",
                code, room, *tries + 1, (obs_now_ms() - since) / 1e3, cause);
    return OBS_EIO;
  }
  double wait = fmin(60, ldexp(1, *tries));
  (*tries)++;
  srv_job_log(app, j->id,
              "its outputs do not fit the results disk (%s%s) while smaller files do: the render "
              "is kept, try %d of %d in %.0f s; the other jobs go on",
              code, room, *tries + 1, app->cfg.output_space_retries + 1, wait);
  return wait_space(sl, wait);
}

/* The staging directory of an attempt's outputs. */
static void stage_path(const srv_app *app, const srv_job *j, char *buf, size_t n) {
  snprintf(buf, n, "%s/.tmp-%lld-%d", app->results_dir, (long long)j->id, j->attempts);
}

/* Writes the outputs into a staging directory (unless `res` is NULL: an mpirun job's CLI wrote
 * them there already) and renames it into place. A failure the environment caused (disk full,
 * read-only, I/O) pauses the lanes and retries with the render kept in memory (or on disk).
 * Returns 0, <0 for a job fault (err filled), or a stop reason (>0). */
static int publish(slot *sl, srv_job *j, obs_result *res, const obs_scene *sc, srv_output *outs,
                   int *nouts, obs_err *err) {
  srv_app *app = sl->app;
  char stage[4200], final[4200];
  stage_path(app, j, stage, sizeof stage);
  srv_results_path(app, j->id, final, sizeof final);
  int room_tries = 0;
  double since = obs_now_ms();
  for (int tries = 0;; tries++) {
    obs_err_clear(err);
    if (res) srv_remove_tree(stage);
    *nouts = 0;
    int rc = res ? obs_result_write(res, sc, stage, err) : 0;
    if (!rc) rc = srv_outputs_describe(stage, outs, 16, nouts, err);
    if (!rc) {
      srv_remove_tree(final);
      if (rename(stage, final))
        rc = obs_err_set(err, OBS_EIO, "%s: cannot publish the outputs: %s", final,
                         strerror(errno));
    }
    if (!rc) return 0;
    if (res) srv_remove_tree(stage);
    char code[40] = "";
    obs_err probe = OBS_ERR_INIT;
    int env = srv_outputs_fault(app->results_dir, obs_err_message(err), code, sizeof code, &probe);
    obs_err_free(&probe);
    /* Once more before blaming the job: the probe may have just recreated a removed directory. */
    if (!env && tries == 0) continue;
    if (!env) {
      srv_remove_tree(stage);
      return rc;
    }
    if (env == SRV_OUTPUTS_NO_ROOM) {
      int why = no_room(sl, j, &room_tries, since, code, err);
      if (!why) continue;
      srv_remove_tree(stage);
      return why;
    }
    srv_fault_raise(SRV_FAULT_RESULTS, app->results_dir, code, obs_err_message(err), NULL);
    srv_log("job %lld: cannot write its outputs yet (%s); the render is kept and the lanes wait",
            (long long)j->id, obs_err_message(err));
    int why = wait_fault(sl, SRV_FAULT_RESULTS, 0);
    if (why) {
      srv_remove_tree(stage);
      return why;
    }
  }
}

/* The job's warnings and its success line; `res` NULL: an mpirun job, whose summary.json text
 * is `summary`. */
static void log_success(srv_app *app, const srv_job *j, const obs_result *res,
                        const char *summary) {
  if (!res) {
    srv_mpi_succeeded(app, j, summary);
    return;
  }
  srv_metrics_render(res->technique->name, obs_backend_name(res->backend),
                     res->timings.total_ms / 1e3);
  for (int w = 0; w < res->nwarnings; w++) srv_job_log(app, j->id, "warning: %s", res->warnings[w]);
  char where[32] = "the Vulkan device";
  if (res->backend != OBS_BACKEND_VULKAN)
    snprintf(where, sizeof where, "%d CPU thread%s", res->threads, res->threads == 1 ? "" : "s");
  srv_job_log(app, j->id,
              "running -> succeeded (%s/%s %dx%d on %s, %.1f ms: load %.1f, build %.1f, "
              "render %.1f, write %.1f)",
              res->technique->name, obs_backend_name(res->backend), res->image.width,
              res->image.height, where, res->timings.total_ms, res->timings.load_ms,
              res->timings.build_ms, res->timings.render_ms, res->timings.write_ms);
}

/* Publishes a finished render and records it; returns 1 when the job succeeded. `res` NULL: an
 * mpirun job, whose outputs are in the staging directory and whose summary.json text is
 * `mpi_summary` (taken). */
static int finish_render(slot *sl, srv_job *j, obs_result *res, const obs_scene *sc,
                         char *mpi_summary, const srv_run *runs, int nruns, obs_err *err) {
  srv_app *app = sl->app;
  srv_output outs[16];
  int nouts = 0;
  int rc = publish(sl, j, res, sc, outs, &nouts, err);
  if (rc > 0) {
    /* Stopped while waiting for the results directory: nothing was published, so the attempt
     * ends as any stopped render does (a shutdown requeues it without counting it). */
    free(mpi_summary);
    stopped(sl, j, rc);
    return 0;
  }
  char *summary = mpi_summary;
  if (!rc && res) {
    json_t *sum = obs_result_summary_json(res, sc);
    summary = json_dumps(sum, JSON_COMPACT | JSON_REAL_PRECISION(9));
    json_decref(sum);
  }
  if (!rc) {
    /* The log lines go first: a client that sees the job succeeded must find them in its log. */
    log_success(app, j, res, summary);
    outcome o = {.kind = OUT_SUCCESS,
                 .backend = res ? obs_backend_name(res->backend) : "cpu",
                 .summary = summary,
                 .outs = outs,
                 .nouts = nouts,
                 .runs = runs,
                 .nruns = nruns};
    /* Published first, committed second: a crash in between leaves a job still `running` in
     * the database, which recovery requeues and whose directory it removes. */
    rc = record(sl, j->id, &o, err);
    if (rc)
      srv_job_log(app, j->id, "the success above was not recorded: %s", obs_err_message(err));
  }
  free(summary);
  if (rc == OBS_ETRANSIENT) return 0; /* stopping with the database down: left to recovery */
  if (rc) {
    char final[4200];
    srv_results_path(app, j->id, final, sizeof final);
    srv_remove_tree(final);
    fail_job(sl, j, SRV_FAILED, obs_err_message(err));
    return 0;
  }
  job_done(app->sched);
  return 1;
}

/* A job on Open MPI ranks: mpirun renders it into the staging directory (mpi_jobs.c), under the
 * same render gate, time limit, cancel and publication as a local render. Returns 1 when it
 * succeeded. */
static int run_mpi(slot *sl, srv_job *j) {
  srv_app *app = sl->app;
  obs_err err = OBS_ERR_INIT;
  /* Submission accepted it for the CPU backend only. */
  if (srv_db_set_backend(app->db, j->id, "cpu", &err))
    srv_log("job %lld: %s", (long long)j->id, obs_err_message(&err));
  obs_err_clear(&err);
  char stage[4200];
  stage_path(app, j, stage, sizeof stage);
  pthread_mutex_lock(&app->sched->mu);
  sl->deadline_ms = INFINITY; /* waiting at the gate is not rendering */
  pthread_mutex_unlock(&app->sched->mu);
  int gated = gate_enter(app->sched, sl, 0), rc = OBS_ECANCELED, ok = 0;
  char *summary = NULL;
  if (gated) {
    pthread_mutex_lock(&app->sched->mu);
    sl->deadline_ms = obs_now_ms() + 1e3 * app->cfg.max_render_seconds;
    pthread_mutex_unlock(&app->sched->mu);
    rc = srv_mpi_render(app, j, stage, &sl->cancel, &sl->progress_ppm, &summary, &err);
    gate_leave(app->sched, 0);
  }
  pthread_mutex_lock(&app->sched->mu);
  sl->deadline_ms = INFINITY;
  pthread_mutex_unlock(&app->sched->mu);
  int why = stop_reason(sl);
  if (why || rc) {
    free(summary);
    srv_remove_tree(stage);
    if (why) stopped(sl, j, why);
    else fail_job(sl, j, SRV_FAILED, obs_err_message(&err));
  } else {
    ok = finish_render(sl, j, NULL, NULL, summary, NULL, 0, &err);
  }
  obs_err_free(&err);
  return ok;
}

/* Runs one claimed job to its outcome; returns 1 when it succeeded. */
static int run_job(slot *sl, srv_job *j) {
  srv_app *app = sl->app;
  int succeeded = 0;
  srv_job_log(app, j->id, "queued -> running (%s lane, attempt %d%s)", srv_lane_name(sl->lane),
              j->attempts, j->ranks > 1 ? ", on Open MPI ranks" : "");
  if (j->ranks > 1) return run_mpi(sl, j);
  obs_err err = OBS_ERR_INIT;
  double t0 = obs_now_ms();
  obs_scene sc;
  int rc = obs_scene_load_string(&sc, j->doc, j->scene, app->scenes_real, NULL, 0, &err);
  if (rc) {
    fail_job(sl, j, SRV_FAILED, obs_err_message(&err));
    obs_err_free(&err);
    return 0;
  }
  double load_ms = obs_now_ms() - t0;
  /* The lane decided the backend when the job was accepted (or at recovery); pin it, so an
   * "auto" job on the CPU lane cannot drift to Vulkan. */
  obs_backend be = sl->lane == SRV_LANE_VULKAN ? OBS_BACKEND_VULKAN : OBS_BACKEND_CPU;
  rc = obs_technique_pick_backend(sc.technique, be, &be, &err);
  if (!rc) {
    sc.backend = be;
    obs_err e2 = OBS_ERR_INIT;
    if (srv_db_set_backend(app->db, j->id, obs_backend_name(be), &e2))
      srv_log("job %lld: %s", (long long)j->id, obs_err_message(&e2));
    obs_err_free(&e2);
  }
  obs_result res;
  memset(&res, 0, sizeof res);
  /* Comparison jobs render once untimed (warm caches: page cache, allocator, Vulkan pipelines),
   * then `repeats` timed renders; every timed one is stored, the last one's image is the output
   * (renders are deterministic, so all are the same image). */
  int repeats = j->repeats >= 1 && j->repeats <= SRV_MAX_REPEATS ? j->repeats : 1;
  int nrenders = repeats + (j->warmup ? 1 : 0), nruns = 0;
  srv_run runs[SRV_MAX_REPEATS];
  atomic_store(&sl->render_count, nrenders);
  /* No time limit while waiting at the gate (waiting is not rendering); a stop raised meanwhile
   * (cancel, shutdown) ends the wait and is recorded below like any other stop. */
  const int exclusive = j->warmup;
  int gated = 0;
  /* A preview for jobs that are not timed against others: a comparison's renders stay alone. */
  srv_preview *preview = j->warmup ? NULL : srv_preview_begin(app, j->id, sc.technique->name);
  if (!rc) {
    pthread_mutex_lock(&app->sched->mu);
    sl->deadline_ms = INFINITY;
    pthread_mutex_unlock(&app->sched->mu);
    if (exclusive)
      srv_job_log(app, j->id, "timed renders wait until no other render runs");
    gated = gate_enter(app->sched, sl, exclusive);
    if (!gated) rc = OBS_ECANCELED;
  }
  for (int k = 0; !rc && k < nrenders; k++) {
    obs_result_free(&res);
    atomic_store(&sl->render_index, k);
    /* The limit is per render: a comparison job's warm-up and repeats each get the whole of it
     * (the submission-time work cap is per render too). */
    pthread_mutex_lock(&app->sched->mu);
    sl->deadline_ms = obs_now_ms() + 1e3 * app->cfg.max_render_seconds;
    pthread_mutex_unlock(&app->sched->mu);
    obs_render_opts opts = {.threads = app->cpu_threads,
                            .progress = on_progress,
                            .progress_user = sl,
                            .cancel = &sl->cancel,
                            .watch = srv_preview_watch(preview)};
    rc = obs_render(&sc, &opts, &res, &err);
    if (!rc && (k > 0 || !j->warmup)) {
      srv_run *r = &runs[nruns++];
      r->build_ms = res.timings.build_ms;
      r->render_ms = res.timings.render_ms;
      r->total_ms = res.timings.total_ms;
      /* post: what obs_render spent outside the technique's build and render (output assembly,
       * readback bookkeeping); never negative through rounding. */
      r->post_ms = r->total_ms - r->build_ms - r->render_ms;
      if (r->post_ms < 0) r->post_ms = 0;
      r->total_ms = r->build_ms + r->render_ms + r->post_ms;
    }
    if (stop_reason(sl)) break;
  }
  if (gated) gate_leave(app->sched, exclusive);
  srv_preview_finish(preview);
  /* The time limit is the renders': publishing and committing an outcome is not held to it (a
   * slow or faulty disk must not turn a finished render into a timed-out job). */
  pthread_mutex_lock(&app->sched->mu);
  sl->deadline_ms = INFINITY;
  pthread_mutex_unlock(&app->sched->mu);
  int why = stop_reason(sl);
  if (why) {
    stopped(sl, j, why);
  } else if (rc) {
    fail_job(sl, j, SRV_FAILED, obs_err_message(&err));
  } else {
    res.timings.load_ms = load_ms;
    res.timings.total_ms += load_ms;
    succeeded = finish_render(sl, j, &res, &sc, NULL, runs, nruns, &err);
  }
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return succeeded;
}

/* srv_db_claim returns 0 (claimed) or 1 (none queued); this is "not claiming: a fault". */
enum { CLAIM_PAUSED = 2 };

static void *worker(void *arg) {
  slot *sl = arg;
  srv_sched *s = sl->app->sched;
  /* Renders run niced (the renderer's tile threads inherit it from this thread): with every core
   * busy rendering, HTTP threads still get the CPU at once, which keeps API latency low. */
  if (sl->app->cfg.worker_nice &&
      setpriority(PRIO_PROCESS, (id_t)syscall(SYS_gettid), sl->app->cfg.worker_nice))
    srv_log("worker %d: cannot lower its priority (continuing)", sl->index);
  for (;;) {
    srv_job j;
    int have = 0;
    pthread_mutex_lock(&s->mu);
    while (!s->stopping) {
      if (atomic_exchange(&s->metrics_due, 0)) {
        /* Metrics a database fault kept from being stored are computed again (they are only
         * computed after a job's commit or at start otherwise). */
        pthread_mutex_unlock(&s->mu);
        if (gate_enter(s, NULL, 0)) {
          srv_compare_metrics(sl->app, 0);
          gate_leave(s, 0);
        }
        pthread_mutex_lock(&s->mu);
        continue;
      }
      unsigned long gen = s->generation;
      obs_err err = OBS_ERR_INIT;
      /* Every lane writes to the same results directory and database: while either has a
       * fault no lane claims, so no job renders only to wait (or, worse, fail). */
      int rc = srv_fault_any() ? CLAIM_PAUSED : srv_db_claim(sl->app->db, sl->lane, &j, &err);
      if (rc == OBS_ETRANSIENT)
        srv_fault_raise(SRV_FAULT_DB, srv_db_path(sl->app->db), NULL, obs_err_message(&err),
                        NULL);
      else if (rc < 0)
        srv_log("worker %d: %s", sl->index, obs_err_message(&err));
      obs_err_free(&err);
      if (rc == 0) {
        atomic_store(&sl->progress_ppm, 0);
        atomic_store(&sl->cancel, 0);
        sl->stop = j.cancel_requested ? STOP_USER : STOP_NONE;
        if (sl->stop) atomic_store(&sl->cancel, 1);
        sl->deadline_ms = obs_now_ms() + 1e3 * sl->app->cfg.max_render_seconds;
        atomic_store(&sl->attempt, j.attempts);
        atomic_store(&sl->id, j.id);
        have = 1;
        break;
      }
      /* Nothing queued (or the database is busy): sleep until notified; the timeout is only a
       * safety net. */
      struct timespec ts;
      clock_gettime(CLOCK_REALTIME, &ts);
      ts.tv_sec += rc < 0 || rc == CLAIM_PAUSED ? 1 : 5;
      while (gen == s->generation && !s->stopping)
        if (pthread_cond_timedwait(&s->work, &s->mu, &ts) == ETIMEDOUT) break;
    }
    pthread_mutex_unlock(&s->mu);
    if (!have) break;
    int ok = run_job(sl, &j);
    int64_t id = j.id;
    srv_job_free(&j);
    pthread_mutex_lock(&s->mu);
    atomic_store(&sl->id, 0);
    sl->stop = STOP_NONE;
    pthread_mutex_unlock(&s->mu);
    /* After the commit (and with the slot free again): this job may complete a comparison
     * candidate, as the candidate or as its reference, whose metrics are computed here. */
    if (ok && gate_enter(s, NULL, 0)) {
      /* Reading EXRs and computing SSIM is work too: keep it out of another job's timed renders. */
      srv_compare_metrics(sl->app, id);
      gate_leave(s, 0);
    }
  }
  return NULL;
}

/* Render time limits (checked 4 times a second), WAL checkpoints, fault probes and database
 * checks. */
static void *maintenance(void *arg) {
  srv_app *app = arg;
  srv_sched *s = app->sched;
  double last_checkpoint = obs_now_ms();
  srv_fault_clock mc = {.identity_ms = obs_now_ms(), .check_ms = obs_now_ms()};
  pthread_mutex_lock(&s->mu);
  while (!s->stopping) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_nsec += 250 * 1000000L;
    if (ts.tv_nsec >= 1000000000L) {
      ts.tv_sec++;
      ts.tv_nsec -= 1000000000L;
    }
    pthread_cond_timedwait(&s->maint_cv, &s->mu, &ts);
    if (s->stopping) break;
    double now = obs_now_ms();
    for (int i = 0; i < s->nslots; i++) {
      slot *sl = &s->slots[i];
      if (atomic_load(&sl->id) && !sl->stop && now > sl->deadline_ms) {
        sl->stop = STOP_TIMEOUT;
        atomic_store(&sl->cancel, 1);
        srv_job_log(app, atomic_load(&sl->id), "render time limit of %d s exceeded, stopping it",
                    app->cfg.max_render_seconds);
      }
    }
    pthread_mutex_unlock(&s->mu);
    srv_preview_tick();
    int metrics_due = 0, cleared = srv_faults_check(app, &mc, &metrics_due);
    if (metrics_due) atomic_store(&s->metrics_due, 1); /* postponed error images may go now */
    if (cleared) {
      pthread_mutex_lock(&s->mu);
      s->generation++;
      pthread_cond_broadcast(&s->work);
      pthread_cond_broadcast(&s->fault_cv);
      pthread_mutex_unlock(&s->mu);
    }
    if (!srv_fault_active(SRV_FAULT_DB_LOST) &&
        (now - last_checkpoint >= 1e3 * app->cfg.checkpoint_seconds ||
         atomic_load(&s->finished_since_checkpoint) >= app->cfg.checkpoint_jobs)) {
      obs_err err = OBS_ERR_INIT;
      int rc = srv_db_checkpoint(app->db, &err);
      if (rc == OBS_ETRANSIENT)
        srv_fault_raise(SRV_FAULT_DB, srv_db_path(app->db), NULL, obs_err_message(&err), NULL);
      else if (rc < 0)
        srv_log("checkpoint: %s", obs_err_message(&err));
      obs_err_free(&err);
      atomic_store(&s->finished_since_checkpoint, 0);
      last_checkpoint = obs_now_ms();
    }
    pthread_mutex_lock(&s->mu);
  }
  pthread_mutex_unlock(&s->mu);
  return NULL;
}

int srv_sched_start(srv_app *app, obs_err *err) {
  srv_sched *s = calloc(1, sizeof *s);
  if (!s) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  pthread_mutex_init(&s->mu, NULL);
  pthread_cond_init(&s->gate_cv, NULL);
  pthread_cond_init(&s->work, NULL);
  pthread_cond_init(&s->maint_cv, NULL);
  pthread_cond_init(&s->fault_cv, NULL);
  s->nslots = app->cfg.workers + (app->vulkan_lane ? 1 : 0);
  s->slots = calloc((size_t)s->nslots, sizeof *s->slots);
  if (!s->slots) {
    free(s);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  app->sched = s;
  for (int i = 0; i < s->nslots; i++) {
    slot *sl = &s->slots[i];
    atomic_init(&sl->id, 0);
    atomic_init(&sl->attempt, 0);
    atomic_init(&sl->cancel, 0);
    atomic_init(&sl->progress_ppm, 0);
    atomic_init(&sl->render_index, 0);
    atomic_init(&sl->render_count, 1);
    sl->lane = i < app->cfg.workers ? SRV_LANE_CPU : SRV_LANE_VULKAN;
    sl->index = i;
    sl->app = app;
  }
  atomic_init(&s->finished_since_checkpoint, 0);
  atomic_init(&s->metrics_due, 0);
  /* A results directory that cannot take files shows in health from the start, and no job is
   * claimed until it can. */
  char code[40] = "";
  obs_err probe = OBS_ERR_INIT;
  if (srv_outputs_probe(app->results_dir, code, sizeof code, &probe))
    srv_fault_raise(SRV_FAULT_RESULTS, app->results_dir, code, obs_err_message(&probe), NULL);
  obs_err_free(&probe);
  for (int i = 0; i < s->nslots; i++) {
    if (pthread_create(&s->slots[i].thread, NULL, worker, &s->slots[i])) {
      s->nslots = i;
      srv_sched_stop(app);
      return obs_err_set(err, OBS_EINTERNAL, "cannot start worker threads");
    }
  }
  if (pthread_create(&s->maint, NULL, maintenance, app)) {
    srv_sched_stop(app);
    return obs_err_set(err, OBS_EINTERNAL, "cannot start the maintenance thread");
  }
  s->maint_started = 1;
  return 0;
}

void srv_sched_stop(srv_app *app) {
  srv_sched *s = app->sched;
  if (!s) return;
  pthread_mutex_lock(&s->mu);
  s->stopping = 1;
  for (int i = 0; i < s->nslots; i++) {
    slot *sl = &s->slots[i];
    if (atomic_load(&sl->id) && !sl->stop) {
      sl->stop = STOP_SHUTDOWN;
      atomic_store(&sl->cancel, 1);
    }
  }
  pthread_cond_broadcast(&s->work);
  pthread_cond_broadcast(&s->maint_cv);
  pthread_cond_broadcast(&s->fault_cv);
  pthread_cond_broadcast(&s->gate_cv);
  pthread_mutex_unlock(&s->mu);
  for (int i = 0; i < s->nslots; i++) pthread_join(s->slots[i].thread, NULL);
  if (s->maint_started) pthread_join(s->maint, NULL);
  pthread_mutex_destroy(&s->mu);
  pthread_cond_destroy(&s->gate_cv);
  pthread_cond_destroy(&s->work);
  pthread_cond_destroy(&s->maint_cv);
  pthread_cond_destroy(&s->fault_cv);
  free(s->slots);
  free(s);
  app->sched = NULL;
}
