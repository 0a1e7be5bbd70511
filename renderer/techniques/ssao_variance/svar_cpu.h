/* ssao_variance's CPU rows shared by cpu.c and its AVX2 kernels in cpu_avx2.c. */
#ifndef OBS_SVAR_CPU_H
#define OBS_SVAR_CPU_H

#include "simd.h"
#include "ssao_variance.h"

/* A frame's passes: the depth, the plan's box and the moments planes. */
typedef struct obs_svar_rows {
  const float *depth;
  int w, h, stride, taps;
  float zscale;
  float *mn, *m1, *m2, *mc; /* n, sum d, sum d^2, shift; mc filled before the moments rows */
  float *taps_x;            /* per column: the taps of the box's row (2 min(taps, m/stride) + 1) */
} obs_svar_rows;

#if OBS_SIMD_AVX2
/* The moments of row y (mn, m1, m2 from the shifts in mc), eight pixels at a time with the taps
 * in registers: the scalar rows' bits. `zrow` holds w floats (the row's scaled depths). */
void obs_svar_moments_row_avx2(const obs_svar_rows *r, int y, float *zrow);
/* The AO of row y into `out` for the pixels below w rounded down to a multiple of 8, which it
 * returns, likewise; `scratch` holds 4 w floats. */
int obs_svar_ao_row_avx2(const obs_svar_rows *r, const obs_svar_ao_push *ap, int y, float *scratch,
                         float *out);
#endif

#endif
