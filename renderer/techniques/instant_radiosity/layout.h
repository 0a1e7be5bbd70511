/* instant_radiosity's parameter blocks and limits, declared once for C and GLSL
 * (core/layout_glsl.h): the gather pass's and the filter pass's push constants, the VPL record the
 * gather reads, and the interleaving's tile. */
#ifndef OBS_IRAD_LAYOUT_H
#define OBS_IRAD_LAYOUT_H

#include "layout_glsl.h"

/* Interleaved sampling: the VPLs are dealt to OBS_IRAD_CLASSES classes, one per pixel of a 4x4
 * tile ((y & 3) * 4 + (x & 3)), so every 4x4 window of the image sees each class once. */
#define OBS_IRAD_CLASSES 16
/* A VPL is three vec4 in the gather's buffer: view-space position (w unused), view-space unit
 * normal (w: 1 when it emits on both sides), intensity coefficient RGB (w unused): its
 * irradiance at a receiver is coef * F with F the clamped form factor. */
#define OBS_IRAD_VPL_VEC4 3
/* The filter's window: (x + dx, y + dy) for dx, dy in [LO, LO + 3], so it holds each class once;
 * a rejected sample is replaced by the same class 4 pixels away on the other side (the article's
 * extended neighbourhood): dx + 4 for dx < 0, dx - 4 otherwise, first in x, then in y, then both. */
#define OBS_IRAD_FILTER_LO (-2)
/* Gather flags. */
#define OBS_IRAD_ORTHO 1

#if !defined(VULKAN) || defined(OBS_IRAD_GATHER)
OBS_PUSH_BEGIN(obs_irad_gather_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 flags;
  OBS_I32 classes; /* classes in use: min(16, paths); pixel class = tile index % classes */
  OBS_F32 half_w;
  OBS_F32 half_h;
  OBS_F32 nc2;     /* N_c^2, the clamp's squared distance from the VPL's plane */
  OBS_I32 start[OBS_IRAD_CLASSES + 1]; /* class k's VPLs are start[k] .. start[k+1] - 1 */
OBS_PUSH_END(obs_irad_gather_push)
OBS_PUSH_CHECK(obs_irad_gather_push)
#endif

#if !defined(VULKAN) || defined(OBS_IRAD_FILTER)
OBS_PUSH_BEGIN(obs_irad_filter_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 flags;      /* OBS_IRAD_ORTHO */
  OBS_F32 half_w;
  OBS_F32 half_h;
  OBS_F32 depth_tol;  /* a sample counts where |n_c . (p - p_c)| <= depth_tol z_c */
  OBS_F32 normal_min; /* and where n . n_c >= normal_min */
  OBS_F32 inv_count[OBS_IRAD_CLASSES + 1]; /* 1 / n for the n samples kept, 1..16 */
OBS_PUSH_END(obs_irad_filter_push)
OBS_PUSH_CHECK(obs_irad_filter_push)
#endif

#endif
