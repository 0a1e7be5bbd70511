/* Host-side preparation of the G-buffer rasteriser's triangles in double: view-space rotation,
 * clipping to a guard band, depth slabs, face normals (see gbuffer_clip.c and docs/vulkan.md). */
#ifndef OBS_VK_GBUFFER_CLIP_H
#define OBS_VK_GBUFFER_CLIP_H

#include <stddef.h>

#include "camera.h"

/* Floats per vertex: view-space position, then the triangle's unit face normal in view space. */
#define OBS_VK_CLIP_FLOATS 6

typedef struct obs_vk_clip {
  double right[3], up[3], forward[3];
  int ortho;
  double keep_x, keep_y; /* drawn unchanged inside these half-extents (slopes when perspective) */
  double cut_x, cut_y;   /* otherwise clipped to these (inside the rasteriser's guard band) */
  double znear;          /* and to view depth z >= znear */
  double zmin, zmax;     /* view depths of everything emitted so far (+inf, -inf at first) */
} obs_vk_clip;

void obs_vk_clip_init(obs_vk_clip *c, const obs_camera_rig *rig, double znear);

/* Prepares one triangle (3 camera-relative vertices): writes the vertices the device draws for
 * it (a multiple of 3, OBS_VK_CLIP_FLOATS floats each, rounded once from double) to `out` unless it
 * is NULL, and returns how many. The same call gives the same count with or without `out`. */
size_t obs_vk_clip_triangle(obs_vk_clip *c, const double tri[9], float *out);

#endif
