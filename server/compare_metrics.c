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
