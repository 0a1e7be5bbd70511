/* Image metrics: channel statistics, RMSE, SSIM, candidate-vs-reference comparisons and error
 * images (signed EXR + colour-mapped PNG), used by tests, benchmarks and the comparison server. */
#include "obscura/metrics.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscura/path.h"
#include "metrics_internal.h"

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

/* Count, NaN and inf counts, mean, min and max of the n values of v; with a mask, only where the
 * mask is > 0 (a NaN mask value deselects, like 0). */
static obs_stats stats_of(const float *v, const float *m, size_t n) {
  obs_stats s;
  memset(&s, 0, sizeof s);
  metrics_acc acc = {0, 0};
  double lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
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
  return s;
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

  *out = stats_of(v, m, (size_t)img->width * (size_t)img->height);
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

/* One row or column pass of the SSIM window's normalised Gaussian over n values at stride `st`,
 * the line mirrored at its ends as scipy.ndimage's "reflect" mode does (d c b a | a b c d); n is
 * at least the window, so one mirroring reaches every tap. */
static void ssim_pass(const double *in, double *out, int n, size_t st, const double *g, int r) {
  for (int i = 0; i < n; i++) {
    double s = 0;
    for (int k = -r; k <= r; k++) {
      int j = i + k;
      j = j < 0 ? -j - 1 : j >= n ? 2 * n - j - 1 : j;
      s += g[k + r] * in[(size_t)j * st];
    }
    out[(size_t)i * st] = s;
  }
}

/* The Gaussian-filtered plane of `v` (w x h, in place through `tmp`). */
static void ssim_filter(double *v, double *tmp, int w, int h, const double *g, int r) {
  for (int y = 0; y < h; y++) ssim_pass(v + (size_t)y * w, tmp + (size_t)y * w, w, 1, g, r);
  for (int x = 0; x < w; x++) ssim_pass(tmp + x, v + x, h, (size_t)w, g, r);
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
  if (w < OBS_SSIM_WINDOW || h < OBS_SSIM_WINDOW) {
    *ssim = NAN; /* no whole window fits: undefined, as skimage refuses it */
    return OBS_OK;
  }
  /* skimage's window: radius int(3.5 sigma + 0.5) = 5, weights exp(-k^2 / 2 sigma^2) / sum. */
  enum { R = OBS_SSIM_WINDOW / 2 };
  double g[OBS_SSIM_WINDOW], gs = 0;
  for (int k = -R; k <= R; k++) gs += g[k + R] = exp(-(double)(k * k) / (2 * OBS_SSIM_SIGMA * OBS_SSIM_SIGMA));
  for (int k = 0; k < OBS_SSIM_WINDOW; k++) g[k] /= gs;
  size_t n = (size_t)w * (size_t)h;
  double *buf = malloc(6 * n * sizeof *buf);
  if (!buf) return obs_err_set(err, OBS_ENOMEM, "metrics: ssim: out of memory (%dx%d)", w, h);
  double *mx = buf, *my = buf + n, *mxx = buf + 2 * n, *myy = buf + 3 * n, *mxy = buf + 4 * n,
         *tmp = buf + 5 * n;
  for (size_t i = 0; i < n; i++) {
    double x = pa[i], y = pb[i];
    mx[i] = x, my[i] = y, mxx[i] = x * x, myy[i] = y * y, mxy[i] = x * y;
  }
  for (int p = 0; p < 5; p++) ssim_filter(buf + (size_t)p * n, tmp, w, h, g, R);
  const double c1 = pow(0.01 * OBS_SSIM_DATA_RANGE, 2), c2 = pow(0.03 * OBS_SSIM_DATA_RANGE, 2);
  metrics_acc acc = {0, 0};
  size_t counted = 0;
  for (int y = R; y < h - R; y++)
    for (int x = R; x < w - R; x++) {
      size_t i = (size_t)y * (size_t)w + (size_t)x;
      if (m && !(m[i] > 0.0f)) continue;
      double ux = mx[i], uy = my[i];
      double vx = mxx[i] - ux * ux, vy = myy[i] - uy * uy, vxy = mxy[i] - ux * uy;
      metrics_add(&acc, ((2 * ux * uy + c1) * (2 * vxy + c2)) /
                            ((ux * ux + uy * uy + c1) * (vx + vy + c2)));
      counted++;
    }
  free(buf);
  *ssim = counted ? metrics_total(&acc) / (double)counted : 1.0;
  return OBS_OK;
}

/* The planes a candidate/reference comparison reads: both images the same size, `channel` in both,
 * `mask` (optional) in the reference. `what` names the operation in messages. */
static int metrics_pair(const obs_image *a, const obs_image *b, const char *channel,
                        const char *mask, const void *out, const char *what, const float **pa,
                        const float **pb, const float **m, obs_err *err) {
  if (!a || !b || !a->data || !b->data || !channel || !out)
    return obs_err_set(err, OBS_EINVAL,
                       "metrics: %s needs a candidate, a reference, a channel and an output", what);
  if (a->width != b->width || a->height != b->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: image sizes differ (%dx%d vs %dx%d)", a->width,
                       a->height, b->width, b->height);
  int code = OBS_OK;
  if (!(*pa = metrics_find(a, channel, "candidate", &code, err))) return code;
  if (!(*pb = metrics_find(b, channel, "reference", &code, err))) return code;
  *m = NULL;
  if (mask && !(*m = metrics_find(b, mask, "reference (mask)", &code, err))) return code;
  return OBS_OK;
}

/* The same pass as obs_metrics_rmse (same order, same compensated sum, so rmse is bit-identical)
 * extended with the signed sum and the largest magnitude. */
int obs_metrics_compare(const obs_image *candidate, const obs_image *reference, const char *channel,
                        const char *mask, obs_compare *out, obs_err *err) {
  const float *pa, *pb, *m;
  int code = metrics_pair(candidate, reference, channel, mask, out, "compare", &pa, &pb, &m, err);
  if (code) return code;
  const obs_image *a = candidate, *b = reference;

  obs_compare r;
  memset(&r, 0, sizeof r);
  metrics_acc sq = {0, 0}, sum = {0, 0};
  int any_nan = 0, pos_inf = 0, neg_inf = 0;
  double max_abs = 0.0;
  size_t used = 0, n = (size_t)a->width * (size_t)a->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
    used++;
    if (pa[i] == pb[i]) continue;
    double d = (double)pa[i] - (double)pb[i];
    if (isnan(d)) {
      any_nan = 1;
    } else if (isinf(d)) {
      if (d > 0)
        pos_inf = 1;
      else
        neg_inf = 1;
    } else {
      metrics_add(&sq, d * d);
      metrics_add(&sum, d);
      if (fabs(d) > max_abs) max_abs = fabs(d);
    }
  }
  r.pixels = (int64_t)used;
  if (any_nan) {
    r.rmse = r.bias = r.max_abs = r.psnr = NAN;
  } else if (pos_inf || neg_inf) {
    r.rmse = r.max_abs = INFINITY;
    r.psnr = -INFINITY;
    r.bias = pos_inf && neg_inf ? NAN : pos_inf ? INFINITY : -INFINITY;
  } else if (used) {
    double mse = metrics_total(&sq) / (double)used;
    r.rmse = sqrt(mse);
    r.bias = metrics_total(&sum) / (double)used;
    r.max_abs = max_abs;
    r.psnr = mse > 0 ? fmin(10.0 * log10(1.0 / mse), OBS_METRICS_PSNR_MAX) : OBS_METRICS_PSNR_MAX;
  } else {
    r.psnr = OBS_METRICS_PSNR_MAX; /* nothing selected: no error, like obs_metrics_rmse */
  }
  code = obs_metrics_ssim(a, b, channel, mask, &r.ssim, err);
  if (code) return code;

  /* The reference's own Monte-Carlo noise: "<channel>_stderr" (ao_stderr for "ao"). */
  char se_name[OBS_CHANNEL_NAME_MAX + 8];
  if ((size_t)snprintf(se_name, sizeof se_name, "%s_stderr", channel) < sizeof se_name &&
      obs_image_channel(b, se_name)) {
    obs_stats st;
    code = obs_metrics_stats(b, se_name, mask, &st, err);
    if (code) return code;
    r.ref_noise = st.mean;
  }
  r.at_reference_accuracy = r.rmse < 2.0 * r.ref_noise; /* false for NaN and for ref_noise 0 */
  *out = r;
  return OBS_OK;
}

/* Ramp ends of the error image (ColorBrewer RdBu's outer colours, display-encoded). */
static const float k_err_neg[3] = {0x21 / 255.0f, 0x66 / 255.0f, 0xAC / 255.0f};
static const float k_err_pos[3] = {0xB2 / 255.0f, 0x18 / 255.0f, 0x2B / 255.0f};

int obs_metrics_error_image(const obs_image *candidate, const obs_image *reference,
                            const char *channel, const char *mask, obs_image *out, obs_err *err) {
  if (out) memset(out, 0, sizeof *out);
  const float *pa, *pb, *m;
  int code =
      metrics_pair(candidate, reference, channel, mask, out, "error image", &pa, &pb, &m, err);
  if (code) return code;
  const obs_image *a = candidate;

  static const char *const names[] = {"error", "R", "G", "B"};
  code = obs_image_init(out, a->width, a->height, 4, names, err);
  if (code) return code;
  float *e = obs_image_channel(out, "error");
  float *rgb[3] = {obs_image_channel(out, "R"), obs_image_channel(out, "G"),
                   obs_image_channel(out, "B")};
  size_t n = (size_t)a->width * (size_t)a->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) {
      for (int c = 0; c < 3; c++) rgb[c][i] = 0.5f; /* e[i] stays 0 */
      continue;
    }
    double d = pa[i] == pb[i] ? 0.0 : (double)pa[i] - (double)pb[i];
    e[i] = (float)d;
    if (isnan(d)) {
      rgb[0][i] = 0.0f;
      rgb[1][i] = 1.0f;
      rgb[2][i] = 0.0f;
      continue;
    }
    double t = fabs(d) / OBS_METRICS_ERROR_SCALE;
    if (t > 1.0) t = 1.0;
    const float *end = d < 0 ? k_err_neg : k_err_pos;
    for (int c = 0; c < 3; c++) rgb[c][i] = (float)(1.0 - t * (1.0 - (double)end[c]));
  }
  return OBS_OK;
}

int obs_metrics_write_map_files(const obs_image *img, const char *channel, const obs_image *rgb,
                                const char *dir, const char *base, obs_err *err) {
  const float *e = obs_image_channel(img, channel);
  if (!e)
    return obs_err_set(err, OBS_ENOTFOUND, "metrics: %s image has no channel \"%s\"", base,
                       channel);
  static const char *const names[] = {"R", "G", "B"};
  for (int c = 0; c < 3; c++)
    if (!obs_image_channel(rgb, names[c]))
      return obs_err_set(err, OBS_ENOTFOUND, "metrics: %s image has no channel \"%s\"", base,
                         names[c]);
  int code = obs_path_make_dirs(dir, err);
  if (code) return code;

  /* A one-channel view of the plane, so the EXR holds that channel only (no copy). */
  obs_image view;
  memset(&view, 0, sizeof view);
  view.width = img->width;
  view.height = img->height;
  view.nchannels = 1;
  snprintf(view.names[0], sizeof view.names[0], "%s", channel);
  view.data = (float *)e; /* only read by the writer */

  static const char *const ext[] = {"exr", "png"};
  char stage[2][4200], final[2][4200];
  for (int i = 0; i < 2; i++) {
    if (snprintf(stage[i], sizeof stage[i], "%s/.%s.%s.new", dir, base, ext[i]) >=
            (int)sizeof stage[i] ||
        snprintf(final[i], sizeof final[i], "%s/%s.%s", dir, base, ext[i]) >= (int)sizeof final[i])
      return obs_err_set(err, OBS_EINVAL, "%s: output path too long", dir);
  }
  code = obs_image_write_exr(&view, stage[0], err);
  if (!code) code = obs_image_write_png(rgb, names, 3, 0, stage[1], err);
  for (int i = 0; !code && i < 2; i++)
    if (rename(stage[i], final[i]))
      code =
          obs_err_set(err, OBS_EIO, "%s: cannot rename into place: %s", final[i], strerror(errno));
  if (code)
    for (int i = 0; i < 2; i++) unlink(stage[i]);
  return code;
}

int obs_metrics_write_error_files(const obs_image *err_img, const char *dir, obs_err *err) {
  if (!err_img || !err_img->data || !dir || !dir[0])
    return obs_err_set(err, OBS_EINVAL,
                       "metrics: writing error files needs an image and a directory");
  return obs_metrics_write_map_files(err_img, "error", err_img, dir, "error", err);
}

/* ---- Pareto set ------------------------------------------------------------------------------ */

static int pareto_usable(const obs_pareto_point *p) {
  return !isnan(p->time_ms) && (p->at_reference_accuracy || !isnan(p->error));
}

/* Error as ranked: every point within the reference's noise ranks as the best possible error. */
static double pareto_error(const obs_pareto_point *p) {
  return p->at_reference_accuracy ? -INFINITY : p->error;
}

/* The time spread of a point: [lo, hi] around time_ms, time_ms itself where none was measured. */
static void pareto_spread(const obs_pareto_point *p, double *lo, double *hi) {
  *lo = p->time_min_ms > 0 && p->time_min_ms <= p->time_ms ? p->time_min_ms : p->time_ms;
  *hi = p->time_max_ms >= p->time_ms ? p->time_max_ms : p->time_ms;
}

static double pareto_tolerance(const obs_pareto_point *a, const obs_pareto_point *b) {
  double ta = a->error_tolerance > 0 ? a->error_tolerance : 0;
  double tb = b->error_tolerance > 0 ? b->error_tolerance : 0;
  return ta > tb ? ta : tb;
}

/* Whether j dominates i, with the margins of obs_metrics_pareto. */
static int pareto_dominates(const obs_pareto_point *j, const obs_pareto_point *i) {
  double ilo, ihi, jlo, jhi;
  pareto_spread(i, &ilo, &ihi);
  pareto_spread(j, &jlo, &jhi);
  double ei = pareto_error(i), ej = pareto_error(j), tol = pareto_tolerance(i, j);
  int faster = jhi < ilo, slower = jlo > ihi;
  /* -INFINITY (at reference accuracy) minus a tolerance stays -INFINITY: such points tie. */
  int more_accurate = ej < ei - tol, less_accurate = ej > ei + tol;
  return !slower && !less_accurate && (faster || more_accurate);
}

int obs_metrics_pareto(const obs_pareto_point *pts, size_t n, unsigned char *optimal,
                       obs_err *err) {
  if (n && (!pts || !optimal))
    return obs_err_set(err, OBS_EINVAL, "metrics: pareto needs points and an output array");
  int count = 0;
  /* O(n^2): comparisons hold at most a few hundred candidates. */
  for (size_t i = 0; i < n; i++) {
    optimal[i] = 0;
    if (!pareto_usable(&pts[i])) continue;
    int dominated = 0;
    for (size_t j = 0; j < n && !dominated; j++)
      dominated = j != i && pareto_usable(&pts[j]) && pareto_dominates(&pts[j], &pts[i]);
    if (!dominated) {
      optimal[i] = 1;
      count++;
    }
  }
  return count;
}

/* ---- RGB outputs and per-patch values ------------------------------------------------------- */

/* The three planes "<rgb>.R/G/B" of `img`, or an error naming the missing one. */
static int metrics_rgb(const obs_image *img, const char *rgb, const char *what, const float *p[3],
                       obs_err *err) {
  static const char *const suffix[3] = {"R", "G", "B"};
  int code = OBS_OK;
  for (int c = 0; c < 3; c++) {
    char name[OBS_CHANNEL_NAME_MAX + 4];
    snprintf(name, sizeof name, "%s.%s", rgb, suffix[c]);
    if (!(p[c] = metrics_find(img, name, what, &code, err))) return code;
  }
  return OBS_OK;
}

int obs_metrics_luminance_mean(const obs_image *img, const char *rgb, const char *mask,
                               double *mean, obs_err *err) {
  if (!img || !img->data || !rgb || !mean)
    return obs_err_set(err, OBS_EINVAL, "metrics: luminance needs an image, an output and a mean");
  const float *p[3], *m = NULL;
  int code = metrics_rgb(img, rgb, "the", p, err);
  if (code) return code;
  if (mask && !(m = metrics_find(img, mask, "the mask", &code, err))) return code;
  metrics_acc acc = {0, 0};
  size_t used = 0, n = (size_t)img->width * (size_t)img->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
    double y = OBS_LUMINANCE(p[0][i], p[1][i], p[2][i]);
    if (!isfinite(y)) continue;
    metrics_add(&acc, y);
    used++;
  }
  *mean = used ? metrics_total(&acc) / (double)used : 0.0;
  return OBS_OK;
}

int obs_metrics_luminance_image(const obs_image *img, const char *rgb, const char *stderr_rgb,
                                obs_image *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  if (!img || !img->data || !rgb || strlen(rgb) + 8 > OBS_CHANNEL_NAME_MAX)
    return obs_err_set(err, OBS_EINVAL, "metrics: luminance image needs an image and an output");
  const float *p[3], *s[3] = {NULL, NULL, NULL};
  int code = metrics_rgb(img, rgb, "the", p, err);
  if (code) return code;
  obs_err ignore = OBS_ERR_INIT;
  int have_se = stderr_rgb && metrics_rgb(img, stderr_rgb, "the", s, &ignore) == OBS_OK;
  obs_err_free(&ignore);
  const float *alpha = obs_image_channel(img, "alpha");
  char names[3][OBS_CHANNEL_NAME_MAX];
  const char *np[3];
  int nch = 0;
  snprintf(names[nch], sizeof names[0], "%s", rgb);
  np[nch] = names[nch], nch++;
  if (have_se) {
    snprintf(names[nch], sizeof names[0], "%s_stderr", rgb);
    np[nch] = names[nch], nch++;
  }
  if (alpha) {
    snprintf(names[nch], sizeof names[0], "alpha");
    np[nch] = names[nch], nch++;
  }
  code = obs_image_init(out, img->width, img->height, nch, np, err);
  if (code) return code;
  size_t n = (size_t)img->width * (size_t)img->height;
  float *y = obs_image_channel(out, names[0]);
  float *ys = have_se ? obs_image_channel(out, names[1]) : NULL;
  for (size_t i = 0; i < n; i++) {
    y[i] = (float)OBS_LUMINANCE(p[0][i], p[1][i], p[2][i]);
    if (ys) ys[i] = (float)OBS_LUMINANCE(s[0][i], s[1][i], s[2][i]);
  }
  if (alpha) memcpy(obs_image_channel(out, "alpha"), alpha, n * sizeof(float));
  return OBS_OK;
}

/* Sum of squared differences into `acc`, with obs_metrics_rmse's rules for non-finite ones. */
static void metrics_sq(metrics_acc *acc, double a, double b, double weight, int *nan, int *inf) {
  if (a == b) return;
  double d = a - b;
  if (isnan(d))
    *nan = 1;
  else if (isinf(d))
    *inf = 1;
  else
    metrics_add(acc, weight * d * d);
}

static double metrics_root(const metrics_acc *acc, double count, int nan, int inf) {
  if (nan) return NAN;
  if (inf) return INFINITY;
  return count > 0 ? sqrt(metrics_total(acc) / count) : 0.0;
}

int obs_metrics_compare_rgb(const obs_image *candidate, const obs_image *reference,
                            const char *rgb, const char *mask, obs_compare_rgb *out,
                            obs_err *err) {
  if (!candidate || !reference || !candidate->data || !reference->data || !rgb || !out)
    return obs_err_set(err, OBS_EINVAL, "metrics: rgb compare needs two images and an output");
  if (candidate->width != reference->width || candidate->height != reference->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: image sizes differ (%dx%d vs %dx%d)",
                       candidate->width, candidate->height, reference->width, reference->height);
  const float *pa[3], *pb[3], *m = NULL;
  int code = metrics_rgb(candidate, rgb, "candidate", pa, err);
  if (!code) code = metrics_rgb(reference, rgb, "reference", pb, err);
  if (!code && mask && !(m = metrics_find(reference, mask, "reference (mask)", &code, err)))
    return code;
  if (code) return code;
  obs_compare_rgb r;
  memset(&r, 0, sizeof r);
  metrics_acc ch[3] = {{0, 0}, {0, 0}, {0, 0}}, lum = {0, 0}, rel = {0, 0};
  int nan = 0, inf = 0, rel_nan = 0, rel_inf = 0;
  size_t used = 0, n = (size_t)candidate->width * (size_t)candidate->height;
  for (size_t i = 0; i < n; i++) {
    if (m && !(m[i] > 0.0f)) continue;
    used++;
    for (int c = 0; c < 3; c++) {
      metrics_sq(&ch[c], pa[c][i], pb[c][i], 1.0, &nan, &inf);
      double rr = pb[c][i];
      metrics_sq(&rel, pa[c][i], pb[c][i], 1.0 / (rr * rr + OBS_METRICS_RELMSE_EPS), &rel_nan,
                 &rel_inf);
    }
    double ya = OBS_LUMINANCE(pa[0][i], pa[1][i], pa[2][i]);
    double yb = OBS_LUMINANCE(pb[0][i], pb[1][i], pb[2][i]);
    metrics_sq(&lum, ya, yb, 1.0, &nan, &inf);
  }
  r.pixels = (int64_t)used;
  for (int c = 0; c < 3; c++) r.rmse[c] = metrics_root(&ch[c], (double)used, nan, inf);
  r.rmse_luminance = metrics_root(&lum, (double)used, nan, inf);
  r.rel_mse = rel_nan ? NAN : rel_inf ? INFINITY
                                      : used ? metrics_total(&rel) / (3.0 * (double)used) : 0.0;
  /* SSIM on the luminance images, with the reference's mask copied beside it. */
  obs_image la, lb;
  code = obs_metrics_luminance_image(candidate, rgb, NULL, &la, err);
  if (!code) code = obs_metrics_luminance_image(reference, rgb, NULL, &lb, err);
  else memset(&lb, 0, sizeof lb);
  if (!code) {
    if (mask && !obs_image_channel(&lb, mask)) /* a mask other than alpha: use its plane */
      code = obs_err_set(err, OBS_EINVAL, "metrics: rgb compare supports only \"alpha\" masks");
    else
      code = obs_metrics_ssim(&la, &lb, rgb, mask, &r.ssim_luminance, err);
  }
  obs_image_free(&la);
  obs_image_free(&lb);
  if (!code) *out = r;
  return code;
}

void obs_metrics_patch_stats(const obs_patches *p, obs_stats *out) {
  size_t n = p && p->values ? obs_patches_values(p) : 0;
  *out = stats_of(n ? p->values : NULL, NULL, n);
}

int obs_metrics_patch_rmse(const obs_patches *candidate, const obs_patches *reference,
                           double *rmse, obs_err *err) {
  if (!candidate || !reference || !candidate->values || !reference->values || !rmse)
    return obs_err_set(err, OBS_EINVAL, "metrics: patch rmse needs two patch sets and an output");
  int cf = candidate->frames > 1 ? candidate->frames : 1;
  int rf = reference->frames > 1 ? reference->frames : 1;
  if (candidate->count != reference->count || candidate->components != reference->components ||
      cf != rf)
    return obs_err_set(err, OBS_EINVAL,
                       "metrics: patch sets differ (%d x %lld x %d vs %d x %lld x %d values)", cf,
                       (long long)candidate->count, candidate->components, rf,
                       (long long)reference->count, reference->components);
  const float *area = reference->area ? reference->area : candidate->area;
  metrics_acc acc = {0, 0}, total = {0, 0};
  int nan = 0, inf = 0, k = reference->components;
  /* Every frame counts alike: the patches' areas are frame 0's in all of them. */
  for (int f = 0; f < rf; f++)
    for (int64_t i = 0; i < reference->count; i++) {
      double a = area ? area[i] : 1.0;
      if (!(a > 0.0)) continue;
      metrics_add(&total, a);
      for (int c = 0; c < k; c++) {
        size_t j = ((size_t)f * (size_t)reference->count + (size_t)i) * (size_t)k + (size_t)c;
        metrics_sq(&acc, candidate->values[j], reference->values[j], a, &nan, &inf);
      }
    }
  *rmse = metrics_root(&acc, metrics_total(&total) * k, nan, inf);
  return OBS_OK;
}
