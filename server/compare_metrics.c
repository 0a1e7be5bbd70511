/* The comparisons' metrics step, run when a candidate and its reference have both succeeded,
 * and the time-budget choice of POST /api/v1/jobs from the stored metrics. */
#include <jansson.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare_internal.h"
#include "obscurad.h"

/* ---- the metrics step ------------------------------------------------------------------------ */

/* One at a time: the candidate's and the reference's workers may both find the pair ready, and
 * the error images of one candidate must be written once. */
static pthread_mutex_t metrics_mu = PTHREAD_MUTEX_INITIALIZER;

/* Computes and stores one candidate's metrics and error images. Returns 0, or <0 with the reason
 * in `why` when the inputs cannot give metrics (stored as metrics_error). Database trouble is only
 * logged: the next start retries. */
static void metrics_one(srv_app *app, const json_t *row) {
  json_int_t cmp = json_integer_value(json_object_get(row, "comparison"));
  int idx = (int)json_integer_value(json_object_get(row, "idx"));
  json_int_t job = json_integer_value(json_object_get(row, "job"));
  json_int_t rjob = json_integer_value(json_object_get(row, "reference_job"));
  obs_response resp = OBS_RESPONSE_IDENTITY;
  obs_err e = OBS_ERR_INIT;
  obs_image eimg, flip;
  memset(&eimg, 0, sizeof eimg);
  memset(&flip, 0, sizeof flip);
  char dir[4200], rdir[4200];
  srv_results_path(app, job, dir, sizeof dir);
  srv_results_path(app, rjob, rdir, sizeof rdir);
  srv_output outs[16], err_outs[6];
  int nouts = 0, nerr = 0;
  obs_metric_values m;
  int rc = obs_response_parse(json_string_value(json_object_get(row, "response")), &resp)
               ? obs_err_set(&e, OBS_EINVAL, "unknown response mapping")
               : 0;
  json_t *extra = json_object();
  /* A further measurement (common reference, another output) has figures only: the error images,
   * FLIP map and mapped reference are the candidate's own row's. */
  const char *role = json_string_value(json_object_get(row, "role"));
  int own = !role || !strcmp(role, "own");
  /* An output a technique pairs with its reference's (bent normals): every metric that applies. */
  const char *output = json_string_value(json_object_get(row, "output"));
  json_t *pair = output ? json_object() : NULL;
  if (!rc && output) rc = srv_compare_output(dir, rdir, output, pair, &e);
  else if (!rc) rc = srv_compare_primary(dir, rdir, resp, &m, extra, &eimg, &flip, &e);
  /* Written into the candidate's published directory under staging names and renamed, so a crash
   * leaves either no error image or a whole one (recorded below, or again after a restart). */
  if (!rc && own) rc = obs_metrics_write_error_files(&eimg, dir, &e);
  if (!rc && own && flip.data) rc = obs_metrics_write_flip_files(&flip, dir, &e);
  if (!rc && own) rc = srv_outputs_describe(dir, outs, 16, &nouts, &e);
  for (int i = 0; !rc && i < nouts; i++)
    if ((!strncmp(outs[i].name, "error.", 6) || !strncmp(outs[i].name, "flip.", 5) ||
         !strcmp(outs[i].name, SRV_MAPPED_REFERENCE_PNG) ||
         !strcmp(outs[i].name, SRV_MAPPED_REFERENCE_EXR)) &&
        nerr < (int)(sizeof err_outs / sizeof *err_outs))
      err_outs[nerr++] = outs[i];
  char *metrics = NULL;
  if (!rc && pair) {
    metrics = json_dumps(pair, JSON_COMPACT | JSON_REAL_PRECISION(17));
  } else if (!rc) {
    /* Every metric of the table that applied, at its place (the table's json_group/json_key). */
    json_t *mj = json_object();
    obs_metric_values_json(&m, mj);
    json_object_update(mj, extra);
    metrics = json_dumps(mj, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(mj);
  }
  obs_err dberr = OBS_ERR_INIT;
  /* I/O trouble and memory shortage may pass (a full disk is freed): leave the candidate pending,
   * so the next trigger or the next start retries, instead of failing the comparison for good. */
  if (rc == OBS_EIO || rc == OBS_ENOMEM)
    srv_log("comparison %lld candidate %d: metrics postponed: %s", (long long)cmp, idx,
            obs_err_message(&e));
  else if (srv_db_set_metrics(app->db, cmp, idx, job, metrics, rc ? obs_err_message(&e) : NULL,
                              err_outs, nerr, &dberr))
    srv_log("comparison %lld candidate %d: cannot store metrics: %s", (long long)cmp, idx,
            obs_err_message(&dberr));
  else if (rc)
    srv_log("comparison %lld candidate %d: no metrics: %s", (long long)cmp, idx,
            obs_err_message(&e));
  else if (pair)
    srv_log("comparison %lld candidate %d: output %s measured (job %lld vs reference %lld)",
            (long long)cmp, idx, output, (long long)job, (long long)rjob);
  else
    srv_log("comparison %lld candidate %d: rmse %.4g, ssim %.4g, flip %.4g (job %lld vs "
            "reference %lld)",
            (long long)cmp, idx, m.v[OBS_METRIC_RMSE], m.v[OBS_METRIC_SSIM], m.v[OBS_METRIC_FLIP],
            (long long)job, (long long)rjob);
  free(metrics);
  json_decref(pair);
  json_decref(extra);
  obs_err_free(&dberr);
  obs_err_free(&e);
  obs_image_free(&eimg);
  obs_image_free(&flip);
}

void srv_compare_metrics(srv_app *app, int64_t job) {
  pthread_mutex_lock(&metrics_mu);
  json_t *rows = NULL;
  obs_err err = OBS_ERR_INIT;
  srv_arg arg = {SRV_ARG_INT, job, 0, NULL};
  if (srv_db_query(app->db, SRV_Q_METRICS_PENDING, &arg, 1, &rows, &err))
    srv_log("comparison metrics: %s", obs_err_message(&err));
  for (size_t i = 0; i < json_array_size(rows); i++) metrics_one(app, json_array_get(rows, i));
  json_decref(rows);
  obs_err_free(&err);
  pthread_mutex_unlock(&metrics_mu);
}

/* One stored candidate that can inform a time budget: a known technique, a backend this daemon
 * runs, and a finite RMSE of AO. RMSEs of other outputs (the luminance of path_trace's radiance)
 * measure another quantity on another scale, so they are not ranked against AO ones. */
typedef struct budget_row {
  size_t row;          /* index into the stored rows */
  obs_pareto_point pt; /* median time, spread, RMSE, the reference's noise */
} budget_row;

static int budget_metrics(const srv_app *app, const json_t *row, obs_pareto_point *pt) {
  obs_backend be = OBS_BACKEND_AUTO;
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(row, "technique")));
  if (!t || obs_backend_parse(json_string_value(json_object_get(row, "backend")), &be) ||
      (be == OBS_BACKEND_VULKAN && !app->vulkan_lane))
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
static void budget_times(srv_app *app, const json_t *row, obs_pareto_point *pt) {
  json_t *runs = NULL;
  obs_err err = OBS_ERR_INIT;
  srv_arg arg = {SRV_ARG_INT, json_integer_value(json_object_get(row, "job")), 0, NULL};
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
      budget_times(app, row, &out[k].pt);
      if (isnan(out[k].pt.time_ms)) continue;
      out[k++].row = i;
    }
    *same_scene = pass;
  }
  return k;
}

/* The configuration to run among those that fit: of the Pareto set with margins (faster only
 * beyond the run-to-run spreads, more accurate only beyond the reference's noise), the lowest
 * RMSE; among those as accurate as it within that noise, the fastest median. -1: none fits. */
static int budget_pick(const budget_row *c, size_t n, double budget_ms, unsigned char *opt) {
  obs_pareto_point *pts = malloc((n ? n : 1) * sizeof *pts);
  if (!pts) return -1;
  for (size_t i = 0; i < n; i++) {
    pts[i] = c[i].pt;
    if (c[i].pt.time_ms > budget_ms) pts[i].time_ms = NAN; /* does not fit: takes no part */
  }
  int best = -1;
  if (obs_metrics_pareto(pts, n, opt, NULL) > 0) {
    double lowest = INFINITY, tol = 0;
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
  free(pts);
  return best;
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
  unsigned char *opt = calloc(n ? n : 1, 1);
  int same_scene = 0, best = -1;
  size_t measured = c && opt ? budget_rows(app, rows, scene, pixels, c, &same_scene) : 0;
  double fastest_ms = INFINITY;
  for (size_t i = 0; i < measured; i++) fastest_ms = fmin(fastest_ms, c[i].pt.time_ms);
  if (measured) best = budget_pick(c, measured, budget_ms, opt);
  int rc = 0;
  if (!c || !opt) {
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
    char reason[700];
    snprintf(reason, sizeof reason,
             "%s among %zu measured configuration(s) %s that fit %g ms (RMSEs within the "
             "reference's noise count as equal, times within their run-to-run spread too): %s on "
             "%s takes %.4g ms (median) with RMSE %.4g (comparison %lld, candidate %lld)",
             b->at_reference_accuracy ? "the fastest at reference accuracy"
                                      : "the fastest of the lowest RMSE",
             measured, same_scene ? "of this scene" : "of scenes of a similar size", budget_ms,
             json_string_value(json_object_get(row, "technique")),
             json_string_value(json_object_get(row, "backend")), b->time_ms, b->error,
             (long long)json_integer_value(json_object_get(row, "comparison")),
             (long long)json_integer_value(json_object_get(row, "idx")));
    *choice = json_pack("{s:O, s:O, s:o, s:f, s:f, s:O, s:s}", "technique",
                        json_object_get(row, "technique"), "backend",
                        json_object_get(row, "backend"), "params", params ? params : json_object(),
                        "expected_ms", b->time_ms, "expected_rmse", b->error, "comparison_id",
                        json_object_get(row, "comparison"), "reason", reason);
    if (!*choice) rc = obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  }
  free(c);
  free(opt);
  json_decref(rows);
  return rc;
}
