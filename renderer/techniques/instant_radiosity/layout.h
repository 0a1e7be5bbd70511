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
#define OBS_IRAD_APPROX 2 /* approximate visibility: depth pyramid and distance cube */

/* Approximate visibility. The min-pyramid of the depth buffer is one image, its levels side by
 * side (level l, ceil(w / 2^l) x ceil(h / 2^l), starts at x = the widths of the levels before it),
 * uncovered texels at OBS_IRAD_FAR. The march toward a VPL takes a sample 2^(i+1) pixels from the
 * receiver for i = 0 .. OBS_IRAD_STEPS - 1, on level max(0, i - 1). */
#define OBS_IRAD_LEVELS 6
#define OBS_IRAD_STEPS 8
#define OBS_IRAD_FAR 3.0e38
/* The distance-impostor cube: 6 faces of OBS_IRAD_CUBE^2 texels side by side (face f = 2 axis +
 * (negative ? 1 : 0), view-space axes), each the distance from the cube's centre to the nearest
 * off-screen surface in its direction (OBS_IRAD_FAR: none); the off-screen part of a segment is
 * sampled OBS_IRAD_CUBE_SAMPLES times. */
#define OBS_IRAD_CUBE 64
#define OBS_IRAD_CUBE_SAMPLES 2
/* A march sample starts to occlude where the pyramid's depth lies bias z in front of the
 * segment, and occludes fully at 2 bias z (smoothstep between): the article's soft comparison;
 * it stops occluding again from thickness z to 2 thickness z (the occluder assumed that thick).
 * A cube sample occludes from bias d to 2 bias d behind the surface (d its distance from the
 * cube's centre), however far behind. */

#if !defined(VULKAN) || defined(OBS_IRAD_GATHER)
OBS_PUSH_BEGIN(obs_irad_gather_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 flags;
  OBS_I32 classes; /* classes in use: min(16, paths); pixel class = tile index % classes */
  OBS_F32 half_w;
  OBS_F32 half_h;
  OBS_F32 nc2;     /* N_c^2, the clamp's squared distance from the VPL's plane */
  OBS_F32 bias;    /* approximate visibility's relative depth bias */
  OBS_F32 thickness; /* and the relative depth behind an occluder where it stops occluding */
  OBS_F32 cube_x;  /* the distance cube's centre in view space */
  OBS_F32 cube_y;
  OBS_F32 cube_z;
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
