/* The pilot grid of the per-pixel driver's pooled prior of standard errors (driver.h,
 * obs_pixel_prior), for the driver alone. */
#ifndef OBS_DRIVER_PRIOR_H
#define OBS_DRIVER_PRIOR_H

#include <stdatomic.h>
#include <stdint.h>

#include "driver.h"

#define OBS_PRIOR_MAX_SE 8

/* The pilot variances of a window of the grid of OBS_PRIOR_CELL-pixel cells. Owns `var`. */
typedef struct obs_prior_grid {
  int cx0, cy0, ncx, ncy, nse;
  float *var;     /* ncy x ncx x nse; NAN where the pilot saw no surface */
  uint64_t *rays; /* ncy x ncx: the rays each cell's pilot traced (obs_prior_grid_build) */
} obs_prior_grid;

/* The window of cells region `r` of a width x height image needs (its own and one around), with
 * room for nse variances per cell: 0 or OBS_ENOMEM (g then empty). */
int obs_prior_grid_init(obs_prior_grid *g, const obs_region *r, int width, int height, int nse);
/* The pilot pixel of the window's cell (cx, cy) (relative to its corner). */
void obs_prior_grid_pilot(const obs_prior_grid *g, int cx, int cy, int width, int height, int *px,
                          int *py);
/* Shades the pilots of the cells region `r` of a width x height image needs on `threads`
 * threads with ops->prior's replicas, keeping each cell's rays, reporting the fraction done to
 * `progress` (may be NULL). 0, OBS_ECANCELED or OBS_ENOMEM (g then empty). A backend that shades
 * its pilots itself fills an obs_prior_grid_init window's `var` instead: per cell and channel the
 * sample variance of the OBS_PRIOR_REPLICAS replicas' values (obs_prior_grid_set). */
int obs_prior_grid_build(obs_prior_grid *g, const obs_pixel_ops *ops, const void *job,
                         const obs_region *r, int width, int height, int threads,
                         const atomic_int *cancel, void (*progress)(void *, double),
                         void *progress_user);
/* The rays of the pilots whose pixel lies in `r`: each pilot counted by the one tile of a split
 * render that holds it. */
uint64_t obs_prior_grid_rays(const obs_prior_grid *g, const obs_region *r, int width, int height);
/* Sets the variance of channel c of the window's cell (cx, cy) from its pilot's replicas' values
 * v; NAN (left out) unless `covered`: every replica saw a surface. */
void obs_prior_grid_set(obs_prior_grid *g, int cx, int cy, int c,
                        const double v[OBS_PRIOR_REPLICAS], int covered);
/* Replaces pixel (x, y)'s standard errors in v by their combination with the prior. */
void obs_prior_grid_apply(const obs_prior_grid *g, const obs_pixel_prior *p, const void *job,
                          int x, int y, float *v);
void obs_prior_grid_free(obs_prior_grid *g);

#endif
