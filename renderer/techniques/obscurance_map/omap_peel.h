/* obscurance_map's depth_peeling estimator on Vulkan: per bundle direction (the CPU bundles' own
 * directions and grids, obscurance_lines.h) an orthographic render of the patches peeled layer by
 * layer, and the transfers between consecutive layers accumulated per patch on the device. */
#ifndef OBS_OMAP_PEEL_H
#define OBS_OMAP_PEEL_H

#include <stdatomic.h>
#include <stdint.h>

#include "camera.h"
#include "geometry.h"
#include "obscura/scene.h"
#include "obscura/technique.h"
#include "obscurance_map.h"
#include "patch_mesh.h"
#include "vk.h"

/* Window depth a fragment must lie behind the previous layer to be peeled next (the depth range
 * is the bounding sphere's diameter, so 1e-6 of it: the CPU line estimators' merge distance). */
#define OBS_PEEL_EPS 1e-6f
/* Layers peeled per direction at most; deeper pixels stop transferring there (as the CPU's lines
 * stop at 1024 hits). */
#define OBS_PEEL_LAYERS_MAX 1024

/* A map's values, as the CPU's obs_omap has them. Owns everything inside. */
typedef struct obs_omap_peel {
  obs_patch_mesh pm;
  float *w;          /* count x 3, patch-major: W per channel */
  float *se;         /* count x 3: standard error of a patch's W per channel (1: no sample) */
  uint64_t *n;       /* count: samples per patch */
  int64_t unsampled; /* patches of positive area that received no sample */
  uint64_t layers;   /* layers rendered over all directions (the empty last ones included) */
  int capped;        /* directions that reached OBS_PEEL_LAYERS_MAX */
  double r_ave[3];
  int32_t *ids; /* with a camera: width x height patch ids of the primary view, -1: none */
} obs_omap_peel;

/* Computes the map of `p` (method depth_peeling) over `geo` (built from `scene`). With `show`
 * (may be NULL) also renders the patch each pixel of that camera sees into out->ids. Patches
 * without a sample take the value of "nothing within d_max" and a standard error of 1, as on the
 * CPU. `cancel` and `progress` may be NULL. */
int obs_omap_peel_compute(obs_vk *vk, const obs_scene *scene, const obs_geometry *geo,
                          const obs_obscurance_map_params *p, const obs_camera_rig *show,
                          const atomic_int *cancel, obs_progress_fn progress, void *progress_user,
                          obs_omap_peel *out, double *device_ms, obs_err *err);
void obs_omap_peel_free(obs_omap_peel *m);

#endif
