/* Bounds on the work obscurad accepts: queued work per client and in total (a small request can
 * expand into hundreds of jobs), and a refusal at submission of a job whose estimated render time
 * exceeds the per-render limit, rather than letting it run into the limit and fail. */
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

/* ---- queued work ------------------------------------------------------------------------------ */

/* Check and insert under one lock: two submissions that each fit could otherwise both pass the
 * check and together exceed the cap. This daemon is the database's only writer of jobs. */
static pthread_mutex_t admit_mu = PTHREAD_MUTEX_INITIALIZER;

/* What a job costs the queue: every render it will do. */
static double job_work(const srv_new_job *j) {
  return j->work * ((j->repeats > 0 ? j->repeats : 1) + (j->warmup ? 1 : 0));
}

/* 0 when `adding` fits both caps; else 429 with the problem. Called under admit_mu. */
static unsigned check_caps(srv_app *app, const char *client, double adding, int *retry_after,
                           obs_err *problems) {
  double mine = 0, total = 0;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_queued_work(app->db, client, &mine, &total, &e)) {
    obs_err_set(problems, OBS_EIO, "%s", obs_err_message(&e));
    obs_err_free(&e);
    return 503;
  }
  const srv_config *c = &app->cfg;
  double over = 0;
  if (mine + adding > c->max_queued_work) {
    obs_err_set(problems, OBS_EINVAL,
                "queued work of client %s would be %.4g (%.4g queued or running + %.4g in this "
                "request), over the server's limit max-queued-work = %.4g per client",
                client, mine + adding, mine, adding, c->max_queued_work);
    over = mine + adding - c->max_queued_work;
  }
  if (total + adding > c->max_queued_work_total) {
    obs_err_set(problems, OBS_EINVAL,
                "queued work of all clients would be %.4g (%.4g queued or running + %.4g in this "
                "request), over the server's limit max-queued-work-total = %.4g",
                total + adding, total, adding, c->max_queued_work_total);
    double o = total + adding - c->max_queued_work_total;
    if (o > over) over = o;
  }
  if (over <= 0) return 0;
  /* Roughly when enough of the queue will have rendered, at the slowest built-in rate. */
  double s = ceil(fmin(over, adding) * FALLBACK_UNKNOWN / 1e3);
  *retry_after = s < 5 ? 5 : s > 3600 ? 3600 : (int)s;
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

unsigned srv_admit_job(srv_app *app, const char *client, const srv_new_job *nj, int64_t *id,
                       int *retry_after, obs_err *problems) {
  pthread_mutex_lock(&admit_mu);
  unsigned st = check_caps(app, client, job_work(nj), retry_after, problems);
  int rc = st ? 0 : srv_db_insert_job(app->db, nj, id, problems);
  if (rc) st = insert_failed(app, rc, problems);
  if (!st) {
    obs_err e = OBS_ERR_INIT;
    /* The job is queued either way; without its client it counts only towards the total. */
    if (srv_db_set_job_client(app->db, *id, 0, client, &e))
      srv_log("job %lld: client not recorded: %s", (long long)*id, obs_err_message(&e));
    obs_err_free(&e);
  }
  pthread_mutex_unlock(&admit_mu);
  return st;
}

unsigned srv_admit_comparison(srv_app *app, const char *client, const srv_new_comparison *c,
                              int64_t *id, int *retry_after, obs_err *problems) {
  double adding = 0;
  for (int i = 0; i < c->nreferences; i++) adding += job_work(&c->references[i]);
  for (int i = 0; i < c->ncandidates; i++) adding += job_work(&c->candidates[i].job);
  pthread_mutex_lock(&admit_mu);
  unsigned st = check_caps(app, client, adding, retry_after, problems);
  int rc = st ? 0 : srv_db_insert_comparison(app->db, c, id, problems);
  if (rc) st = insert_failed(app, rc, problems);
  if (!st) {
    obs_err e = OBS_ERR_INIT;
    if (srv_db_set_job_client(app->db, 0, *id, client, &e))
      srv_log("comparison %lld: client not recorded: %s", (long long)*id, obs_err_message(&e));
    obs_err_free(&e);
  }
  pthread_mutex_unlock(&admit_mu);
  return st;
}

int srv_respond_too_busy(srv_req *r, int retry_after, const obs_err *problems) {
  json_t *list = json_array();
  const char *t = obs_err_message(problems);
  while (*t) {
    size_t n = strcspn(t, "\n");
    json_array_append_new(list, json_stringn(t, n));
    t += n;
    if (*t) t++;
  }
  char msg[96];
  snprintf(msg, sizeof msg, "too much queued work: try again in %d s", retry_after);
  struct MHD_Response *resp =
      srv_json_response(json_pack("{s:s, s:o}", "error", msg, "problems", list));
  if (!resp) return MHD_NO;
  char ra[16];
  snprintf(ra, sizeof ra, "%d", retry_after);
  MHD_add_response_header(resp, "Retry-After", ra);
  return srv_respond(r, 429, resp);
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
