/* The comparisons' metrics step, run when a candidate and its reference have both succeeded. */
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
  /* Either job may have run on another node: its outputs come from the store first. */
  if (!rc) rc = srv_outputs_local_all(app, job, &e);
  if (!rc) rc = srv_outputs_local_all(app, rjob, &e);
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
  /* ... and the error images go there too, so every node serves them. */
  if (!rc && app->results_via_store) rc = srv_outputs_put_blobs(app, dir, err_outs, nerr, &e);
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
