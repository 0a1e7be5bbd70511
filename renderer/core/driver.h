/* The shared drivers of techniques: the per-pixel driver, which owns the image, the tiles over
 * the context's region, progress, cancellation, rays and render time of every per-pixel CPU
 * technique (a technique supplies one shade function), and the hook through which a backend
 * builds what a technique's `needs` asks before its run. Owned by core; backends plug in. */
#ifndef OBS_DRIVER_H
#define OBS_DRIVER_H

#include <stdint.h>

#include "obscura/error.h"
#include "obscura/image.h"
#include "obscura/technique.h"

/* One pixel of a per-pixel technique: writes ops->nchannels values (channel order of
 * ops->channels) for pixel (x, y) and returns the rays it traced. `thread` < ctx->threads. */
typedef uint64_t (*obs_shade_fn)(const void *job, int thread, int x, int y, float *values);

/* The pixels of a block, for techniques whose pixels are cheaper together (camera rays traced as
 * one packet): blocks are the cells of an OBS_PIXEL_BLOCK x OBS_PIXEL_BLOCK grid on the image
 * (corners at multiples of it), cut to the tile being shaded, so a block is [x0, x1) x [y0, y1)
 * inside one cell. Writes ops->nchannels planes of the block's n = (x1 - x0) (y1 - y0) pixels in
 * row order (channel c of pixel (x, y) at values[c n + (y - y0) (x1 - x0) + (x - x0)]) and
 * returns the rays traced for those pixels. A pixel's values may depend on its cell (the same
 * whatever the tile) but not on which part of it is shaded. */
enum { OBS_PIXEL_BLOCK = 4 };
typedef uint64_t (*obs_shade_block_fn)(const void *job, int thread, int x0, int y0, int x1, int y1,
                                       float *values);

/* The pooled prior of a technique's standard-error channels (driver_prior.c; docs/accuracy.md,
 * "Standard errors"). A pixel's own variance estimate rests on few degrees of freedom and cannot
 * see events rarer than its samples (a path tracer's rare bright paths): where they were missed,
 * the mean and its spread are both low, and the error is far outside 3 standard errors. So before
 * the tiles, the driver shades a pilot pixel at the centre of every OBS_PRIOR_CELL-pixel cell
 * OBS_PRIOR_REPLICAS times, each with a copy of the job whose seed (the uint32_t at `seed_offset`)
 * is that of a replica (sampling.h, obs_sampler_replica_seed), and takes the variance of those
 * independent estimates; p, the mean of the pilot variances of a pixel's cell and the 8 around it
 * (pilots that see no surface left out), is its prior. A pixel's own variance v (the square of its
 * stderr channel) at or above p stands: rare events missed only ever lower it. One below becomes
 * (df v + w p) / (df + w), df its degrees of freedom, w = OBS_PRIOR_WEIGHT. A shade function with a
 * prior writes -f (the sign bit set, f >= 0) into a stderr channel when its samples all agreed:
 * their spread of 0 then counts with no more weight than the prior, w p / (min(df, w) + w), and f
 * is the conservative floor (mcerr.h) it reports where no pilot covers its neighbourhood; +0 marks
 * an exact value, which stays 0. A pilot depends only on its position and the seed: the same bits
 * for any thread count, region or tile source; `rays` counts the pilots whose pixel lies in the
 * region (with a tile source: in the tiles shaded), so split renders add up to the whole. */
typedef struct obs_pixel_prior {
  int nse;                      /* standard-error channels */
  const int *se, *value;        /* their indices, and those of the channels they are the error of */
  int alpha;                    /* coverage: pilots where it is 0 in any replica are left out */
  size_t job_size, seed_offset; /* the job's size, and where its seed lies in it */
  /* The degrees of freedom of a pixel's own variance estimate in standard-error channel c. */
  double (*df)(const void *job, int c);
} obs_pixel_prior;
#define OBS_PRIOR_CELL 8
#define OBS_PRIOR_REPLICAS 8
#define OBS_PRIOR_WEIGHT 8.0

typedef struct obs_pixel_ops {
  int nchannels;
  const char *const *channels; /* EXR channel names of `out` */
  obs_shade_fn shade;           /* NULL when block is set */
  obs_shade_block_fn block;     /* NULL: shade, one pixel at a time */
  const obs_pixel_prior *prior; /* NULL: the stderr channels are the pixel's own; needs shade */
} obs_pixel_ops;

/* Allocates `out`, runs shade (or block) over ctx's region in tiles on ctx->threads threads with
 * progress and cancellation, adds ctx->rays and sets ctx->render_ms (stage "shade"; with a prior,
 * its pilot first, stage "prior"). Bit-identical for any thread count.
 * Pixels outside the region stay 0. With ctx->tiles it shades only the tiles that source hands
 * out, calls its `done` after each, reports no progress and sets ctx->tiled; the pixels it shades
 * are the same bits either way. On failure (OBS_ECANCELED when ctx->cancel was raised; the
 * source's code, or OBS_EINVAL for a tile outside the region) `out` is released and nothing stays
 * allocated. */
int obs_driver_pixels(obs_render_ctx *ctx, const obs_pixel_ops *ops, const void *job,
                      obs_image *out, obs_err *err);

/* ctx's region clamped to a width x height image (all zero: the whole image). OBS_EINVAL when
 * the region is empty or not inside the image. */
int obs_driver_region(const obs_render_ctx *ctx, int width, int height, obs_region *out,
                      obs_err *err);
/* The region to render (obs_driver_region) and `out` allocated at the scene's full size with
 * `names`; on failure `out` is left empty. */
int obs_driver_image(const obs_render_ctx *ctx, int nchannels, const char *const *names,
                     obs_image *out, obs_region *region, obs_err *err);
/* Sets every channel of the pixels of `img` outside `r` to 0 (drivers whose passes run on the
 * whole image, the screen-space ones, honour a region this way). */
void obs_driver_clear_outside(obs_image *img, const obs_region *r);
/* Adds `ms` to stage `name` of ctx, appending it when new (obs_render_ctx_stage appends). */
void obs_driver_stage_add(obs_render_ctx *ctx, const char *name, double ms);
/* OBS_ECANCELED with "<scene>: render cancelled" when ctx->cancel is raised, else 0. */
int obs_driver_cancelled(const obs_render_ctx *ctx, obs_err *err);

/* What a backend builds for a technique's `needs` before its run function is called (timed as
 * the render's build): `build` fills ctx (e.g. ctx->rt) and *state, which `release` frees after
 * the run, whatever the run returned. */
typedef struct obs_needs_builder {
  int (*build)(obs_render_ctx *ctx, unsigned needs, void **state, obs_err *err);
  void (*release)(void *state);
} obs_needs_builder;

#endif
