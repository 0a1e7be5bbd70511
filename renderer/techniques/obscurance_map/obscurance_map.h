/* obscurance_map's parameters as its CPU backend reads them (bound from the descriptor's table). */
#ifndef OBS_OBSCURANCE_MAP_PARAMS_H
#define OBS_OBSCURANCE_MAP_PARAMS_H

#include <stdint.h>

#include "obscura/technique.h"

/* Values of `method`: the indices of its choices in the table. AUTO is RAYS on the CPU and
 * DEPTH_PEELING on Vulkan. */
enum { OBS_OMAP_RAYS, OBS_OMAP_GLOBAL_LINES, OBS_OMAP_BUNDLES, OBS_OMAP_DEPTH_PEELING, OBS_OMAP_AUTO };

/* The estimator `method` means on a backend: auto is rays on the CPU, depth_peeling on Vulkan. */
static inline int obs_omap_method_on(int method, int vulkan) {
  return method != OBS_OMAP_AUTO ? method : vulkan ? OBS_OMAP_DEPTH_PEELING : OBS_OMAP_RAYS;
}

/* Values of `update`: how a frame after the first is computed when objects move. */
enum { OBS_OMAP_UPDATE_FULL, OBS_OMAP_UPDATE_EXACT, OBS_OMAP_UPDATE_ARTICLE };

typedef struct obs_obscurance_map_params {
  int method;                 /* OBS_OMAP_* */
  double d_max;               /* scene units, > 0 */
  int falloff;                /* obs_falloff_kind (obscurance.h) */
  double tau;                 /* exp falloff's rate per scene unit */
  int color_bleeding;         /* 0 or 1 */
  uint32_t samples;           /* rays: per patch */
  uint32_t directions;        /* bundles; global_lines: the line count's scale */
  uint32_t bundle_resolution; /* bundles: lines per side of each grid */
  uint32_t lines;             /* global_lines; 0: directions x bundle_resolution^2 */
  double patch_size;          /* longest patch edge in scene units; INFINITY: no split */
  uint32_t seed;
  int update;                 /* OBS_OMAP_UPDATE_* */
  int measure_full;           /* 0 or 1: also recompute every frame in full, to compare */
} obs_obscurance_map_params;

/* bundles and depth_peeling take a patch's standard error from obs_bundle_groups' groups of
 * directions: below this many directions (8 groups of 2) the groups are too few for it, and it
 * understates the error (docs/accuracy.md, "Standard errors": RMS stderr / RMSE 0.55 at 4). */
#define OBS_OMAP_STDERR_MIN_DIRECTIONS 16u

/* Says so on a render whose estimator (`method` as run) groups directions too few for its
 * standard errors. */
static inline void obs_omap_warn_stderr(obs_render_ctx *ctx, int method,
                                        const obs_obscurance_map_params *p) {
  if ((method == OBS_OMAP_BUNDLES || method == OBS_OMAP_DEPTH_PEELING) &&
      p->directions < OBS_OMAP_STDERR_MIN_DIRECTIONS)
    obs_render_ctx_warn(ctx,
                        "obscurance_stderr is calibrated from %u directions; with %u its groups of "
                        "directions are too few and it understates the error (docs/accuracy.md, "
                        "Standard errors)",
                        OBS_OMAP_STDERR_MIN_DIRECTIONS, p->directions);
}

/* The run of each backend (cpu.c and vulkan.c), named by the descriptor's `run`. */
int obs_obscurance_map_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_obscurance_map_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
