/* isosurface_mesh's device layout, declared once for vulkan.c and the extraction shaders
 * (renderer/core/layout_glsl.h): the storage-image bindings, the table buffer's sections and the
 * push-constant block. Every per-point or per-cell array lives in a 2D image OBS_ISO_W texels
 * wide, element e at (e % OBS_ISO_W, e / OBS_ISO_W), so a lattice of 257^3 points fits the
 * device's image sides. */
#ifndef OBS_ISO_LAYOUT_H
#define OBS_ISO_LAYOUT_H

#include "layout_glsl.h"

#define OBS_ISO_W 4096
/* Storage images (set 0). */
#define OBS_ISO_B_VALUES 0 /* r32f per lattice point: the field minus the isovalue */
#define OBS_ISO_B_CENTRE 1 /* r32f per cell: the same at its centre (refine) */
#define OBS_ISO_B_COUNTS 2 /* rgba32f per point: crossed edges it owns, triangles of its cell,
                            * the mask of those edges' slots */
#define OBS_ISO_B_BASES 3  /* rgba32f per point: its first vertex, its cell's first triangle */
#define OBS_ISO_B_VERTS 4  /* rgba32f per vertex: t, the edge's key (bits, see below), 0, 0 */
#define OBS_ISO_B_TRIS 5   /* rgba32f per triangle: its three vertex indices */
#define OBS_ISO_IMAGES 6
/* A key is stored as the float whose bits are key | OBS_ISO_KEY_BIAS: a normal float for every
 * key below 2^28, so no device flushes or canonicalises it. */
#define OBS_ISO_KEY_BIAS 0x40000000u
/* The table buffer (set 1, uints): per axis a, OBS_ISO_T_AXIS + a * stride holds 2 c[a] + 1
 * lower indices, as many upper indices and as many weights (float bits); then the
 * polygonisation table at `table` (push): ntets x 4 corners, ntets x 16 triangle counts, ntets x
 * 16 x 2 x 3 x 2 edge corners. */
#define OBS_ISO_T_AXIS 0
/* The buffer's binding in set 1: obs_vk_pass's OBS_VK_MAX_TEXTURES (vulkan.c asserts it). */
#define OBS_ISO_T_BINDING 4

OBS_PUSH_BEGIN(obs_iso_push)
  OBS_I32 c[4];      /* cells per axis, refine */
  OBS_I32 axis[4];   /* where each axis's table starts in the buffer; the polygonisation table */
  OBS_I32 npoints;   /* (c0 + 1)(c1 + 1)(c2 + 1) */
  OBS_F32 iso;
OBS_PUSH_END(obs_iso_push)
OBS_PUSH_CHECK(obs_iso_push)

#endif
