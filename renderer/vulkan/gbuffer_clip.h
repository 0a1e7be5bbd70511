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

/* A vertex prepared once and shared by the triangles that use it. */
typedef struct obs_vk_clip_vertex {
  double p[3]; /* camera-relative world position */
  double v[3]; /* view coordinates (right, up, forward) */
  int band;    /* inside the keep band's side planes */
} obs_vk_clip_vertex;

void obs_vk_clip_vertex_init(const obs_vk_clip *c, const double p[3], obs_vk_clip_vertex *out);

/* Prepares one triangle: writes the vertices the device draws for it (a multiple of 3,
 * OBS_VK_CLIP_FLOATS floats each, rounded once from double) to `out` unless it is NULL, and
 * returns how many. The same call gives the same count with or without `out`. */
size_t obs_vk_clip_triangle(obs_vk_clip *c, const obs_vk_clip_vertex *a,
                            const obs_vk_clip_vertex *b, const obs_vk_clip_vertex *d, float *out);

#endif
