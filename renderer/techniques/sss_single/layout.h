/* sss_single's push-constant blocks, image bindings, texture layers and parameter rows, declared
 * once for vulkan.c, sss_maps.c, sss_single.comp.glsl and sss_maps.comp.glsl
 * (renderer/core/layout_glsl.h). A shader has one push block: sss_maps.comp.glsl defines
 * OBS_SSS_MAPS_PASS before including this file and sees only its own. */
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
 * (g, eta, 0, 0); per light: (pos, point), (dir, half), (power, 0), (centre, back), (right, 0),
 * (up, 0), (fwd, 0). */
#define OBS_SSS_OBJ_ROWS 3
#define OBS_SSS_LIGHT_ROWS 7

/* The maps pass (sss_maps.comp.glsl), one dispatch per light over its map_size^2 texels: the
 * G-buffer rasterised from the light (renderer/vulkan/gbuffer_vk.c) in, the three map layers out
 * (rgba32f, copied into the texture's layers afterwards). */
#define OBS_SSS_M_DEPTH 0  /* r32f: linear depth along the light's forward axis, 0 uncovered */
#define OBS_SSS_M_NORMAL 1 /* the face normal in the light view's axes, facing the light */
#define OBS_SSS_M_ALBEDO 2 /* w: the object seen + 1 */
#define OBS_SSS_M_POS 3    /* out: OBS_SSS_LAYER_POS */
#define OBS_SSS_M_NRM 4    /* out: OBS_SSS_LAYER_NRM */
#define OBS_SSS_M_IRR 5    /* out: OBS_SSS_LAYER_IRR */
#define OBS_SSS_M_BINDINGS 6

#if !defined(VULKAN) || !defined(OBS_SSS_MAPS_PASS)
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

#if !defined(VULKAN) || defined(OBS_SSS_MAPS_PASS)
OBS_PUSH_BEGIN(obs_sss_maps_push)
  OBS_I32 size;     /* map_size */
  OBS_I32 light;    /* the light whose maps this dispatch fills */
  OBS_I32 nobjects;
  OBS_I32 pad;
OBS_PUSH_END(obs_sss_maps_push)
OBS_PUSH_CHECK(obs_sss_maps_push)
#endif

#endif
