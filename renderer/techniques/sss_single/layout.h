/* sss_single's push-constant block, image bindings, texture layers and parameter rows, declared
 * once for vulkan.c, sss_maps.c and sss_single.comp.glsl (renderer/core/layout_glsl.h). */
#ifndef OBS_SSS_LAYOUT_H
#define OBS_SSS_LAYOUT_H

#include "layout_glsl.h"

/* Storage images of one pixel sample (rgba32f). */
#define OBS_SSS_B_POS 0 /* camera hit in the ray tracer's frame; w: object, -1 none */
#define OBS_SSS_B_NRM 1 /* its shading normal */
#define OBS_SSS_B_DIR 2 /* the unit camera ray */
#define OBS_SSS_B_OUT 3 /* radiance rgb */
#define OBS_SSS_BINDINGS 4
/* The maps' layers per light in the 2D array texture (rgba, nearest). */
#define OBS_SSS_LAYER_POS 0 /* first surface from the light; w: its object, -1 none */
#define OBS_SSS_LAYER_NRM 1 /* its outward normal */
#define OBS_SSS_LAYER_IRR 2 /* transmitted irradiance E_t (Eq. 6.5.4) */
#define OBS_SSS_LAYERS 3
/* vec4 rows of the parameter buffer per object: (sigma_s, has medium), (sigma_t, sigma_min),
 * (g, eta, 0, 0); per light: (pos, point), (dir, half), (power, 0), (centre, 0), (right, 0),
 * (up, 0), (fwd, 0). */
#define OBS_SSS_OBJ_ROWS 3
#define OBS_SSS_LIGHT_ROWS 7

OBS_PUSH_BEGIN(obs_sss_push)
  OBS_I32 width; OBS_I32 height;
  OBS_I32 nobjects; OBS_I32 nlights;
  OBS_I32 samples;  /* M */
  OBS_I32 adaptive;
  OBS_U32 seed;
  OBS_I32 pixel_sample; /* the pixel sample this dispatch shades */
  OBS_I32 map_size;
  OBS_F32 jitter;   /* texels */
OBS_PUSH_END(obs_sss_push)
OBS_PUSH_CHECK(obs_sss_push)

#endif
