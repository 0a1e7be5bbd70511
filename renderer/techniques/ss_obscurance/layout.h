/* ss_obscurance's parameter blocks, binding numbers and limits, declared once for its C files and
 * its shaders (renderer/core/layout_glsl.h). */
#ifndef OBS_SSO_LAYOUT_H
#define OBS_SSO_LAYOUT_H

#include "layout_glsl.h"

/* Offsets per pixel, and the cells of the 4x4 interleaving pattern (one offset set each). */
#define OBS_SSO_MAX_SAMPLES 64
#define OBS_SSO_CELLS 16
/* The 4x4 average's footprint: pixels (x + dx, y + dy) for dx, dy in [LO, HI]. An even window
 * sees every cell of the 4x4 pattern once away from the image's edges. */
#define OBS_SSO_AVG_LO (-2)
#define OBS_SSO_AVG_HI 1
/* The plane test's slack, 2^-20: a sample counts as in front of a texel's surface unless it lies
 * more than this share of the magnitudes involved behind its plane, so the rounding of positions
 * and normals never closes a sample above a plane (docs/techniques/ss_obscurance.md). */
#define OBS_SSO_SLACK 9.5367431640625e-7
/* flags of the obscurance pass */
#define OBS_SSO_FLAG_ORTHO 1
#define OBS_SSO_FLAG_INTERLEAVE 2

/* The obscurance pass. The offset table is an image of cells rows (obs_sso_tables.offsets as the
 * host holds it, OBS_SSO_MAX_SAMPLES + 1 texels a row): texel (k, c) for k < samples holds cell
 * c's tangent-space offset k in units of R (xyz) and its weight (w); texel (samples, c) holds
 * 1 / (sum of cell c's weights) in x. */
#define OBS_SSO_B_DEPTH 0
#define OBS_SSO_B_NORMAL 1
#define OBS_SSO_B_OFFSETS 2
#define OBS_SSO_B_RAW 3
/* A shader declares one push-constant block: it defines OBS_SSO_SHADER_AO or OBS_SSO_SHADER_AVG
 * before including this file; C sees both. */
#if !defined(VULKAN) || defined(OBS_SSO_SHADER_AO)
OBS_PUSH_BEGIN(obs_sso_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 samples;
  OBS_I32 flags;
  OBS_F32 half_w;    /* obs_gbuffer's: tan of the half field of view, or half extents (ortho) */
  OBS_F32 half_h;
  OBS_F32 radius;    /* R in scene units */
  OBS_F32 two_inv_w; /* 2 / width and 2 / height rounded once on the host */
  OBS_F32 two_inv_h;
  OBS_F32 inv_half_w; /* 1 / half_w and 1 / half_h rounded once on the host: the projection */
  OBS_F32 inv_half_h; /* divides once per sample (by z), not once per axis */
OBS_PUSH_END(obs_sso_push)
OBS_PUSH_CHECK(obs_sso_push)
#endif

/* The 4x4 average (interleave only). */
#define OBS_SSO_A_DEPTH 0
#define OBS_SSO_A_RAW 1
#define OBS_SSO_A_OUT 2
#if !defined(VULKAN) || defined(OBS_SSO_SHADER_AVG)
OBS_PUSH_BEGIN(obs_sso_avg_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_F32 radius;        /* neighbours whose depth differs from the centre's by at most R mix */
  OBS_F32 inv_count[17]; /* 1 / n for n in 1..16, rounded on the host */
OBS_PUSH_END(obs_sso_avg_push)
OBS_PUSH_CHECK(obs_sso_avg_push)
#endif

#endif
