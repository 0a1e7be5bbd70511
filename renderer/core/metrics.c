/* Channel statistics and RMSE between images, used by tests and reference comparisons. */
#include "obscura/metrics.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

/* Neumaier-compensated sum: large renders sum millions of values of similar magnitude, where a
 * plain double accumulator would drift in the last digits that reference comparisons look at. */
typedef struct {
  double sum, comp;
} metrics_acc;

static void metrics_add(metrics_acc *a, double v) {
  double t = a->sum + v;
  if (fabs(a->sum) >= fabs(v))
    a->comp += (a->sum - t) + v;
  else
    a->comp += (v - t) + a->sum;
  a->sum = t;
}

static double metrics_total(const metrics_acc *a) { return a->sum + a->comp; }

static const float *metrics_find(const obs_image *img, const char *name, const char *what,
                                 int *code, obs_err *err) {
  const float *p = obs_image_channel(img, name);
  if (!p)
    *code = obs_err_set(err, OBS_ENOTFOUND, "metrics: %s image has no channel \"%s\"", what,
                        name ? name : "(null)");
  return p;
}

int obs_metrics_stats(const obs_image *img, const char *channel, const char *mask, obs_stats *out,
                      obs_err *err) {
  if (!img || !img->data || !channel || !out)
    return obs_err_set(err, OBS_EINVAL, "metrics: stats needs an image, a channel and an output");
  int code = OBS_OK;
  const float *v = metrics_find(img, channel, "the", &code, err);
  if (!v) return code;
  const float *m = NULL;
  if (mask && !(m = metrics_find(img, mask, "the mask", &code, err))) return code;

  obs_stats s;
  memset(&s, 0, sizeof s);
  metrics_acc acc = {0, 0};
  double lo = INFINITY, hi = -INFINITY;
  size_t n = (size_t)img->width * (size_t)img->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue; /* NaN mask values deselect, like 0 */
    float x = v[i];
    if (isnan(x)) {
      s.nan_count++;
    } else if (isinf(x)) {
      s.inf_count++;
    } else {
      s.count++;
      metrics_add(&acc, x);
      if (x < lo) lo = x;
      if (x > hi) hi = x;
    }
  }
  if (s.count > 0) {
    s.mean = metrics_total(&acc) / (double)s.count;
    s.min = lo;
    s.max = hi;
  }
  *out = s;
  return OBS_OK;
}

/* A NaN in a selected pixel makes the result NaN, and an infinite difference makes it +Inf, on
 * purpose: a comparison against a reference must not quietly pass when a render produced garbage.
 * Identical values (equal infinities too) contribute no error. With no pixel selected the result is
 * 0, matching obs_stats' convention for empty sets. */
int obs_metrics_rmse(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *rmse, obs_err *err) {
  if (!a || !b || !a->data || !b->data || !channel || !rmse)
    return obs_err_set(err, OBS_EINVAL, "metrics: rmse needs two images, a channel and an output");
  if (a->width != b->width || a->height != b->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: image sizes differ (%dx%d vs %dx%d)", a->width,
                       a->height, b->width, b->height);
  int code = OBS_OK;
  const float *pa = metrics_find(a, channel, "first", &code, err);
  if (!pa) return code;
  const float *pb = metrics_find(b, channel, "second", &code, err);
  if (!pb) return code;
  const float *m = NULL;
  if (mask && !(m = metrics_find(b, mask, "second (mask)", &code, err))) return code;

  metrics_acc acc = {0, 0};
  int any_nan = 0, any_inf = 0;
  size_t used = 0, n = (size_t)a->width * (size_t)a->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
    used++;
    if (pa[i] == pb[i]) continue; /* equal infinities are no error; inf - inf would be NaN */
    double d = (double)pa[i] - (double)pb[i];
    if (isnan(d))
      any_nan = 1;
    else if (isinf(d))
      any_inf = 1;
    else
      metrics_add(&acc, d * d); /* float differences squared stay finite in double */
  }
  if (any_nan)
    *rmse = NAN;
  else if (any_inf)
    *rmse = INFINITY;
  else
    *rmse = used ? sqrt(metrics_total(&acc) / (double)used) : 0.0;
  return OBS_OK;
}

int obs_metrics_ssim(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *ssim, obs_err *err) {
  if (!a || !b || !a->data || !b->data || !channel || !ssim)
    return obs_err_set(err, OBS_EINVAL, "metrics: ssim needs two images, a channel and an output");
  if (a->width != b->width || a->height != b->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: image sizes differ (%dx%d vs %dx%d)", a->width,
                       a->height, b->width, b->height);
  int code = OBS_OK;
  const float *pa = metrics_find(a, channel, "first", &code, err);
  if (!pa) return code;
  const float *pb = metrics_find(b, channel, "second", &code, err);
  if (!pb) return code;
  const float *m = NULL;
  if (mask && !(m = metrics_find(b, mask, "second (mask)", &code, err))) return code;
  int w = a->width, h = a->height;
  int ww = w < 8 ? w : 8, wh = h < 8 ? h : 8;
  /* Separable Gaussian weights centred in the window, normalised to sum 1. */
  double gx[8], gy[8], sx = 0, sy = 0;
  for (int i = 0; i < ww; i++) sx += gx[i] = exp(-pow(i - (ww - 1) / 2.0, 2) / (2 * 1.5 * 1.5));
  for (int i = 0; i < wh; i++) sy += gy[i] = exp(-pow(i - (wh - 1) / 2.0, 2) / (2 * 1.5 * 1.5));
  const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  metrics_acc acc = {0, 0};
  size_t windows = 0;
  for (int y0 = 0; y0 + wh <= h; y0++)
    for (int x0 = 0; x0 + ww <= w; x0++) {
      int cx = x0 + ww / 2, cy = y0 + wh / 2;
      if (m && !(m[(size_t)cy * (size_t)w + (size_t)cx] > 0.0f)) continue;
      double ma = 0, mb = 0, va = 0, vb = 0, cov = 0;
      for (int j = 0; j < wh; j++)
        for (int i = 0; i < ww; i++) {
          double g = gx[i] / sx * gy[j] / sy;
          size_t k = (size_t)(y0 + j) * (size_t)w + (size_t)(x0 + i);
          ma += g * pa[k];
          mb += g * pb[k];
        }
      for (int j = 0; j < wh; j++)
        for (int i = 0; i < ww; i++) {
          double g = gx[i] / sx * gy[j] / sy;
          size_t k = (size_t)(y0 + j) * (size_t)w + (size_t)(x0 + i);
          double da = pa[k] - ma, db = pb[k] - mb;
          va += g * da * da;
          vb += g * db * db;
          cov += g * da * db;
        }
      metrics_add(&acc, ((2 * ma * mb + c1) * (2 * cov + c2)) /
                            ((ma * ma + mb * mb + c1) * (va + vb + c2)));
      windows++;
    }
  *ssim = windows ? metrics_total(&acc) / (double)windows : 1.0;
  return OBS_OK;
}
