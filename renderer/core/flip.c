/* FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020) and
 * HDR-FLIP (Andersson et al., "Visualizing Errors in Rendered High Dynamic Range Images", EG 2021):
 * the per-pixel perceived difference between a test image and a reference, its mean, and the
 * magma-coloured picture of it. Written from the papers and the reference implementation's
 * documentation; docs/metrics.md states every step. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/metrics.h"
#include "metrics_internal.h"

/* ---- colour spaces (D65 white; sRGB primaries) ---------------------------------------------- */

static const double k_white[3] = {0.950428545, 1.000000000, 1.088900371};

static double srgb_decode(double v) {
  return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static void rgb_to_xyz(const double c[3], double o[3]) {
  o[0] = (10135552.0 * c[0] + 8788810.0 * c[1] + 4435075.0 * c[2]) / 24577794.0;
  o[1] = (2613072.0 * c[0] + 8788810.0 * c[1] + 887015.0 * c[2]) / 12288897.0;
  o[2] = (1425312.0 * c[0] + 8788810.0 * c[1] + 70074185.0 * c[2]) / 73733382.0;
}

/* The exact inverse of rgb_to_xyz's matrix (to the digits given). */
static void xyz_to_rgb(const double x[3], double o[3]) {
  o[0] = 3.241003275 * x[0] - 1.537398934 * x[1] - 0.498615861 * x[2];
  o[1] = -0.969224334 * x[0] + 1.875930071 * x[1] + 0.041554224 * x[2];
  o[2] = 0.055639423 * x[0] - 0.204011202 * x[1] + 1.057148933 * x[2];
}

/* YCxCz: the linear opponent space the contrast sensitivity filters work in. */
static void xyz_to_ycxcz(const double x[3], double o[3]) {
  double r = x[0] / k_white[0], g = x[1] / k_white[1], b = x[2] / k_white[2];
  o[0] = 116.0 * g - 16.0;
  o[1] = 500.0 * (r - g);
  o[2] = 200.0 * (g - b);
}

static void ycxcz_to_xyz(const double y[3], double o[3]) {
  double g = (y[0] + 16.0) / 116.0;
  o[0] = (g + y[1] / 500.0) * k_white[0];
  o[1] = g * k_white[1];
  o[2] = (g - y[2] / 200.0) * k_white[2];
}

static double lab_f(double t) {
  const double d = 6.0 / 29.0;
  return t > d * d * d ? cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

/* CIE L*a*b* with the Hunt adjustment (a*, b* scaled by 0.01 L*: colours look less saturated in
 * the dark). */
static void rgb_to_hunt_lab(const double c[3], double o[3]) {
  double x[3];
  rgb_to_xyz(c, x);
  double fx = lab_f(x[0] / k_white[0]), fy = lab_f(x[1] / k_white[1]),
         fz = lab_f(x[2] / k_white[2]);
  double l = 116.0 * fy - 16.0;
  o[0] = l;
  o[1] = 0.01 * l * 500.0 * (fx - fy);
  o[2] = 0.01 * l * 200.0 * (fy - fz);
}

/* HyAB distance: |dL| + the Euclidean distance in (a, b). */
static double hyab(const double p[3], const double q[3]) {
  return fabs(p[0] - q[0]) + hypot(p[1] - q[1], p[2] - q[2]);
}

/* ---- the LDR-FLIP constants ----------------------------------------------------------------- */

#define FLIP_QC 0.7
#define FLIP_QF 0.5
#define FLIP_PC 0.4
#define FLIP_PT 0.95
#define FLIP_EDGE_W 0.082 /* peak-to-trough width of the human edge detector, degrees */

/* The largest colour difference: Hunt-adjusted green against blue, raised to qc. */
static double flip_cmax(void) {
  const double green[3] = {0, 1, 0}, blue[3] = {0, 0, 1};
  double g[3], b[3];
  rgb_to_hunt_lab(green, g);
  rgb_to_hunt_lab(blue, b);
  return pow(hyab(g, b), FLIP_QC);
}

/* Maps a colour error raised to qc to [0, 1]: [0, pc cmax) linearly onto [0, pt), the rest onto
 * [pt, 1]. */
static double flip_redistribute(double e, double cmax) {
  double pccmax = FLIP_PC * cmax;
  return e < pccmax ? FLIP_PT / pccmax * e
                    : FLIP_PT + (e - pccmax) / (cmax - pccmax) * (1.0 - FLIP_PT);
}

/* ---- separable filters with replicated borders ---------------------------------------------- */

typedef struct flip_kernel {
  int r;      /* taps -r..r */
  double *k;  /* 2r + 1 weights */
} flip_kernel;

static void flip_pass(const float *in, float *out, int n, size_t st, const flip_kernel *k) {
  for (int i = 0; i < n; i++) {
    double s = 0;
    for (int t = -k->r; t <= k->r; t++) {
      int j = i + t;
      j = j < 0 ? 0 : j >= n ? n - 1 : j;
      s += k->k[t + k->r] * in[(size_t)j * st];
    }
    out[(size_t)i * st] = (float)s;
  }
}

/* out = (kx along rows, then ky along columns) applied to in; tmp has w*h floats. */
static void flip_filter(const float *in, float *out, float *tmp, int w, int h,
                        const flip_kernel *kx, const flip_kernel *ky) {
  for (int y = 0; y < h; y++) flip_pass(in + (size_t)y * w, tmp + (size_t)y * w, w, 1, kx);
  for (int x = 0; x < w; x++) flip_pass(tmp + x, out + x, h, (size_t)w, ky);
}

/* The filters for one viewing distance. The contrast sensitivity functions are sums of Gaussians
 * a sqrt(pi/b) exp(-pi^2 r^2 / b) (r in degrees), normalised over the kernel: achromatic (1,
 * 0.0047), red-green (1, 0.0053), blue-yellow (34.1, 0.04) + (13.5, 0.025); each Gaussian term is
 * separable, so a channel is filtered by one or two separable passes. The feature detectors are
 * the first (edges) and second (points) derivative of a Gaussian of standard deviation
 * 0.5 w ppd, positive and negative weights each normalised to sum to +-1: separable too. */
typedef struct flip_filters {
  flip_kernel csf[4];   /* A, RG, BY term 1, BY term 2 (1D, unnormalised) */
  double csf_scale[4];  /* each term's weight over its channel's 2D kernel sum */
  flip_kernel edge, point, gauss; /* 1D: derivative kernels and the normalised Gaussian */
  double store[4 * 64 + 3 * 64];
} flip_filters;

static int flip_filters_init(flip_filters *f, double ppd, obs_err *err) {
  static const double a[4] = {1.0, 1.0, 34.1, 13.5}, b[4] = {0.0047, 0.0053, 0.04, 0.025};
  int r = (int)ceil(3.0 * sqrt(0.04 / (2.0 * M_PI * M_PI)) * ppd);
  double sd = 0.5 * FLIP_EDGE_W * ppd;
  int rf = (int)ceil(3.0 * sd);
  if (r > 31 || rf > 31)
    return obs_err_set(err, OBS_EINVAL, "flip: %g pixels per degree is more than this filter "
                                        "size supports (at most about 200)", ppd);
  double *s = f->store;
  double sums[4];
  for (int t = 0; t < 4; t++, s += 64) {
    f->csf[t].r = r;
    f->csf[t].k = s;
    sums[t] = 0;
    for (int i = -r; i <= r; i++) {
      double d = i / ppd;
      sums[t] += s[i + r] = exp(-M_PI * M_PI * d * d / b[t]);
    }
  }
  /* 2D sum of term t: c_t (sum of its 1D weights)^2, c_t = a sqrt(pi / b). */
  double c[4], tot[3];
  for (int t = 0; t < 4; t++) c[t] = a[t] * sqrt(M_PI / b[t]) * sums[t] * sums[t];
  tot[0] = c[0], tot[1] = c[1], tot[2] = c[2] + c[3];
  for (int t = 0; t < 4; t++)
    f->csf_scale[t] = a[t] * sqrt(M_PI / b[t]) / tot[t < 2 ? t : 2];
  flip_kernel *fk[3] = {&f->edge, &f->point, &f->gauss};
  for (int q = 0; q < 3; q++, s += 64) {
    fk[q]->r = rf;
    fk[q]->k = s;
    double pos = 0, neg = 0;
    for (int i = -rf; i <= rf; i++) {
      double g = exp(-(double)(i * i) / (2.0 * sd * sd));
      double v = q == 0 ? -i * g : q == 1 ? ((double)(i * i) / (sd * sd) - 1.0) * g : g;
      s[i + rf] = v;
      if (v > 0) pos += v; else neg -= v;
    }
    for (int i = 0; i <= 2 * rf; i++) s[i] = s[i] > 0 ? s[i] / pos : neg > 0 ? s[i] / neg : 0;
  }
  return OBS_OK;
}

/* ---- LDR-FLIP ------------------------------------------------------------------------------- */

/* One image's preprocessed planes: Hunt-adjusted L*a*b* after the CSFs, and the edge and point
 * strengths of its achromatic channel. */
typedef struct flip_side {
  float *lab[3], *edge, *point;
} flip_side;

/* lin: linear RGB planes in [0, 1]; buf: 7 w*h planes of scratch. */
static void flip_prepare(float *const lin[3], int w, int h, const flip_filters *f, float *buf,
                         flip_side *out) {
  size_t n = (size_t)w * (size_t)h;
  float *ycc[3] = {buf, buf + n, buf + 2 * n}, *tmp = buf + 3 * n, *acc = buf + 4 * n;
  float *fx = buf + 5 * n, *fy = buf + 6 * n;
  for (size_t i = 0; i < n; i++) {
    double c[3] = {lin[0][i], lin[1][i], lin[2][i]}, x[3], y[3];
    rgb_to_xyz(c, x);
    xyz_to_ycxcz(x, y);
    for (int k = 0; k < 3; k++) ycc[k][i] = (float)y[k];
  }
  /* Features of the achromatic channel, normalised to [0, 1]: (Y + 16) / 116 = Y / Yn. */
  float *ach = acc;
  for (size_t i = 0; i < n; i++) ach[i] = (ycc[0][i] + 16.0f) / 116.0f;
  const flip_kernel *det[2] = {&f->edge, &f->point};
  float *dst[2] = {out->edge, out->point};
  for (int q = 0; q < 2; q++) {
    flip_filter(ach, fx, tmp, w, h, det[q], &f->gauss);
    flip_filter(ach, fy, tmp, w, h, &f->gauss, det[q]);
    for (size_t i = 0; i < n; i++) dst[q][i] = hypotf(fx[i], fy[i]);
  }
  /* Colour: each opponent channel through its CSF (into out->lab as scratch), back to linear RGB,
   * clamped to the unit cube, to Hunt-adjusted L*a*b*. */
  for (int ch = 0; ch < 3; ch++) {
    flip_filter(ycc[ch], out->lab[ch], tmp, w, h, &f->csf[ch], &f->csf[ch]);
    double s0 = f->csf_scale[ch];
    if (ch < 2) {
      for (size_t i = 0; i < n; i++) out->lab[ch][i] = (float)(s0 * out->lab[ch][i]);
    } else {
      flip_filter(ycc[2], acc, tmp, w, h, &f->csf[3], &f->csf[3]);
      for (size_t i = 0; i < n; i++)
        out->lab[2][i] = (float)(s0 * out->lab[2][i] + f->csf_scale[3] * acc[i]);
    }
  }
  for (size_t i = 0; i < n; i++) {
    double y[3] = {out->lab[0][i], out->lab[1][i], out->lab[2][i]}, x[3], c[3], l[3];
    ycxcz_to_xyz(y, x);
    xyz_to_rgb(x, c);
    for (int k = 0; k < 3; k++) c[k] = c[k] < 0 ? 0 : c[k] > 1 ? 1 : c[k];
    rgb_to_hunt_lab(c, l);
    for (int k = 0; k < 3; k++) out->lab[k][i] = (float)l[k];
  }
}

/* err[i] = LDR-FLIP of test against reference (linear RGB planes in [0, 1]); `err` is filled, or
 * max-ed into when `accumulate`. */
static int flip_ldr(float *const test[3], float *const ref[3], int w, int h,
                    const flip_filters *f, float *err_out, int accumulate, obs_err *err) {
  size_t n = (size_t)w * (size_t)h;
  float *mem = malloc(17 * n * sizeof *mem); /* 7 planes of scratch, 5 per image */
  if (!mem) return obs_err_set(err, OBS_ENOMEM, "flip: out of memory (%dx%d)", w, h);
  flip_side s[2];
  for (int k = 0; k < 2; k++) {
    float *b = mem + 7 * n + (size_t)k * 5 * n;
    s[k] = (flip_side){{b, b + n, b + 2 * n}, b + 3 * n, b + 4 * n};
  }
  flip_prepare(ref, w, h, f, mem, &s[0]);
  flip_prepare(test, w, h, f, mem, &s[1]);
  double cmax = flip_cmax();
  for (size_t i = 0; i < n; i++) {
    double p[3] = {s[0].lab[0][i], s[0].lab[1][i], s[0].lab[2][i]};
    double q[3] = {s[1].lab[0][i], s[1].lab[1][i], s[1].lab[2][i]};
    double dc = flip_redistribute(pow(hyab(p, q), FLIP_QC), cmax);
    double df = fmax(fabs((double)s[0].edge[i] - s[1].edge[i]),
                     fabs((double)s[0].point[i] - s[1].point[i]));
    df = pow(df / sqrt(2.0), FLIP_QF);
    float e = (float)pow(dc, 1.0 - df);
    err_out[i] = accumulate && err_out[i] > e ? err_out[i] : e;
  }
  free(mem);
  return OBS_OK;
}

/* ---- HDR-FLIP ------------------------------------------------------------------------------- */

/* The approximation of the ACES filmic curve HDR-FLIP assumes (Narkowicz 2016, with its 0.6
 * pre-exposure folded in): y = (k0 x^2 + k1 x) / (k3 x^2 + k4 x + k5), clamped to [0, 1]. */
static const double k_aces[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0, 0.6 * 0.6 * 2.43, 0.6 * 0.59,
                                 0.14};

static double aces(double x) {
  double y = (k_aces[0] * x * x + k_aces[1] * x + k_aces[2]) /
             (k_aces[3] * x * x + k_aces[4] * x + k_aces[5]);
  return isnan(y) ? 1.0 : y < 0 ? 0 : y > 1 ? 1 : y; /* inf/inf: very bright */
}

/* The x the curve maps to t (0.85 for both ends, as the paper). */
static double aces_inverse(double t) {
  double c0 = (k_aces[1] - k_aces[4] * t) / (k_aces[0] - k_aces[3] * t);
  double c1 = (k_aces[2] - k_aces[5] * t) / (k_aces[0] - k_aces[3] * t);
  return -0.5 * c0 + sqrt(0.25 * c0 * c0 - c1);
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* numpy's percentile 50 (linear interpolation) of the n values of v (sorted in place). */
static double median_of(double *v, size_t n) {
  qsort(v, n, sizeof *v, cmp_double);
  double pos = 0.5 * (double)(n - 1);
  size_t lo = (size_t)pos;
  return lo + 1 < n ? v[lo] + (pos - (double)lo) * (v[lo + 1] - v[lo]) : v[lo];
}

/* Start and stop exposures from the reference's finite luminances: the start maps its maximum,
 * the stop its median, to 0.85 on the tone curve; when the median is 0 (mostly black images) the
 * median of the non-zero luminances stands in, so the longest exposure still shows a typical lit
 * pixel. Returns the number of exposures: max(2, ceil(stop - start)), 1 when they coincide. */
static int hdr_exposures(float *const ref[3], size_t n, double *start, double *step,
                         obs_err *err) {
  double *y = malloc((n ? n : 1) * sizeof *y);
  if (!y) return obs_err_set(err, OBS_ENOMEM, "flip: out of memory");
  size_t m = 0, pos = 0;
  double hi = 0;
  for (size_t i = 0; i < n; i++) {
    double l = OBS_LUMINANCE(fmax(ref[0][i], 0), fmax(ref[1][i], 0), fmax(ref[2][i], 0));
    if (!isfinite(l)) continue;
    y[m++] = l;
    if (l > hi) hi = l;
  }
  double x = aces_inverse(0.85);
  if (!m || hi <= 0) {
    free(y);
    *start = *step = 0;
    return 1;
  }
  double lo = median_of(y, m);
  if (lo <= 0) {
    while (pos < m && y[pos] <= 0) pos++;
    lo = median_of(y + pos, m - pos);
  }
  free(y);
  *start = log2(x / hi);
  double stop = log2(x / lo);
  if (stop <= *start) {
    *step = 0;
    return 1;
  }
  int k = (int)fmax(2.0, ceil(stop - *start));
  *step = (stop - *start) / (k - 1);
  return k;
}

/* ---- the public functions ------------------------------------------------------------------- */

/* Linear RGB planes in [0, 1] (or, for HDR, >= 0) of `channel` of img: a scalar display value
 * becomes grey sRGB, an RGB output's linear values are taken as they are. Non-finite values
 * become 0 (the filters must read numbers) and are flagged in `bad`. */
static int flip_planes(const obs_image *img, const char *channel, int hdr, float *planes,
                       unsigned char *bad, const char *what, obs_err *err) {
  size_t n = (size_t)img->width * (size_t)img->height;
  const float *src[3];
  const float *s = obs_image_channel(img, channel);
  if (s && hdr)
    return obs_err_set(err, OBS_EINVAL,
                       "flip: \"%s\" is a scalar channel: HDR-FLIP needs an RGB output", channel);
  for (int k = 0; k < 3; k++) {
    char name[OBS_CHANNEL_NAME_MAX + 4];
    snprintf(name, sizeof name, "%s.%c", channel, "RGB"[k]);
    src[k] = s ? s : obs_image_channel(img, name);
    if (!src[k])
      return obs_err_set(err, OBS_ENOTFOUND,
                         "flip: the %s image has neither a channel \"%s\" nor \"%s.R/G/B\"", what,
                         channel, channel);
  }
  for (int k = 0; k < 3; k++)
    for (size_t i = 0; i < n; i++) {
      double v = src[k][i];
      if (!isfinite(v)) {
        bad[i] = 1;
        v = 0;
      }
      if (!hdr) v = v < 0 ? 0 : v > 1 ? 1 : v;
      if (s) v = srgb_decode(v); /* the grey the PNG shows: v is the display-encoded value */
      planes[(size_t)k * n + i] = (float)(hdr ? fmax(v, 0) : v);
    }
  return OBS_OK;
}

static int flip_compute(const obs_image *test, const obs_image *ref, const char *channel, int hdr,
                        double ppd, float *e, unsigned char *bad, obs_err *err) {
  int w = ref->width, h = ref->height;
  size_t n = (size_t)w * (size_t)h;
  flip_filters f;
  int rc = flip_filters_init(&f, ppd, err);
  if (rc) return rc;
  /* The inputs' planes, and for HDR-FLIP one exposure's tone-mapped planes. */
  float *mem = malloc((hdr ? 12 : 6) * n * sizeof *mem);
  if (!mem) return obs_err_set(err, OBS_ENOMEM, "flip: out of memory (%dx%d)", w, h);
  float *tp[3] = {mem, mem + n, mem + 2 * n}, *rp[3] = {mem + 3 * n, mem + 4 * n, mem + 5 * n};
  float *tm[3] = {NULL, NULL, NULL}, *rm[3] = {NULL, NULL, NULL};
  for (int k = 0; hdr && k < 3; k++) tm[k] = mem + (6 + k) * n, rm[k] = mem + (9 + k) * n;
  rc = flip_planes(test, channel, hdr, mem, bad, "test", err);
  if (!rc) rc = flip_planes(ref, channel, hdr, mem + 3 * n, bad, "reference", err);
  if (!rc && !hdr) rc = flip_ldr(tp, rp, w, h, &f, e, 0, err);
  double start = 0, step = 0;
  int count = !rc && hdr ? hdr_exposures(rp, n, &start, &step, err) : 0;
  if (count < 0) rc = count;
  for (int x = 0; !rc && x < count; x++) {
    /* Each exposure: scaled by 2^exposure, tone-mapped, compared as LDR (linear in [0, 1]). */
    double scale = exp2(start + x * step);
    for (int k = 0; k < 3; k++)
      for (size_t i = 0; i < n; i++) {
        tm[k][i] = (float)aces(scale * tp[k][i]);
        rm[k][i] = (float)aces(scale * rp[k][i]);
      }
    rc = flip_ldr(tm, rm, w, h, &f, e, x > 0, err);
  }
  free(mem);
  return rc;
}

int obs_metrics_flip_ppd(const obs_image *test, const obs_image *reference, const char *channel,
                         const char *mask, int hdr, double ppd, obs_image *map, double *mean,
                         obs_err *err) {
  if (map) memset(map, 0, sizeof *map);
  if (!test || !reference || !test->data || !reference->data || !channel || !mean)
    return obs_err_set(err, OBS_EINVAL,
                       "flip: needs a test image, a reference, a channel and an output");
  if (!(ppd > 0) || !isfinite(ppd))
    return obs_err_set(err, OBS_EINVAL, "flip: pixels per degree must be > 0 (got %g)", ppd);
  if (test->width != reference->width || test->height != reference->height)
    return obs_err_set(err, OBS_EINVAL, "flip: image sizes differ (%dx%d vs %dx%d)", test->width,
                       test->height, reference->width, reference->height);
  const float *m = NULL;
  if (mask && !(m = obs_image_channel(reference, mask)))
    return obs_err_set(err, OBS_ENOTFOUND, "flip: the reference has no mask channel \"%s\"", mask);
  size_t n = (size_t)reference->width * (size_t)reference->height;
  float *e = malloc(n * sizeof *e);
  unsigned char *bad = calloc(n, 1);
  int rc = e && bad ? OBS_OK : obs_err_set(err, OBS_ENOMEM, "flip: out of memory");
  if (!rc) rc = flip_compute(test, reference, channel, hdr, ppd, e, bad, err);
  if (!rc) {
    double s = 0, c = 0;
    size_t used = 0;
    for (size_t i = 0; i < n; i++) {
      if (bad[i]) e[i] = NAN;
      if (m && !(m[i] > 0.0f)) continue;
      /* Kahan: a mean of up to millions of values in [0, 1]. */
      double y = (double)e[i] - c, t = s + y;
      c = (t - s) - y;
      s = t;
      used++;
    }
    *mean = used ? s / (double)used : 0.0;
  }
  if (!rc && map) {
    static const char *const names[] = {"flip"};
    rc = obs_image_init(map, reference->width, reference->height, 1, names, err);
    if (!rc) memcpy(map->data, e, n * sizeof *e);
  }
  free(e);
  free(bad);
  return rc;
}

int obs_metrics_flip(const obs_image *test, const obs_image *reference, const char *channel,
                     const char *mask, int hdr, obs_image *map, double *mean, obs_err *err) {
  return obs_metrics_flip_ppd(test, reference, channel, mask, hdr, OBS_FLIP_DEFAULT_PPD, map,
                              mean, err);
}

/* ---- the map's files ------------------------------------------------------------------------ */

/* matplotlib's magma at every 15th of its 256 entries (display-encoded): FLIP's own display of
 * its error, dark for none, light yellow for the largest. */
static const float k_magma[18][3] = {
    {0.001462f, 0.000466f, 0.013866f}, {0.035520f, 0.028397f, 0.125209f},
    {0.102815f, 0.063010f, 0.257854f}, {0.191460f, 0.064818f, 0.396152f},
    {0.291366f, 0.064553f, 0.475462f}, {0.384299f, 0.097855f, 0.501002f},
    {0.475780f, 0.134577f, 0.507921f}, {0.569172f, 0.167454f, 0.504105f},
    {0.664915f, 0.198075f, 0.488836f}, {0.761077f, 0.231214f, 0.460162f},
    {0.852126f, 0.276106f, 0.418573f}, {0.925937f, 0.346844f, 0.374959f},
    {0.969680f, 0.446936f, 0.360311f}, {0.989363f, 0.557873f, 0.391671f},
    {0.996580f, 0.668256f, 0.456192f}, {0.996727f, 0.776795f, 0.541039f},
    {0.992440f, 0.884330f, 0.640099f}, {0.987053f, 0.991438f, 0.749504f}};

int obs_metrics_write_flip_files(const obs_image *map, const char *dir, obs_err *err) {
  const float *e = map ? obs_image_channel(map, "flip") : NULL;
  if (!e || !dir)
    return obs_err_set(err, OBS_EINVAL, "flip: writing the map needs a map with a \"flip\" "
                                        "channel and a directory");
  static const char *const names[] = {"R", "G", "B"};
  obs_image rgb;
  int rc = obs_image_init(&rgb, map->width, map->height, 3, names, err);
  if (rc) return rc;
  size_t n = (size_t)map->width * (size_t)map->height;
  for (size_t i = 0; i < n; i++) {
    double t = e[i];
    for (int k = 0; k < 3; k++) {
      if (isnan(t)) { /* off the ramp, like the error image's NaN green */
        rgb.data[(size_t)k * n + i] = k == 1 ? 1.0f : 0.0f;
        continue;
      }
      double u = (t < 0 ? 0 : t > 1 ? 1 : t) * 17.0;
      int a = u >= 17.0 ? 16 : (int)u;
      double f = u - a;
      rgb.data[(size_t)k * n + i] = (float)((1 - f) * k_magma[a][k] + f * k_magma[a + 1][k]);
    }
  }
  rc = obs_metrics_write_map_files(map, "flip", &rgb, dir, "flip", err);
  obs_image_free(&rgb);
  return rc;
}
