/* isosurface_mesh: the bound parameters and the backends' entry points (ShaderX7 1.1). */
#ifndef OBS_ISOSURFACE_MESH_H
#define OBS_ISOSURFACE_MESH_H

#include <stdint.h>

#include "obscura/technique.h"

typedef struct obs_isosurface_mesh_params {
  int32_t grid;   /* extraction cells along each volume's longest side */
  int32_t refine; /* 0, or 1: every cell's diagonal bisected at a centre sample */
} obs_isosurface_mesh_params;

enum { ISO_CH_NX, ISO_CH_NY, ISO_CH_NZ, ISO_CH_DEPTH, ISO_CH_ALPHA, ISO_CH_COUNT };
extern const char *const obs_isosurface_mesh_channels[ISO_CH_COUNT];

int obs_isosurface_mesh_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
