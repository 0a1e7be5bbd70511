/* Image statistics and error metrics between two images' channels. */
#ifndef OBSCURA_METRICS_H
#define OBSCURA_METRICS_H

#include <stdint.h>
#include "obscura/image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct obs_stats {
  double mean, min, max;   /* over finite values only; 0 when there are none */
  int64_t count;           /* finite values counted */
  int64_t nan_count;       /* NaN values */
  int64_t inf_count;       /* +-Inf values */
} obs_stats;

/* Statistics of one channel. `mask` (may be NULL) names a channel whose value > 0 selects the
 * pixels counted (e.g. "alpha" for covered pixels). */
int obs_metrics_stats(const obs_image *img, const char *channel, const char *mask, obs_stats *out,
                      obs_err *err);

/* Root-mean-square error of channel `channel` between a and b (same size), over pixels where `mask`
 * (channel of b, may be NULL) is > 0. */
int obs_metrics_rmse(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *rmse, obs_err *err);

/* Mean structural similarity of channel `channel` (values in [0,1]) between a and b: 8x8 windows at
 * every position, Gaussian-weighted (sigma 1.5), C1 = 0.01^2, C2 = 0.03^2. With `mask` (channel of
 * b, may be NULL) only windows whose pixel (x+4, y+4) is selected count. Images smaller than 8
 * pixels in a dimension use one window of that size. 1 means identical. */
int obs_metrics_ssim(const obs_image *a, const obs_image *b, const char *channel, const char *mask,
                     double *ssim, obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
