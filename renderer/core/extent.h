/* The scene's size and distance from the world origin, and the check of a render against the
 * range its technique's backend guarantees (obs_range in obscura/technique.h). */
#ifndef OBS_EXTENT_H
#define OBS_EXTENT_H

#include "obscura/scene.h"
#include "obscura/technique.h"

typedef struct obs_extent {
  int empty;            /* 1 when the scene has no objects (nothing below is meaningful) */
  double bounds[2][3];  /* world-space bounding box of the transformed geometry, in double */
  double size;          /* the box's diagonal */
  double translation;   /* max(|camera position|, |box centre|) / size (inf when size is 0) */
  double distance;      /* the numerator of translation, in scene units */
} obs_extent;

/* Computes the extent of a loaded scene: shapes given by vertices and spheres exactly, displaced
 * spheres and imported meshes by their object-space bounding box put through the transform (a
 * rotated box can only grow, by at most sqrt(3)); a mesh by the box the loader measured when it
 * imported it (obs_shape.mesh.bounds), so nothing is imported again. Returns 0 today. */
int obs_scene_extent(const obs_scene *scene, obs_extent *out, obs_err *err);

/* The quantities of `scene` (extent `ex`) outside `range`, each as one warning added to `ctx`
 * that names the quantity, its value and the guaranteed range (of `technique` on the backend
 * named `backend`); returns how many were added. */
int obs_range_check(const obs_range *range, const char *technique, const char *backend,
                    const obs_scene *scene, const obs_extent *ex, obs_render_ctx *ctx);

#endif
