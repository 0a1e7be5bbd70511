/* proximity_ao's device layouts, declared once for vulkan.c, vulkan_flood.c and the shaders
 * proximity_ao.comp.glsl, prox_flood_xy.comp.glsl and prox_flood_z.comp.glsl
 * (renderer/core/layout_glsl.h): the push-constant blocks, the image bindings and the rows of the
 * reconstruction's parameter buffer. GLSL allows one push-constant block per shader: a shader
 * defines OBS_PROX_RECON_PASS or OBS_PROX_FLOOD_PASS before including this, C sees both. */
#ifndef OBS_PROX_LAYOUT_H
#define OBS_PROX_LAYOUT_H

#include "layout_glsl.h"

/* The reconstruction's storage images (set 0), in binding order. */
#define OBS_PROX_B_DEPTH 0  /* linear view depth */
#define OBS_PROX_B_NORMAL 1 /* view-space normal, coverage */
#define OBS_PROX_B_ALBEDO 2 /* a: object index + 1 */
#define OBS_PROX_B_ACC 3    /* per pixel: occlusion sum, product of (1 - a), fields read, ao */
#define OBS_PROX_B_SURF 4   /* per pixel: world normal, view depth */

/* The parameter buffer, rows of 4 floats: a header (the camera, the reconstruction's constants,
 * the disc table), OBS_PROX_F_COUNT rows per field, then one row per scene object (an analytic
 * sphere's centre in view coordinates and radius, or zeros). The header's sizes follow from
 * proximity.h's OBS_PROX_MAX_STEPS and OBS_PROX_DISC_POINTS (vulkan.c asserts them). */
#define OBS_PROX_H_RIGHT 0  /* camera right, half_w */
#define OBS_PROX_H_UP 1     /* camera up, half_h */
#define OBS_PROX_H_FWD 2    /* camera forward, orthographic (1) or not (0) */
#define OBS_PROX_H_RECON 3  /* stop_value, scale_before, scale_after */
#define OBS_PROX_H_FIRST 4  /* the disc table's first point of each step, 4 to a row */
#define OBS_PROX_H_DISC 21  /* the disc points, 2 to a row */
#define OBS_PROX_H_COUNT 517
/* A field's rows: the grid coordinates of the camera origin (w: the object's index); the grid
 * images of the camera's forward, right and up axes (w: the field's corner in the atlas, x y z);
 * the grid images of the world axes times the step length R / N (w: the grid's voxels, x y z). */
#define OBS_PROX_F_ORIGIN 0
#define OBS_PROX_F_FWD 1
#define OBS_PROX_F_RIGHT 2
#define OBS_PROX_F_UP 3
#define OBS_PROX_F_NX 4
#define OBS_PROX_F_NY 5
#define OBS_PROX_F_NZ 6
#define OBS_PROX_F_COUNT 7

/* The reconstruction's phase flags: which dispatch of a render this is. */
#define OBS_PROX_PHASE_FIRST 1 /* starts the accumulation, writes surf */
#define OBS_PROX_PHASE_LAST 2  /* turns the accumulation into ao */

#if !defined(VULKAN) || defined(OBS_PROX_RECON_PASS)
/* One dispatch of the reconstruction: fields [f0, f1) over the region. */
OBS_PUSH_BEGIN(obs_prox_recon_push)
  OBS_I32 region[4]; /* x0, y0, w, h */
  OBS_I32 size[2];   /* the image's width and height */
  OBS_I32 f0; OBS_I32 f1;
  OBS_I32 steps; OBS_I32 mode; OBS_I32 combine; OBS_I32 self_occlusion;
  OBS_I32 phase;   /* OBS_PROX_PHASE_* */
  OBS_I32 objects; /* the row of object 0 */
OBS_PUSH_END(obs_prox_recon_push)
OBS_PUSH_CHECK(obs_prox_recon_push)
#endif

/* The flood's 3D images: the values (updated in place by the z pass), the x-y block sums, the
 * occupancy (1 where the surface touches). */
#define OBS_PROX_FLOOD_B_VAL 0
#define OBS_PROX_FLOOD_B_SXY 1
#define OBS_PROX_FLOOD_B_OCC 2

#if !defined(VULKAN) || defined(OBS_PROX_FLOOD_PASS)
/* Both passes of a flood iteration (the x-y pass reads dims only). */
OBS_PUSH_BEGIN(obs_prox_flood_push)
  OBS_I32 dims[3]; /* voxels per axis */
  OBS_F32 inv26;   /* the host's float 1/26 (OBS_PROX_INV26) */
OBS_PUSH_END(obs_prox_flood_push)
OBS_PUSH_CHECK(obs_prox_flood_push)
#endif

#endif
