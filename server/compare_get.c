/* GET /api/v1/comparisons/{id}[.csv] and GET /api/v1/comparisons: a comparison's candidates
 * with their timings, metrics and output links, as JSON or CSV, and the list of comparisons. */
#include <jansson.h>
#include <math.h>
#include <microhttpd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "compare_internal.h"
#include "json_util.h"
#include "obscurad.h"

/* The comparison's state from its counts (docs/comparisons.md): running while a job is queued or
 * running, or while finished candidates (or their further measurements) still wait for their
 * metrics; failed when a candidate can no longer get metrics; succeeded when all have them. */
static const char *state_of(const json_t *row) {
  json_int_t active = json_integer_value(json_object_get(row, "active"));
  json_int_t broken = json_integer_value(json_object_get(row, "broken"));
  json_int_t measured = json_integer_value(json_object_get(row, "measured"));
  json_int_t total = json_integer_value(json_object_get(row, "candidates"));
  json_int_t measuring = json_integer_value(json_object_get(row, "measuring"));
  if (active || measuring) return "running";
  if (broken) return "failed";
  return measured == total ? "succeeded" : "running";
}

/* ---- GET /api/v1/comparisons/{id}[.csv] ------------------------------------------------------ */

static const char *const stages[4] = {"build", "render", "post", "total"};

/* {"median": {...} | null, "min": {...} | null, "max": {...} | null, "runs": [...]} from the runs
 * rows of one job: min and max are the run-to-run spread of each stage. */
static json_t *timings_of(const json_t *runs, json_int_t job, json_t **machine) {
  json_t *list = json_array();
  double v[4][SRV_MAX_REPEATS];
  size_t n = 0;
  if (machine) *machine = NULL;
  for (size_t i = 0; i < json_array_size(runs); i++) {
    json_t *row = json_array_get(runs, i);
    if (json_integer_value(json_object_get(row, "job")) != job) continue;
    json_t *o = json_object();
    for (int k = 0; k < 4; k++) {
      char col[16];
      snprintf(col, sizeof col, "%s_ms", stages[k]);
      double d = json_number_value(json_object_get(row, col));
      json_object_set_new(o, stages[k], num_or_null(d));
      if (n < SRV_MAX_REPEATS) v[k][n] = d;
    }
    /* The node that timed it: with several daemons on one store, hosts differ between jobs. */
    json_t *host = json_object_get(row, "host");
    json_object_set_new(o, "host", json_is_string(host) ? json_incref(host) : json_null());
    json_array_append_new(list, o);
    if (n < SRV_MAX_REPEATS) n++;
    if (machine && !*machine && json_is_string(json_object_get(row, "cpu_model")))
      *machine = json_pack("{s:O, s:O, s:O, s:O}", "cpu_model", json_object_get(row, "cpu_model"),
                           "cores", json_object_get(row, "cores"), "vulkan_device",
                           json_object_get(row, "vulkan_device"), "vulkan_kind",
                           json_object_get(row, "vulkan_kind"));
  }
  json_t *med = json_null(), *lo = json_null(), *hi = json_null();
  if (n) {
    med = json_object();
    lo = json_object();
    hi = json_object();
    for (int k = 0; k < 4; k++) {
      double mn = v[k][0], mx = v[k][0];
      for (size_t i = 1; i < n; i++) {
        mn = fmin(mn, v[k][i]);
        mx = fmax(mx, v[k][i]);
      }
      json_object_set_new(med, stages[k], num_or_null(srv_median(v[k], n)));
      json_object_set_new(lo, stages[k], num_or_null(mn));
      json_object_set_new(hi, stages[k], num_or_null(mx));
    }
  }
  if (machine && !*machine) *machine = json_null();
  return json_pack("{s:o, s:o, s:o, s:o}", "median", med, "min", lo, "max", hi, "runs", list);
}

static int has_output(const json_t *outs, json_int_t job, const char *name) {
  for (size_t i = 0; i < json_array_size(outs); i++) {
    json_t *row = json_array_get(outs, i);
    if (json_integer_value(json_object_get(row, "job")) == job &&
        !strcmp(json_string_value(json_object_get(row, "name")), name))
      return 1;
  }
  return 0;
}

static void output_link(json_t *links, const json_t *outs, json_int_t job, const char *name,
                        const char *as) {
  if (!has_output(outs, job, name)) return;
  char url[128];
  snprintf(url, sizeof url, API "/jobs/%lld/outputs/%s", (long long)job, name);
  json_object_set_new(links, as, json_string(url));
}

/* The PNG of the primary output of `technique` ("ao.png" for today's AO techniques). */
static const char *primary_png(const char *technique) {
  const obs_output *o = obs_technique_primary(obs_technique_find(technique));
  return o && o->png ? o->png : "ao.png";
}

/* A candidate's figures for the Pareto set: median total time and its spread over the timed runs,
 * RMSE and the reference's noise; anything missing takes no part (NaN). */
static void pareto_point(const json_t *tm, const json_t *metrics, obs_pareto_point *p) {
  json_t *total = json_object_get(json_object_get(tm, "median"), "total");
  json_t *rmse = json_object_get(metrics, "rmse"), *noise = json_object_get(metrics, "ref_noise");
  p->time_ms = metrics && json_is_number(total) ? json_number_value(total) : NAN;
  p->time_min_ms = json_number_value(json_object_get(json_object_get(tm, "min"), "total"));
  p->time_max_ms = json_number_value(json_object_get(json_object_get(tm, "max"), "total"));
  p->error = json_is_number(rmse) ? json_number_value(rmse) : NAN;
  p->error_tolerance = json_is_number(noise) ? json_number_value(noise) : 0;
  p->at_reference_accuracy = json_is_true(json_object_get(metrics, "at_reference_accuracy"));
}

/* A reference's entry of the comparison document (row: a candidate row naming it). */
static json_t *reference_json(srv_app *app, const json_t *row, json_int_t rjob, const json_t *runs,
                              const json_t *outs) {
  json_t *ro = json_object();
  json_object_set_new(ro, "job_id", json_integer(rjob));
  const char *rtech = json_string_value(json_object_get(row, "ref_technique"));
  json_object_set_new(ro, "technique", json_string(rtech ? rtech : "rt_ao"));
  const char *rst = json_string_value(json_object_get(row, "ref_state"));
  json_object_set(ro, "state", json_object_get(row, "ref_state"));
  double prog = json_number_value(json_object_get(row, "ref_progress"));
  if (rst && !strcmp(rst, "running")) srv_sched_progress(app, rjob, &prog);
  json_object_set_new(ro, "progress", json_real(prog));
  json_t *rp = json_loads(json_string_value(json_object_get(row, "reference_params")), 0, NULL);
  json_object_set_new(ro, "params", rp ? rp : json_null());
  /* What the candidates are measured against: the job mapped through the response. */
  const char *resp = json_string_value(json_object_get(row, "response"));
  json_t *def = srv_compare_definition(rtech ? rtech : "rt_ao", rp);
  char *label = srv_compare_label(rtech ? rtech : "rt_ao", def, resp);
  json_object_set_new(ro, "definition", def);
  json_object_set_new(ro, "response", json_string(resp ? resp : "identity"));
  json_object_set_new(ro, "label", label ? json_string(label) : json_null());
  free(label);
  const char *st = json_string_value(json_object_get(row, "ref_summary"));
  json_t *sum = json_loads(st ? st : "null", JSON_DECODE_ANY, NULL);
  json_t *se = json_object_get(sum, "ao_stderr_mean");
  json_object_set_new(ro, "ao_stderr_mean",
                      json_is_number(se) ? num_or_null(json_number_value(se)) : json_null());
  json_decref(sum);
  json_object_set_new(ro, "timings_ms", timings_of(runs, rjob, NULL));
  json_t *links = json_object();
  char url[96];
  snprintf(url, sizeof url, API "/jobs/%lld", (long long)rjob);
  json_object_set_new(links, "job", json_string(url));
  output_link(links, outs, rjob, "ao.png", "ao.png");
  output_link(links, outs, rjob, primary_png(rtech), "image");
  json_object_set_new(ro, "links", links);
  return ro;
}

/* A candidate's entry of the comparison document; *pt gets its place on the time/error plane. */
static json_t *candidate_json(srv_app *app, const json_t *row, const json_t *runs,
                              const json_t *outs, obs_pareto_point *pt) {
  json_int_t job = json_integer_value(json_object_get(row, "job"));
  json_int_t rjob = json_integer_value(json_object_get(row, "reference_job"));
  json_t *co = json_object();
  json_object_set(co, "index", json_object_get(row, "idx"));
  json_object_set_new(co, "job_id", json_integer(job));
  json_object_set_new(co, "reference_job_id", json_integer(rjob));
  json_object_set(co, "technique", json_object_get(row, "technique"));
  json_object_set(co, "backend", json_object_get(row, "backend"));
  json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
  json_object_set_new(co, "params", params ? params : json_object());
  json_object_set(co, "response", json_object_get(row, "response"));
  const char *st = json_string_value(json_object_get(row, "state"));
  json_object_set(co, "state", json_object_get(row, "state"));
  double prog = json_number_value(json_object_get(row, "progress"));
  if (st && !strcmp(st, "running")) srv_sched_progress(app, job, &prog);
  json_object_set_new(co, "progress", json_real(prog));
  json_t *machine = NULL;
  json_t *tm = timings_of(runs, job, &machine);
  json_object_set_new(co, "timings_ms", tm);
  const char *mt = json_string_value(json_object_get(row, "metrics"));
  json_t *metrics = mt ? json_loads(mt, 0, NULL) : NULL;
  json_object_set_new(co, "metrics", metrics ? metrics : json_null());
  json_object_set(co, "error", json_object_get(row, "metrics_error"));
  json_object_set_new(co, "device",
                      srv_device_json(json_string_value(json_object_get(row, "backend")), machine));
  json_object_set_new(co, "machine", machine);
  json_t *links = json_object();
  char url[96];
  snprintf(url, sizeof url, API "/jobs/%lld", (long long)job);
  json_object_set_new(links, "job", json_string(url));
  /* "image" is the primary output's PNG of any technique; "ao.png" stays for AO ones. */
  const char *png = primary_png(json_string_value(json_object_get(row, "technique")));
  output_link(links, outs, job, "ao.png", "ao.png");
  output_link(links, outs, job, png, "image");
  output_link(links, outs, job, "error.png", "error.png");
  output_link(links, outs, job, "error.exr", "error.exr");
  output_link(links, outs, job, "flip.png", "flip.png");
  output_link(links, outs, job, "flip.exr", "flip.exr");
  output_link(links, outs, rjob,
              primary_png(json_string_value(json_object_get(row, "ref_technique"))),
              "reference.png");
  output_link(links, outs, job, SRV_MAPPED_REFERENCE_PNG, SRV_MAPPED_REFERENCE_PNG);
  output_link(links, outs, job, SRV_MAPPED_REFERENCE_EXR, SRV_MAPPED_REFERENCE_EXR);
  json_object_set_new(co, "links", links);
  /* Ranking: median total time against RMSE; anything missing takes no part (NaN). */
  pareto_point(tm, metrics, pt);
  return co;
}

/* The comparison's own facts (h: its row). */
static json_t *comparison_head(int64_t id, const json_t *h) {
  json_t *o = json_object();
  json_object_set_new(o, "id", json_integer(id));
  json_object_set(o, "label", json_object_get(h, "label"));
  json_object_set(o, "scene", json_object_get(h, "scene"));
  json_object_set_new(o, "state", json_string(state_of(h)));
  json_object_set_new(o, "created_at",
                      srv_json_time(json_integer_value(json_object_get(h, "created_ms"))));
  json_object_set(o, "repeats", json_object_get(h, "repeats"));
  json_object_set_new(o, "image",
                      json_pack("{s:O, s:O}", "width", json_object_get(h, "width"), "height",
                                json_object_get(h, "height")));
  json_object_set_new(o, "notes",
                      srv_json_array_of(json_string_value(json_object_get(h, "notes"))));
  return o;
}

/* The id ("R1", "R2", ...) of the reference a candidate row is measured against: its job mapped
 * through the row's response, entered into `refs` when new; `role` says which rows use it
 * ("candidates", "common", "output"). Borrowed from refs. */
static const char *reference_id(srv_app *app, json_t *refs, const json_t *row, const char *role,
                                const json_t *runs, const json_t *outs) {
  json_int_t rjob = json_integer_value(json_object_get(row, "reference_job"));
  const char *resp = json_string_value(json_object_get(row, "response"));
  json_t *r = NULL;
  for (size_t k = 0; !r && k < json_array_size(refs); k++) {
    json_t *e = json_array_get(refs, k);
    if (json_integer_value(json_object_get(e, "job_id")) == rjob &&
        !strcmp(json_string_value(json_object_get(e, "response")), resp ? resp : "identity"))
      r = e;
  }
  if (!r) {
    r = reference_json(app, row, rjob, runs, outs);
    char id[24];
    snprintf(id, sizeof id, "R%zu", json_array_size(refs) + 1);
    json_object_set_new(r, "id", json_string(id));
    json_object_set_new(r, "roles", json_array());
    json_array_append_new(refs, r);
  }
  json_t *roles = json_object_get(r, "roles");
  int seen = 0;
  for (size_t k = 0; k < json_array_size(roles); k++)
    seen |= !strcmp(json_string_value(json_array_get(roles, k)), role);
  if (!seen) json_array_append_new(roles, json_string(role));
  return json_string_value(json_object_get(r, "id"));
}

/* {reference, reference_job_id, label} of a measurement against reference `rid` of refs. */
static json_t *reference_ref(const json_t *refs, const char *rid) {
  for (size_t k = 0; k < json_array_size(refs); k++) {
    json_t *e = json_array_get(refs, k);
    if (!strcmp(json_string_value(json_object_get(e, "id")), rid))
      return json_pack("{s:s, s:O, s:O, s:O, s:O}", "id", rid, "job_id",
                       json_object_get(e, "job_id"), "label", json_object_get(e, "label"),
                       "definition", json_object_get(e, "definition"), "response",
                       json_object_get(e, "response"));
  }
  return json_null();
}

/* A further measurement (row of role "common" or "output") of candidate object `co`. */
static void attach_measure(json_t *co, const json_t *row, const json_t *refs, const char *rid) {
  const char *mt = json_string_value(json_object_get(row, "metrics"));
  json_t *metrics = mt ? json_loads(mt, 0, NULL) : NULL;
  json_t *m = json_pack("{s:o, s:O, s:o, s:O}", "reference", reference_ref(refs, rid),
                        "reference_job_id", json_object_get(row, "reference_job"), "metrics",
                        metrics ? metrics : json_null(), "error",
                        json_object_get(row, "metrics_error"));
  const char *role = json_string_value(json_object_get(row, "role"));
  if (!strcmp(role, "common")) {
    json_object_set_new(co, "common", m);
    return;
  }
  /* Which output of the candidate, against which output of the reference. */
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(row, "technique")));
  const obs_technique *rt =
      obs_technique_find(json_string_value(json_object_get(row, "ref_technique")));
  const char *pout = json_string_value(json_object_get(row, "output"));
  const obs_output *o = t && rt ? obs_technique_compared_output(t, rt) : NULL;
  const obs_output *ro = rt ? obs_technique_primary(rt) : NULL;
  /* A pair the technique declares: its output against the reference's output it names. */
  for (const obs_output_pair *q = t && rt && pout ? t->compared_outputs : NULL; q && q->output; q++)
    if (!strcmp(q->output, pout)) {
      o = obs_technique_output(t, q->output);
      ro = obs_technique_output(rt, q->reference_output);
    }
  json_object_set_new(m, "output", o ? json_string(o->name) : json_null());
  json_object_set_new(m, "reference_output", ro ? json_string(ro->name) : json_null());
  json_array_append_new(json_object_get(co, "outputs"), m);
}

/* The candidates' rows into `list` (one object each, with its reference, its common measurement
 * and its other outputs) and their references into `refs`; pts[i] gets candidate i's place. */
static void candidates_of(srv_app *app, const json_t *rows, const json_t *runs, const json_t *outs,
                          json_t *refs, json_t *list, obs_pareto_point *pts, int has_common) {
  for (int pass = 0; pass < 2; pass++) {
    for (size_t i = 0; i < json_array_size(rows); i++) {
      json_t *row = json_array_get(rows, i);
      const char *role = json_string_value(json_object_get(row, "role"));
      int own = !role || !strcmp(role, "own");
      if (own != !pass) continue;
      const char *rid =
          reference_id(app, refs, row, own ? "candidates" : role, runs, outs);
      if (own) {
        json_t *co = candidate_json(app, row, runs, outs, &pts[json_array_size(list)]);
        json_object_set_new(co, "reference", reference_ref(refs, rid));
        if (has_common) json_object_set_new(co, "common", json_null());
        json_object_set_new(co, "outputs", json_array());
        json_array_append_new(list, co);
        continue;
      }
      json_int_t job = json_integer_value(json_object_get(row, "job"));
      for (size_t k = 0; k < json_array_size(list); k++) {
        json_t *co = json_array_get(list, k);
        if (json_integer_value(json_object_get(co, "job_id")) == job)
          attach_measure(co, row, refs, rid);
      }
    }
  }
}

/* Ranks the candidates of `o` within their references' groups (and on the common reference's
 * scale when there is one), into o's "groups", "pareto", "ranking", "comparable", "note" and
 * "common". */
static void rank_all(json_t *o, json_t *list, obs_pareto_point *pts, const json_t *refs) {
  size_t n = json_array_size(list);
  json_t **holder = calloc(n + 1, sizeof *holder), **ms = calloc(n + 1, sizeof *ms);
  const char **group = calloc(n + 1, sizeof *group);
  obs_pareto_point *cp = calloc(n + 1, sizeof *cp);
  if (!holder || !ms || !group || !cp) n = 0;
  size_t with_metrics = 0, ncommon = 0;
  for (size_t i = 0; i < n; i++) {
    json_t *co = json_array_get(list, i);
    holder[i] = co;
    ms[i] = json_object_get(co, "metrics");
    group[i] = json_string_value(json_object_get(json_object_get(co, "reference"), "id"));
  }
  json_t *pareto, *ranking;
  json_t *groups = srv_compare_rank(holder, ms, group, pts, n, &pareto, &ranking);
  for (size_t g = 0; g < json_array_size(groups); g++) {
    json_t *gr = json_array_get(groups, g);
    json_t *ref = reference_ref(refs, json_string_value(json_object_get(gr, "reference")));
    json_object_set(gr, "label", json_object_get(ref, "label"));
    json_decref(ref);
    int any = 0;
    json_t *members = json_object_get(gr, "candidates");
    for (size_t k = 0; k < json_array_size(members); k++)
      any |= json_is_object(ms[json_integer_value(json_array_get(members, k))]);
    with_metrics += any;
  }
  json_object_set_new(o, "groups", groups);
  json_object_set_new(o, "pareto", pareto);
  json_object_set_new(o, "ranking", ranking);
  json_object_set_new(o, "comparable", json_boolean(with_metrics <= 1));
  json_object_set_new(o, "note", with_metrics > 1
      ? json_string("errors measured against different references are not comparable: the "
                    "candidates are ranked within each reference's group; a common reference "
                    "ranks them on one scale")
      : json_null());
  /* The common reference's scale: every candidate that has a common measurement, in one group. */
  const char *cid = NULL;
  for (size_t i = 0; i < n; i++) {
    json_t *cm = json_object_get(json_array_get(list, i), "common");
    holder[i] = cm;
    ms[i] = json_object_get(cm, "metrics");
    group[i] = json_is_object(cm) ? json_string_value(json_object_get(json_object_get(cm, "reference"), "id")) : NULL;
    if (group[i]) cid = group[i], ncommon++;
    cp[i] = pts[i];
    json_t *rm = json_object_get(ms[i], "rmse"), *rn = json_object_get(ms[i], "ref_noise");
    cp[i].error = json_is_number(rm) ? json_number_value(rm) : NAN;
    cp[i].error_tolerance = json_is_number(rn) ? json_number_value(rn) : 0;
    cp[i].at_reference_accuracy = json_is_true(json_object_get(ms[i], "at_reference_accuracy"));
  }
  if (ncommon) {
    json_t *cpareto, *cranking;
    json_decref(srv_compare_rank(holder, ms, group, cp, n, &cpareto, &cranking));
    json_object_set_new(o, "common", json_pack("{s:o, s:o, s:o}", "reference",
                                               reference_ref(refs, cid), "pareto", cpareto,
                                               "ranking", cranking));
  }
  free(holder);
  free(ms);
  free(group);
  free(cp);
}

/* The comparison document of docs/comparisons.md. 0, OBS_ENOTFOUND, or a database error. */
static int comparison_json(srv_app *app, int64_t id, json_t **out, obs_err *err) {
  *out = NULL;
  srv_arg arg = {SRV_ARG_INT, id, 0, NULL};
  json_t *head = NULL, *cands = NULL, *runs = NULL, *outs = NULL;
  int rc = srv_db_query(app->db, SRV_Q_COMPARISON, &arg, 1, &head, err);
  if (!rc && json_array_size(head) == 0) rc = OBS_ENOTFOUND;
  if (!rc) rc = srv_db_query(app->db, SRV_Q_CANDIDATES, &arg, 1, &cands, err);
  if (!rc) rc = srv_db_query(app->db, SRV_Q_COMPARISON_RUNS, &arg, 1, &runs, err);
  if (!rc) rc = srv_db_query(app->db, SRV_Q_COMPARISON_OUTPUTS, &arg, 1, &outs, err);
  size_t n = json_array_size(cands);
  obs_pareto_point *pts = rc ? NULL : calloc(n + 1, sizeof *pts);
  if (!rc && !pts)
    rc = obs_err_set(err, OBS_ENOMEM, "comparison %lld: out of memory", (long long)id);
  if (!rc) {
    json_t *o = comparison_head(id, json_array_get(head, 0));
    json_t *refs = json_array(), *list = json_array();
    int has_common = 0;
    for (size_t i = 0; i < n; i++) {
      const char *role = json_string_value(json_object_get(json_array_get(cands, i), "role"));
      has_common |= role && !strcmp(role, "common");
    }
    candidates_of(app, cands, runs, outs, refs, list, pts, has_common);
    json_object_set_new(o, "references", refs);
    json_object_set_new(o, "candidates", list);
    rank_all(o, list, pts, refs);
    json_object_set_new(o, "answer", srv_compare_answer(list, json_number_value(json_object_get(
                                                                  json_array_get(head, 0),
                                                                  "budget_ms"))));
    char self[64], csv[72];
    snprintf(self, sizeof self, API "/comparisons/%lld", (long long)id);
    snprintf(csv, sizeof csv, "%s.csv", self);
    json_object_set_new(o, "links", json_pack("{s:s, s:s}", "self", self, "csv", csv));
    *out = o;
  }
  free(pts);
  json_decref(head);
  json_decref(cands);
  json_decref(runs);
  json_decref(outs);
  return rc;
}

/* ---- CSV ------------------------------------------------------------------------------------- */

typedef struct sbuf {
  char *p;
  size_t len, cap;
  int oom;
} sbuf;

static void sb_put(sbuf *b, const char *s, size_t n) {
  if (b->oom) return;
  if (b->len + n + 1 > b->cap) {
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->len + n + 1) cap *= 2;
    char *np = realloc(b->p, cap);
    if (!np) {
      b->oom = 1;
      return;
    }
    b->p = np;
    b->cap = cap;
  }
  memcpy(b->p + b->len, s, n);
  b->len += n;
  b->p[b->len] = '\0';
}

/* One field, quoted per RFC 4180 when it holds a comma, quote or line break. */
static void csv_field(sbuf *b, const char *s, int first) {
  if (!first) sb_put(b, ",", 1);
  if (!s) return;
  if (!strpbrk(s, ",\"\r\n")) {
    sb_put(b, s, strlen(s));
    return;
  }
  sb_put(b, "\"", 1);
  for (const char *c = s; *c; c++) {
    if (*c == '"') sb_put(b, "\"", 1);
    sb_put(b, c, 1);
  }
  sb_put(b, "\"", 1);
}

/* A JSON value as a CSV field: numbers exactly as the JSON answer writes them (12 significant
 * digits, srv_respond_json), so both parse to the same double; strings raw, booleans true/false,
 * null empty. */
static void csv_value(sbuf *b, const json_t *v) {
  char buf[64];
  if (json_is_integer(v)) {
    snprintf(buf, sizeof buf, "%lld", (long long)json_integer_value(v));
    csv_field(b, buf, 0);
  } else if (json_is_real(v)) {
    char *t = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(12));
    csv_field(b, t ? t : "", 0);
    free(t);
  } else if (json_is_string(v)) {
    csv_field(b, json_string_value(v), 0);
  } else if (json_is_boolean(v)) {
    csv_field(b, json_is_true(v) ? "true" : "false", 0);
  } else {
    csv_field(b, NULL, 0);
  }
}

/* One CSV row: candidate c with metrics m (its own, or one further output's) against reference
 * ref ({id, label, ...}); common: its common measurement (null on an output's row). */
static void csv_row(sbuf *b, const json_t *c, const json_t *m, const json_t *ref,
                    const json_t *common, const char *output) {
  char buf[32];
  snprintf(buf, sizeof buf, "%lld", (long long)json_integer_value(json_object_get(c, "index")));
  csv_field(b, buf, 1);
  csv_value(b, json_object_get(c, "job_id"));
  csv_value(b, json_object_get(c, "technique"));
  csv_value(b, json_object_get(c, "backend"));
  sbuf pb = {0};
  const char *key;
  json_t *v;
  int first = 1;
  json_object_foreach(json_object_get(c, "params"), key, v) {
    if (!first) sb_put(&pb, ";", 1);
    first = 0;
    sb_put(&pb, key, strlen(key));
    sb_put(&pb, "=", 1);
    char *t = json_is_string(v)
                  ? strdup(json_string_value(v))
                  : json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(12));
    if (t) sb_put(&pb, t, strlen(t));
    free(t);
  }
  csv_field(b, pb.p ? pb.p : "", 0);
  free(pb.p);
  csv_value(b, json_object_get(c, "state"));
  json_t *tm = json_object_get(c, "timings_ms"), *med = json_object_get(tm, "median");
  static const char *const order[4] = {"total", "build", "render", "post"};
  for (int k = 0; k < 4; k++) csv_value(b, json_object_get(med, order[k]));
  snprintf(buf, sizeof buf, "%zu", json_array_size(json_object_get(tm, "runs")));
  csv_field(b, buf, 0);
  const obs_metric *table = obs_metric_table();
  for (int k = 0; k < OBS_METRIC_COUNT; k++) csv_value(b, obs_metric_json_get(m, &table[k]));
  csv_value(b, json_object_get(m, "at_reference_accuracy"));
  csv_value(b, output ? NULL : json_object_get(c, "pareto"));
  json_t *mach = json_object_get(c, "machine");
  csv_value(b, json_object_get(mach, "cpu_model"));
  csv_value(b, json_object_get(mach, "cores"));
  csv_value(b, json_object_get(mach, "vulkan_device"));
  /* The compared output; empty without metrics. */
  json_t *out = json_object_get(m, "output");
  if (output)
    csv_field(b, output, 0);
  else if (json_is_object(m) && !out)
    csv_field(b, "ao", 0);
  else
    csv_value(b, out);
  /* The run-to-run spread of the total time, last so older readers' columns stay put. */
  csv_value(b, json_object_get(json_object_get(tm, "min"), "total"));
  csv_value(b, json_object_get(json_object_get(tm, "max"), "total"));
  /* What the row's figures are measured against, and the candidate's figures against the common
   * reference (empty without one). */
  csv_value(b, json_object_get(ref, "id"));
  csv_value(b, json_object_get(ref, "label"));
  json_t *cm = json_object_get(common, "metrics");
  static const char *const ck[5] = {"rmse", "bias", "psnr", "ssim", "flip"};
  for (int k = 0; k < 5; k++) csv_value(b, json_object_get(cm, ck[k]));
  csv_value(b, output ? NULL : json_object_get(common, "pareto"));
  csv_value(b, json_object_get(json_object_get(c, "device"), "label"));
  sb_put(b, "\r\n", 2);
}

/* A row per candidate, then a row per further output of it (its "output" column names which). */
static char *comparison_csv(const json_t *o, size_t *len) {
  sbuf b = {0};
  /* The metric columns are the metric table's, in its order (docs/comparisons.md); then what
   * each row is measured against and the candidate's figures against the common reference. */
  static const char head[] = "index,job_id,technique,backend,params,state,total_ms,build_ms,"
                             "render_ms,post_ms,runs,";
  static const char tail[] = "at_reference_accuracy,pareto,cpu_model,cores,vulkan_device,output,"
                             "total_ms_min,total_ms_max,reference,reference_label,common_rmse,"
                             "common_bias,common_psnr,common_ssim,common_flip,common_pareto,device\r\n";
  const obs_metric *table = obs_metric_table();
  sb_put(&b, head, sizeof head - 1);
  for (int k = 0; k < OBS_METRIC_COUNT; k++) {
    sb_put(&b, table[k].name, strlen(table[k].name));
    sb_put(&b, ",", 1);
  }
  sb_put(&b, tail, sizeof tail - 1);
  json_t *cands = json_object_get(o, "candidates");
  for (size_t i = 0; i < json_array_size(cands); i++) {
    json_t *c = json_array_get(cands, i);
    csv_row(&b, c, json_object_get(c, "metrics"), json_object_get(c, "reference"),
            json_object_get(c, "common"), NULL);
    json_t *outs = json_object_get(c, "outputs");
    for (size_t k = 0; k < json_array_size(outs); k++) {
      json_t *x = json_array_get(outs, k);
      csv_row(&b, c, json_object_get(x, "metrics"), json_object_get(x, "reference"), NULL,
              json_string_value(json_object_get(x, "output")));
    }
  }
  if (b.oom) {
    free(b.p);
    return NULL;
  }
  *len = b.len;
  return b.p;
}

int srv_compare_get(srv_req *r, int64_t id, int csv) {
  json_t *o = NULL;
  obs_err err = OBS_ERR_INIT;
  double budget_ms = NAN;
  if (srv_compare_budget_arg(r, &budget_ms, &err)) {
    int ret = srv_respond_error(r, MHD_HTTP_BAD_REQUEST, &err, "bad query parameters");
    obs_err_free(&err);
    return ret;
  }
  int rc = comparison_json(r->app, id, &o, &err);
  /* A budget asked in the query answers for it instead of the stored one (the chart's input). */
  if (!rc && !isnan(budget_ms))
    json_object_set_new(o, "answer", srv_compare_answer(json_object_get(o, "candidates"), budget_ms));
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no comparison %lld", (long long)id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  if (!csv) return srv_respond_json(r, MHD_HTTP_OK, o);
  size_t len = 0;
  char *text = comparison_csv(o, &len);
  json_decref(o);
  if (!text) return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "out of memory");
  struct MHD_Response *resp = MHD_create_response_from_buffer(len, text, MHD_RESPMEM_MUST_FREE);
  char disp[96];
  snprintf(disp, sizeof disp, "inline; filename=\"comparison-%lld.csv\"", (long long)id);
  MHD_add_response_header(resp, "Content-Type", "text/csv; charset=utf-8; header=present");
  MHD_add_response_header(resp, "Content-Disposition", disp);
  return srv_respond(r, MHD_HTTP_OK, resp);
}

/* ---- GET /api/v1/comparisons ----------------------------------------------------------------- */

typedef struct list_query {
  int64_t after;
  int limit;
  int seen[2];
  obs_err *problems;
} list_query;

static enum MHD_Result on_list_arg(void *cls, enum MHD_ValueKind kind, const char *key,
                                   const char *value) {
  (void)kind;
  list_query *q = cls;
  int k = !strcmp(key, "limit") ? 0 : !strcmp(key, "after") ? 1 : -1;
  char shown[80];
  srv_printable(value, shown, sizeof shown);
  if (k < 0) {
    char ks[40];
    srv_printable(key, ks, sizeof ks);
    obs_err_set(q->problems, OBS_EINVAL, "query: /%s: unknown parameter (known: limit, after)", ks);
    return MHD_YES;
  }
  if (q->seen[k]++) {
    obs_err_set(q->problems, OBS_EINVAL, "query: /%s: given more than once", key);
    return MHD_YES;
  }
  int64_t n;
  if (!value) value = "";
  if (srv_parse_id(value, strlen(value), &n) || (k == 0 && n > 500))
    obs_err_set(q->problems, OBS_EINVAL,
                k ? "query: /after: must be a comparison id from a previous page's \"next\" "
                    "(got \"%s\")"
                  : "query: /limit: must be an integer from 1 to 500 (got \"%s\")",
                shown);
  else if (k == 0)
    q->limit = (int)n;
  else
    q->after = n;
  return MHD_YES;
}

int srv_compare_list(srv_req *r) {
  obs_err problems = OBS_ERR_INIT;
  list_query q = {0, 50, {0, 0}, &problems};
  MHD_get_connection_values(r->conn, MHD_GET_ARGUMENT_KIND, on_list_arg, &q);
  if (problems.count) {
    int rc = srv_respond_error(r, MHD_HTTP_BAD_REQUEST, &problems, "bad query parameters");
    obs_err_free(&problems);
    return rc;
  }
  json_t *rows = NULL;
  srv_arg args[2] = {{SRV_ARG_INT, q.after, 0, NULL}, {SRV_ARG_INT, q.limit + 1, 0, NULL}};
  if (srv_db_query(r->app->db, SRV_Q_COMPARISONS, args, 2, &rows, &problems))
    return srv_respond_unavailable(r, &problems);
  json_t *list = json_array();
  size_t n = json_array_size(rows), shown = n > (size_t)q.limit ? (size_t)q.limit : n;
  for (size_t i = 0; i < shown; i++) {
    json_t *row = json_array_get(rows, i);
    json_int_t total = json_integer_value(json_object_get(row, "candidates"));
    json_int_t done = json_integer_value(json_object_get(row, "measured")) +
                      json_integer_value(json_object_get(row, "broken"));
    json_array_append_new(
        list, json_pack("{s:O, s:O, s:O, s:s, s:o, s:I, s:I}", "id", json_object_get(row, "id"),
                        "label", json_object_get(row, "label"), "scene",
                        json_object_get(row, "scene"), "state", state_of(row), "created_at",
                        srv_json_time(json_integer_value(json_object_get(row, "created_ms"))),
                        "candidates", total, "done", done));
    /* Each comparison's answer, so the list says it without opening one. */
    json_t *full = NULL;
    obs_err aerr = OBS_ERR_INIT;
    if (!comparison_json(r->app, json_integer_value(json_object_get(row, "id")), &full, &aerr))
      json_object_set(json_array_get(list, json_array_size(list) - 1), "answer",
                      json_object_get(full, "answer"));
    json_decref(full);
    obs_err_free(&aerr);
  }
  json_t *next = json_null();
  if (n > shown && shown) {
    char buf[24];
    snprintf(buf, sizeof buf, "%lld",
             (long long)json_integer_value(json_object_get(json_array_get(rows, shown - 1), "id")));
    json_decref(next);
    next = json_string(buf);
  }
  json_decref(rows);
  return srv_respond_json(r, MHD_HTTP_OK,
                          json_pack("{s:o, s:o}", "comparisons", list, "next", next));
}
