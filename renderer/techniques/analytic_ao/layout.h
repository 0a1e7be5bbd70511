/* analytic_ao's push-constant blocks, declared once for vulkan.c and the shaders
 * analytic_ao.comp.glsl, analytic_ao_up.comp.glsl, analytic_ao_pp.comp.glsl and analytic_ao_raster.*.glsl
 * (renderer/core/layout_glsl.h). GLSL allows one push-constant block per shader: a shader defines
 * OBS_AAO_AO_PASS, OBS_AAO_UP_PASS, OBS_AAO_PP_PASS or OBS_AAO_RASTER_PASS before including this, C sees all. */
#ifndef OBS_ANALYTIC_AO_LAYOUT_H
#define OBS_ANALYTIC_AO_LAYOUT_H

#include "layout_glsl.h"

/* vec4s per occluder in the storage buffer: obs_aao_occluder's layout (analytic_ao.h). */
#define OBS_AAO_VEC4S 10
/* The AO pass's modes (cpu.c's AAO_PASS_*): every pixel, pixel (2X, 2Y) of each half-resolution
 * cell, the pixels the upsampling marked. */
#define OBS_AAO_MODE_FULL 0
#define OBS_AAO_MODE_LOW 1
#define OBS_AAO_MODE_EDGES 2

#if !defined(VULKAN) || defined(OBS_AAO_AO_PASS)
OBS_PUSH_BEGIN(obs_aao_push)
  OBS_I32 width; OBS_I32 height; /* the G-buffer's */
  OBS_I32 ortho;     /* its projection (gbuffer.h) */
  OBS_I32 first;     /* this dispatch's occluders: [first, first + count) */
  OBS_I32 count;
  OBS_I32 accumulate; /* 0: the first dispatch writes the AO; 1: later ones multiply into it */
  OBS_I32 mode;       /* OBS_AAO_MODE_* */
  OBS_F32 half_w; OBS_F32 half_h;
OBS_PUSH_END(obs_aao_push)
OBS_PUSH_CHECK(obs_aao_push)
#endif

#if !defined(VULKAN) || defined(OBS_AAO_UP_PASS)
OBS_PUSH_BEGIN(obs_aao_up_push)
  OBS_I32 width; OBS_I32 height; /* the G-buffer's */
  OBS_I32 lw; OBS_I32 lh;        /* the half-resolution grid's */
  OBS_F32 depth_limit;           /* OBS_AAO_UP_DEPTH */
OBS_PUSH_END(obs_aao_up_push)
OBS_PUSH_CHECK(obs_aao_up_push)
#endif

/* The push-pull passes (analytic_ao_pp.comp.glsl, cpu.c's aao_pp_*): one dispatch per level. */
#define OBS_AAO_PP_PUSH0 0 /* the frame's samples into level 1 */
#define OBS_AAO_PP_PUSH 1  /* atlas level at sx into the level at dx */
#define OBS_AAO_PP_PULL 2  /* the level at dx from its parent at sx */
#define OBS_AAO_PP_PULL0 3 /* the frame from level 1 */

#if !defined(VULKAN) || defined(OBS_AAO_PP_PASS)
OBS_PUSH_BEGIN(obs_aao_pp_push)
  OBS_I32 width; OBS_I32 height; /* the G-buffer's */
  OBS_I32 mode;                  /* OBS_AAO_PP_* */
  OBS_I32 sx; OBS_I32 sw; OBS_I32 sh; /* the source (push) or parent (pull) level */
  OBS_I32 dx; OBS_I32 dw; OBS_I32 dh; /* the level written */
OBS_PUSH_END(obs_aao_pp_push)
OBS_PUSH_CHECK(obs_aao_pp_push)
#endif

/* The rasterised proxies (analytic_ao_raster.vert.glsl and .frag.glsl): their bindings, and the
 * margin of each proxy cube over the occluder's bound, relative to it, on top of two pixels at
 * its far side, so that rounding in the projection never leaves out a receiver the compute pass
 * admits (the fragment shader's own test decides, as there). */
#define OBS_AAO_RB_DEPTH 0
#define OBS_AAO_RB_NORMAL 1
#define OBS_AAO_RB_OCC 2
#define OBS_AAO_RB_BINDINGS 3
#define OBS_AAO_PROXY_MARGIN 0.0625

#if !defined(VULKAN) || defined(OBS_AAO_RASTER_PASS)
OBS_PUSH_BEGIN(obs_aao_raster_push)
  OBS_I32 width; OBS_I32 height; /* the G-buffer's */
  OBS_I32 ortho;                 /* its projection (gbuffer.h) */
  OBS_F32 half_w; OBS_F32 half_h;
OBS_PUSH_END(obs_aao_raster_push)
OBS_PUSH_CHECK(obs_aao_raster_push)
#endif

#endif
