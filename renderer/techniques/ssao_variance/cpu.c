/* ssao_variance on the CPU: the twin of ssao_variance_moments.comp.glsl and
 * ssao_variance_ao.comp.glsl, operation for operation (float32, the shaders' order, nothing
 * contracted: docs/architecture.md, "Screen-space twins"). Each pass runs a row of a tile at a
 * time with the taps in the outer loop, so the inner loops over pixels vectorise; every pixel
 * still adds its taps in the shader's order. */
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"
#include "simd.h"
#include "ssao_variance.h"
#include "svar_cpu.h"
#include "techniques.h"

typedef struct svar_job {
  const obs_gbuffer *g;
  const obs_svar_plan *plan;
  obs_svar_ao_push ap;
  obs_svar_rows rows; /* the moments planes: n, sum d, sum d^2, shift */
  float *ao;
  float *scratch; /* per thread: the AO pass's depth and three sums of one row */
  int *row_lo;    /* per row: the first and last covered pixel (lo > hi: none) */
  int *row_hi;
  int simd;       /* run the AVX2 rows (svar_cpu.h) */
} svar_job;

/* The shift of an uncovered pixel: the nearest covered tap's scaled depth (left before right),
 * so its sums stay relative to a depth of its window; 0 when there is none. */
static float shift_of_uncovered(const float *zr, int x, int m, int s, int K, float zs) {
  for (int j = 1; j <= K; j++) {
    if (j * s > m) break;
    float zl = zr[x - j * s] * zs;
    if (zl > 0.0f) return zl;
    float zr2 = zr[x + j * s] * zs;
    if (zr2 > 0.0f) return zr2;
  }
  return 0.0f;
}

/* The passes run over bands of whole rows (the driver's tiles over a one-pixel-wide image, so
 * x0 = 0 and x1 = 1): a row's taps then sweep the full width, which vectorises better than the
 * 32 pixels of a tile. */
OBS_HOT_INLINE int moments_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)x0;
  (void)x1;
  const svar_job *j = user;
  const int w = j->g->width, s = j->plan->stride, K = j->plan->taps;
  const float zs = j->plan->zscale;
  for (int y = y0; y < y1; y++) {
    const size_t row = (size_t)y * (size_t)w;
    const float *restrict zr = j->g->depth + row;
    float *restrict n = j->rows.mn + row, *restrict h1 = j->rows.m1 + row,
                    *restrict h2 = j->rows.m2 + row, *restrict c = j->rows.mc + row;
    const int clo = j->rows.clo, chi = j->rows.chi;
    for (int x = clo; x < chi; x++) {
      const int m = x < w - 1 - x ? x : w - 1 - x;
      const float zc = zr[x] * zs;
      c[x] = zc > 0.0f ? zc : shift_of_uncovered(zr, x, m, s, K, zs);
      n[x] = h1[x] = h2[x] = 0.0f;
    }
#if OBS_SIMD_AVX2
    if (j->simd) {
      obs_svar_moments_row_avx2(&j->rows, y, j->scratch + (size_t)thread * 4 * (size_t)w);
      continue;
    }
#endif
    for (int k = -K; k <= K; k++) {
      const int a = (k < 0 ? -k : k) * s;
      /* Tap k counts where the symmetric box reaches it: a <= x <= w - 1 - a. */
      const float *restrict zt_row = zr + k * s;
      const int lo = a > clo ? a : clo, hi = w - a < chi ? w - a : chi;
      for (int x = lo; x < hi; x++) {
        /* The shader adds only covered taps; adding cov x (an uncovered tap's finite terms) is
         * adding +-0, which leaves the sums' bits alone (they are never -0). */
        const float zt = zt_row[x] * zs;
        const float d = zt - c[x];
        const float cov = (float)(zt > 0.0f);
        n[x] += cov;
        h1[x] += cov * d;
        h2[x] += cov * (d * d);
      }
    }
  }
  return 0;
}
OBS_TILE_KERNELS(moments_tile)

/* The estimator (docs/techniques/ssao_variance.md) over a row of nx pixels from their box sums,
 * written without branches so it vectorises: each lane computes both methods' values and keeps the
 * one the shader's branches would, with the same operations. 1 / N is a division here and the
 * shader's table entry there: the table holds 1.0f / N, which a correctly rounded division
 * reproduces. `taps_x` holds each column's taps in the box's row, `taps_y` is the row's. */
OBS_HOT_INLINE void svar_estimate_row(const obs_svar_ao_push *ap, int nx, const float *z0,
                                      const float *nn, const float *t1, const float *t2,
                                      const float *taps_x, float taps_y, float *restrict out) {
  const int variance = ap->method == OBS_SVAR_VARIANCE;
  for (int i = 0; i < nx; i++) {
    const float z = z0[i];
    const float iv = 1.0f / (nn[i] > 0.0f ? nn[i] : 1.0f);
    const float mo = t1[i] * iv;
    const float e2 = t2[i] * iv;
    float var = e2 - mo * mo;
    var = var > 0.0f ? var : 0.0f;
    const float share = nn[i] * (1.0f / (taps_x[i] * taps_y));
    const float tz = ap->tol * z;
    const float dd = (0.0f - mo) - tz;
    const float R = ap->ortho ? ap->rw : ap->rw * z;
    const float den = var + dd * dd;
    const float vis = var / (den > 0.0f ? den : 1.0f);
    const float q = var / (R * R);
    const float ov = 1.0f - (den > 0.0f ? vis : 1.0f);
    const float vv = (1.0f - share * ov) + ap->weight * q;
    const float u = dd / R;
    const float vu = 1.0f - share * (ap->strength * u);
    float v = variance ? vv : vu;
    v = dd > 0.0f ? v : 1.0f;
    v = v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f;
    out[i] = z > 0.0f ? v : 1.0f;
  }
}

OBS_HOT_INLINE int ao_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)x0;
  (void)x1;
  const svar_job *j = user;
  const int w = j->g->width, h = j->g->height, s = j->plan->stride, K = j->plan->taps;
  const float zs = j->plan->zscale;
  float *restrict z0 = j->scratch + (size_t)thread * 4 * (size_t)w;
  float *restrict nn = z0 + w, *restrict t1 = nn + w, *restrict t2 = t1 + w;
  for (int y = y0; y < y1; y++) {
    const size_t row = (size_t)y * (size_t)w;
    float *out = j->ao + row;
    /* Only the covered span [lo, hi) needs the sums (chunk-aligned from lo); the rest is open. */
    const int lo = j->row_lo[y] & ~7, hi = j->row_hi[y] + 1;
    if (lo >= hi) {
      for (int x = 0; x < w; x++) out[x] = 1.0f;
      continue;
    }
    for (int x = 0; x < lo; x++) out[x] = 1.0f;
    for (int x = hi; x < w; x++) out[x] = 1.0f;
    int xb = lo; /* pixels [xb, hi) are the scalar loop's */
#if OBS_SIMD_AVX2
    if (j->simd) xb = obs_svar_ao_row_avx2(&j->rows, &j->ap, y, lo, hi, z0, out);
#endif
    if (xb == hi) continue;
    const int m = y < h - 1 - y ? y : h - 1 - y;
    for (int x = xb; x < hi; x++) {
      z0[x] = j->g->depth[row + (size_t)x] * zs;
      nn[x] = t1[x] = t2[x] = 0.0f;
    }
    for (int k = -K; k <= K; k++) {
      if ((k < 0 ? -k : k) * s > m) continue;
      const size_t r = (size_t)(y + k * s) * (size_t)w;
      const float *restrict an = j->rows.mn + r, *restrict a1 = j->rows.m1 + r,
                            *restrict a2 = j->rows.m2 + r, *restrict ac = j->rows.mc + r;
      for (int x = xb; x < hi; x++) {
        const float dl = ac[x] - z0[x];
        const float an_d = an[x] * dl;
        t1[x] = t1[x] + (a1[x] + an_d);
        const float tw = 2.0f * dl;
        t2[x] = t2[x] + ((a2[x] + tw * a1[x]) + an_d * dl);
        nn[x] = nn[x] + an[x];
      }
    }
    const float ty = (float)(2 * (K < m / s ? K : m / s) + 1);
    svar_estimate_row(&j->ap, hi - xb, z0 + xb, nn + xb, t1 + xb, t2 + xb, j->rows.taps_x + xb, ty,
                      out + xb);
  }
  return 0;
}
OBS_TILE_KERNELS(ao_tile)

/* Both passes within a render (r) or outside one. */
static int svar_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_ssao_variance_params *p,
                       float *ao, double *stage_ms, obs_svar_plan *plan_out, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SVAR_CPU_STAGES; k++) stage_ms[k] = 0.0;
  if (!g || !p || !ao || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ssao_variance: missing G-buffer, parameters or output");
  const size_t n = (size_t)g->width * (size_t)g->height;
  obs_svar_plan *plan = malloc(sizeof *plan);
  if (!plan) return obs_err_set(err, OBS_ENOMEM, "ssao_variance: out of memory");
  double t0 = obs_now_ms();
  obs_svar_projection proj = {g->ortho, g->half_w};
  obs_svar_plan_make(p, g->depth, g->width, g->height, &proj, plan);
  double t1 = obs_now_ms(), t2 = t1, t3 = t1;
  int rc = 0;
  r->passes = plan->taps ? 2 : 0;
  if (!plan->taps) {
    /* A box of one pixel holds no neighbour: every pixel is open. */
    for (size_t i = 0; i < n; i++) ao[i] = 1.0f;
  } else {
    const int threads = r->threads < 1 ? 1 : r->threads;
    const size_t wz = (size_t)g->width;
    float *planes = malloc((4 * n + (size_t)threads * 4 * wz + wz) * sizeof *planes);
    int *ranges = malloc(2 * (size_t)g->height * sizeof *ranges);
    if (!planes || !ranges) {
      free(planes);
      free(ranges);
      free(plan);
      return obs_err_set(err, OBS_ENOMEM, "ssao_variance: %dx%d: out of memory", g->width,
                         g->height);
    }
    svar_job j = {.g = g,
                  .plan = plan,
                  .ao = ao,
                  .scratch = planes + 4 * n,
                  .row_lo = ranges,
                  .row_hi = ranges + g->height,
                  .simd = obs_simd_avx2()};
    j.rows = (obs_svar_rows){.depth = g->depth,
                             .w = g->width,
                             .h = g->height,
                             .stride = plan->stride,
                             .taps = plan->taps,
                             .zscale = plan->zscale,
                             .mn = planes,
                             .m1 = planes + n,
                             .m2 = planes + 2 * n,
                             .mc = planes + 3 * n,
                             .taps_x = planes + 4 * n + (size_t)threads * 4 * wz};
    /* Each column's taps in the box's row: the symmetric box's, 2 min(taps, m / stride) + 1. */
    for (int x = 0; x < g->width; x++) {
      const int m = x < g->width - 1 - x ? x : g->width - 1 - x, k = m / plan->stride;
      j.rows.taps_x[x] = (float)(2 * (plan->taps < k ? plan->taps : k) + 1);
    }
    /* Each row's covered span, and the columns any row covers. */
    int cmin = g->width, cmax = -1;
    for (int y = 0; y < g->height; y++) {
      const float *zr = g->depth + (size_t)y * wz;
      int lo = 0, hi = g->width - 1;
      while (lo < g->width && !(zr[lo] > 0.0f)) lo++;
      while (hi >= lo && !(zr[hi] > 0.0f)) hi--;
      j.row_lo[y] = lo;
      j.row_hi[y] = hi;
      if (lo <= hi && lo < cmin) cmin = lo;
      if (lo <= hi && hi > cmax) cmax = hi;
    }
    j.rows.clo = cmin & ~7;
    j.rows.chi = cmax + 1;
    obs_svar_ao_push_make(p, plan, g->width, g->height, g->ortho, &j.ap);
    const int isa = obs_simd_isa();
    rc = obs_screen_cpu_tiles(r, 1, g->height, obs_simd_tile_pick(moments_tile, isa), &j);
    t2 = obs_now_ms();
    if (!rc) rc = obs_screen_cpu_tiles(r, 1, g->height, obs_simd_tile_pick(ao_tile, isa), &j);
    t3 = obs_now_ms();
    free(planes);
    free(ranges);
  }
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = t2 - t1;
    stage_ms[2] = t3 - t2;
  }
  if (plan_out) *plan_out = *plan;
  free(plan);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ssao_variance: CPU passes failed");
  return rc;
}

int obs_svar_cpu_apply(const obs_gbuffer *g, const obs_ssao_variance_params *p, int threads,
                       float *ao, double *stage_ms, obs_svar_plan *plan_out, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return svar_passes(&r, g, p, ao, stage_ms, plan_out, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  double st[OBS_SVAR_CPU_STAGES];
  int rc = svar_passes(r, g, params, ao, st, NULL, err);
  if (rc) return rc;
  memcpy(ao_raw, ao, (size_t)g->width * (size_t)g->height * sizeof *ao);
  obs_screen_cpu_stage(r, "blur", st[0] + st[1]);
  obs_screen_cpu_stage(r, "ao", st[2]);
  return 0;
}

int obs_ssao_variance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
