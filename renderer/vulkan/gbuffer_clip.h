/* Host-side clipping of camera-relative triangles to a guard band around the view frustum, in
 * double, before the G-buffer rasteriser sees them (see docs/vulkan.md, "Huge triangles"). */
#ifndef OBS_VK_GBUFFER_CLIP_H
#define OBS_VK_GBUFFER_CLIP_H

#include <stddef.h>

#include "camera.h"

/* A triangle clipped by five planes has at most 8 corners: a fan of 6 triangles. */
#define OBS_VK_CLIP_MAX_VERTS 18

typedef struct obs_vk_clip {
  double right[3], up[3], forward[3];
  int ortho;
  double keep_x, keep_y; /* drawn unchanged inside these half-extents (slopes when perspective) */
  double cut_x, cut_y;   /* otherwise clipped to these (inside the rasteriser's guard band) */
  double znear;          /* and to view depth z >= znear */
  double zmin, zmax;     /* view depths of everything emitted so far (+inf, -inf at first) */
} obs_vk_clip;

void obs_vk_clip_init(obs_vk_clip *c, const obs_camera_rig *rig, double znear);

/* Clips one triangle (3 camera-relative float vertices). Writes the result, a multiple of 3
 * vertices (at most OBS_VK_CLIP_MAX_VERTS), to `out` unless it is NULL, and returns how many.
 * A triangle inside the keep band comes back bit-identical. */
size_t obs_vk_clip_triangle(obs_vk_clip *c, const float tri[9], float *out);

#endif
