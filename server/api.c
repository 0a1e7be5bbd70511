/* The routes of obscurad's JSON API (/api/v1/...) and /metrics: routing, query parsing, and the
 * job object as the API shows it. */
#include <dirent.h>
#include <jansson.h>
#include <limits.h>
#include <microhttpd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "json_util.h"
#include "obscurad.h"

#define API "/api/v1"

/* Splits /api/v1/jobs/{id}[/rest]: returns the route and fills the id text and the rest. */
static srv_route job_route(const char *path, const char **id, size_t *idlen, const char **rest) {
  const char *p = path + sizeof API "/jobs/" - 1;
  const char *slash = strchr(p, '/');
  *id = p;
  *idlen = slash ? (size_t)(slash - p) : strlen(p);
  *rest = slash ? slash : "";
  if (!slash) return SRV_ROUTE_JOB;
  if (!strcmp(slash, "/cancel")) return SRV_ROUTE_JOB_CANCEL;
  if (!strcmp(slash, "/retry")) return SRV_ROUTE_JOB_RETRY;
  if (!strcmp(slash, "/document")) return SRV_ROUTE_JOB_DOCUMENT;
  if (!strcmp(slash, "/log")) return SRV_ROUTE_JOB_LOG;
  if (!strcmp(slash, "/preview.exr")) return SRV_ROUTE_JOB_PREVIEW;
  if (!strncmp(slash, "/outputs/", 9) && slash[9] && !strchr(slash + 9, '/'))
    return SRV_ROUTE_JOB_OUTPUT;
  return SRV_ROUTE_UNKNOWN;
}

srv_route srv_api_route(const char *path) {
  if (!strcmp(path, "/metrics")) return SRV_ROUTE_METRICS;
  if (!strcmp(path, API "/comparisons")) return SRV_ROUTE_COMPARISONS;
  if (!strncmp(path, API "/comparisons/", sizeof API "/comparisons/" - 1))
    return strchr(path + sizeof API "/comparisons/" - 1, '/') ? SRV_ROUTE_UNKNOWN
                                                              : SRV_ROUTE_COMPARISON;
  if (strncmp(path, "/api/", 5) && strcmp(path, "/api")) return SRV_ROUTE_STATIC;
  if (!strcmp(path, API "/jobs")) return SRV_ROUTE_JOBS;
  if (!strcmp(path, API "/techniques")) return SRV_ROUTE_TECHNIQUES;
  if (!strcmp(path, API "/metrics")) return SRV_ROUTE_METRIC_TABLE;
  if (!strcmp(path, API "/scenes")) return SRV_ROUTE_SCENES;
  if (!strncmp(path, API "/scenes/", sizeof API "/scenes/" - 1)) {
    const char *slash = strchr(path + sizeof API "/scenes/" - 1, '/');
    return slash && !strcmp(slash, "/defaults") ? SRV_ROUTE_SCENE_DEFAULTS : SRV_ROUTE_UNKNOWN;
  }
  if (!strcmp(path, API "/health")) return SRV_ROUTE_HEALTH;
  if (!strcmp(path, API "/diff")) return SRV_ROUTE_DIFF;
  if (!strcmp(path, API "/session")) return SRV_ROUTE_SESSION;
  if (!strncmp(path, API "/jobs/", sizeof API "/jobs/" - 1)) {
    const char *id, *rest;
    size_t n;
    return job_route(path, &id, &n, &rest);
  }
  return SRV_ROUTE_UNKNOWN;
}

static int is_get(const srv_req *r) {
  return !strcmp(r->method, "GET") || !strcmp(r->method, "HEAD");
}

/* ---- the job object -------------------------------------------------------------------------- */

static json_t *str_or_null(const char *s) { return s ? json_string(s) : json_null(); }

static json_t *job_links(int64_t id, const srv_job *j) {
  char self[64], cancel[80], retry[80];
  snprintf(self, sizeof self, API "/jobs/%lld", (long long)id);
  snprintf(cancel, sizeof cancel, "%s/cancel", self);
  snprintf(retry, sizeof retry, "%s/retry", self);
  char logl[80];
  snprintf(logl, sizeof logl, "%s/log", self);
  json_t *outs = json_object();
  for (int i = 0; j && i < j->noutputs; i++) {
    char url[128];
    snprintf(url, sizeof url, "%s/outputs/%s", self, j->outputs[i].name);
    json_object_set_new(outs, j->outputs[i].name, json_string(url));
  }
  json_t *l = json_pack("{s:s, s:s, s:s, s:s, s:o}", "self", self, "cancel", cancel, "retry", retry,
                        "log", logl, "outputs", outs);
  if (j && j->comparison) {
    char cmp[64];
    snprintf(cmp, sizeof cmp, API "/comparisons/%lld", (long long)j->comparison);
    json_object_set_new(l, "comparison", json_string(cmp));
  }
  return l;
}

static json_t *job_json(srv_app *app, const srv_job *j) {
  double progress = j->progress;
  if (j->state == SRV_RUNNING) srv_sched_progress(app, j->id, &progress);
  json_t *o = json_object();
  json_object_set_new(o, "id", json_integer(j->id));
  json_object_set_new(o, "state", json_string(srv_state_name(j->state)));
  json_object_set_new(o, "progress", json_real(progress));
  json_object_set_new(o, "attempts", json_integer(j->attempts));
  json_object_set_new(o, "priority", json_integer(j->priority));
  json_object_set_new(o, "label", str_or_null(j->label));
  json_object_set_new(o, "comparison_id",
                      j->comparison ? json_integer(j->comparison) : json_null());
  json_object_set_new(o, "scene", str_or_null(j->scene));
  json_object_set_new(o, "scene_name",
                      str_or_null(j->scene_name                            ? j->scene_name
                                  : j->scene && strcmp(j->scene, "inline") ? j->scene
                                                                           : NULL));
  json_object_set_new(o, "notes", srv_json_array_of(j->notes));
  json_object_set_new(o, "technique", str_or_null(j->technique));
  json_object_set_new(
      o, "backend",
      json_pack("{s:o, s:o, s:o}", "requested", str_or_null(j->backend_requested), "actual",
                str_or_null(j->backend), "reason", str_or_null(j->backend_reason)));
  json_object_set_new(o, "repeats", json_integer(j->repeats));
  json_object_set_new(o, "ranks", json_integer(j->ranks > 1 ? j->ranks : 1));
  json_object_set_new(
      o, "image",
      json_pack("{s:i, s:i, s:i}", "width", j->width, "height", j->height, "spp", j->spp));
  json_object_set_new(o, "created_at", srv_json_time(j->created_ms));
  json_object_set_new(o, "started_at", srv_json_time(j->started_ms));
  json_object_set_new(o, "finished_at", srv_json_time(j->finished_ms));
  json_object_set_new(o, "cancel_requested", json_boolean(j->cancel_requested));
  json_t *sum = j->summary ? json_loads(j->summary, 0, NULL) : NULL;
  json_t *timings = json_object_get(sum, "timings_ms");
  json_object_set(o, "timings_ms", timings ? timings : json_null());
  json_t *rays = json_object_get(sum, "rays");
  json_object_set(o, "rays", rays ? rays : json_null());
  json_t *frames = json_object_get(sum, "frames");
  json_object_set(o, "frames", json_is_array(frames) ? frames : json_null());
  json_t *built = json_object_get(sum, "built");
  json_object_set(o, "built", json_is_array(built) ? built : json_null());
  if (sum) {
    json_t *stats = json_object();
    json_t *ao = json_object_get(sum, "ao");
    if (ao) json_object_set(stats, "ao", ao);
    json_t *nan = json_object_get(sum, "nan_count");
    json_object_set(stats, "nan_count", nan ? nan : json_integer(0));
    json_t *se = json_object_get(sum, "ao_stderr_mean");
    if (se) json_object_set(stats, "ao_stderr_mean", se);
    /* Per declared output (obs_result_summary_json), for techniques without ao too. */
    json_t *prim = json_object_get(sum, "primary_output"), *outs = json_object_get(sum, "outputs");
    if (json_is_string(prim)) json_object_set(stats, "primary_output", prim);
    if (json_is_object(outs)) json_object_set(stats, "outputs", outs);
    json_object_set_new(o, "stats", stats);
  } else {
    json_object_set_new(o, "stats", json_null());
  }
  /* Summaries stored before warnings existed have none. */
  json_t *warn = json_object_get(sum, "warnings");
  json_object_set_new(o, "warnings", json_is_array(warn) ? json_incref(warn) : json_array());
  json_decref(sum);
  json_object_set_new(o, "error", str_or_null(j->error));
  json_t *outs = json_array();
  for (int i = 0; i < j->noutputs; i++) {
    const srv_output *x = &j->outputs[i];
    char url[128];
    snprintf(url, sizeof url, API "/jobs/%lld/outputs/%s", (long long)j->id, x->name);
    json_array_append_new(
        outs, json_pack("{s:s, s:I, s:s, s:s, s:s}", "name", x->name, "size", (json_int_t)x->size,
                        "sha256", x->sha256, "content_type", x->content_type, "url", url));
  }
  json_object_set_new(o, "outputs", outs);
  json_object_set_new(o, "links", job_links(j->id, j));
  return o;
}

/* ---- /api/v1/jobs ---------------------------------------------------------------------------- */


static int submit(srv_req *r) {
  int refused;
  if (srv_refuse_non_json(r, &refused)) return refused;
  if (srv_refuse_when_faulted(r, &refused)) return refused;
  srv_submission s;
  obs_err problems = OBS_ERR_INIT;
  const char *message = NULL;
  unsigned status = srv_submit_parse(r->app, r->body, r->len, &s, &message, &problems);
  if (status) {
    int rc = srv_respond_error(r, status, &problems, "%s", message);
    obs_err_free(&problems);
    return rc;
  }
  char *notes = json_array_size(s.notes) ? json_dumps(s.notes, JSON_COMPACT) : NULL;
  char *choice = s.choice ? json_dumps(s.choice, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
  srv_new_job nj = {.priority = s.priority,
                    .label = s.label,
                    .scene = s.scene,
                    .doc = s.doc,
                    .technique = s.technique,
                    .backend_requested = s.backend_requested,
                    .lane = s.lane,
                    .width = s.width,
                    .height = s.height,
                    .spp = s.spp,
                    .repeats = 1,
                    .work = s.work,
                    .backend_reason = s.backend_reason,
                    .scene_name = s.scene_name,
                    .notes = notes,
                    .ranks = s.ranks,
                    .choice = choice};
  int64_t id = 0;
  int retry = 0;
  unsigned admit = srv_admit_job(r->app, r->client, &nj, &id, &retry, &problems);
  free(notes);
  free(choice);
  if (admit) {
    srv_submission_free(&s);
    if (admit != 429) return srv_respond_unavailable(r, &problems);
    int rc = srv_respond_too_busy(r, retry, &problems);
    obs_err_free(&problems);
    return rc;
  }
  srv_job_log(r->app, id, "submitted -> queued (%s, %s/%s, %dx%d, priority %d; backend: %s)",
              s.scene, s.technique, s.backend_requested, s.width, s.height, s.priority,
              s.backend_reason ? s.backend_reason : "requested");
  size_t k;
  json_t *note;
  json_array_foreach(s.notes, k, note) srv_job_log(r->app, id, "note: %s", json_string_value(note));
  json_t *body = json_pack("{s:I, s:s, s:o}", "id", (json_int_t)id, "state", "queued", "links",
                           job_links(id, NULL));
  if (s.choice) json_object_set(body, "choice", s.choice);
  /* Parameters derived from the scene's size, so the client can say so. */
  json_object_set_new(body, "notes", s.notes ? json_incref(s.notes) : json_array());
  srv_submission_free(&s);
  srv_sched_notify(r->app);
  char loc[64];
  snprintf(loc, sizeof loc, API "/jobs/%lld", (long long)id);
  return srv_respond_created(r, body, loc);
}

typedef struct query {
  srv_job_filter f;
  obs_err *problems;
  int seen[6];
} query;

static const char *const query_keys[] = {"state", "technique", "backend",
                                         "limit", "after",     "order"};

static enum MHD_Result on_query_arg(void *cls, enum MHD_ValueKind kind, const char *key,
                                    const char *value) {
  (void)kind;
  query *q = cls;
  int k = -1;
  for (int i = 0; i < 6; i++)
    if (!strcmp(key, query_keys[i])) k = i;
  char shown[80];
  srv_printable(value, shown, sizeof shown);
  if (k < 0) {
    char kshown[40];
    srv_printable(key, kshown, sizeof kshown);
    obs_err_set(q->problems, OBS_EINVAL,
                "query: /%s: unknown parameter (known: state, technique, backend, limit, after, "
                "order)",
                kshown);
    return MHD_YES;
  }
  if (q->seen[k]++) {
    obs_err_set(q->problems, OBS_EINVAL, "query: /%s: given more than once", key);
    return MHD_YES;
  }
  if (!value) value = "";
  if (k == 0) {
    if (srv_state_parse(value, &q->f.state))
      obs_err_set(q->problems, OBS_EINVAL,
                  "query: /state: must be one of queued, running, succeeded, failed, cancelled "
                  "(got \"%s\")",
                  shown);
    else
      q->f.has_state = 1;
  } else if (k == 1) {
    if (!obs_technique_find(value))
      obs_err_set(q->problems, OBS_EINVAL,
                  "query: /technique: not a technique (got \"%s\"; GET /api/v1/techniques lists "
                  "them)",
                  shown);
    else
      q->f.technique = value;
  } else if (k == 2) {
    obs_backend be;
    if (obs_backend_parse(value, &be))
      obs_err_set(q->problems, OBS_EINVAL,
                  "query: /backend: must be one of cpu, vulkan, auto (got \"%s\")", shown);
    else
      q->f.backend = value;
  } else if (k == 3) {
    int64_t n;
    if (srv_parse_id(value, strlen(value), &n) || n > 500)
      obs_err_set(q->problems, OBS_EINVAL,
                  "query: /limit: must be an integer from 1 to 500 (got \"%s\")", shown);
    else
      q->f.limit = (int)n;
  } else if (k == 4) {
    if (srv_parse_id(value, strlen(value), &q->f.after))
      obs_err_set(q->problems, OBS_EINVAL,
                  "query: /after: must be a job id from a previous page's \"next\" (got \"%s\")",
                  shown);
  } else {
    if (!strcmp(value, "asc"))
      q->f.ascending = 1;
    else if (strcmp(value, "desc"))
      obs_err_set(q->problems, OBS_EINVAL, "query: /order: must be asc or desc (got \"%s\")",
                  shown);
  }
  return MHD_YES;
}

static int list_jobs(srv_req *r) {
  obs_err problems = OBS_ERR_INIT;
  query q;
  memset(&q, 0, sizeof q);
  q.f.limit = 50;
  q.problems = &problems;
  MHD_get_connection_values(r->conn, MHD_GET_ARGUMENT_KIND, on_query_arg, &q);
  if (problems.count) {
    int rc = srv_respond_error(r, MHD_HTTP_BAD_REQUEST, &problems, "bad query parameters");
    obs_err_free(&problems);
    return rc;
  }
  srv_job *jobs;
  int n;
  if (srv_db_list_jobs(r->app->db, &q.f, &jobs, &n, &problems))
    return srv_respond_unavailable(r, &problems);
  json_t *arr = json_array();
  int shown = n > q.f.limit ? q.f.limit : n;
  for (int i = 0; i < shown; i++) json_array_append_new(arr, job_json(r->app, &jobs[i]));
  json_t *next = json_null();
  if (n > q.f.limit) {
    char buf[24];
    snprintf(buf, sizeof buf, "%lld", (long long)jobs[shown - 1].id);
    json_decref(next);
    next = json_string(buf);
  }
  srv_jobs_free(jobs, n);
  return srv_respond_json(r, MHD_HTTP_OK, json_pack("{s:o, s:o}", "jobs", arr, "next", next));
}

/* ---- /api/v1/jobs/{id}... -------------------------------------------------------------------- */

static int not_found_job(srv_req *r, int64_t id) {
  return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no job %lld", (long long)id);
}

static int get_job(srv_req *r, int64_t id, unsigned status) {
  srv_job j;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_get_job(r->app->db, id, &j, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return not_found_job(r, id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  json_t *o = job_json(r->app, &j);
  srv_job_free(&j);
  /* Where it ran (one job's page says "on <device>" or "N threads"); not in the list. */
  json_t *rows = NULL;
  srv_arg arg = {SRV_ARG_INT, id, 0, NULL};
  json_t *m = NULL;
  if (!srv_db_query(r->app->db, SRV_Q_JOB_MACHINE, &arg, 1, &rows, &err))
    m = json_incref(json_array_get(rows, 0));
  obs_err_free(&err);
  json_decref(rows);
  json_object_set_new(o, "device", srv_device_json(json_string_value(json_object_get(
                                                       json_object_get(o, "backend"), "actual")),
                                                   m));
  json_object_set_new(o, "machine", m ? m : json_null());
  json_object_set_new(o, "choice", srv_job_choice_json(r->app, id));
  return srv_respond_json(r, status, o);
}

static int cancel_job(srv_req *r, int64_t id) {
  srv_cancel_result res;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_sched_cancel(r->app, id, &res, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return not_found_job(r, id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  if (res == SRV_CANCEL_FINISHED) {
    srv_state st = SRV_SUCCEEDED;
    srv_db_job_exists(r->app->db, id, &st, &err);
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_CONFLICT, NULL,
                             "job %lld already finished (%s); nothing to cancel", (long long)id,
                             srv_state_name(st));
  }
  return get_job(r, id, MHD_HTTP_ACCEPTED);
}

static int delete_job(srv_req *r, int64_t id) {
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_delete(r->app->db, id, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return not_found_job(r, id);
  }
  if (rc == OBS_EUNSUPPORTED) {
    obs_err_free(&err);
    json_t *rows = NULL;
    srv_arg arg = {SRV_ARG_INT, id, 0, NULL};
    long long cmp = 0;
    if (!srv_db_query(r->app->db, SRV_Q_JOB_COMPARISON, &arg, 1, &rows, &err))
      cmp = (long long)json_integer_value(json_object_get(json_array_get(rows, 0), "comparison"));
    json_decref(rows);
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_CONFLICT, NULL,
                             "job %lld belongs to comparison %lld, which keeps its jobs",
                             (long long)id, cmp);
  }
  if (rc == OBS_EINVAL) {
    obs_err_free(&err);
    srv_state st = SRV_QUEUED;
    srv_db_job_exists(r->app->db, id, &st, &err);
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_CONFLICT, NULL,
                             "job %lld is %s: only finished jobs can be deleted (cancel it first)",
                             (long long)id, srv_state_name(st));
  }
  if (rc) return srv_respond_unavailable(r, &err);
  srv_outputs_remove(r->app, id);
  srv_log("job %lld: deleted", (long long)id);
  struct MHD_Response *resp = MHD_create_response_from_buffer(0, "", MHD_RESPMEM_PERSISTENT);
  return srv_respond(r, MHD_HTTP_NO_CONTENT, resp);
}

/* A retry queues the job's work again, so it passes the same admission as a submission. */
static int retry_job(srv_req *r, int64_t id) {
  obs_err err = OBS_ERR_INIT;
  srv_state st = SRV_QUEUED;
  int retry = 0;
  unsigned status = srv_admit_retry(r->app, r->client, id, &st, &retry, &err);
  if (status == 404) {
    obs_err_free(&err);
    return not_found_job(r, id);
  }
  if (status == 409) {
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_CONFLICT, NULL,
                             "job %lld is %s: only failed or cancelled jobs can be retried",
                             (long long)id, srv_state_name(st));
  }
  if (status == 429) {
    int rc = srv_respond_too_busy(r, retry, &err);
    obs_err_free(&err);
    return rc;
  }
  if (status) return srv_respond_unavailable(r, &err);
  srv_job_log(r->app, id, "retried by request -> queued");
  srv_sched_notify(r->app);
  return get_job(r, id, MHD_HTTP_ACCEPTED);
}

/* The scene document the job renders (what a clone starts from), with its scene, label and
 * priority. */
static int job_document(srv_req *r, int64_t id) {
  obs_err err = OBS_ERR_INIT;
  json_t *rows = NULL;
  srv_arg arg = {SRV_ARG_INT, id, 0, NULL};
  if (srv_db_query(r->app->db, SRV_Q_JOB_DOC, &arg, 1, &rows, &err))
    return srv_respond_unavailable(r, &err);
  json_t *row = json_array_get(rows, 0);
  if (!row) {
    json_decref(rows);
    return not_found_job(r, id);
  }
  const char *text = json_string_value(json_object_get(row, "doc"));
  json_t *doc = text ? json_loads(text, 0, NULL) : NULL;
  json_t *o = json_pack("{s:o, s:O, s:O, s:O, s:O}", "document", doc ? doc : json_null(), "scene",
                        json_object_get(row, "scene"), "scene_name",
                        json_object_get(row, "scene_name"), "label", json_object_get(row, "label"),
                        "priority", json_object_get(row, "priority"));
  json_decref(rows);
  return srv_respond_json(r, MHD_HTTP_OK, o);
}

/* The job's own log: one timestamped line per entry (joblog.c). */
static int job_log(srv_req *r, int64_t id) {
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_job_exists(r->app->db, id, NULL, &err);
  if (rc < 0) return srv_respond_unavailable(r, &err);
  if (rc == 0) return not_found_job(r, id);
  size_t len;
  char *text = srv_job_log_read(r->app, id, &len);
  if (!text)
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL,
                             "cannot read the log of job %lld", (long long)id);
  json_t *lines = json_array();
  for (char *p = text, *nl; *p; p = nl + 1) {
    nl = strchr(p, '\n');
    if (!nl)
      nl = p + strlen(p) - 1;
    else
      *nl = '\0';
    json_t *l = json_string(p);
    /* A line that is not UTF-8 (a path's bytes) is shown with its bytes replaced. */
    if (!l) {
      for (char *q = p; *q; q++)
        if ((unsigned char)*q >= 0x80) *q = '?';
      l = json_string(p);
    }
    if (l) json_array_append_new(lines, l);
  }
  free(text);
  return srv_respond_json(r, MHD_HTTP_OK,
                          json_pack("{s:I, s:o}", "job", (json_int_t)id, "lines", lines));
}

static int delete_comparison(srv_req *r, int64_t id) {
  obs_err err = OBS_ERR_INIT;
  int64_t *ids = NULL;
  int n = 0;
  int rc = srv_db_delete_comparison(r->app->db, id, &ids, &n, &err);
  if (rc == OBS_ENOTFOUND || rc == OBS_EINVAL) {
    obs_err_free(&err);
    return rc == OBS_ENOTFOUND
               ? srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no comparison %lld", (long long)id)
               : srv_respond_error(r, MHD_HTTP_CONFLICT, NULL,
                                   "comparison %lld still has queued or running jobs or metrics "
                                   "being computed (cancel the jobs or wait)",
                                   (long long)id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  for (int i = 0; i < n; i++) srv_outputs_remove(r->app, ids[i]);
  free(ids);
  srv_log("comparison %lld: deleted with its %d jobs", (long long)id, n);
  struct MHD_Response *resp = MHD_create_response_from_buffer(0, "", MHD_RESPMEM_PERSISTENT);
  return srv_respond(r, MHD_HTTP_NO_CONTENT, resp);
}

/* ---- catalogue routes ------------------------------------------------------------------------ */

static int techniques(srv_req *r) {
  return srv_respond_json(
      r, MHD_HTTP_OK,
      json_pack("{s:o, s:b, s:{s:i, s:i}}", "techniques", obs_technique_registry_json(),
                "vulkan_available", r->app->vulkan_lane, "comparison_defaults", "repeats",
                SRV_COMPARE_REPEATS, "reference_samples", SRV_COMPARE_REF_SAMPLES));
}

/* The metric table every comparison's figures follow (the dashboard builds its columns from it). */
static int metric_table(srv_req *r) {
  return srv_respond_json(r, MHD_HTTP_OK, json_pack("{s:o}", "metrics", obs_metric_table_json()));
}

static int cmp_names(const void *a, const void *b) {
  return strcmp(json_string_value(json_object_get(*(json_t *const *)a, "name")),
                json_string_value(json_object_get(*(json_t *const *)b, "name")));
}

static int scenes(srv_req *r) {
  srv_app *app = r->app;
  json_t *list = json_array();
  DIR *d = opendir(app->scenes_real);
  struct dirent *e;
  while (d && (e = readdir(d))) {
    size_t n = strlen(e->d_name);
    if (e->d_name[0] == '.' || n < 6 || strcmp(e->d_name + n - 5, ".json")) continue;
    char path[PATH_MAX + 300], real[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", app->scenes_real, e->d_name);
    struct stat st;
    if (!realpath(path, real) || !obs_path_is_inside(app->scenes_real, real) || stat(real, &st) ||
        !S_ISREG(st.st_mode))
      continue;
    json_t *s = json_pack("{s:s, s:I}", "name", e->d_name, "size", (json_int_t)st.st_size);
    json_error_t je;
    json_t *doc = st.st_size <= 64 * 1024 * 1024 ? json_load_file(real, 0, &je) : NULL;
    json_t *t = json_object_get(doc, "technique"), *img = json_object_get(doc, "image");
    const char *tn = json_string_value(json_object_get(t, "name"));
    const char *be = json_string_value(json_object_get(t, "backend"));
    json_object_set_new(s, "technique", str_or_null(tn));
    json_object_set_new(s, "backend", str_or_null(be));
    json_t *w = json_object_get(img, "width"), *h = json_object_get(img, "height");
    json_object_set(s, "width", json_is_integer(w) ? w : json_null());
    json_object_set(s, "height", json_is_integer(h) ? h : json_null());
    if (!doc) json_object_set_new(s, "error", json_string("not valid JSON"));
    json_decref(doc);
    json_array_append_new(list, s);
  }
  if (d) closedir(d);
  size_t n = json_array_size(list);
  json_t **items = malloc((n ? n : 1) * sizeof *items);
  for (size_t i = 0; items && i < n; i++) items[i] = json_incref(json_array_get(list, i));
  if (items) {
    qsort(items, n, sizeof *items, cmp_names);
    json_array_clear(list);
    for (size_t i = 0; i < n; i++) json_array_append_new(list, items[i]);
    free(items);
  }
  return srv_respond_json(r, MHD_HTTP_OK, json_pack("{s:o}", "scenes", list));
}

/* The technique params a job of bundled scene {name} with ?technique= starts from, as a submission
 * naming only the technique gets them (srv_submit_set_technique): the dashboard's form values. */
static int scene_defaults(srv_req *r) {
  const char *start = r->path + sizeof API "/scenes/" - 1;
  char name[160];
  size_t n = (size_t)(strchr(start, '/') - start);
  if (n >= sizeof name) n = sizeof name - 1;
  memcpy(name, start, n);
  name[n] = '\0';
  const char *tn = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "technique");
  obs_err problems = OBS_ERR_INIT;
  obs_jpath p;
  obs_jpath_init(&p, "request", &problems);
  json_t *jname = json_string(name);
  json_t *doc = srv_submit_load_bundled(r->app, &p, jname);
  json_decref(jname);
  /* Copied: the document's technique object is replaced below. */
  char own[64] = "", want[64] = "";
  const char *dn = json_string_value(json_object_get(json_object_get(doc, "technique"), "name"));
  snprintf(own, sizeof own, "%s", dn ? dn : "");
  snprintf(want, sizeof want, "%s", tn ? tn : own);
  tn = want;
  if (doc && !obs_technique_find(tn))
    obs_err_set(&problems, OBS_EINVAL,
                "request: ?technique: no such technique (got \"%s\"; GET "
                "/api/v1/techniques lists them)",
                tn);
  if (problems.count) {
    json_decref(doc);
    int rc = srv_respond_error(r, MHD_HTTP_NOT_FOUND, &problems, "no such scene or technique");
    obs_err_free(&problems);
    return rc;
  }
  json_t *notes = json_array();
  json_t *tech = json_pack("{s:s}", "name", tn);
  json_t *scene_technique = json_string(own);
  /* The scene's backend, for its own technique: what the form preselects. */
  json_t *backend = json_incref(
      !strcmp(tn, own) ? json_object_get(json_object_get(doc, "technique"), "backend") : NULL);
  srv_submit_set_technique(r->app, doc, name, tech, notes);
  json_t *t = json_object_get(doc, "technique");
  json_t *o = json_pack(
      "{s:s, s:O, s:s, s:O, s:O, s:o}", "scene", name, "scene_technique", scene_technique,
      "technique", tn, "backend", backend ? backend : json_null(), "params",
      json_object_get(t, "params") ? json_object_get(t, "params") : json_object(), "notes", notes);
  json_decref(scene_technique);
  json_decref(backend);
  json_decref(tech);
  json_decref(doc);
  if (!o) return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "out of memory");
  return srv_respond_json(r, MHD_HTTP_OK, o);
}

static int health(srv_req *r) {
  srv_app *app = r->app;
  int64_t counts[SRV_NSTATES];
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_counts(app->db, counts, &err);
  int level = 0;
  json_t *faults = srv_fault_json(&level);
  if (rc && level < 1) level = 1;
  static const char *const names[] = {"ok", "degraded", "error"};
  json_t *o = json_pack(
      "{s:s, s:s, s:s, s:I, s:I, s:{s:i, s:i}, s:b, s:b, s:f}", "status", names[level], "version",
      OBSCURA_VERSION, "db", rc ? obs_err_message(&err) : "ok", "queue_depth",
      (json_int_t)(rc ? 0 : counts[SRV_QUEUED]), "running",
      /* Counted from the rows, as the job list shows them (the scheduler's slots and the rows'
       * states change at different moments); the slots when the database cannot be read. */
      rc ? (json_int_t)srv_sched_running(app) : (json_int_t)counts[SRV_RUNNING], "workers",
      "cpu", app->cfg.workers, "vulkan", app->vulkan_lane, "vulkan_available", app->vulkan_lane,
      "vulkan_device", app->vk_available, "uptime_s", (obs_now_ms() - app->start_ms) / 1e3);
  obs_err_free(&err);
  if (!o) {
    json_decref(faults);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "out of memory");
  }
  /* Lanes do not claim while any fault is active; `paused` counts the workers holding a
   * finished job until theirs clears. */
  json_object_set_new(o, "faults", faults ? faults : json_array());
  json_t *recent = srv_fault_recent_json();
  json_object_set_new(o, "recent_faults", recent ? recent : json_array());
  json_object_set_new(o, "lanes_paused", json_boolean(level > 0 && srv_fault_any()));
  json_object_set_new(o, "devices", srv_devices_json(app));
  json_object_set_new(o, "paused", json_integer(srv_sched_paused(app)));
  /* Refusing work for want of room is degraded service, even with every fault clear. */
  int refusing = 0;
  json_t *capacity = srv_refusals_json(&refusing);
  json_object_set_new(capacity, "inflight_bytes", json_integer(srv_guard_inflight(app->guard)));
  json_object_set_new(capacity, "max_inflight_bytes", json_integer(app->cfg.max_inflight));
  json_object_set_new(o, "capacity", capacity);
  if (refusing && level < 1) json_object_set_new(o, "status", json_string(names[1]));
  return srv_respond_json(r, rc || level == 2 ? MHD_HTTP_SERVICE_UNAVAILABLE : MHD_HTTP_OK, o);
}

static int metrics(srv_req *r) {
  size_t len = 0;
  char *text = srv_metrics_text(r->app, &len);
  if (!text) return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "out of memory");
  struct MHD_Response *resp = MHD_create_response_from_buffer(len, text, MHD_RESPMEM_MUST_FREE);
  MHD_add_response_header(resp, "Content-Type", "text/plain; version=0.0.4; charset=utf-8");
  return srv_respond(r, MHD_HTTP_OK, resp);
}

/* ---- dispatch -------------------------------------------------------------------------------- */

int srv_api_dispatch(srv_req *r) {
  switch (r->route) {
    case SRV_ROUTE_STATIC:
      return srv_static_serve(r);
    case SRV_ROUTE_METRICS:
      return is_get(r) ? metrics(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_TECHNIQUES:
      return is_get(r) ? techniques(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_METRIC_TABLE:
      return is_get(r) ? metric_table(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_SCENES:
      return is_get(r) ? scenes(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_SCENE_DEFAULTS:
      return is_get(r) ? scene_defaults(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_HEALTH:
      return is_get(r) ? health(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_SESSION:
      return srv_session_serve(r);
    case SRV_ROUTE_DIFF:
      return is_get(r) ? srv_diff_serve(r) : srv_respond_method(r, "GET, HEAD");
    case SRV_ROUTE_COMPARISONS:
      if (!strcmp(r->method, "POST")) return srv_compare_post(r);
      return is_get(r) ? srv_compare_list(r) : srv_respond_method(r, "GET, HEAD, POST");
    case SRV_ROUTE_COMPARISON: {
      const char *idtext = r->path + sizeof API "/comparisons/" - 1;
      size_t n = strlen(idtext);
      int csv = n > 4 && !strcmp(idtext + n - 4, ".csv");
      int64_t id;
      if (srv_parse_id(idtext, csv ? n - 4 : n, &id))
        return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL,
                                 "no such comparison (ids are positive integers without leading "
                                 "zeros, optionally followed by .csv)");
      if (!csv && !strcmp(r->method, "DELETE")) return delete_comparison(r, id);
      return is_get(r) ? srv_compare_get(r, id, csv)
                       : srv_respond_method(r, csv ? "GET, HEAD" : "GET, HEAD, DELETE");
    }
    case SRV_ROUTE_JOBS:
      if (!strcmp(r->method, "POST")) return submit(r);
      return is_get(r) ? list_jobs(r) : srv_respond_method(r, "GET, HEAD, POST");
    case SRV_ROUTE_JOB:
    case SRV_ROUTE_JOB_CANCEL:
    case SRV_ROUTE_JOB_RETRY:
    case SRV_ROUTE_JOB_DOCUMENT:
    case SRV_ROUTE_JOB_LOG:
    case SRV_ROUTE_JOB_PREVIEW:
    case SRV_ROUTE_JOB_OUTPUT: {
      const char *idtext, *rest;
      size_t n;
      int64_t id;
      job_route(r->path, &idtext, &n, &rest);
      if (srv_parse_id(idtext, n, &id))
        return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL,
                                 "no such job (ids are positive integers without leading zeros)");
      if (r->route == SRV_ROUTE_JOB) {
        if (is_get(r)) return get_job(r, id, MHD_HTTP_OK);
        if (!strcmp(r->method, "DELETE")) return delete_job(r, id);
        return srv_respond_method(r, "GET, HEAD, DELETE");
      }
      if (r->route == SRV_ROUTE_JOB_CANCEL)
        return !strcmp(r->method, "POST") ? cancel_job(r, id) : srv_respond_method(r, "POST");
      if (r->route == SRV_ROUTE_JOB_RETRY)
        return !strcmp(r->method, "POST") ? retry_job(r, id) : srv_respond_method(r, "POST");
      if (r->route == SRV_ROUTE_JOB_DOCUMENT)
        return is_get(r) ? job_document(r, id) : srv_respond_method(r, "GET, HEAD");
      if (r->route == SRV_ROUTE_JOB_LOG)
        return is_get(r) ? job_log(r, id) : srv_respond_method(r, "GET, HEAD");
      if (r->route == SRV_ROUTE_JOB_PREVIEW)
        return is_get(r) ? srv_preview_serve(r, id) : srv_respond_method(r, "GET, HEAD");
      return is_get(r) ? srv_output_serve(r, id, rest + 9) : srv_respond_method(r, "GET, HEAD");
    }
    default:
      break;
  }
  return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no such route");
}
