/* What the RGB benchmarks share: the pictures they write for the docs (a render's radiance,
 * scaled by 2^exposure, as an sRGB PNG) and their error against a reference render (the
 * luminance RMSE over the pixels both cover, beside the reference's own noise). */
#ifndef OBS_BENCH_PNG_H
#define OBS_BENCH_PNG_H

#include <math.h>
#include <stdio.h>

#include "obscura/obscura.h"

/* Writes img's radiance.R/G/B times 2^exposure to `path`; `prog` prefixes the message of a
 * failure. Returns 0 or the error code. */
static inline int bench_write_radiance_png(const obs_image *img, double exposure,
                                           const char *path, const char *prog) {
  static const char *const rgb[3] = {"radiance.R", "radiance.G", "radiance.B"};
  static const char *const out_names[3] = {"R", "G", "B"};
  obs_image t;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_image_init(&t, img->width, img->height, 3, out_names, &err);
  size_t n = (size_t)img->width * (size_t)img->height;
  double scale = pow(2.0, exposure);
  for (int k = 0; !rc && k < 3; k++) {
    const float *v = obs_image_channel(img, rgb[k]);
    for (size_t i = 0; i < n; i++) t.data[(size_t)k * n + i] = (float)(v[i] * scale);
  }
  if (!rc) rc = obs_image_write_png(&t, out_names, 3, 1, path, &err);
  if (rc) fprintf(stderr, "%s: %s\n", prog, obs_err_message(&err));
  obs_image_free(&t);
  obs_err_free(&err);
  return rc;
}

static inline double bench_lum(const obs_image *img, size_t i) {
  return 0.2126 * obs_image_channel(img, "radiance.R")[i] +
         0.7152 * obs_image_channel(img, "radiance.G")[i] +
         0.0722 * obs_image_channel(img, "radiance.B")[i];
}

/* Luminance RMSE of `a` against the reference `ref` (path_trace, or sss_single trace) over the pixels both
 * cover, and the reference's own noise there (the RMS of its luminance standard error). */
static inline double bench_lum_rmse(const obs_image *a, const obs_image *ref, double *noise) {
  size_t n = (size_t)a->width * (size_t)a->height, cnt = 0;
  const float *aa = obs_image_channel(a, "alpha"), *ra = obs_image_channel(ref, "alpha");
  const float *se[3] = {obs_image_channel(ref, "radiance_stderr.R"),
                        obs_image_channel(ref, "radiance_stderr.G"),
                        obs_image_channel(ref, "radiance_stderr.B")};
  double ss = 0, nn = 0;
  for (size_t i = 0; i < n; i++) {
    if (!(aa[i] > 0) || !(ra[i] > 0)) continue;
    double d = bench_lum(a, i) - bench_lum(ref, i);
    double s = 0.2126 * se[0][i] + 0.7152 * se[1][i] + 0.0722 * se[2][i];
    ss += d * d, nn += s * s, cnt++;
  }
  *noise = cnt ? sqrt(nn / (double)cnt) : 0;
  return cnt ? sqrt(ss / (double)cnt) : 0;
}

#endif
