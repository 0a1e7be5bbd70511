/* Stand-in for the shared per-pixel driver (renderer/core/driver.h): the same declarations, so
 * path_trace codes against the driver's API before the real one exists; dropped when it does. */
#ifndef OBS_PATH_TRACE_DRIVER_TMP_H
#define OBS_PATH_TRACE_DRIVER_TMP_H

#include <stdint.h>

#include "obscura/technique.h"

/* One pixel of a per-pixel technique: writes ops->nchannels values (channel order of
 * ops->channels) for pixel (x, y) and returns the rays it traced. `thread` < ctx->threads. */
typedef uint64_t (*obs_shade_fn)(const void *job, int thread, int x, int y, float *values);
typedef struct obs_pixel_ops {
  int nchannels;
  const char *const *channels; /* EXR channel names of `out` */
  obs_shade_fn shade;
} obs_pixel_ops;
/* Allocates `out`, runs shade over ctx's region in tiles on ctx->threads threads with progress
 * and cancellation, adds ctx->rays and sets ctx->render_ms. Bit-identical for any thread count. */
int obs_driver_pixels(obs_render_ctx *ctx, const obs_pixel_ops *ops, const void *job,
                      obs_image *out, obs_err *err);

#endif
