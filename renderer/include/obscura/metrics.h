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

#ifdef __cplusplus
}
#endif
#endif
