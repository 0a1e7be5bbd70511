/* The per-pixel driver and the helpers every driver shares (regions, stages, cancellation). A
 * pixel's values depend only on the shade function and (x, y), never on the tile or thread that
 * computed it, so any thread count and any region give the same bits per pixel. */
#include "driver.h"

#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "driver_prior.h"
#include "parallel.h"

/* Per-thread slots sit a cache line apart so the counters of two threads never share one. */
#define SLOT 8

typedef struct pixel_run {
  const obs_pixel_ops *ops;
  const void *job;
  obs_image *img;
  obs_region r;
  float *values;   /* threads x SLOT-rounded nchannels (a block's pixels' with ops->block) */
  size_t stride;   /* floats per thread in values */
  uint64_t *rays;  /* threads x SLOT */
  const obs_tile_source *src; /* NULL: the driver's own tiles over r */
  atomic_int bad;  /* the source gave a tile outside r (bad_tile holds the first) */
  obs_region bad_tile;
  const obs_prior_grid *prior; /* NULL: none */
  const obs_tile_watch *watch;  /* NULL: none */
} pixel_run;

/* Tells the watcher that tile [x0, x1) x [y0, y1) of the region is final. */
static void tile_watched(const pixel_run *pr, int x0, int y0, int x1, int y1) {
  if (!pr->watch || !pr->watch->tile) return;
  obs_region t = {x0 + pr->r.x0, y0 + pr->r.y0, x1 + pr->r.x0, y1 + pr->r.y0};
  pr->watch->tile(pr->watch->user, pr->img, &t);
}

/* Shades the image's pixels [x0, x1) x [y0, y1) block by block (obs_shade_block_fn). */
static uint64_t shade_blocks(pixel_run *pr, int thread, int x0, int y0, int x1, int y1) {
  obs_image *img = pr->img;
  const size_t plane = (size_t)img->width * (size_t)img->height;
  const int nch = pr->ops->nchannels, B = OBS_PIXEL_BLOCK;
  float *v = pr->values + (size_t)thread * pr->stride;
  uint64_t rays = 0;
  for (int by = y0; by < y1; by = (by / B + 1) * B)
    for (int bx = x0; bx < x1; bx = (bx / B + 1) * B) {
      int ex = (bx / B + 1) * B, ey = (by / B + 1) * B;
      if (ex > x1) ex = x1;
      if (ey > y1) ey = y1;
      rays += pr->ops->block(pr->job, thread, bx, by, ex, ey, v);
      const int w = ex - bx, n = w * (ey - by);
      for (int c = 0; c < nch; c++)
        for (int y = by; y < ey; y++) {
          float *to = img->data + (size_t)c * plane + (size_t)y * (size_t)img->width + (size_t)bx;
          const float *from = v + (size_t)c * (size_t)n + (size_t)(y - by) * (size_t)w;
          for (int x = 0; x < w; x++) to[x] = from[x];
        }
    }
  return rays;
}

/* Shades [x0, x1) x [y0, y1) of the region (relative to its corner); returns the rays traced. */
static uint64_t shade_tile(pixel_run *pr, int thread, int x0, int y0, int x1, int y1) {
  if (pr->ops->block)
    return shade_blocks(pr, thread, x0 + pr->r.x0, y0 + pr->r.y0, x1 + pr->r.x0, y1 + pr->r.y0);
  obs_image *img = pr->img;
  const size_t plane = (size_t)img->width * (size_t)img->height;
  const int nch = pr->ops->nchannels;
  float *v = pr->values + (size_t)thread * pr->stride;
  uint64_t rays = 0;
  for (int y = y0 + pr->r.y0; y < y1 + pr->r.y0; y++)
    for (int x = x0 + pr->r.x0; x < x1 + pr->r.x0; x++) {
      rays += pr->ops->shade(pr->job, thread, x, y, v);
      if (pr->prior) obs_prior_grid_apply(pr->prior, pr->ops->prior, pr->job, x, y, v);
      size_t i = (size_t)y * (size_t)img->width + (size_t)x;
      for (int c = 0; c < nch; c++) img->data[(size_t)c * plane + i] = v[c];
    }
  return rays;
}

static int pixel_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  pixel_run *pr = user;
  pr->rays[(size_t)thread * SLOT] += shade_tile(pr, thread, x0, y0, x1, y1);
  tile_watched(pr, x0, y0, x1, y1);
  return 0;
}

/* The source's next tile, checked against the region and made relative to its corner. */
static int source_next(void *user, int *x0, int *y0, int *x1, int *y1) {
  pixel_run *pr = user;
  obs_region t;
  int rc = pr->src->next(pr->src->user, &t);
  if (rc <= 0) return rc;
  if (t.x0 < pr->r.x0 || t.y0 < pr->r.y0 || t.x1 > pr->r.x1 || t.y1 > pr->r.y1 || t.x0 >= t.x1 ||
      t.y0 >= t.y1) {
    int expected = 0;
    if (atomic_compare_exchange_strong(&pr->bad, &expected, 1)) pr->bad_tile = t;
    return OBS_EINVAL;
  }
  *x0 = t.x0 - pr->r.x0, *y0 = t.y0 - pr->r.y0, *x1 = t.x1 - pr->r.x0, *y1 = t.y1 - pr->r.y0;
  return 1;
}

static int source_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  pixel_run *pr = user;
  uint64_t rays = shade_tile(pr, thread, x0, y0, x1, y1);
  obs_region t = {x0 + pr->r.x0, y0 + pr->r.y0, x1 + pr->r.x0, y1 + pr->r.y0};
  if (pr->prior) rays += obs_prior_grid_rays(pr->prior, &t, pr->img->width, pr->img->height);
  pr->rays[(size_t)thread * SLOT] += rays;
  tile_watched(pr, x0, y0, x1, y1);
  return pr->src->done ? pr->src->done(pr->src->user, pr->img, &t, rays) : 0;
}

/* Why the tile loop stopped, in the driver's words. */
static int loop_failed(const pixel_run *pr, const char *name, int rc, obs_err *err) {
  if (rc == OBS_ECANCELED) return obs_err_set(err, rc, "%s: render cancelled", name);
  if (atomic_load(&pr->bad)) {
    const obs_region *t = &pr->bad_tile;
    return obs_err_set(err, rc,
                       "%s: the tile source gave tile [%d,%d)x[%d,%d), empty or outside the "
                       "region [%d,%d)x[%d,%d)",
                       name, t->x0, t->x1, t->y0, t->y1, pr->r.x0, pr->r.x1, pr->r.y0, pr->r.y1);
  }
  if (pr->src)
    return obs_err_set(err, rc, "%s: render failed: tile source: %s", name, obs_strerror(rc));
  return obs_err_set(err, rc, "%s: render failed", name);
}

int obs_driver_region(const obs_render_ctx *ctx, int width, int height, obs_region *out,
                      obs_err *err) {
  obs_region r = ctx->region;
  if (!r.x0 && !r.y0 && !r.x1 && !r.y1) r = (obs_region){0, 0, width, height};
  if (r.x0 < 0 || r.y0 < 0 || r.x1 > width || r.y1 > height || r.x0 >= r.x1 || r.y0 >= r.y1)
    return obs_err_set(err, OBS_EINVAL,
                       "region [%d,%d)x[%d,%d) is empty or outside the %dx%d image", r.x0, r.x1,
                       r.y0, r.y1, width, height);
  *out = r;
  return 0;
}

int obs_driver_image(const obs_render_ctx *ctx, int nchannels, const char *const *names,
                     obs_image *out, obs_region *region, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  memset(out, 0, sizeof *out);
  int rc = obs_driver_region(ctx, sc->width, sc->height, region, err);
  return rc ? rc : obs_image_init(out, sc->width, sc->height, nchannels, names, err);
}

int obs_driver_cancelled(const obs_render_ctx *ctx, obs_err *err) {
  if (!ctx->cancel || !atomic_load(ctx->cancel)) return 0;
  return obs_err_set(err, OBS_ECANCELED, "%s: render cancelled",
                     ctx->scene ? ctx->scene->name : "render");
}

int obs_driver_pixels(obs_render_ctx *ctx, const obs_pixel_ops *ops, const void *job,
                      obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  const char *name = sc ? sc->name : "render";
  memset(out, 0, sizeof *out);
  if (!sc || !ops || (!ops->shade && !ops->block) || ops->nchannels < 1)
    return obs_err_set(err, OBS_EINVAL, "%s: per-pixel driver: no scene or shade function", name);
  if (ops->prior && !ops->shade) /* the pilots shade single pixels */
    return obs_err_set(err, OBS_EINVAL, "%s: per-pixel driver: a prior needs a shade function",
                       name);
  obs_region r;
  int rc = obs_driver_region(ctx, sc->width, sc->height, &r, err);
  if (rc) return rc;
  int threads = ctx->threads < 1 ? 1 : ctx->threads;
  size_t per = (size_t)ops->nchannels * (ops->block ? OBS_PIXEL_BLOCK * OBS_PIXEL_BLOCK : 1);
  size_t stride = (per + SLOT - 1) / SLOT * SLOT;
  float *values = calloc((size_t)threads * stride, sizeof *values);
  uint64_t *rays = calloc((size_t)threads * SLOT, sizeof *rays);
  /* The image is allocated before timing starts: the render is not charged for it. */
  if (!values || !rays)
    rc = obs_err_set(err, OBS_ENOMEM, "%s: per-pixel driver: out of memory", name);
  else
    rc = obs_image_init(out, sc->width, sc->height, ops->nchannels, ops->channels, err);
  if (rc) {
    free(values);
    free(rays);
    return rc;
  }
  pixel_run pr = {ops, job, out, r, values, stride, rays, ctx->tiles, 0, {0, 0, 0, 0}, NULL,
                  ctx->watch};
  obs_prior_grid grid;
  memset(&grid, 0, sizeof grid);
  double t0 = obs_now_ms(), prior_ms = 0;
  /* The pilots' share of the work: OBS_PRIOR_REPLICAS pixels per cell of the window. */
  obs_progress_part parts[2] = {{ctx->progress, ctx->progress_user, 0, 0},
                                {ctx->progress, ctx->progress_user, 0, 1}};
  if (ops->prior) {
    double cells = ((r.x1 - r.x0) / (double)OBS_PRIOR_CELL + 2) *
                   ((r.y1 - r.y0) / (double)OBS_PRIOR_CELL + 2) * OBS_PRIOR_REPLICAS;
    double pixels = (double)(r.x1 - r.x0) * (r.y1 - r.y0);
    parts[0].share = parts[1].base = cells / (cells + pixels);
    parts[1].share = 1 - parts[1].base;
    /* No progress while tiles come from a source (its ranks tell from progress that a run does
     * not render per pixel, and would leave their tiles to rank 0). */
    int report = ctx->progress && !ctx->tiles;
    rc = obs_prior_grid_build(&grid, ops, job, &r, sc->width, sc->height, threads, ctx->cancel,
                              report ? obs_progress_part_report : NULL, &parts[0]);
    if (rc) {
      free(values);
      free(rays);
      obs_image_free(out);
      if (rc == OBS_ECANCELED) return obs_err_set(err, rc, "%s: render cancelled", name);
      return obs_err_set(err, rc, "%s: per-pixel driver: out of memory", name);
    }
    pr.prior = &grid;
    prior_ms = obs_now_ms() - t0;
    obs_driver_stage_add(ctx, "prior", prior_ms);
  }
  if (ctx->tiles) {
    ctx->tiled = 1;
    rc = obs_parallel_tiles_from(source_next, &pr, threads, source_tile, &pr, ctx->cancel);
  } else {
    rc = obs_parallel_tiles(r.x1 - r.x0, r.y1 - r.y0, threads, pixel_tile, &pr, ctx->cancel,
                            ctx->progress ? obs_progress_part_report : NULL, &parts[1]);
  }
  ctx->render_ms = obs_now_ms() - t0;
  /* After the timing: the watcher may still be copying tiles out of the image. */
  if (pr.watch && pr.watch->end) pr.watch->end(pr.watch->user, out);
  for (int t = 0; t < threads; t++) ctx->rays += rays[(size_t)t * SLOT];
  if (pr.prior && !ctx->tiles) ctx->rays += obs_prior_grid_rays(&grid, &r, sc->width, sc->height);
  obs_prior_grid_free(&grid);
  free(values);
  free(rays);
  if (rc) {
    obs_image_free(out);
    return loop_failed(&pr, name, rc, err);
  }
  obs_driver_stage_add(ctx, "shade", ctx->render_ms - prior_ms);
  return 0;
}

void obs_driver_clear_outside(obs_image *img, const obs_region *r) {
  const size_t w = (size_t)img->width, plane = w * (size_t)img->height;
  if (r->x0 == 0 && r->y0 == 0 && r->x1 == img->width && r->y1 == img->height) return;
  for (int c = 0; c < img->nchannels; c++) {
    float *p = img->data + (size_t)c * plane;
    for (int y = 0; y < img->height; y++) {
      float *row = p + (size_t)y * w;
      if (y < r->y0 || y >= r->y1) {
        memset(row, 0, w * sizeof *row);
        continue;
      }
      memset(row, 0, (size_t)r->x0 * sizeof *row);
      memset(row + r->x1, 0, (w - (size_t)r->x1) * sizeof *row);
    }
  }
}

void obs_driver_stage_add(obs_render_ctx *ctx, const char *name, double ms) {
  for (int i = 0; i < ctx->nstages; i++)
    if (!strcmp(ctx->stage_names[i], name)) {
      ctx->stage_ms[i] += ms;
      return;
    }
  obs_render_ctx_stage(ctx, name, ms);
}
