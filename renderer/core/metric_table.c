/* The metric table (every figure a comparison reports, declared once) and obs_metrics_compare_all,
 * the one function the server's comparisons, `obscura diff` and the tests compute them with. */
#include "obscura/metric_table.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define INF INFINITY

static const obs_metric k_table[OBS_METRIC_COUNT] = {
    [OBS_METRIC_RMSE] = {"rmse", NULL, "rmse", -1, "RMSE", "", OBS_METRIC_LOWER, 0, INF,
                         OBS_METRIC_NEEDS_SCALAR, 4,
                         "sqrt(mean((c - r)^2)) over the selected pixels", NULL},
    [OBS_METRIC_BIAS] = {"bias", NULL, "bias", -1, "Bias", "", OBS_METRIC_ZERO, -INF, INF,
                         OBS_METRIC_NEEDS_SCALAR, 4,
                         "mean(c - r): > 0 means the candidate is too bright", NULL},
    [OBS_METRIC_MAX_ABS] = {"max_abs", NULL, "max_abs", -1, "Max |error|", "", OBS_METRIC_LOWER,
                            0, INF, OBS_METRIC_NEEDS_SCALAR, 4, "max |c - r|", NULL},
    [OBS_METRIC_PSNR] = {"psnr", NULL, "psnr", -1, "PSNR", "dB", OBS_METRIC_HIGHER, -INF,
                         OBS_METRICS_PSNR_MAX, OBS_METRIC_NEEDS_SCALAR, 3,
                         "min(10 log10(1 / RMSE^2), 100): peak 1, 100 dB for identical images", NULL},
    [OBS_METRIC_SSIM] = {"ssim", NULL, "ssim", -1, "SSIM", "", OBS_METRIC_HIGHER, -1, 1,
                         OBS_METRIC_NEEDS_SCALAR, 4,
                         "mean SSIM (Wang et al. 2004, as scikit-image): 11x11 Gaussian window, "
                         "sigma 1.5, K1 0.01, K2 0.03, data range 1, 5-pixel border cropped", NULL},
    [OBS_METRIC_FLIP] = {"flip", NULL, "flip", -1, "FLIP", "", OBS_METRIC_LOWER, 0, 1,
                         OBS_METRIC_NEEDS_DISPLAY, 4,
                         "mean FLIP error at 67 pixels per degree (Andersson et al. 2020): "
                         "LDR-FLIP of a [0, 1] channel as grey sRGB, HDR-FLIP of an RGB output", NULL},
    [OBS_METRIC_ANGLE_DEG] = {"angle_deg", NULL, "angle_deg", -1, "Mean angle", "deg",
                              OBS_METRIC_LOWER, 0, 180, OBS_METRIC_NEEDS_VECTOR, 3,
                              "mean angle between candidate and reference directions, degrees", NULL},
    [OBS_METRIC_REF_NOISE] = {"ref_noise", NULL, "ref_noise", -1,
                              "Reference noise", "", OBS_METRIC_NONE, 0, INF,
                              OBS_METRIC_NEEDS_STDERR, 3,
                              "mean of the reference's standard error over the selected pixels", NULL},
    [OBS_METRIC_PATCH_RMSE] = {"patch_rmse", NULL, "patch_rmse", -1, "RMSE over patches", "",
                               OBS_METRIC_LOWER, 0, INF, OBS_METRIC_NEEDS_PATCHES, 4,
                               "area-weighted RMSE over the per-patch values", NULL},
    [OBS_METRIC_RMSE_R] = {"rmse_r", "rgb", "rmse", 0, "RMSE R", "", OBS_METRIC_LOWER, 0, INF,
                           OBS_METRIC_NEEDS_RGB, 3, "RMSE of the R channel", NULL},
    [OBS_METRIC_RMSE_G] = {"rmse_g", "rgb", "rmse", 1, "RMSE G", "", OBS_METRIC_LOWER, 0, INF,
                           OBS_METRIC_NEEDS_RGB, 3, "RMSE of the G channel", NULL},
    [OBS_METRIC_RMSE_B] = {"rmse_b", "rgb", "rmse", 2, "RMSE B", "", OBS_METRIC_LOWER, 0, INF,
                           OBS_METRIC_NEEDS_RGB, 3, "RMSE of the B channel", NULL},
    [OBS_METRIC_RMSE_LUMINANCE] = {"rmse_luminance", "rgb", "rmse_luminance", -1,
                                   "RMSE of luminance", "", OBS_METRIC_LOWER, 0, INF,
                                   OBS_METRIC_NEEDS_RGB, 4,
                                   "RMSE of Y = 0.2126 R + 0.7152 G + 0.0722 B", "rmse"},
    [OBS_METRIC_SSIM_LUMINANCE] = {"ssim_luminance", "rgb", "ssim_luminance", -1,
                                   "SSIM of luminance", "", OBS_METRIC_HIGHER, -1, 1,
                                   OBS_METRIC_NEEDS_RGB, 4, "SSIM of Y, data range 1", "ssim"},
    [OBS_METRIC_REL_MSE] = {"rel_mse", "rgb", "rel_mse", -1, "Rel. MSE", "", OBS_METRIC_LOWER, 0,
                            INF, OBS_METRIC_NEEDS_RGB, 4,
                            "mean over pixels and channels of (c - r)^2 / (r^2 + 0.01)", NULL},
};

const obs_metric *obs_metric_table(void) { return k_table; }

const obs_metric *obs_metric_find(const char *name) {
  for (int i = 0; name && i < OBS_METRIC_COUNT; i++)
    if (!strcmp(k_table[i].name, name)) return &k_table[i];
  return NULL;
}

const char *obs_metric_direction_name(obs_metric_direction d) {
  static const char *const names[] = {"lower", "higher", "zero", "none"};
  return (unsigned)d < 4 ? names[d] : "?";
}

const char *obs_metric_needs_name(obs_metric_needs n) {
  static const char *const names[] = {"scalar", "display", "rgb", "vector", "stderr", "patches"};
  return (unsigned)n < 6 ? names[n] : "?";
}

/* ---- computing them ------------------------------------------------------------------------- */

static void put(obs_metric_values *o, obs_metric_id id, double v) {
  o->v[id] = v;
  o->has[id] = 1;
}

/* Whether every finite selected value of the reference's `channel` lies in [0, 1]: a display
 * value (AO, coverage) that LDR-FLIP can see as grey; depth or radiance cannot. */
static int display_range(const obs_image *ref, const char *channel, const float *m) {
  const float *p = obs_image_channel(ref, channel);
  size_t n = (size_t)ref->width * (size_t)ref->height;
  for (size_t i = 0; p && i < n; i++)
    if ((!m || m[i] > 0.0f) && isfinite(p[i]) && (p[i] < 0.0f || p[i] > 1.0f)) return 0;
  return p != NULL;
}

static void put_scalar(obs_metric_values *o, const obs_compare *c) {
  put(o, OBS_METRIC_RMSE, c->rmse);
  put(o, OBS_METRIC_BIAS, c->bias);
  put(o, OBS_METRIC_MAX_ABS, c->max_abs);
  put(o, OBS_METRIC_PSNR, c->psnr);
  put(o, OBS_METRIC_SSIM, c->ssim);
  put(o, OBS_METRIC_REF_NOISE, c->ref_noise);
  o->pixels = c->pixels;
  o->at_reference_accuracy = c->at_reference_accuracy;
}

static int compare_scalar(const obs_image *cand, const obs_image *ref, const obs_metric_opts *op,
                          obs_metric_values *o, obs_err *err) {
  obs_compare c;
  int rc = obs_metrics_compare(cand, ref, op->channel, op->mask, &c, err);
  if (rc) return rc;
  put_scalar(o, &c);
  const float *m = op->mask ? obs_image_channel(ref, op->mask) : NULL;
  double flip;
  if (display_range(ref, op->channel, m)) {
    rc = obs_metrics_flip_ppd(cand, ref, op->channel, op->mask, 0,
                              op->ppd > 0 ? op->ppd : OBS_FLIP_DEFAULT_PPD, op->flip_map, &flip,
                              err);
    if (!rc) put(o, OBS_METRIC_FLIP, flip);
  }
  return rc;
}

static int compare_rgb(const obs_image *cand, const obs_image *ref, const obs_metric_opts *op,
                       obs_metric_values *o, obs_err *err) {
  obs_compare_rgb c;
  int rc = obs_metrics_compare_rgb(cand, ref, op->channel, op->mask, &c, err);
  if (rc) return rc;
  put(o, OBS_METRIC_RMSE_R, c.rmse[0]);
  put(o, OBS_METRIC_RMSE_G, c.rmse[1]);
  put(o, OBS_METRIC_RMSE_B, c.rmse[2]);
  put(o, OBS_METRIC_RMSE_LUMINANCE, c.rmse_luminance);
  put(o, OBS_METRIC_SSIM_LUMINANCE, c.ssim_luminance);
  put(o, OBS_METRIC_REL_MSE, c.rel_mse);
  /* The scalar figures on the luminance, the reference's noise from its standard error's. */
  char se[OBS_CHANNEL_NAME_MAX + 8];
  snprintf(se, sizeof se, "%s_stderr", op->channel);
  obs_image lc, lr;
  memset(&lr, 0, sizeof lr);
  rc = obs_metrics_luminance_image(cand, op->channel, NULL, &lc, err);
  if (!rc)
    rc = obs_metrics_luminance_image(ref, op->channel,
                                     op->stderr_channel ? op->stderr_channel : se, &lr, err);
  obs_compare s;
  if (!rc) rc = obs_metrics_compare(&lc, &lr, op->channel, op->mask, &s, err);
  if (!rc) put_scalar(o, &s);
  obs_image_free(&lc);
  obs_image_free(&lr);
  double flip;
  if (!rc)
    rc = obs_metrics_flip_ppd(cand, ref, op->channel, op->mask, 1,
                              op->ppd > 0 ? op->ppd : OBS_FLIP_DEFAULT_PPD, op->flip_map, &flip,
                              err);
  if (!rc) put(o, OBS_METRIC_FLIP, flip);
  return rc;
}

/* Mean angle between the directions "<name>.X/Y/Z" of the pair over the selected pixels, from
 * atan2(|a x b|, a . b): exact near 0 and 180 degrees, where acos of a dot product loses half its
 * digits, and independent of the vectors' lengths. Pixels where either vector has length 0 (no
 * direction) are left out; a NaN component makes the mean NaN. */
static int compare_vector(const obs_image *cand, const obs_image *ref, const obs_metric_opts *op,
                          obs_metric_values *o, obs_err *err) {
  const float *a[3], *b[3], *m = NULL;
  for (int k = 0; k < 3; k++) {
    char name[OBS_CHANNEL_NAME_MAX + 4];
    snprintf(name, sizeof name, "%s.%c", op->channel, "XYZ"[k]);
    a[k] = obs_image_channel(cand, name);
    b[k] = obs_image_channel(ref, name);
    if (!a[k] || !b[k])
      return obs_err_set(err, OBS_ENOTFOUND, "metrics: the %s image has no channel \"%s\"",
                         a[k] ? "reference" : "candidate", name);
  }
  if (op->mask && !(m = obs_image_channel(ref, op->mask)))
    return obs_err_set(err, OBS_ENOTFOUND, "metrics: the reference has no mask channel \"%s\"",
                       op->mask);
  size_t n = (size_t)ref->width * (size_t)ref->height, used = 0;
  double sum = 0, comp = 0;
  int nan = 0;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
    double x[3] = {a[0][i], a[1][i], a[2][i]}, y[3] = {b[0][i], b[1][i], b[2][i]};
    double cx = x[1] * y[2] - x[2] * y[1], cy = x[2] * y[0] - x[0] * y[2],
           cz = x[0] * y[1] - x[1] * y[0];
    double dot = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    double la = x[0] * x[0] + x[1] * x[1] + x[2] * x[2], lb = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
    if (isnan(la) || isnan(lb)) {
      nan = 1;
      continue;
    }
    if (la == 0 || lb == 0) continue;
    double ang = atan2(sqrt(cx * cx + cy * cy + cz * cz), dot) * (180.0 / M_PI);
    double t = sum + (ang - comp); /* Kahan */
    comp = (t - sum) - (ang - comp);
    sum = t;
    used++;
  }
  put(o, OBS_METRIC_ANGLE_DEG, nan ? NAN : used ? sum / (double)used : 0.0);
  o->pixels = (int64_t)used;
  return OBS_OK;
}

int obs_metrics_compare_all(const obs_image *candidate, const obs_image *reference,
                            const obs_metric_opts *opts, obs_metric_values *out, obs_err *err) {
  if (!candidate || !reference || !candidate->data || !reference->data || !opts ||
      !opts->channel || !out)
    return obs_err_set(err, OBS_EINVAL,
                       "metrics: compare_all needs a candidate, a reference, a channel and an "
                       "output");
  if (candidate->width != reference->width || candidate->height != reference->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: image sizes differ (%dx%d vs %dx%d)",
                       candidate->width, candidate->height, reference->width, reference->height);
  if (opts->flip_map) memset(opts->flip_map, 0, sizeof *opts->flip_map);
  obs_metric_values o;
  memset(&o, 0, sizeof o);
  for (int i = 0; i < OBS_METRIC_COUNT; i++) o.v[i] = NAN;
  char probe[OBS_CHANNEL_NAME_MAX + 4];
  const char *ch = opts->channel;
  int rc;
  if (obs_image_channel(reference, ch)) {
    rc = compare_scalar(candidate, reference, opts, &o, err);
  } else if (snprintf(probe, sizeof probe, "%s.R", ch), obs_image_channel(reference, probe)) {
    rc = compare_rgb(candidate, reference, opts, &o, err);
  } else if (snprintf(probe, sizeof probe, "%s.X", ch), obs_image_channel(reference, probe)) {
    rc = compare_vector(candidate, reference, opts, &o, err);
  } else {
    rc = obs_err_set(err, OBS_ENOTFOUND,
                     "metrics: the reference has no channel \"%s\", nor \"%s.R/G/B\" nor "
                     "\"%s.X/Y/Z\"",
                     ch, ch, ch);
  }
  if (!rc) *out = o;
  else if (opts->flip_map) obs_image_free(opts->flip_map);
  return rc;
}

/* ---- JSON ----------------------------------------------------------------------------------- */

static json_t *num_or_null(double v) { return isfinite(v) ? json_real(v) : json_null(); }

json_t *obs_metric_table_json(void) {
  json_t *a = json_array();
  for (int i = 0; a && i < OBS_METRIC_COUNT; i++) {
    const obs_metric *m = &k_table[i];
    json_t *o = json_pack("{s:s, s:s?, s:s, s:i, s:s, s:s, s:s, s:o, s:o, s:s, s:i, s:s, s:s?}",
                          "name", m->name, "json_group", m->json_group, "json_key", m->json_key,
                          "json_index", m->json_index, "label", m->label, "unit", m->unit,
                          "direction", obs_metric_direction_name(m->direction), "min",
                          num_or_null(m->min), "max", num_or_null(m->max), "needs",
                          obs_metric_needs_name(m->needs), "digits", m->digits, "definition",
                          m->definition, "same_as", m->same_as);
    if (!o || json_array_append_new(a, o)) {
      json_decref(a);
      return NULL;
    }
  }
  return a;
}

int obs_metric_values_json(const obs_metric_values *vals, json_t *metrics) {
  if (!vals || !json_is_object(metrics)) return OBS_EINVAL;
  for (int i = 0; i < OBS_METRIC_COUNT; i++) {
    const obs_metric *m = &k_table[i];
    if (!vals->has[i]) continue;
    json_t *obj = metrics;
    if (m->json_group) {
      obj = json_object_get(metrics, m->json_group);
      if (!obj) {
        obj = json_object();
        if (json_object_set_new(metrics, m->json_group, obj)) return OBS_ENOMEM;
      }
    }
    json_t *v = num_or_null(vals->v[i]);
    if (m->json_index >= 0) {
      json_t *arr = json_object_get(obj, m->json_key);
      if (!arr) {
        arr = json_array();
        if (json_object_set_new(obj, m->json_key, arr)) return OBS_ENOMEM;
      }
      while ((int)json_array_size(arr) < m->json_index) json_array_append_new(arr, json_null());
      if (json_array_insert_new(arr, (size_t)m->json_index, v)) return OBS_ENOMEM;
    } else if (json_object_set_new(obj, m->json_key, v)) {
      return OBS_ENOMEM;
    }
  }
  if (json_object_set_new(metrics, "pixels", json_integer(vals->pixels)) ||
      json_object_set_new(metrics, "at_reference_accuracy",
                          json_boolean(vals->at_reference_accuracy)))
    return OBS_ENOMEM;
  return OBS_OK;
}

json_t *obs_metric_json_get(const json_t *metrics, const obs_metric *m) {
  const json_t *obj = m->json_group ? json_object_get(metrics, m->json_group) : metrics;
  json_t *v = json_object_get(obj, m->json_key);
  return m->json_index >= 0 ? json_array_get(v, (size_t)m->json_index) : v;
}
