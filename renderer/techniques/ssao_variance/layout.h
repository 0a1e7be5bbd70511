/* ssao_variance's parameter blocks, binding numbers and limits, written once for C and GLSL
 * (renderer/core/layout_glsl.h): the moments pass (ssao_variance_moments.comp.glsl, cpu.c's
 * moments rows) and the AO pass (ssao_variance_ao.comp.glsl, cpu.c's ao rows). */
#ifndef OBS_SSAO_VARIANCE_LAYOUT_H
#define OBS_SSAO_VARIANCE_LAYOUT_H

#include "layout_glsl.h"

/* The most taps per side of the box along each axis (the `taps` parameter t): a box of
 * half-width r pixels is read at offsets k * stride, |k| <= K, stride = ceil(r / t),
 * K = floor(r / stride), so at most (2 t + 1)^2 depths per pixel whatever the radius (exactly the
 * box up to r = t). */
#define OBS_SVAR_MAX_TAPS 16
/* Entries of the reciprocal table 1/N for N = 0 .. (2 * taps + 1)^2. */
#define OBS_SVAR_INV_COUNT (33 * 33 + 1)
/* The depth tolerance: a pixel counts as behind its neighbourhood's mean only by more than
 * 2^-20 of its depth, twice the rasteriser's measured depth error (docs/vulkan.md). */
#define OBS_SVAR_DEPTH_TOL 9.5367431640625e-07

/* Bindings of the moments pass: the G-buffer depth in, (n, sum d, sum d^2, shift) out. */
#define OBS_SVAR_M_DEPTH 0
#define OBS_SVAR_M_MOMENTS 1
/* Bindings of the AO pass. */
#define OBS_SVAR_A_DEPTH 0
#define OBS_SVAR_A_MOMENTS 1
#define OBS_SVAR_A_INV 2
#define OBS_SVAR_A_AO 3

/* A shader declares one push-constant block: it defines OBS_SVAR_MOMENTS_PASS or
 * OBS_SVAR_AO_PASS before including this file; C sees both. */
#if !defined(VULKAN) || defined(OBS_SVAR_MOMENTS_PASS)
/* The moments pass: the row part of the box around each pixel. */
OBS_PUSH_BEGIN(obs_svar_moments_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 stride; /* pixels between taps */
  OBS_I32 taps;   /* taps per side */
  OBS_F32 zscale; /* power of two that brings the median depth into [1, 2) */
OBS_PUSH_END(obs_svar_moments_push)
OBS_PUSH_CHECK(obs_svar_moments_push)
#endif

#if !defined(VULKAN) || defined(OBS_SVAR_AO_PASS)
/* The AO pass: the column part of the box, the moments and the estimator. */
OBS_PUSH_BEGIN(obs_svar_ao_push)
  OBS_I32 width;
  OBS_I32 height;
  OBS_I32 stride;
  OBS_I32 taps;
  OBS_I32 method; /* 0: variance (Chebyshev), 1: depth_unsharp */
  OBS_I32 ortho;  /* orthographic camera: the box's world radius does not grow with depth */
  OBS_F32 zscale;
  OBS_F32 rw;     /* the box's world radius in scaled depth units: per unit of depth
                     (perspective) or absolute (orthographic) */
  OBS_F32 tol;    /* OBS_SVAR_DEPTH_TOL */
  OBS_F32 weight; /* variance_weight k */
  OBS_F32 strength; /* depth_unsharp's lambda */
OBS_PUSH_END(obs_svar_ao_push)
OBS_PUSH_CHECK(obs_svar_ao_push)
#endif

#endif
