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
  /* The columns [clo, chi) the moments pass computes: from the first covered column rounded down
   * to a multiple of 8 to the last covered one; no pixel outside them reads their moments. */
  int clo, chi;
} obs_svar_rows;

#if OBS_SIMD_AVX2
/* The moments of row y's columns [clo, chi) (mn, m1, m2 from the shifts in mc), eight pixels at
 * a time with the taps in registers: the scalar rows' bits. `zrow` holds w floats (the row's
 * scaled depths). */
void obs_svar_moments_row_avx2(const obs_svar_rows *r, int y, float *zrow);
/* The AO of row y's pixels [lo, lo + a multiple of 8 <= hi) into `out` (the row), likewise;
 * returns where it stopped. `scratch` holds 4 w floats. */
int obs_svar_ao_row_avx2(const obs_svar_rows *r, const obs_svar_ao_push *ap, int y, int lo, int hi,
                         float *scratch, float *out);
#endif

#endif
