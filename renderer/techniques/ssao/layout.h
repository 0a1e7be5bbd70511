/* ssao's push-constant blocks, declared once for vulkan.c and the shaders ssao.comp.glsl and
 * ssao_blur.comp.glsl (renderer/core/layout_glsl.h). GLSL allows one push-constant block per
 * shader: a shader defines OBS_SSAO_AO_PASS or OBS_SSAO_BLUR_PASS before including this, C sees
 * both. */
#ifndef OBS_SSAO_LAYOUT_H
#define OBS_SSAO_LAYOUT_H

#include "layout_glsl.h"

/* The AO pass's flags. */
#define OBS_SSAO_FLAG_NORMAL_ORIENTED 1
#define OBS_SSAO_FLAG_ORTHO 2
/* Entries of the blur's reciprocal table: 1 / n for the n in 1..16 pixels of its 4x4 window. */
#define OBS_SSAO_BLUR_COUNTS 17

#if !defined(VULKAN) || defined(OBS_SSAO_AO_PASS)
OBS_PUSH_BEGIN(obs_ssao_ao_push)
  OBS_I32 width; OBS_I32 height; OBS_I32 samples;
  OBS_I32 flags; /* OBS_SSAO_FLAG_* */
  OBS_F32 half_w; OBS_F32 half_h;
  OBS_F32 inv_samples; /* 1 / samples rounded on the host */
OBS_PUSH_END(obs_ssao_ao_push)
OBS_PUSH_CHECK(obs_ssao_ao_push)
#endif

#if !defined(VULKAN) || defined(OBS_SSAO_BLUR_PASS)
OBS_PUSH_BEGIN(obs_ssao_blur_push)
  OBS_I32 width; OBS_I32 height;
  OBS_F32 threshold; /* relative depth difference that still mixes */
  OBS_F32 inv_count[OBS_SSAO_BLUR_COUNTS]; /* 1/n rounded on the host, so no division differs */
OBS_PUSH_END(obs_ssao_blur_push)
OBS_PUSH_CHECK(obs_ssao_blur_push)
#endif

#endif
