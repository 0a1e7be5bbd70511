/* The pictures the RGB benchmarks write for the docs: a render's radiance, scaled by 2^exposure,
 * as an sRGB PNG. */
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

#endif
