/* What the metrics' source files share and nothing else may call. */
#ifndef OBSCURA_METRICS_INTERNAL_H
#define OBSCURA_METRICS_INTERNAL_H

#include "obscura/image.h"

/* Writes `dir`/`base`.exr (channel `channel` of img only, float) and `dir`/`base`.png (8-bit RGB
 * from rgb's "R","G","B", display values), creating `dir` when missing; both under staging names,
 * renamed into place only when both succeeded. */
int obs_metrics_write_map_files(const obs_image *img, const char *channel, const obs_image *rgb,
                                const char *dir, const char *base, obs_err *err);

#endif
