/* The budget question, answered from measured comparisons: the time-budget choice of POST
 * /api/v1/jobs (technique "auto" with time_budget_ms, from every stored candidate), and each
 * comparison's answer (per reference: the best candidate, and the best within a budget). Both
 * rank with the margins of the Pareto set (obs_metrics_pareto), by one rule (budget_pick). */
#include <jansson.h>
#include <math.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare_internal.h"
#include "obscurad.h"

/* One stored candidate that can inform a time budget: a known technique, a backend this daemon
 * runs (on Vulkan, on a device of this lane's kind: a software rasteriser's time never predicts a
 * GPU's), and a finite RMSE of AO. RMSEs of other outputs (the luminance of path_trace's
 * radiance) measure another quantity on another scale, so they are not ranked against AO ones. */
typedef struct budget_row {
  size_t row;          /* index into the stored rows */
  obs_pareto_point pt; /* median time, spread, RMSE, the reference's noise */
  char *scale;         /* what the RMSE is measured against (scale_key; owned) */
} budget_row;

/* The scale a stored RMSE is on: its reference's technique, definition (srv_compare_definition:
 * the keys that define the reference, not its quality or seed) and response. Two RMSEs are
 * comparable only on one scale (an ssao RMSE against its mapped sqrt-falloff reference says
 * nothing against an rt_ao one against binary AO). */
static json_t *scale_definition(const json_t *row) {
  const char *rt = json_string_value(json_object_get(row, "reference_technique"));
  json_t *params = json_loads(json_string_value(json_object_get(row, "reference_params")), 0, NULL);
  json_t *def = srv_compare_definition(rt ? rt : "rt_ao", params);
  json_decref(params);
  return def ? def : json_object();
}

/* scale_definition as text, with the technique and response; NULL when out of memory. */
static char *scale_key(const json_t *row) {
  const char *rt = json_string_value(json_object_get(row, "reference_technique"));
  json_t *def = scale_definition(row);
  char *d = json_dumps(def, JSON_SORT_KEYS | JSON_COMPACT);
  json_decref(def);
  const char *resp = json_string_value(json_object_get(row, "response"));
  size_t n = (d ? strlen(d) : 0) + (rt ? strlen(rt) : 0) + (resp ? strlen(resp) : 0) + 3;
  char *key = malloc(n);
  if (key) snprintf(key, n, "%s|%s|%s", rt ? rt : "", d ? d : "", resp ? resp : "");
  free(d);
  return key;
}

/* Keeps the rows of one scale in c[0..n), in their order (ties in budget_pick go to the
 * earlier): the scale on which the most techniques were measured (the question is which
 * technique to run), then the most configurations, then the newest comparison's (rows come newest
 * first). The other rows follow. One pass over the rows per distinct scale seen, techniques as
 * bits of their registry index. Returns how many rows stay; *dropped gets the others. */
static size_t one_scale(budget_row *c, size_t n, size_t *dropped, const json_t *rows) {
  typedef struct {
    const char *scale;
    uint64_t techs;
    size_t nrows;
  } group;
  group *g = calloc(n ? n : 1, sizeof *g);
  budget_row *sorted = malloc((n ? n : 1) * sizeof *sorted);
  size_t ng = 0, best = 0, k = 0;
  if (!g || !sorted) n = 0; /* out of memory: nothing is ranked */
  for (size_t i = 0; i < n; i++) {
    size_t j = 0;
    while (j < ng && strcmp(g[j].scale, c[i].scale)) j++;
    if (j == ng) g[ng++].scale = c[i].scale;
    const obs_technique *t = obs_technique_find(
        json_string_value(json_object_get(json_array_get(rows, c[i].row), "technique")));
    for (size_t x = 0; x < obs_technique_count() && x < 64; x++)
      if (obs_technique_at(x) == t) g[j].techs |= (uint64_t)1 << x;
    g[j].nrows++;
  }
  for (size_t j = 1; j < ng; j++) {
    int tj = __builtin_popcountll(g[j].techs), tb = __builtin_popcountll(g[best].techs);
    if (tj > tb || (tj == tb && g[j].nrows > g[best].nrows)) best = j;
  }
  for (int keep = 1; keep >= 0; keep--)
    for (size_t i = 0; i < n; i++)
      if ((strcmp(c[i].scale, g[best].scale) == 0) == keep) sorted[k++] = c[i];
  if (n) memcpy(c, sorted, n * sizeof *c);
  *dropped = n ? n - g[best].nrows : 0;
  size_t kept = n ? g[best].nrows : 0;
  free(g);
  free(sorted);
  return kept;
}

static int budget_metrics(const srv_app *app, const json_t *row, obs_pareto_point *pt) {
  obs_backend be = OBS_BACKEND_AUTO;
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(row, "technique")));
  const char *kind = json_string_value(json_object_get(row, "vulkan_kind"));
  if (!t || obs_backend_parse(json_string_value(json_object_get(row, "backend")), &be) ||
      (be == OBS_BACKEND_VULKAN &&
       (!app->vulkan_lane || !kind || !app->vulkan_kind || strcmp(kind, app->vulkan_kind))))
    return 0;
  json_t *m = json_loads(json_string_value(json_object_get(row, "metrics")), 0, NULL);
  json_t *rm = json_object_get(m, "rmse"), *rn = json_object_get(m, "ref_noise");
  pt->error = json_is_number(rm) ? json_number_value(rm) : NAN;
  pt->error_tolerance = json_is_number(rn) ? json_number_value(rn) : 0;
  pt->at_reference_accuracy = json_is_true(json_object_get(m, "at_reference_accuracy"));
  int ao = !json_object_get(m, "output");
  json_decref(m);
  return ao && !isnan(pt->error);
}

/* The median, fastest and slowest timed run of a candidate's job (NaN median: none). */
static void budget_times(srv_app *app, json_int_t job, obs_pareto_point *pt) {
  json_t *runs = NULL;
  obs_err err = OBS_ERR_INIT;
  srv_arg arg = {SRV_ARG_INT, job, 0, NULL};
  double v[SRV_MAX_REPEATS];
  size_t nv = 0;
  if (!srv_db_query(app->db, SRV_Q_JOB_RUNS, &arg, 1, &runs, &err))
    for (size_t k = 0; k < json_array_size(runs) && nv < SRV_MAX_REPEATS; k++)
      v[nv++] = json_number_value(json_object_get(json_array_get(runs, k), "total_ms"));
  obs_err_free(&err);
  json_decref(runs);
  pt->time_ms = srv_median(v, nv);
  pt->time_min_ms = pt->time_max_ms = 0;
  for (size_t k = 0; k < nv; k++) {
    if (!k || v[k] < pt->time_min_ms) pt->time_min_ms = v[k];
    if (!k || v[k] > pt->time_max_ms) pt->time_max_ms = v[k];
  }
}

/* The stored candidates measured on `scene` at a similar size (within 2x the pixel samples), or,
 * when there are none, on any scene at a similar size. Returns how many went to `out` (n slots). */
static size_t budget_rows(srv_app *app, const json_t *rows, const char *scene, double pixels,
                          budget_row *out, int *same_scene) {
  size_t n = json_array_size(rows), k = 0;
  for (int pass = 1; pass >= 0 && !k; pass--) {
    for (size_t i = 0; i < n; i++) {
      const json_t *row = json_array_get(rows, i);
      double px = json_number_value(json_object_get(row, "pixels"));
      const char *sc = json_string_value(json_object_get(row, "scene"));
      if (!(px >= pixels / 2 && px <= pixels * 2)) continue;
      if (pass && (!sc || strcmp(sc, scene))) continue;
      if (!budget_metrics(app, row, &out[k].pt)) continue;
      budget_times(app, json_integer_value(json_object_get(row, "job")), &out[k].pt);
      if (isnan(out[k].pt.time_ms)) continue;
      out[k].scale = scale_key(row);
      if (!out[k].scale) continue;
      out[k++].row = i;
    }
    *same_scene = pass;
  }
  return k;
}

/* Why a candidate that fits the budget was not picked, or NULL for the pick. */
typedef enum { WHY_PICKED, WHY_OVER, WHY_BEATEN, WHY_LESS_ACCURATE, WHY_SLOWER, WHY_UNMEASURED } why_not;

static const char *const why_text[] = {
    "picked", "over the budget", "beaten: another that fits is faster and as accurate",
    "less accurate than the pick", "as accurate as the pick but slower", "no time or no RMSE"};

/* The configuration to run among those that fit: of the Pareto set with margins (faster only
 * beyond the run-to-run spreads, more accurate only beyond the reference's noise), the lowest
 * RMSE; among those as accurate as it within that noise, the fastest median. -1: none fits.
 * `why` (n slots, or NULL) gets each point's verdict. */
static int budget_pick(const obs_pareto_point *in, size_t n, double budget_ms, why_not *why) {
  obs_pareto_point *pts = calloc(n ? n : 1, sizeof *pts);
  unsigned char *opt = calloc(n ? n : 1, 1);
  if (!pts || !opt) {
    free(pts);
    free(opt);
    return -1;
  }
  for (size_t i = 0; i < n; i++) {
    pts[i] = in[i];
    if (in[i].time_ms > budget_ms) pts[i].time_ms = NAN; /* does not fit: takes no part */
  }
  int best = -1;
  double lowest = INFINITY, tol = 0;
  if (obs_metrics_pareto(pts, n, opt, NULL) > 0) {
    for (size_t i = 0; i < n; i++)
      if (opt[i]) {
        double e = pts[i].at_reference_accuracy ? -INFINITY : pts[i].error;
        if (e < lowest)
          lowest = e, tol = isnan(pts[i].error_tolerance) ? 0 : pts[i].error_tolerance;
      }
    for (size_t i = 0; i < n; i++) {
      double e = pts[i].at_reference_accuracy ? -INFINITY : pts[i].error;
      if (opt[i] && e <= lowest + tol && (best < 0 || pts[i].time_ms < pts[best].time_ms))
        best = (int)i;
    }
  }
  for (size_t i = 0; why && i < n; i++) {
    double e = pts[i].at_reference_accuracy ? -INFINITY : pts[i].error;
    why[i] = (int)i == best                             ? WHY_PICKED
             : isnan(in[i].time_ms) || isnan(in[i].error) ? WHY_UNMEASURED
             : in[i].time_ms > budget_ms                ? WHY_OVER
             : !opt[i]                                  ? WHY_BEATEN
             : e > lowest + tol                         ? WHY_LESS_ACCURATE
                                                        : WHY_SLOWER;
  }
  free(pts);
  free(opt);
  return best;
}

/* ---- time budgets ---------------------------------------------------------------------------- */

/* At most this many alternatives are stored with a choice: the closest in RMSE to the pick. */
#define MAX_ALTERNATIVES 12

static const budget_row *sort_rows; /* budget_pick's input, for by_error (one sort at a time) */

static int by_error(const void *a, const void *b) {
  double x = sort_rows[*(const size_t *)a].pt.error, y = sort_rows[*(const size_t *)b].pt.error;
  return (x > y) - (x < y);
}

/* The configurations considered beside the pick `best`, each with its expected time and RMSE and
 * why it lost, in ascending RMSE. */
static json_t *alternatives(const json_t *rows, const budget_row *c, size_t n, int best,
                            double budget_ms) {
  json_t *list = json_array();
  why_not *why = calloc(n ? n : 1, sizeof *why);
  size_t *order = calloc(n ? n : 1, sizeof *order);
  obs_pareto_point *pts = calloc(n ? n : 1, sizeof *pts);
  if (!why || !order || !pts) n = 0;
  for (size_t i = 0; i < n; i++) pts[i] = c[i].pt, order[i] = i;
  if (n) budget_pick(pts, n, budget_ms, why);
  static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
  pthread_mutex_lock(&mu);
  sort_rows = c;
  qsort(order, n, sizeof *order, by_error);
  pthread_mutex_unlock(&mu);
  for (size_t k = 0; k < n && json_array_size(list) < MAX_ALTERNATIVES; k++) {
    size_t i = order[k];
    if ((int)i == best) continue;
    json_t *row = json_array_get(rows, c[i].row);
    json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
    json_array_append_new(
        list, json_pack("{s:O, s:O, s:o, s:o, s:o, s:b, s:b, s:s, s:O, s:O}", "technique",
                        json_object_get(row, "technique"), "backend",
                        json_object_get(row, "backend"), "params",
                        params ? params : json_object(), "expected_ms",
                        num_or_null(c[i].pt.time_ms), "expected_rmse", num_or_null(c[i].pt.error),
                        "fits", c[i].pt.time_ms <= budget_ms, "at_reference_accuracy",
                        c[i].pt.at_reference_accuracy, "why_not", why_text[why[i]],
                        "comparison_id", json_object_get(row, "comparison"), "candidate",
                        json_object_get(row, "idx")));
  }
  free(why);
  free(order);
  free(pts);
  return list;
}

/* ---- time budgets ---------------------------------------------------------------------------- */

int srv_compare_budget_choice(srv_app *app, const char *scene, double pixels, double budget_ms,
                              json_t **choice, obs_err *problems) {
  *choice = NULL;
  json_t *rows = NULL;
  obs_err err = OBS_ERR_INIT;
  if (srv_db_query(app->db, SRV_Q_BUDGET, NULL, 0, &rows, &err)) {
    int rc = obs_err_set(problems, OBS_EINVAL,
                         "request: /time_budget_ms: cannot read the stored "
                         "measurements: %s",
                         obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  size_t n = json_array_size(rows);
  budget_row *c = malloc((n ? n : 1) * sizeof *c);
  obs_pareto_point *pts = malloc((n ? n : 1) * sizeof *pts);
  int same_scene = 0, best = -1;
  size_t found = c && pts ? budget_rows(app, rows, scene, pixels, c, &same_scene) : 0;
  size_t other_scales = 0;
  size_t measured = one_scale(c, found, &other_scales, rows);
  char *scale_label = NULL;
  if (measured) {
    const json_t *r0 = json_array_get(rows, c[0].row);
    json_t *def = scale_definition(r0);
    scale_label = srv_compare_label(json_string_value(json_object_get(r0, "reference_technique")),
                                    def, json_string_value(json_object_get(r0, "response")));
    json_decref(def);
  }
  double fastest_ms = INFINITY;
  for (size_t i = 0; i < measured; i++) fastest_ms = fmin(fastest_ms, c[i].pt.time_ms);
  for (size_t i = 0; i < measured; i++) pts[i] = c[i].pt;
  if (measured) best = budget_pick(pts, measured, budget_ms, NULL);
  int rc = 0;
  if (!c || !pts) {
    rc = obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  } else if (!measured) {
    rc = obs_err_set(problems, OBS_EINVAL,
                     "request: /time_budget_ms: nothing has been measured "
                     "yet for %s or any scene of a similar size (%.0f pixel samples, within 2x): "
                     "run a comparison first (POST /api/v1/comparisons)",
                     scene, pixels);
  } else if (best < 0) {
    rc = obs_err_set(problems, OBS_EINVAL,
                     "request: /time_budget_ms: none of the %zu measured "
                     "configurations%s fits %g ms: the fastest takes %.4g ms (median)",
                     measured, same_scene ? " of this scene" : " of similar scenes", budget_ms,
                     fastest_ms);
  } else {
    const obs_pareto_point *b = &c[best].pt;
    json_t *row = json_array_get(rows, c[best].row);
    json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
    char reason[1400];
    snprintf(reason, sizeof reason,
             "%s among %zu measured configuration(s) %s that fit %g ms (RMSEs within the "
             "reference's noise count as equal, times within their run-to-run spread too), all "
             "measured against %s (%zu measured against other references not ranked with them): "
             "%s on %s takes %.4g ms (median) with RMSE %.4g (comparison %lld, candidate %lld)",
             b->at_reference_accuracy ? "the fastest at reference accuracy"
                                      : "the fastest of the lowest RMSE",
             measured, same_scene ? "of this scene" : "of scenes of a similar size", budget_ms,
             scale_label ? scale_label : "one reference", other_scales,
             json_string_value(json_object_get(row, "technique")),
             json_string_value(json_object_get(row, "backend")), b->time_ms, b->error,
             (long long)json_integer_value(json_object_get(row, "comparison")),
             (long long)json_integer_value(json_object_get(row, "idx")));
    /* Where the expectation comes from, kept with the job: the budget, the device kind whose
     * timings were read, and what else was considered. */
    *choice = json_pack("{s:O, s:O, s:o, s:f, s:f, s:O, s:O, s:s, s:f, s:b, s:I, s:o, s:s, s:o}",
                        "technique", json_object_get(row, "technique"), "backend",
                        json_object_get(row, "backend"), "params", params ? params : json_object(),
                        "expected_ms", b->time_ms, "expected_rmse", b->error, "comparison_id",
                        json_object_get(row, "comparison"), "candidate", json_object_get(row, "idx"),
                        "reason", reason, "budget_ms", budget_ms, "same_scene", same_scene,
                        "considered", (json_int_t)measured, "alternatives",
                        alternatives(rows, c, measured, best, budget_ms), "from",
                        "stored comparison candidates with AO metrics (docs/comparisons.md)",
                        "vulkan_kind",
                        app->vulkan_kind ? json_string(app->vulkan_kind) : json_null());
    if (*choice) {
      json_object_set_new(*choice, "reference_label",
                          scale_label ? json_string(scale_label) : json_null());
      json_object_set_new(*choice, "other_references", json_integer((json_int_t)other_scales));
    }
    if (!*choice) rc = obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  }
  for (size_t i = 0; c && i < found; i++) free(c[i].scale);
  free(scale_label);
  free(c);
  free(pts);
  json_decref(rows);
  return rc;
}

/* ---- a comparison's answer ------------------------------------------------------------------- */

/* A candidate object's place on the time/error plane (NaN where it has no time or RMSE). */
static obs_pareto_point answer_point(const json_t *c) {
  const json_t *tm = json_object_get(c, "timings_ms"), *m = json_object_get(c, "metrics");
  const json_t *total = json_object_get(json_object_get(tm, "median"), "total");
  const json_t *rmse = json_object_get(m, "rmse"), *noise = json_object_get(m, "ref_noise");
  obs_pareto_point p = {
      .time_ms = json_is_number(total) && json_is_number(rmse) ? json_number_value(total) : NAN,
      .time_min_ms = json_number_value(json_object_get(json_object_get(tm, "min"), "total")),
      .time_max_ms = json_number_value(json_object_get(json_object_get(tm, "max"), "total")),
      .error = json_is_number(rmse) ? json_number_value(rmse) : NAN,
      .error_tolerance = json_is_number(noise) ? json_number_value(noise) : 0,
      .at_reference_accuracy = json_is_true(json_object_get(m, "at_reference_accuracy"))};
  return p;
}

static json_t *answer_pick(const json_t *c, const obs_pareto_point *p) {
  return json_pack("{s:O, s:O, s:O, s:O, s:o, s:o, s:b}", "index", json_object_get(c, "index"),
                   "technique", json_object_get(c, "technique"), "backend",
                   json_object_get(c, "backend"), "params", json_object_get(c, "params"),
                   "time_ms", num_or_null(p->time_ms), "rmse", num_or_null(p->error),
                   "at_reference_accuracy", p->at_reference_accuracy);
}

/* Whether candidates a and b were measured against the same reference: the same reference id
 * (job and response) where the objects carry one, else the same reference job. */
static int same_reference(const json_t *a, const json_t *b) {
  const char *x = json_string_value(json_object_get(json_object_get(a, "reference"), "id"));
  const char *y = json_string_value(json_object_get(json_object_get(b, "reference"), "id"));
  if (x && y) return !strcmp(x, y);
  return json_integer_value(json_object_get(a, "reference_job_id")) ==
         json_integer_value(json_object_get(b, "reference_job_id"));
}

json_t *srv_compare_answer(const json_t *cands, double budget_ms) {
  size_t n = json_array_size(cands);
  int has_budget = isfinite(budget_ms) && budget_ms > 0;
  json_t *groups = json_array();
  obs_pareto_point *pts = calloc(n ? n : 1, sizeof *pts);
  size_t *idx = calloc(n ? n : 1, sizeof *idx);
  unsigned char *done = calloc(n ? n : 1, 1);
  for (size_t i = 0; pts && idx && done && i < n; i++) {
    if (done[i]) continue;
    /* One reference, one scale: only candidates measured against it (its job seen through one
     * response, the comparison's reference id) are ranked together. */
    const json_t *first = json_array_get(cands, i);
    const json_t *ref = json_object_get(first, "reference");
    json_int_t rjob = json_integer_value(json_object_get(first, "reference_job_id"));
    size_t k = 0, measured = 0;
    for (size_t j = i; j < n; j++) {
      const json_t *c = json_array_get(cands, j);
      if (done[j] || !same_reference(first, c)) continue;
      done[j] = 1;
      idx[k] = j;
      pts[k] = answer_point(c);
      measured += !isnan(pts[k].time_ms);
      k++;
    }
    int best = budget_pick(pts, k, INFINITY, NULL);
    json_t *rid = json_object_get(ref, "id"), *rlabel = json_object_get(ref, "label");
    json_t *g = json_pack("{s:O, s:O, s:I, s:I, s:I}", "reference", rid ? rid : json_null(),
                          "label", rlabel ? rlabel : json_null(), "reference_job_id", rjob,
                          "candidates", (json_int_t)k, "measured", (json_int_t)measured);
    json_object_set_new(g, "best",
                        best < 0 ? json_null()
                                 : answer_pick(json_array_get(cands, idx[best]), &pts[best]));
    if (has_budget) {
      int under = budget_pick(pts, k, budget_ms, NULL);
      json_object_set_new(g, "best_under_budget",
                          under < 0 ? json_null()
                                    : answer_pick(json_array_get(cands, idx[under]), &pts[under]));
    }
    json_array_append_new(groups, g);
  }
  free(pts);
  free(idx);
  free(done);
  return json_pack("{s:o, s:o}", "budget_ms", has_budget ? json_real(budget_ms) : json_null(),
                   "groups", groups);
}

json_t *srv_job_choice_json(srv_app *app, int64_t job) {
  json_t *rows = NULL, *choice = NULL;
  obs_err err = OBS_ERR_INIT;
  srv_arg arg = {SRV_ARG_INT, job, 0, NULL};
  if (!srv_db_query(app->db, SRV_Q_JOB_CHOICE, &arg, 1, &rows, &err)) {
    const char *text = json_string_value(json_object_get(json_array_get(rows, 0), "choice"));
    choice = text ? json_loads(text, 0, NULL) : NULL;
  }
  obs_err_free(&err);
  json_decref(rows);
  if (!choice) return json_null();
  obs_pareto_point p;
  budget_times(app, job, &p);
  json_object_set_new(choice, "actual_ms", num_or_null(p.time_ms));
  return choice;
}

int srv_compare_budget_arg(srv_req *r, double *budget_ms, obs_err *err) {
  const char *v = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "budget_ms");
  *budget_ms = NAN;
  if (!v) return 0;
  char *end = NULL, shown[80];
  double d = strtod(v, &end);
  if (*v && end && !*end && d > 0 && d <= 1e9) {
    *budget_ms = d;
    return 0;
  }
  srv_printable(v, shown, sizeof shown);
  return obs_err_set(err, OBS_EINVAL,
                     "query: /budget_ms: must be a time in milliseconds above 0 and at most 1e9 "
                     "(got \"%s\")",
                     shown);
}
