/* obscurance_map's depth-peeling layout, declared once for vulkan_peel.c and the shaders
 * peel.vert.glsl, peel.frag.glsl and peel_transfer.comp.glsl (renderer/core/layout_glsl.h): the
 * push-constant blocks, the descriptor bindings and the per-patch sums' words. GLSL allows one
 * push-constant block per shader: the draw's two stages define OBS_PEEL_DRAW_PASS, the transfer
 * OBS_PEEL_TRANSFER_PASS, before including this; C sees both. */
#ifndef OBS_PEEL_LAYOUT_H
#define OBS_PEEL_LAYOUT_H

#include "layout_glsl.h"

/* One descriptor set for both pipelines: the two layers as storage images, then the buffers. */
#define OBS_PEEL_B_LAYER_A 0 /* the nearer layer (the peel's previous one) */
#define OBS_PEEL_B_LAYER_B 1 /* the farther layer */
#define OBS_PEEL_B_ACC 2     /* the per-patch sums, OBS_PEEL_ACC_WORDS words each */
#define OBS_PEEL_B_REFL 3    /* the reflectivity table */
#define OBS_PEEL_B_COVERED 4 /* covered pixels per layer of a batch */
#define OBS_PEEL_IMAGES 2    /* bindings below this are images, the rest buffers */
#define OBS_PEEL_BINDINGS 5

/* Per patch: the sum of each channel (lo, hi words) x 3, the sums of squares x 3, the samples,
 * 2 unused. Values are fixed point with OBS_PEEL_FIXED_ONE, the CPU estimators' OMAP_ONE. */
#define OBS_PEEL_ACC_WORDS 16
#define OBS_PEEL_ACC_SUM 0
#define OBS_PEEL_ACC_SQ 6
#define OBS_PEEL_ACC_SAMPLES 12
#define OBS_PEEL_FIXED_ONE 268435456.0 /* 2^28 */

#if !defined(VULKAN) || defined(OBS_PEEL_DRAW_PASS)
/* The peel's draw, read by both of its stages. */
OBS_PUSH_BEGIN(obs_peel_draw_push)
  OBS_F32 m[16];  /* normalised coordinates to clip space, column-major */
  OBS_F32 dir[4]; /* the view direction (into the scene), normalised coordinates; w unused */
  OBS_F32 eps;    /* keep fragments this far behind the previous layer; < 0: no previous layer */
OBS_PUSH_END(obs_peel_draw_push)
OBS_PUSH_CHECK(obs_peel_draw_push)
#endif

#if !defined(VULKAN) || defined(OBS_PEEL_TRANSFER_PASS)
/* The transfers between two consecutive layers. */
OBS_PUSH_BEGIN(obs_peel_transfer_push)
  OBS_F32 dmax;    /* d_max over the depth range (window depth units) */
  OBS_F32 tau;     /* exp falloff's rate per window depth unit */
  OBS_I32 falloff; /* 0 binary, 1 sqrt, 2 exp */
  OBS_I32 bleed;
  OBS_I32 res;
  OBS_U32 bg_s[3]; /* fixed-point value of "nothing within d_max" (host-rounded, as the CPU's) */
  OBS_U32 bg_q[3]; /* and of its square */
  OBS_U32 layer;   /* this layer's slot in the covered counts */
OBS_PUSH_END(obs_peel_transfer_push)
OBS_PUSH_CHECK(obs_peel_transfer_push)
#endif

#endif
