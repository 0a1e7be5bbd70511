/* What the RGB benchmarks measure against a reference render: the luminance RMSE over the pixels
 * both renders cover, and the reference's own noise there. */
#ifndef OBS_BENCH_RADIANCE_H
#define OBS_BENCH_RADIANCE_H

#include <math.h>
#include <stddef.h>

#include "obscura/obscura.h"

/* Rec. 709 luminance of pixel i's radiance. */
static inline double bench_radiance_lum(const obs_image *img, size_t i) {
  return 0.2126 * obs_image_channel(img, "radiance.R")[i] +
         0.7152 * obs_image_channel(img, "radiance.G")[i] +
         0.0722 * obs_image_channel(img, "radiance.B")[i];
}

/* Luminance RMSE of `a` against the reference over the pixels both cover, and the reference's own
 * noise there (the RMS of its luminance standard error) into *noise. */
static inline double bench_radiance_rmse(const obs_image *a, const obs_image *ref, double *noise) {
  size_t n = (size_t)a->width * (size_t)a->height, cnt = 0;
  const float *aa = obs_image_channel(a, "alpha"), *ra = obs_image_channel(ref, "alpha");
  const float *se[3] = {obs_image_channel(ref, "radiance_stderr.R"),
                        obs_image_channel(ref, "radiance_stderr.G"),
                        obs_image_channel(ref, "radiance_stderr.B")};
  double ss = 0, nn = 0;
  for (size_t i = 0; i < n; i++) {
    if (!(aa[i] > 0) || !(ra[i] > 0)) continue;
    double d = bench_radiance_lum(a, i) - bench_radiance_lum(ref, i);
    double s = 0.2126 * se[0][i] + 0.7152 * se[1][i] + 0.0722 * se[2][i];
    ss += d * d, nn += s * s, cnt++;
  }
  *noise = cnt ? sqrt(nn / (double)cnt) : 0;
  return cnt ? sqrt(ss / (double)cnt) : 0;
}

#endif
