/* volume_ao's device layout, declared once for vulkan.c and volume_ao.comp.glsl
 * (renderer/core/layout_glsl.h): the push-constant block, the storage-image bindings, the rows of
 * the parameter buffer and the codes the push block carries. vulkan.c asserts that the codes
 * match the C enums they mirror (volume_ao.h, sampling.h). */
#ifndef OBS_VAO_LAYOUT_H
#define OBS_VAO_LAYOUT_H

#include "layout_glsl.h"

/* The storage images (set 0), in binding order. Per pixel: the sums over the samples, turned
 * into the outputs by the last dispatch; the sample in progress's state. */
#define OBS_VAO_B_ACC0 0 /* R, G, B, ao */
#define OBS_VAO_B_ACC1 1 /* bent normal, depth */
#define OBS_VAO_B_ACC2 2 /* normal, hits (alpha) */
#define OBS_VAO_B_ST0 3  /* open directions, their environment sum */
#define OBS_VAO_B_ST1 4  /* their sum; w: the loop-limit flag (kept over the whole render) */
#define OBS_VAO_B_ST2 5  /* open directions of the replicate, Welford mean and M2; w: variance */
#define OBS_VAO_IMAGES 6

/* The parameter buffer, rows of 4 floats: a header, then per volume OBS_VAO_V_COUNT rows, per
 * light OBS_VAO_L_COUNT rows, then the colormaps' points (value, r, g, b). World space is
 * relative to the reference point Q (vulkan.c). */
#define OBS_VAO_H_FWD 0      /* camera forward; w: Q's distance along it */
#define OBS_VAO_H_RIGHT 1    /* camera right, half_w */
#define OBS_VAO_H_UP 2       /* camera up, half_h */
#define OBS_VAO_H_MARCH 3    /* start, step, the march's end, shininess */
#define OBS_VAO_H_ATLAS 4    /* 1 / the atlas's sides, specular */
#define OBS_VAO_H_ENV_MEAN 5 /* the environment's mean radiance */
#define OBS_VAO_H_SH 6       /* 9 rows: its irradiance's SH coefficients */
#define OBS_VAO_H_COUNT 15
#define OBS_VAO_V_TO_DATA 0  /* 3 rows: Q-relative world -> data space */
#define OBS_VAO_V_TO_WORLD 3 /* 3 rows: data space -> Q-relative world */
#define OBS_VAO_V_NORMAL 6   /* 3 rows: the normal matrix */
#define OBS_VAO_V_EXTENT 9   /* the box's sides, iso */
#define OBS_VAO_V_SPACING 10 /* spacing, the smallest spacing */
#define OBS_VAO_V_DIMS 11    /* samples per axis, colormap points */
#define OBS_VAO_V_AT 12      /* the samples' corner in the atlas, first colormap point */
#define OBS_VAO_V_CELLS 13   /* macrocells per axis, voxels per cell side */
#define OBS_VAO_V_CELL_AT 14 /* the macrocells' corner in their atlas */
#define OBS_VAO_V_COUNT 15
#define OBS_VAO_L_POS 0      /* position (point, w 0) or direction (w 1) */
#define OBS_VAO_L_EMISSION 1 /* emission */
#define OBS_VAO_L_COUNT 2

/* flags: texture reads the shader filters itself, and whether there is an environment. */
#define OBS_VAO_FLAG_VOL_MANUAL 1
#define OBS_VAO_FLAG_ENV_MANUAL 2
#define OBS_VAO_FLAG_ENV 4
/* phase: where a dispatch stands in its sample's direction chunks and in the pixel's samples. */
#define OBS_VAO_PH_FIRST_CHUNK 1
#define OBS_VAO_PH_LAST_CHUNK 2
#define OBS_VAO_PH_FIRST_SAMPLE 4
#define OBS_VAO_PH_FINAL 8
/* ibl: obs_volume_ao_ibl's values (volume_ao.h). */
#define OBS_VAO_IBL_LOOKUP 1
#define OBS_VAO_IBL_IRRADIANCE 2
#define OBS_VAO_IBL_REFERENCE 3
/* sampler_kind: obs_sampler_kind's values (sampling.h). */
#define OBS_VAO_SAMPLER_SOBOL 0
#define OBS_VAO_SAMPLER_HALTON 1
#define OBS_VAO_SAMPLER_RANDOM 2

OBS_PUSH_BEGIN(obs_vao_push)
  OBS_I32 band[4];   /* x0, y0, w, h: the pixels of this dispatch */
  OBS_I32 origin[2]; /* the region's corner: pixel (x, y) is stored at (x, y) - origin */
  OBS_I32 size[2];   /* the image's width and height */
  OBS_I32 spp;
  OBS_U32 samples;
  OBS_I32 sampler_kind; /* OBS_VAO_SAMPLER_* */
  OBS_U32 seed;
  OBS_I32 ibl; /* OBS_VAO_IBL_* */
  OBS_I32 crossing; OBS_I32 blinn; OBS_I32 ortho;
  OBS_I32 nvol; OBS_I32 nlights;
  OBS_I32 env_res; /* 0: constant white */
  OBS_I32 last;    /* < 0: AO never blocked */
  OBS_I32 flags;   /* OBS_VAO_FLAG_* */
  OBS_I32 pixel_sample; /* the pixel sample this dispatch shades */
  OBS_U32 dir0; OBS_U32 dir1; /* its AO directions [dir0, dir1) */
  OBS_I32 phase;      /* OBS_VAO_PH_* */
  OBS_U32 iter_limit; /* obs_vk_loop_limit; 0: none */
  OBS_I32 pilot;    /* 0; the prior's pilots: the cell side, invocation (i, j) the pilot of cell */
  OBS_I32 cell0[2]; /* (cell0 + (i, j)), stored at (i, j) */
OBS_PUSH_END(obs_vao_push)
OBS_PUSH_CHECK(obs_vao_push)

#endif
