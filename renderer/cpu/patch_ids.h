/* Which patch (triangle, numbered as obscura/patches.h says) each pixel's primary ray sees: the
 * bridge from per-patch values to an image of them. */
#ifndef OBS_PATCH_IDS_H
#define OBS_PATCH_IDS_H

#include <stdint.h>
#include "obscura/patches.h"
#include "raytrace.h"

/* Fills ids[y * width + x] (scene->width x scene->height) with the patch the ray through pixel
 * (x, y)'s centre hits first, or -1 for a miss or an analytic sphere (which has no patches). */
void obs_patch_ids(const obs_rt *rt, const obs_scene *scene, int32_t *ids);
/* The same with another numbering of patches: `map` turns each primary hit on a mesh into its
 * patch id (e.g. a sub-triangle of the hit triangle), or -1. */
typedef int64_t (*obs_patch_map_fn)(const void *user, const obs_rt *rt, const obs_hit *hit);
void obs_patch_ids_map(const obs_rt *rt, const obs_scene *scene, obs_patch_map_fn map,
                       const void *user, int32_t *ids);

/* What a per-patch technique's run does to show its values: casts the primary rays and fills
 * `out`'s planes `channels` (p->components of them, `out` sized as the scene's image) with the
 * value of the patch each pixel sees (0 where none). */
int obs_patch_show(const obs_rt *rt, const obs_scene *scene, const obs_patches *p,
                   obs_image *out, const char *const *channels, obs_err *err);

#endif
