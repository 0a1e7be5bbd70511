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
  obs_image eimg;
  memset(&eimg, 0, sizeof eimg);
  char dir[4200], rdir[4200];
  srv_results_path(app, job, dir, sizeof dir);
  srv_results_path(app, rjob, rdir, sizeof rdir);
  srv_output outs[16], err_outs[3];
  int nouts = 0, nerr = 0;
  obs_compare m;
  int rc = obs_response_parse(json_string_value(json_object_get(row, "response")), &resp)
               ? obs_err_set(&e, OBS_EINVAL, "unknown response mapping")
               : 0;
  json_t *extra = json_object();
  if (!rc) rc = srv_compare_primary(dir, rdir, resp, &m, extra, &eimg, &e);
  /* Written into the candidate's published directory under staging names and renamed, so a crash
   * leaves either no error image or a whole one (recorded below, or again after a restart). */
  if (!rc) rc = obs_metrics_write_error_files(&eimg, dir, &e);
  if (!rc) rc = srv_outputs_describe(dir, outs, 16, &nouts, &e);
  for (int i = 0; !rc && i < nouts; i++)
    if ((!strncmp(outs[i].name, "error.", 6) || !strcmp(outs[i].name, SRV_MAPPED_REFERENCE_PNG)) &&
        nerr < (int)(sizeof err_outs / sizeof *err_outs))
      err_outs[nerr++] = outs[i];
  char *metrics = NULL;
  if (!rc) {
    json_t *mj = json_object();
    json_object_set_new(mj, "rmse", num_or_null(m.rmse));
    json_object_set_new(mj, "bias", num_or_null(m.bias));
    json_object_set_new(mj, "max_abs", num_or_null(m.max_abs));
    json_object_set_new(mj, "psnr", num_or_null(m.psnr));
    json_object_set_new(mj, "ssim", num_or_null(m.ssim));
    json_object_set_new(mj, "ref_noise", num_or_null(m.ref_noise));
    json_object_set_new(mj, "at_reference_accuracy", json_boolean(m.at_reference_accuracy));
    json_object_set_new(mj, "pixels", json_integer(m.pixels));
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
  else
    srv_log("comparison %lld candidate %d: rmse %.4g, ssim %.4g (job %lld vs reference %lld)",
            (long long)cmp, idx, m.rmse, m.ssim, (long long)job, (long long)rjob);
  free(metrics);
  json_decref(extra);
  obs_err_free(&dberr);
  obs_err_free(&e);
  obs_image_free(&eimg);
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

/* Whether a stored candidate can inform a time budget here: a known technique, a backend this
 * daemon runs, and a finite RMSE (filled in) of AO. RMSEs of other outputs (the luminance of
 * path_trace's radiance) measure another quantity on another scale, so they are not ranked
 * against AO ones. */
static int budget_row(const srv_app *app, const json_t *row, double *rmse, int *at_ref) {
  obs_backend be = OBS_BACKEND_AUTO;
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(row, "technique")));
  if (!t || obs_backend_parse(json_string_value(json_object_get(row, "backend")), &be) ||
      (be == OBS_BACKEND_VULKAN && !app->vulkan_lane))
    return 0;
  json_t *m = json_loads(json_string_value(json_object_get(row, "metrics")), 0, NULL);
  json_t *rm = json_object_get(m, "rmse");
  *rmse = json_is_number(rm) ? json_number_value(rm) : NAN;
  *at_ref = json_is_true(json_object_get(m, "at_reference_accuracy"));
  int ao = !json_object_get(m, "output");
  json_decref(m);
  return ao && !isnan(*rmse);
}

/* ---- time budgets ---------------------------------------------------------------------------- */

int srv_compare_budget_choice(srv_app *app, const char *scene, double pixels, double budget_ms,
                              json_t **choice, obs_err *problems) {
  *choice = NULL;
  json_t *rows = NULL;
  obs_err err = OBS_ERR_INIT;
  if (srv_db_query(app->db, SRV_Q_BUDGET, NULL, 0, &rows, &err)) {
    int rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: cannot read the stored "
                         "measurements: %s", obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  /* Measurements of this scene at a similar size, else of any scene at a similar size. */
  size_t n = json_array_size(rows);
  int same_scene = 0;
  for (size_t i = 0; i < n; i++) {
    json_t *row = json_array_get(rows, i);
    double px = json_number_value(json_object_get(row, "pixels"));
    const char *sc = json_string_value(json_object_get(row, "scene"));
    double rmse;
    int at_ref;
    if (px >= pixels / 2 && px <= pixels * 2 && sc && !strcmp(sc, scene) &&
        budget_row(app, row, &rmse, &at_ref))
      same_scene = 1;
  }
  int best = -1, measured = 0;
  double best_ms = 0, best_rmse = 0, fastest_ms = INFINITY;
  int best_at_ref = 0;
  for (size_t i = 0; i < n; i++) {
    json_t *row = json_array_get(rows, i);
    double px = json_number_value(json_object_get(row, "pixels"));
    const char *sc = json_string_value(json_object_get(row, "scene"));
    if (!(px >= pixels / 2 && px <= pixels * 2)) continue;
    if (same_scene && (!sc || strcmp(sc, scene))) continue;
    double rmse;
    int at_ref;
    if (!budget_row(app, row, &rmse, &at_ref)) continue;
    json_t *runs = NULL;
    srv_arg arg = {SRV_ARG_INT, json_integer_value(json_object_get(row, "job")), 0, NULL};
    double v[SRV_MAX_REPEATS];
    size_t nv = 0;
    if (!srv_db_query(app->db, SRV_Q_JOB_RUNS, &arg, 1, &runs, &err))
      for (size_t k = 0; k < json_array_size(runs) && nv < SRV_MAX_REPEATS; k++)
        v[nv++] = json_number_value(json_object_get(json_array_get(runs, k), "total_ms"));
    obs_err_clear(&err);
    json_decref(runs);
    double ms = srv_median(v, nv);
    if (isnan(ms)) continue;
    measured++;
    if (ms < fastest_ms) fastest_ms = ms;
    if (ms > budget_ms) continue;
    /* Within the reference's noise, configurations are equally accurate: the fastest wins. */
    int better = best < 0 || (at_ref && !best_at_ref) ||
                 (at_ref && best_at_ref && ms < best_ms) ||
                 (!at_ref && !best_at_ref && (rmse < best_rmse || (rmse == best_rmse && ms < best_ms)));
    if (better) {
      best = (int)i;
      best_ms = ms;
      best_rmse = rmse;
      best_at_ref = at_ref;
    }
  }
  obs_err_free(&err);
  int rc = 0;
  if (!measured) {
    rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: nothing has been measured "
                     "yet for %s or any scene of a similar size (%.0f pixel samples, within 2x): "
                     "run a comparison first (POST /api/v1/comparisons)", scene, pixels);
  } else if (best < 0) {
    rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: none of the %d measured "
                     "configurations%s fits %g ms: the fastest takes %.4g ms (median)", measured,
                     same_scene ? " of this scene" : " of similar scenes", budget_ms, fastest_ms);
  } else {
    json_t *row = json_array_get(rows, (size_t)best);
    json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
    char reason[600];
    snprintf(reason, sizeof reason,
             "%s among %d measured configuration(s) %s that fit %g ms: %s on %s takes %.4g ms "
             "(median) with RMSE %.4g (comparison %lld, candidate %lld)",
             best_at_ref ? "the fastest at reference accuracy" : "the lowest RMSE", measured,
             same_scene ? "of this scene" : "of scenes of a similar size", budget_ms,
             json_string_value(json_object_get(row, "technique")),
             json_string_value(json_object_get(row, "backend")), best_ms, best_rmse,
             (long long)json_integer_value(json_object_get(row, "comparison")),
             (long long)json_integer_value(json_object_get(row, "idx")));
    *choice = json_pack("{s:O, s:O, s:o, s:f, s:f, s:O, s:s}", "technique",
                        json_object_get(row, "technique"), "backend",
                        json_object_get(row, "backend"), "params",
                        params ? params : json_object(), "expected_ms", best_ms, "expected_rmse",
                        best_rmse, "comparison_id", json_object_get(row, "comparison"), "reason",
                        reason);
    if (!*choice) rc = obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  }
  json_decref(rows);
  return rc;
}
