/* obscurance_map's parameters as its CPU backend reads them (bound from the descriptor's table). */
#ifndef OBS_OBSCURANCE_MAP_PARAMS_H
#define OBS_OBSCURANCE_MAP_PARAMS_H

#include <stdint.h>

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

#endif
