/* Scenes and closed forms shared by the per-patch obscurance tests of every backend
 * (tests/unit/test_obscurance_map.c, tests/vulkan/test_obscurance_peel.c). */
#ifndef OBS_OMAP_SCENES_H
#define OBS_OMAP_SCENES_H

#include "obscurance_map.h"

/* The parameters the tests start from: `method`, d_max 1, sqrt falloff, colour bleeding, 64
 * samples, 64 directions of 64 x 64 lines, one patch per triangle, seed 1. */
obs_obscurance_map_params obs_test_omap_defaults(int method);

/* An open 4 x 4 quad at y = 0 facing up, reflectivity (refl, refl / 2, refl / 4): nothing within
 * any d_max. The text lives until the next obs_test_fmt call. */
const char *obs_test_omap_plane_doc(double refl);
/* Plates of half-width L at y = 0 (facing up, reflectivity (0.2, 0.5, 0.8)) and y = h (facing
 * down, (0.6, 0.4, 0.3)). */
const char *obs_test_omap_plates_doc(double h, double L);
/* W at a plate facing another at distance h < d_max, sqrt falloff, m0 = h / d_max. */
double obs_test_omap_plates_w(double m0, double r_ave, double r_other);
/* Checks a map of the plates (doc from obs_test_omap_plates_doc(h, ...), sqrt falloff, d_max
 * `dmax`, colour bleeding `bleed`; pm, w and se as obs_omap has them) against the closed form on
 * the central patches of each plate (centroid within 0.6 of the axis, so everything within d_max
 * of them lies on the other plate): every patch within 5 sigma, the area-weighted mean per plate
 * and channel within 3 sigma. `what` names the estimator in the lines it prints. */
struct obs_patch_mesh;
void obs_test_omap_check_plates(const char *what, const char *doc, double h, double dmax,
                                int bleed, const struct obs_patch_mesh *pm, const float *w,
                                const float *se);
/* scenes/cornell_box.json's text (free it). */
char *obs_test_omap_cornell_doc(void);

#endif
