/* hbao's push-constant blocks, declared once for vulkan.c and the shaders hbao_*.comp.glsl
 * (renderer/core/layout_glsl.h). GLSL allows one push-constant block per shader: a shader
 * defines the OBS_HBAO_*_PASS of its block before including this, C sees all four. */
#ifndef OBS_HBAO_LAYOUT_H
#define OBS_HBAO_LAYOUT_H

#include "layout_glsl.h"

#if !defined(VULKAN) || defined(OBS_HBAO_DOWN_PASS)
/* The half-resolution copy of depth and normals. */
OBS_PUSH_BEGIN(obs_hbao_down_push)
  OBS_I32 lw; OBS_I32 lh;
OBS_PUSH_END(obs_hbao_down_push)
OBS_PUSH_CHECK(obs_hbao_down_push)
#endif

#if !defined(VULKAN) || defined(OBS_HBAO_AO_PASS)
/* The horizon search over the lw x lh level, s = 2 with half_res, else 1. */
OBS_PUSH_BEGIN(obs_hbao_ao_push)
  OBS_I32 lw; OBS_I32 lh; OBS_I32 s; OBS_I32 width; OBS_I32 height; OBS_I32 ortho;
  OBS_I32 directions; OBS_I32 steps;
  OBS_F32 half_w; OBS_F32 half_h; OBS_F32 radius; OBS_F32 cos_b; OBS_F32 sin_b; OBS_F32 scale;
  OBS_F32 inv_r;     /* 1 / radius, a host float (obs_hbao_inv_radius) */
  OBS_F32 depth_eps; /* OBS_HBAO_DEPTH_EPS */
OBS_PUSH_END(obs_hbao_ao_push)
OBS_PUSH_CHECK(obs_hbao_ao_push)
#endif

#if !defined(VULKAN) || defined(OBS_HBAO_UP_PASS)
/* The depth-aware upsampling of the half-resolution AO. */
OBS_PUSH_BEGIN(obs_hbao_up_push)
  OBS_I32 width; OBS_I32 height; OBS_I32 lw; OBS_I32 lh;
  OBS_F32 max_rel_dz; OBS_F32 upsample_k;
OBS_PUSH_END(obs_hbao_up_push)
OBS_PUSH_CHECK(obs_hbao_up_push)
#endif

#if !defined(VULKAN) || defined(OBS_HBAO_BLUR_PASS)
/* One direction of the cross-bilateral blur: axis 0 along x, 1 along y. */
OBS_PUSH_BEGIN(obs_hbao_blur_push)
  OBS_I32 width; OBS_I32 height; OBS_I32 axis; OBS_I32 radius;
  OBS_F32 falloff; OBS_F32 sharpness; OBS_F32 max_rel_dz;
OBS_PUSH_END(obs_hbao_blur_push)
OBS_PUSH_CHECK(obs_hbao_blur_push)
#endif

#endif
