/* Bounds on the work obscurad accepts: what its queue holds per client and in total — work, jobs
 * (renderer processes: a job on N MPI ranks counts N) and the bytes their documents store — for
 * submissions, comparisons (a small request can expand into hundreds of jobs) and retries alike,
 * and a refusal at submission of a job whose estimated render time exceeds the per-render limit,
 * rather than letting it run into the limit and fail. */
#include <arpa/inet.h>
#include <math.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "obscurad.h"

/* The built-in rate of a technique without stored runs here is its descriptor's ms_per_work
 * (measured with the CLI on this project's reference machine, docs/server.md, "Mesh import and
 * work limits", and rounded up by about a quarter, so that it errs towards refusing). A Vulkan
 * render is estimated at the CPU rate: a device is faster, and its stored runs take over after one
 * job. A technique that declares no rate gets this one, the slowest of those measured: */
#define FALLBACK_UNKNOWN 9e-5
/* Runs much smaller than the job are dominated by fixed costs (scene build, BVH, output) and
 * would overstate its rate: only runs of at least this fraction of the job's work count. */
#define RATE_MIN_FRACTION 0.01
#define RATE_MIN_RUNS 3

static double fallback_rate(const obs_technique *t) {
  return t->ms_per_work > 0 ? t->ms_per_work : FALLBACK_UNKNOWN;
}

void srv_submit_check_estimate(srv_app *app, const obs_scene *sc, obs_err *problems) {
  if (!app->cfg.estimate_render_time) return;
  obs_backend be;
  obs_err e = OBS_ERR_INIT;
  int rc = srv_pick_backend(sc->technique, sc->backend, app->vulkan_lane, &be, &e);
  obs_err_free(&e);
  if (rc) return; /* reported by the backend check */
  double work = obs_scene_work(sc);
  if (!(work > 0)) return;
  double *rates = NULL, rate = NAN;
  size_t n = 0;
  char from[160];
  if (!srv_db_run_rates(app->db, sc->technique->name, obs_backend_name(be), app->machine_id,
                        work * RATE_MIN_FRACTION, &rates, &n, &e) &&
      n >= RATE_MIN_RUNS) {
    rate = srv_median(rates, n);
    snprintf(from, sizeof from, "the median of %zu stored runs of %s on %s here", n,
             sc->technique->name, obs_backend_name(be));
  }
  free(rates);
  if (e.count) srv_log("render-time estimate: %s (using the built-in rate)", obs_err_message(&e));
  obs_err_free(&e);
  if (!isfinite(rate)) {
    rate = fallback_rate(sc->technique);
    snprintf(from, sizeof from, "the built-in rate of %s (no stored runs to go by)",
             sc->technique->name);
  }
  double seconds = work * rate / 1e3;
  if (seconds > app->cfg.max_render_seconds)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /image: estimated render time %.0f s (work %.4g x %.3g ms per unit of work, "
                "%s) exceeds the server's limit max-render-seconds = %d s; lower the image size, "
                "spp or samples",
                sc->name, seconds, work, rate, from, app->cfg.max_render_seconds);
}

/* ---- admission: the queue's work, jobs and stored bytes ------------------------------------- */

/* Check and insert under one lock: two submissions that each fit could otherwise both pass the
 * check and together exceed the cap. The mutex orders this daemon's threads; the store's
 * admission lock orders the nodes sharing a store (a no-op for SQLite's one daemon). */
static pthread_mutex_t admit_mu = PTHREAD_MUTEX_INITIALIZER;

static int admit_enter(srv_app *app, obs_err *problems) {
  pthread_mutex_lock(&admit_mu);
  int rc = srv_db_admit_lock(app->db, problems);
  if (rc) pthread_mutex_unlock(&admit_mu);
  return rc;
}

static void admit_leave(srv_app *app) {
  srv_db_admit_unlock(app->db);
  pthread_mutex_unlock(&admit_mu);
}

/* What a job costs the queue: every render it will do, its renderer processes, its bytes. */
static srv_load job_load(const srv_new_job *j, int64_t extra) {
  srv_load l = {j->work * ((j->repeats > 0 ? j->repeats : 1) + (j->warmup ? 1 : 0)),
                j->ranks > 1 ? j->ranks : 1, (double)(srv_job_stored_bytes(j) + extra)};
  return l;
}

/* One queue dimension: its caps and how a problem names it. */
typedef struct cap {
  const char *what, *unit, *per_client, *total;
  int whole; /* amounts are counts, shown in full (work is shown to 4 digits) */
  double (*get)(const srv_load *);
  double mine_cap, total_cap;
} cap;

static double get_work(const srv_load *l) { return l->work; }
static double get_jobs(const srv_load *l) { return l->jobs; }
static double get_bytes(const srv_load *l) { return l->bytes; }

static void amount(char *buf, size_t n, double v, int whole) {
  if (whole) snprintf(buf, n, "%.0f", v);
  else snprintf(buf, n, "%.4g", v);
}

/* A queue of `work` drains in about this many seconds at the slowest built-in rate (5 s to 1 h):
 * when a client may usefully try again. */
static int drain_seconds(double work) {
  double s = ceil(work * FALLBACK_UNKNOWN / 1e3);
  return s < 5 ? 5 : s > 3600 ? 3600 : (int)s;
}

/* 0 when `adding` fits every cap; else 429 with the problems. Called under admit_mu. */
static unsigned check_caps(srv_app *app, const char *client, const srv_load *adding,
                           int *retry_after, obs_err *problems) {
  srv_load mine, total;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_queued(app->db, client, &mine, &total, &e)) {
    obs_err_set(problems, OBS_EIO, "%s", obs_err_message(&e));
    obs_err_free(&e);
    return 503;
  }
  const srv_config *c = &app->cfg;
  const cap caps[] = {
      {"queued work", "", "max-queued-work", "max-queued-work-total", 0, get_work,
       c->max_queued_work, c->max_queued_work_total},
      {"queued jobs (a job on N MPI ranks counts N)", "", "max-queued-jobs",
       "max-queued-jobs-total", 1, get_jobs, c->max_queued_jobs, c->max_queued_jobs_total},
      {"bytes stored by queued jobs", " bytes", "max-queued-bytes", "max-queued-bytes-total",
       1, get_bytes, (double)c->max_queued_bytes, (double)c->max_queued_bytes_total},
  };
  int wait = 0;
  for (size_t i = 0; i < sizeof caps / sizeof caps[0]; i++) {
    const cap *k = &caps[i];
    double add = k->get(adding), m = k->get(&mine), t = k->get(&total);
    if (add <= 0) continue;
    char sum[32], held[32], more[32], limit[32];
    amount(more, sizeof more, add, k->whole);
    if (m + add > k->mine_cap) {
      amount(sum, sizeof sum, m + add, k->whole);
      amount(held, sizeof held, m, k->whole);
      amount(limit, sizeof limit, k->mine_cap, k->whole);
      obs_err_set(problems, OBS_EINVAL,
                  "%s of client %s would be %s%s (%s queued or running + %s in this request), "
                  "over the server's limit %s = %s per client",
                  k->what, client, sum, k->unit, held, more, k->per_client, limit);
      /* Work: roughly when enough of it will have rendered; otherwise the client's queue. */
      int s = drain_seconds(i == 0 ? fmin(m + add - k->mine_cap, add) : mine.work);
      if (s > wait) wait = s;
      srv_refused(k->per_client);
    }
    if (t + add > k->total_cap) {
      amount(sum, sizeof sum, t + add, k->whole);
      amount(held, sizeof held, t, k->whole);
      amount(limit, sizeof limit, k->total_cap, k->whole);
      obs_err_set(problems, OBS_EINVAL,
                  "%s of all clients would be %s%s (%s queued or running + %s in this request), "
                  "over the server's limit %s = %s",
                  k->what, sum, k->unit, held, more, k->total, limit);
      int s = drain_seconds(i == 0 ? fmin(t + add - k->total_cap, add) : total.work);
      if (s > wait) wait = s;
      srv_refused(k->total);
    }
  }
  if (!wait) return 0;
  *retry_after = wait;
  return 429;
}

/* A failed insert: a transient database fault is raised (health shows it, lanes pause) unless
 * the database is already known lost; either way the client gets a 503. */
static unsigned insert_failed(srv_app *app, int rc, const obs_err *problems) {
  char fault[1400];
  if (rc == OBS_ETRANSIENT && !srv_fault_refusing(fault, sizeof fault))
    srv_fault_raise(SRV_FAULT_DB, srv_db_path(app->db), NULL, obs_err_message(problems), NULL);
  return 503;
}

/* After a job or comparison was queued: whose it is (without its client it counts only towards
 * the total). */
static void record_client(srv_app *app, int64_t job, int64_t comparison, const char *client) {
  obs_err e = OBS_ERR_INIT;
  if (srv_db_set_job_client(app->db, job, comparison, client, &e))
    srv_log("%s %lld: client not recorded: %s", job ? "job" : "comparison",
            (long long)(job ? job : comparison), obs_err_message(&e));
  obs_err_free(&e);
}

unsigned srv_admit_job(srv_app *app, const char *client, const srv_new_job *nj, int64_t *id,
                       int *retry_after, obs_err *problems) {
  srv_load adding = job_load(nj, 0);
  int rc = admit_enter(app, problems);
  if (rc) return insert_failed(app, rc, problems);
  unsigned st = check_caps(app, client, &adding, retry_after, problems);
  rc = st ? 0 : srv_db_insert_job(app->db, nj, id, problems);
  if (rc) st = insert_failed(app, rc, problems);
  if (!st) record_client(app, *id, 0, client);
  admit_leave(app);
  return st;
}

unsigned srv_admit_comparison(srv_app *app, const char *client, const srv_new_comparison *c,
                              int64_t *id, int *retry_after, obs_err *problems) {
  srv_load adding = {0, 0, 0};
  for (int i = 0; i < c->nreferences; i++) {
    srv_load l = job_load(&c->references[i], i ? 0 : srv_comparison_stored_bytes(c));
    adding.work += l.work, adding.jobs += l.jobs, adding.bytes += l.bytes;
  }
  for (int i = 0; i < c->ncandidates; i++) {
    srv_load l = job_load(&c->candidates[i].job, srv_candidate_row_bytes(&c->candidates[i]));
    adding.work += l.work, adding.jobs += l.jobs, adding.bytes += l.bytes;
  }
  int rc = admit_enter(app, problems);
  if (rc) return insert_failed(app, rc, problems);
  unsigned st = check_caps(app, client, &adding, retry_after, problems);
  rc = st ? 0 : srv_db_insert_comparison(app->db, c, id, problems);
  if (rc) st = insert_failed(app, rc, problems);
  if (!st) record_client(app, 0, *id, client);
  admit_leave(app);
  return st;
}

unsigned srv_admit_retry(srv_app *app, const char *client, int64_t id, srv_state *state,
                         int *retry_after, obs_err *problems) {
  srv_load adding;
  int rc = admit_enter(app, problems);
  if (rc) return insert_failed(app, rc, problems);
  rc = srv_db_job_load(app->db, id, &adding, state, problems);
  unsigned st = rc == OBS_ENOTFOUND ? 404 : rc ? 503 : 0;
  /* A job that cannot be retried is answered as such, whatever the queue holds. */
  if (!st && *state != SRV_FAILED && *state != SRV_CANCELLED) st = 409;
  if (!st) st = check_caps(app, client, &adding, retry_after, problems);
  if (!st) {
    rc = srv_db_retry(app->db, id, state, problems);
    st = rc == OBS_ENOTFOUND ? 404 : rc == OBS_EINVAL ? 409 : rc ? insert_failed(app, rc, problems)
                                                                 : 0;
  }
  /* The requeued work is now the retrying client's. */
  if (!st) record_client(app, id, 0, client);
  admit_leave(app);
  return st;
}


void srv_req_client(srv_app *app, struct MHD_Connection *c, char *buf, size_t n) {
  if (app->has_token) {
    /* One token, so one identity: every holder of it shares the caps. */
    snprintf(buf, n, "token");
    return;
  }
  const union MHD_ConnectionInfo *ci = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
  /* The connection guard's notion of one client: an IPv4 address or an IPv6 /64. */
  srv_guard_client_name(ci ? ci->client_addr : NULL, buf, n);
}
