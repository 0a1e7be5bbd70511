/* ss_radiosity's parameter blocks and limits, declared once for C and GLSL (core/layout_glsl.h):
 * the gather pass's and the blur pass's push constants, and the sizes of the tables they read. */
#ifndef OBS_SS_RADIOSITY_LAYOUT_H
#define OBS_SS_RADIOSITY_LAYOUT_H

#include "layout_glsl.h"

#define OBS_SRAD_MAX_SAMPLES 32
/* The blur's window: (x + dx, y + dy) for dx, dy in [LO, HI]; even, so it sees each cell of the
 * 4x4 rotation tile once away from the edges. */
#define OBS_SRAD_BLUR_LO (-2)
#define OBS_SRAD_BLUR_HI 1
/* A sample whose normal has a dot product above this with the pixel's lies on the same plane as
 * far as float face normals tell (two triangles of one quad differ in the last bits): its
 * geometric factor is exactly 0. */
#define OBS_SRAD_COPLANAR 0.9999f
/* Gather flags. */
#define OBS_SRAD_ORTHO 1
#define OBS_SRAD_EXCLUDE_SELF 2
#define OBS_SRAD_PROBES_ADD 4 /* probes combined additively (else multiplicatively) */
/* AO probes a scene may hold (the article's characters use 18). */
#define OBS_SRAD_MAX_PROBES 256

/* A shader declares the one block it uses (GLSL allows one push-constant block per stage) by
 * defining OBS_SRAD_GATHER or OBS_SRAD_BLUR before including this file; C sees both. */
#if !defined(VULKAN) || defined(OBS_SRAD_GATHER)
OBS_PUSH_BEGIN(obs_srad_gather_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 samples;
  OBS_I32 flags;
  OBS_F32 half_w;
  OBS_F32 half_h;
  OBS_F32 kernel_size;
  OBS_F32 directivity;
  OBS_F32 spread; /* 1 - directivity, rounded on the host */
  OBS_F32 attenuation;
  OBS_F32 inv_bias;
  OBS_F32 scale; /* strength / samples, rounded on the host */
  OBS_F32 inv_samples;
  OBS_I32 nprobes;
OBS_PUSH_END(obs_srad_gather_push)
OBS_PUSH_CHECK(obs_srad_gather_push)
#endif

#if !defined(VULKAN) || defined(OBS_SRAD_BLUR)
OBS_PUSH_BEGIN(obs_srad_blur_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_F32 threshold;
  OBS_F32 inv_count[17];
OBS_PUSH_END(obs_srad_blur_push)
OBS_PUSH_CHECK(obs_srad_blur_push)
#endif

#endif
