/* The CPU hbao's pass job, shared by cpu.c (passes, scalar texels, blur) and
 * cpu_avx2.c (the AVX2 AO kernel). Internal to the CPU backend. */
#ifndef OBS_HBAO_CPU_H
#define OBS_HBAO_CPU_H

#include "gbuffer.h"
#include "hbao.h"
#include "simd.h"

/* The texels the AO pass runs on: the full G-buffer or its half-resolution subsample. */
typedef struct hbao_level {
  int w, h, s;         /* size, and full-resolution pixels per texel (1 or 2) */
  const float *depth;  /* w*h */
  const float *normal; /* 3 per texel */
} hbao_level;

typedef struct hbao_job {
  const obs_gbuffer *g; /* full resolution: camera and, for the blur, depth */
  hbao_level lv;
  const obs_hbao_params *p;
  const float *table;
  float cos_b, sin_b;
  float inv_r; /* 1 / radius, rounded once for both backends (obs_hbao_inv_radius) */
  float depth_eps; /* OBS_HBAO_DEPTH_EPS */
  float falloff; /* 1 / (2 sigma^2) of the blur's Gaussian */
  float blur_nkf[2 * OBS_HBAO_MAX_BLUR_RADIUS + 1]; /* -(k^2 falloff) for tap k + radius */
  const float *in;
  float *out;
  int axis;      /* blur: 0 = horizontal, 1 = vertical */
  int simd;      /* run the AVX2 spans (simd.h) */
  int loads;     /* their gathers as scalar loads (obs_simd_gather_loads) */
  /* For the AVX2 spans: obs_gbuffer_position's x and y factors per level column and row, i.e.
   * (2 fx / W - 1) half_w and (1 - 2 fy / H) half_h at the texel's pixel centre, computed with the
   * scalar code's operations so a table lookup gives the same bits as the expression. */
  const float *colf, *rowf;
  /* For the AVX2 spans: the direction table per lane, 16 cells ((y & 3) * 4 + (x & 3) of the
   * span's first texel) x directions x (dx[8], dy[8], jitter[8]), copied bit for bit. */
  const float *dirs8;
} hbao_job;

#if OBS_SIMD_AVX2
/* ao_texel (cpu.c) for texels x + stride l, l = 0..7, of level row y, all inside
 * the level; stride 1 or 4. Writes dst[stride l]. Same bits as ao_texel on every lane. */
void obs_hbao_ao_span8(const hbao_job *jb, int x, int stride, int y, float *dst);
#endif

#endif
