/* isosurface_mesh: the bound parameters and the backends' entry points (ShaderX7 1.1). */
#ifndef OBS_ISOSURFACE_MESH_H
#define OBS_ISOSURFACE_MESH_H

#include <stdint.h>

#include "geometry.h"
#include "isosurface.h"
#include "obscura/technique.h"
#include "volume_scene.h"

typedef struct obs_isosurface_mesh_params {
  int32_t grid;   /* extraction cells along each volume's longest side */
  int32_t refine; /* 0, or 1: every cell's diagonal bisected at a centre sample */
} obs_isosurface_mesh_params;

enum { ISO_CH_NX, ISO_CH_NY, ISO_CH_NZ, ISO_CH_DEPTH, ISO_CH_ALPHA, ISO_CH_COUNT };
extern const char *const obs_isosurface_mesh_channels[ISO_CH_COUNT];

int obs_isosurface_mesh_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_isosurface_mesh_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);
/* The Vulkan extractor (vulkan.c) on its own, for the twin test and the benchmark: the same mesh
 * as obs_iso_extract (keys, indices and order; t within a few float roundings), positions placed
 * from each vertex's key and t; *ms the device passes' time. */
struct obs_vk;
int obs_isosurface_mesh_vk_extract(struct obs_vk *vk, const obs_volume *v, float iso, int cells,
                                   int refine, obs_iso_mesh *m, double *ms, obs_err *err);

/* Volume sv's extracted mesh in the frame world = origin + unit x frame, rounded to float once;
 * with `normals`, the field's gradient at each vertex as its shading normal. */
int obs_iso_mesh_world(const obs_scene_volume *sv, const obs_iso_mesh *im, const double origin[3],
                       double unit, int normals, obs_mesh *m);
/* Appends the mesh's figures to ctx->built ("isosurface_mesh": object, triangles, vertices,
 * cells, bytes, extract_ms). */
void obs_iso_mesh_record(obs_render_ctx *ctx, const obs_scene_volume *sv, const obs_iso_mesh *im,
                         double ms);

#endif
