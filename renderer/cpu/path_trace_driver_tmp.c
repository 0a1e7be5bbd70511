/* Stand-in for the shared per-pixel driver (renderer/core/driver.c): the whole image in tiles
 * through obs_parallel_tiles, with the driver's signature; dropped when the real one exists. */
#include <stdatomic.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "path_trace_driver_tmp.h"

typedef struct tile_job {
  const obs_pixel_ops *ops;
  const void *job;
  obs_image *out;
  _Atomic uint64_t rays;
} tile_job;

static int shade_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  tile_job *tj = user;
  obs_image *img = tj->out;
  size_t plane = (size_t)img->width * (size_t)img->height;
  float values[OBS_IMAGE_MAX_CHANNELS];
  uint64_t rays = 0;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      rays += tj->ops->shade(tj->job, thread, x, y, values);
      size_t i = (size_t)y * (size_t)img->width + (size_t)x;
      for (int c = 0; c < tj->ops->nchannels; c++) img->data[(size_t)c * plane + i] = values[c];
    }
  atomic_fetch_add(&tj->rays, rays);
  return 0;
}

int obs_driver_pixels(obs_render_ctx *ctx, const obs_pixel_ops *ops, const void *job,
                      obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (ops->nchannels > OBS_IMAGE_MAX_CHANNELS)
    return obs_err_set(err, OBS_EINTERNAL, "%s: %d channels, at most %d", sc->name, ops->nchannels,
                       OBS_IMAGE_MAX_CHANNELS);
  int rc = obs_image_init(out, sc->width, sc->height, ops->nchannels, ops->channels, err);
  if (rc) return rc;
  tile_job tj = {.ops = ops, .job = job, .out = out};
  atomic_init(&tj.rays, 0);
  double t0 = obs_now_ms();
  rc = obs_parallel_tiles(sc->width, sc->height, ctx->threads, shade_tile, &tj, ctx->cancel,
                          ctx->progress, ctx->progress_user);
  ctx->render_ms = obs_now_ms() - t0;
  ctx->rays += atomic_load(&tj.rays);
  if (rc) {
    obs_image_free(out);
    return rc == OBS_ECANCELED ? obs_err_set(err, rc, "%s: render cancelled", sc->name)
                               : obs_err_set(err, rc, "%s: render failed", sc->name);
  }
  return 0;
}
