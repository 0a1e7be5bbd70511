/* The end of a render attempt in obscurad's scheduler: the outputs published from their staging
 * directory (and, when outputs travel through the store, put as blobs), the outcome recorded
 * through the store's guarded completion, retried while the database has a fault, and the
 * attempt dropped with its outputs when the store says this node no longer holds it. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sched_internal.h"

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
  const char *dir; /* OUT_SUCCESS: where the outputs are (put as blobs first when they travel
                    * through the store) */
} outcome;

/* Records `o`, retrying while the database has a transient fault: the job stays `running` in
 * this slot (never without a worker) until the write lands. A shutdown meanwhile leaves it to
 * the recovery at the next start. Returns 0 or the last error. */
static int record(slot *sl, int64_t id, const outcome *o, obs_err *err) {
  srv_app *app = sl->app;
  int attempt = atomic_load(&sl->attempt);
  for (;;) {
    obs_err_clear(err);
    /* The bytes before the row that names them: a node serving the job finds every blob. */
    int rc = o->kind == OUT_SUCCESS && app->results_via_store
                 ? srv_outputs_put_blobs(app, o->dir, o->outs, o->nouts, err)
                 : 0;
    if (!rc)
      rc = o->kind == OUT_SUCCESS
                 ? srv_db_finish_success(app->db, id, attempt, o->backend, o->summary, o->outs,
                                         o->nouts, o->runs, o->nruns, app->machine_id, err)
             : o->kind == OUT_FINISH
                 ? srv_db_finish(app->db, id, attempt, o->state, o->msg, o->progress, err)
                 : srv_db_requeue(app->db, id, attempt, err);
    if (!rc) {
      pthread_mutex_lock(&app->sched->mu);
      sl->settled = 1; /* the node loop no longer heartbeats or stops it */
      pthread_mutex_unlock(&app->sched->mu);
    }
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

/* The mark a staged directory carries in a results directory other nodes share: which worker's
 * attempt wrote it, so that a node whose late result was refused removes only its own outputs. */
#define MARK ".attempt"

static void mark_text(const srv_app *app, const srv_job *j, char *buf, size_t n) {
  snprintf(buf, n, "%s %d\n", srv_db_node(app->db)->worker, j->attempts);
}

/* 1 when the published directory `final` is this attempt's (it carries this attempt's mark). */
static int is_mine(const srv_app *app, const srv_job *j, const char *final) {
  char path[4300], want[200], got[200] = "";
  snprintf(path, sizeof path, "%s/" MARK, final);
  mark_text(app, j, want, sizeof want);
  FILE *f = fopen(path, "r");
  if (!f) return 0;
  size_t n = fread(got, 1, sizeof got - 1, f);
  fclose(f);
  got[n] = '\0';
  return !strcmp(got, want);
}

/* What attempt j wrote goes: its staging directory and, once `published`, its results directory
 * (in a shared one only while it is still this attempt's: another node may have placed its own
 * result there since). */
static void drop_outputs(slot *sl, srv_job *j, int published) {
  srv_app *app = sl->app;
  char path[4200];
  srv_slot_stage_path(app, j, path, sizeof path);
  srv_remove_tree(path);
  if (!published) return;
  srv_results_path(app, j->id, path, sizeof path);
  if (!app->cfg.results_dir || is_mine(app, j, path)) srv_remove_tree(path);
}

/* The store refused this attempt's outcome: the node no longer holds it (its lease lapsed; the
 * reaper gave the job back to the queue, and another node may have run it). The outcome is never
 * retried; what the attempt wrote goes. */
static void refused(slot *sl, srv_job *j, int published) {
  drop_outputs(sl, j, published); /* first: whoever reads the line finds them gone */
  srv_job_log(sl->app, j->id, "late result refused (attempt %d no longer held); its outputs are "
              "dropped", j->attempts);
}

/* Records a failure, cancel or requeue (`what` names it in the log when it cannot be recorded;
 * `line` goes to the job's log when it was). */
static void settle(slot *sl, srv_job *j, const outcome *o, const char *what, const char *line) {
  obs_err err = OBS_ERR_INIT;
  int rc = record(sl, j->id, o, &err);
  if (rc == OBS_ECONFLICT)
    refused(sl, j, 0);
  else if (rc)
    srv_log("job %lld: cannot %s: %s", (long long)j->id, what, obs_err_message(&err));
  else
    srv_job_log(sl->app, j->id, "%s", line);
  obs_err_free(&err);
}

void srv_slot_fail(slot *sl, srv_job *j, srv_state state, const char *msg) {
  outcome o = {.kind = OUT_FINISH,
               .state = state,
               .msg = msg,
               .progress = atomic_load(&sl->progress_ppm) / 1e6};
  char line[4400];
  snprintf(line, sizeof line, "running -> %s (%s)", srv_state_name(state), msg);
  settle(sl, j, &o, "record the outcome", line);
  job_done(sl->app->sched);
}

/* The render was stopped (or finished after a stop request): record why. */
void srv_slot_stopped(slot *sl, srv_job *j, int why) {
  srv_app *app = sl->app;
  if (why == STOP_SHUTDOWN) {
    outcome o = {.kind = OUT_REQUEUE};
    settle(sl, j, &o, "requeue", "running -> queued (daemon stopping; this attempt does not count)");
  } else if (why == STOP_LEASE) {
    /* Nothing to record: the store no longer gives this node the job. */
    drop_outputs(sl, j, 0);
    srv_job_log(app, j->id, "lease lost (attempt %d): this node stops the render and drops its "
                "outputs; the store gives the job to a node again", j->attempts);
  } else if (why == STOP_TIMEOUT) {
    char msg[96];
    snprintf(msg, sizeof msg, "render time limit of %d s exceeded", app->cfg.max_render_seconds);
    srv_slot_fail(sl, j, SRV_FAILED, msg);
  } else {
    srv_slot_fail(sl, j, SRV_CANCELLED, "cancelled by request");
  }
}

int srv_slot_stop_reason(slot *sl) {
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
void srv_slot_stage_path(const srv_app *app, const srv_job *j, char *buf, size_t n) {
  snprintf(buf, n, "%s/.tmp-%lld-%d", app->results_dir, (long long)j->id, j->attempts);
}

/* 1 when this node still holds attempt j (a heartbeat of that one job says so). */
static int still_held(srv_app *app, const srv_job *j) {
  int held = 0, cancel = 0, attempt = j->attempts;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_heartbeat(app->db, &j->id, &attempt, 1, &held, &cancel, &err);
  obs_err_free(&err);
  return !rc && held;
}

/* Renames the staged outputs into place. In a results directory of this node only, whatever is
 * there is a leftover and goes. In one other nodes share, what is there may be another node's
 * result: it is replaced only while the store says this node still holds the attempt (else
 * OBS_ECONFLICT: the result is late), and the staged directory is marked with its attempt. */
static int place(srv_app *app, const srv_job *j, const char *stage, const char *final,
                 obs_err *err) {
  if (!app->cfg.results_dir) srv_remove_tree(final);
  else {
    char path[4300], text[200];
    snprintf(path, sizeof path, "%s/" MARK, stage);
    mark_text(app, j, text, sizeof text);
    FILE *f = fopen(path, "w");
    int bad = !f || fputs(text, f) < 0;
    if (f && fclose(f)) bad = 1;
    if (bad)
      return obs_err_set(err, OBS_EIO, "%s: cannot write: %s", path, strerror(errno));
  }
  if (!rename(stage, final)) return 0;
  if (app->cfg.results_dir && (errno == ENOTEMPTY || errno == EEXIST)) {
    if (!still_held(app, j))
      return obs_err_set(err, OBS_ECONFLICT, "job %lld: attempt %d is no longer held",
                         (long long)j->id, j->attempts);
    srv_remove_tree(final);
    if (!rename(stage, final)) return 0;
  }
  return obs_err_set(err, OBS_EIO, "%s: cannot publish the outputs: %s", final, strerror(errno));
}

/* Writes the outputs into a staging directory (unless `res` is NULL: an mpirun job's CLI wrote
 * them there already) and renames it into place. A failure the environment caused (disk full,
 * read-only, I/O) pauses the lanes and retries with the render kept in memory (or on disk).
 * Returns 0, <0 for a job fault (err filled), or a stop reason (>0). */
static int publish(slot *sl, srv_job *j, obs_result *res, const obs_scene *sc, srv_output *outs,
                   int *nouts, obs_err *err) {
  srv_app *app = sl->app;
  char stage[4200], final[4200];
  srv_slot_stage_path(app, j, stage, sizeof stage);
  srv_results_path(app, j->id, final, sizeof final);
  int room_tries = 0;
  double since = obs_now_ms();
  for (int tries = 0;; tries++) {
    obs_err_clear(err);
    if (res) srv_remove_tree(stage);
    *nouts = 0;
    int rc = res ? obs_result_write(res, sc, stage, err) : 0;
    if (!rc) rc = srv_outputs_describe(stage, outs, 16, nouts, err);
    if (!rc) rc = place(app, j, stage, final, err);
    if (!rc || rc == OBS_ECONFLICT) return rc;
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
int srv_slot_finish(slot *sl, srv_job *j, obs_result *res, const obs_scene *sc,
                    char *mpi_summary, const srv_run *runs, int nruns, obs_err *err) {
  srv_app *app = sl->app;
  srv_output outs[16];
  int nouts = 0;
  char final[4200];
  srv_results_path(app, j->id, final, sizeof final);
  int rc = publish(sl, j, res, sc, outs, &nouts, err);
  if (rc == OBS_ECONFLICT) {
    free(mpi_summary);
    refused(sl, j, 0);
    return 0;
  }
  if (rc > 0) {
    /* Stopped while waiting for the results directory: nothing was published, so the attempt
     * ends as any stopped render does (a shutdown requeues it without counting it). */
    free(mpi_summary);
    srv_slot_stopped(sl, j, rc);
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
                 .nruns = nruns,
                 .dir = final};
    /* Published first, committed second: a crash in between leaves a job still `running` in
     * the database, which recovery requeues and whose directory it removes. */
    rc = record(sl, j->id, &o, err);
    if (rc && rc != OBS_ECONFLICT)
      srv_job_log(app, j->id, "the success above was not recorded: %s", obs_err_message(err));
  }
  free(summary);
  if (rc == OBS_ETRANSIENT) return 0; /* stopping with the database down: left to recovery */
  if (rc == OBS_ECONFLICT) {
    refused(sl, j, 1);
    return 0;
  }
  if (rc) {
    srv_remove_tree(final);
    srv_slot_fail(sl, j, SRV_FAILED, obs_err_message(err));
    return 0;
  }
  job_done(app->sched);
  return 1;
}

