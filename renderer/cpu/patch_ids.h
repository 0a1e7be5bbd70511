/* Which patch (triangle, numbered as obscura/patches.h says) each pixel's primary ray sees: the
 * bridge from per-patch values to an image of them. */
#ifndef OBS_PATCH_IDS_H
#define OBS_PATCH_IDS_H

#include <stdint.h>
#include "raytrace.h"

/* Fills ids[y * width + x] (scene->width x scene->height) with the patch the ray through pixel
 * (x, y)'s centre hits first, or -1 for a miss or an analytic sphere (which has no patches). */
void obs_patch_ids(const obs_rt *rt, const obs_scene *scene, int32_t *ids);

#endif
