/* The scheduler of obscurad: worker threads per lane (CPU, Vulkan) that claim queued jobs from the
 * store, render them through the renderer API and hand the outcome to outcome.c; live progress and
 * cancel flags kept in memory, with what the node loop (lease.c) needs: the busy slots and a way
 * to stop one; a maintenance thread for time limits and checkpoints. */
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

#include "sched_internal.h"

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

int srv_sched_slots(srv_app *app) { return app->sched ? app->sched->nslots : 0; }

int srv_sched_busy(srv_app *app, int64_t *ids, int *attempts, int max) {
  srv_sched *s = app->sched;
  int n = 0;
  if (!s) return 0;
  pthread_mutex_lock(&s->mu);
  for (int i = 0; i < s->nslots && n < max; i++) {
    slot *sl = &s->slots[i];
    int64_t id = atomic_load(&sl->id);
    if (!id || sl->settled) continue;
    ids[n] = id;
    attempts[n++] = atomic_load(&sl->attempt);
  }
  pthread_mutex_unlock(&s->mu);
  return n;
}

int srv_sched_stop_job(srv_app *app, int64_t id, int attempt, srv_stop_why why) {
  srv_sched *s = app->sched;
  int stopped = 0;
  if (!s) return 0;
  pthread_mutex_lock(&s->mu);
  for (int i = 0; i < s->nslots; i++) {
    slot *sl = &s->slots[i];
    if (atomic_load(&sl->id) != id || atomic_load(&sl->attempt) != attempt || sl->settled)
      continue;
    /* A lost lease overrides any other reason: whatever the render was stopping for, the store
     * will no longer take its outcome. */
    if (why == SRV_STOP_LEASE ? sl->stop != STOP_LEASE : !sl->stop) {
      sl->stop = why == SRV_STOP_LEASE ? STOP_LEASE : STOP_USER;
      atomic_store(&sl->cancel, 1);
      stopped = 1;
    }
  }
  if (stopped) {
    pthread_cond_broadcast(&s->gate_cv);  /* it may be waiting at the render gate */
    pthread_cond_broadcast(&s->fault_cv); /* ... or for room on the results disk */
  }
  pthread_mutex_unlock(&s->mu);
  return stopped;
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
  srv_slot_stage_path(app, j, stage, sizeof stage);
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
  int why = srv_slot_stop_reason(sl);
  if (why || rc) {
    free(summary);
    srv_remove_tree(stage);
    if (why) srv_slot_stopped(sl, j, why);
    else srv_slot_fail(sl, j, SRV_FAILED, obs_err_message(&err));
  } else {
    ok = srv_slot_finish(sl, j, NULL, NULL, summary, NULL, 0, &err);
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
    srv_slot_fail(sl, j, SRV_FAILED, obs_err_message(&err));
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
    if (srv_slot_stop_reason(sl)) break;
  }
  if (gated) gate_leave(app->sched, exclusive);
  srv_preview_finish(preview);
  /* The time limit is the renders': publishing and committing an outcome is not held to it (a
   * slow or faulty disk must not turn a finished render into a timed-out job). */
  pthread_mutex_lock(&app->sched->mu);
  sl->deadline_ms = INFINITY;
  pthread_mutex_unlock(&app->sched->mu);
  int why = srv_slot_stop_reason(sl);
  if (why) {
    srv_slot_stopped(sl, j, why);
  } else if (rc) {
    srv_slot_fail(sl, j, SRV_FAILED, obs_err_message(&err));
  } else {
    res.timings.load_ms = load_ms;
    res.timings.total_ms += load_ms;
    succeeded = srv_slot_finish(sl, j, &res, &sc, NULL, runs, nruns, &err);
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
        sl->settled = 0;
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
