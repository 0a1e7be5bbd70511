/* ibl_shadows' parameter blocks, declared once for C and GLSL (core/layout_glsl.h): the fit
 * pass's and the blur pass's push constants, and the limits the per-direction table obeys. The
 * table itself (directions, map axes and Y+) is the fit's storage buffer, described below. */
#ifndef OBS_IBL_LAYOUT_H
#define OBS_IBL_LAYOUT_H

#include "layout_glsl.h"

#define OBS_IBL_MAX_MAPS 64
/* Coefficients per pixel live in 4 images of 4 channels: coefficient k in image k / 4, channel
 * k % 4 (the same layout on the host: plane k / 4, pixel i, at (plane N + i) 4 + k % 4). */
#define OBS_IBL_GROUPS 4
/* A shadow-map texel with nothing in front of the receiver plane: farther than any depth. */
#define OBS_IBL_FAR 3.0e38
/* Rasterised maps keep depths from the maps' plane (1.5 radii out) over 3 radii, past the far
 * side of the bounding sphere (2.5 radii): the cleared depth 1 is then farther than any receiver. */
#define OBS_IBL_DEPTH_RANGE 3.0
/* Beyond this cosine the depth bias stops growing with the slope (tan at most 10). */
#define OBS_IBL_MIN_COS 0.0995
#define OBS_IBL_MAX_SLOPE 10.0
/* The table (std430, set 1 at binding OBS_VK_MAX_TEXTURES; obs_ibl_table in C): vec4 dir[64]
 * (toward the environment), vec4 tax[64] and vec4 bax[64] (each map's texel axes), float
 * yplus[16 x 64] (Y+ row k at 64 k). */

#define OBS_IBL_ORTHO 1

#if !defined(VULKAN) || defined(OBS_IBL_FIT)
OBS_PUSH_BEGIN(obs_ibl_fit_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 flags;
  OBS_I32 maps;   /* m */
  OBS_I32 coeffs; /* n */
  OBS_I32 size;   /* shadow-map side S */
  OBS_F32 half_w;
  OBS_F32 half_h;
  OBS_F32 radius;     /* the maps' half extent (the scene's bounding sphere) */
  OBS_F32 start;      /* the maps' plane: start along the direction from the centre */
  OBS_F32 texel_bias; /* bias x 2 radius / S */
  OBS_F32 depth_scale; /* a map's value times this is the distance from the maps' plane */
  OBS_F32 eye[3];     /* the camera relative to the centre, world axes */
  OBS_F32 right[3];   /* the camera's axes in world space */
  OBS_F32 up[3];
  OBS_F32 fwd[3];
OBS_PUSH_END(obs_ibl_fit_push)
OBS_PUSH_CHECK(obs_ibl_fit_push)
#endif

#if !defined(VULKAN) || defined(OBS_IBL_BLUR)
OBS_PUSH_BEGIN(obs_ibl_blur_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 horizontal;
  OBS_F32 weights[9]; /* exp(-i^2 / 10), i = -4..4, made on the host */
OBS_PUSH_END(obs_ibl_blur_push)
OBS_PUSH_CHECK(obs_ibl_blur_push)
#endif

#endif
