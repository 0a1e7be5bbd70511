/* The per-pixel driver's pooled prior of standard errors (driver.h, obs_pixel_prior): the pilot
 * grid shaded before the tiles, and each pixel's variance combined with its neighbourhood's. */
#include "driver_prior.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "sampling.h"

typedef struct pilot_run {
  obs_prior_grid *g;
  const obs_pixel_ops *ops;
  const void *job;
  int width, height;
  float *values;  /* threads x stride */
  size_t stride;
  unsigned char *jobs; /* threads x job_size: each thread's copy of the job */
} pilot_run;

/* The pilot cells of a tile of the window's loop, where each cell is one OBS_TILE x OBS_TILE
 * tile: the loop hands out one cell at a time and checks for cancellation between them. */
static int pilot_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  x0 /= OBS_TILE, y0 /= OBS_TILE;
  x1 = (x1 + OBS_TILE - 1) / OBS_TILE, y1 = (y1 + OBS_TILE - 1) / OBS_TILE;
  pilot_run *pr = user;
  obs_prior_grid *g = pr->g;
  const obs_pixel_prior *p = pr->ops->prior;
  float *v = pr->values + (size_t)thread * pr->stride;
  unsigned char *job = pr->jobs + (size_t)thread * p->job_size;
  uint32_t seed;
  memcpy(job, pr->job, p->job_size);
  memcpy(&seed, job + p->seed_offset, sizeof seed);
  for (int cy = y0; cy < y1; cy++)
    for (int cx = x0; cx < x1; cx++) {
      int px, py;
      obs_prior_grid_pilot(g, cx, cy, pr->width, pr->height, &px, &py);
      double vals[OBS_PRIOR_MAX_SE][OBS_PRIOR_REPLICAS];
      int covered = 1;
      uint64_t *rays = &g->rays[(size_t)cy * (size_t)g->ncx + (size_t)cx];
      for (uint32_t k = 0; k < OBS_PRIOR_REPLICAS; k++) {
        uint32_t rs = obs_sampler_replica_seed(seed, k + 1);
        memcpy(job + p->seed_offset, &rs, sizeof rs);
        *rays += pr->ops->shade(job, thread, px, py, v);
        covered &= p->alpha < 0 || v[p->alpha] > 0.0f;
        for (int c = 0; c < p->nse; c++) vals[c][k] = v[p->value[c]];
      }
      for (int c = 0; c < p->nse; c++) obs_prior_grid_set(g, cx, cy, c, vals[c], covered);
    }
  return 0;
}

int obs_prior_grid_init(obs_prior_grid *g, const obs_region *r, int width, int height, int nse) {
  memset(g, 0, sizeof *g);
  const int gw = (width + OBS_PRIOR_CELL - 1) / OBS_PRIOR_CELL;
  const int gh = (height + OBS_PRIOR_CELL - 1) / OBS_PRIOR_CELL;
  g->cx0 = r->x0 / OBS_PRIOR_CELL - 1, g->cy0 = r->y0 / OBS_PRIOR_CELL - 1;
  int cx1 = (r->x1 - 1) / OBS_PRIOR_CELL + 2, cy1 = (r->y1 - 1) / OBS_PRIOR_CELL + 2;
  if (g->cx0 < 0) g->cx0 = 0;
  if (g->cy0 < 0) g->cy0 = 0;
  if (cx1 > gw) cx1 = gw;
  if (cy1 > gh) cy1 = gh;
  g->ncx = cx1 - g->cx0, g->ncy = cy1 - g->cy0, g->nse = nse;
  g->var = malloc((size_t)g->ncx * (size_t)g->ncy * (size_t)nse * sizeof *g->var);
  g->rays = calloc((size_t)g->ncx * (size_t)g->ncy, sizeof *g->rays);
  if (!g->var || !g->rays) return obs_prior_grid_free(g), OBS_ENOMEM;
  return 0;
}

void obs_prior_grid_pilot(const obs_prior_grid *g, int cx, int cy, int width, int height, int *px,
                          int *py) {
  *px = (g->cx0 + cx) * OBS_PRIOR_CELL + OBS_PRIOR_CELL / 2;
  *py = (g->cy0 + cy) * OBS_PRIOR_CELL + OBS_PRIOR_CELL / 2;
  if (*px >= width) *px = width - 1;
  if (*py >= height) *py = height - 1;
}

int obs_prior_grid_build(obs_prior_grid *g, const obs_pixel_ops *ops, const void *job,
                         const obs_region *r, int width, int height, int threads,
                         const atomic_int *cancel, void (*progress)(void *, double),
                         void *progress_user) {
  const obs_pixel_prior *p = ops->prior;
  memset(g, 0, sizeof *g);
  if (p->nse < 1 || p->nse > OBS_PRIOR_MAX_SE) return OBS_EINVAL;
  if (obs_prior_grid_init(g, r, width, height, p->nse)) return OBS_ENOMEM;
  size_t stride = ((size_t)ops->nchannels + 7) / 8 * 8;
  float *values = calloc((size_t)threads * stride, sizeof *values);
  unsigned char *jobs = malloc((size_t)threads * p->job_size);
  int rc = OBS_ENOMEM;
  if (values && jobs) {
    pilot_run pr = {g, ops, job, width, height, values, stride, jobs};
    rc = obs_parallel_tiles(g->ncx * OBS_TILE, g->ncy * OBS_TILE, threads, pilot_tile, &pr,
                            cancel, progress, progress_user);
  }
  free(values);
  free(jobs);
  if (rc) obs_prior_grid_free(g);
  return rc;
}

void obs_prior_grid_set(obs_prior_grid *g, int cx, int cy, int c,
                        const double v[OBS_PRIOR_REPLICAS], int covered) {
  double mean = 0, m2 = 0; /* Welford over the replicas */
  for (int k = 0; k < OBS_PRIOR_REPLICAS; k++) {
    double d = v[k] - mean;
    mean += d / (k + 1);
    m2 += d * (v[k] - mean);
  }
  g->var[((size_t)cy * (size_t)g->ncx + (size_t)cx) * (size_t)g->nse + (size_t)c] =
      covered ? (float)(m2 / (OBS_PRIOR_REPLICAS - 1)) : NAN;
}

void obs_prior_grid_apply(const obs_prior_grid *g, const obs_pixel_prior *p, const void *job,
                          int x, int y, float *v) {
  const int cx = x / OBS_PRIOR_CELL - g->cx0, cy = y / OBS_PRIOR_CELL - g->cy0;
  for (int c = 0; c < p->nse; c++) {
    double sum = 0;
    int n = 0;
    for (int j = cy - 1; j <= cy + 1; j++)
      for (int i = cx - 1; i <= cx + 1; i++) {
        if (i < 0 || j < 0 || i >= g->ncx || j >= g->ncy) continue;
        float pv = g->var[((size_t)j * (size_t)g->ncx + (size_t)i) * (size_t)g->nse + (size_t)c];
        if (isnan(pv)) continue;
        sum += pv;
        n++;
      }
    float *se = &v[p->se[c]];
    if (*se == 0 && !signbit(*se)) continue; /* exact */
    if (!n) { /* no pilot nearby: the pixel's own, its floor where its samples agreed */
      *se = fabsf(*se);
      continue;
    }
    double prior = sum / n, df = p->df(job, c), own = (double)*se * *se;
    const double w = OBS_PRIOR_WEIGHT;
    /* Samples that all agreed have a spread of 0, which counts as no more than the prior: they
     * may have missed what the pilots saw, or there was nothing to miss. A spread above the prior
     * stands (the pixel's variance is its own: missed events only lower it). */
    *se = signbit(*se)   ? (float)sqrt(w * prior / ((df < w ? df : w) + w))
          : own >= prior ? *se
                         : (float)sqrt((df * own + w * prior) / (df + w));
  }
}

uint64_t obs_prior_grid_rays(const obs_prior_grid *g, const obs_region *r, int width, int height) {
  uint64_t rays = 0;
  for (int cy = 0; cy < g->ncy; cy++)
    for (int cx = 0; cx < g->ncx; cx++) {
      int px, py;
      obs_prior_grid_pilot(g, cx, cy, width, height, &px, &py);
      if (px >= r->x0 && px < r->x1 && py >= r->y0 && py < r->y1)
        rays += g->rays[(size_t)cy * (size_t)g->ncx + (size_t)cx];
    }
  return rays;
}

void obs_prior_grid_free(obs_prior_grid *g) {
  free(g->var);
  free(g->rays);
  memset(g, 0, sizeof *g);
}
