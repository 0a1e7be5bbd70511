/* ss_obscurance on the CPU: the twin of ss_obscurance*.comp.glsl, operation for operation.
 *
 * Both sides must give the same bits on the same G-buffer, so this file keeps to float32, performs
 * each expression in the shader's order (ISO C: nothing is contracted to FMA; the shaders mark
 * the same expressions `precise`) and divides only where the shader divides. The definition is in
 * docs/techniques/ss_obscurance.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "sampling.h"
#include "screen.h"
#include "simd.h"
#include "ss_obscurance.h"
#include "sso_pixel.h"
#include "techniques.h"

typedef struct sso_job {
  const obs_gbuffer *g;
  const obs_sso_params *p;
  const obs_sso_tables *t;
  obs_sso_push pc;
  const float *raw; /* the average's input */
  float *out;
  int simd;  /* run the AVX2 spans (simd.h) */
  int loads; /* their gathers as scalar loads (obs_simd_gather_loads) */
  /* For the AVX2 spans: each lane's offset table, 16 phases ((y & 3) * 4 + (x & 3) of the span's
   * first pixel) x samples x (ox, oy, oz, weight) x 8 lanes, then per phase 1 / (sum of weights)
   * x 8 lanes: obs_sso_tables' floats rearranged, so a load gives the scalar code's operands. */
  const float *lanes;
} sso_job;

#define SSO_LANE_VALUES 4

/* sso_job.lanes (see there); `total` floats: lanes_size(samples). */
static size_t lanes_size(int samples) {
  return (size_t)16 * ((size_t)samples * SSO_LANE_VALUES + 1) * 8;
}

static void lanes_make(const obs_sso_tables *t, int samples, float *out) {
  for (int ph = 0; ph < 16; ph++) {
    float *base = out + (size_t)ph * ((size_t)samples * SSO_LANE_VALUES + 1) * 8;
    for (int l = 0; l < 8; l++) {
      int cell = t->cells == 1 ? 0 : (ph & ~3) | ((ph + l) & 3);
      for (int k = 0; k < samples; k++)
        for (int c = 0; c < SSO_LANE_VALUES; c++)
          base[((size_t)k * SSO_LANE_VALUES + (size_t)c) * 8 + (size_t)l] = t->offsets[cell][k][c];
      base[(size_t)samples * SSO_LANE_VALUES * 8 + (size_t)l] = t->offsets[cell][samples][0];
    }
  }
}

#if OBS_SIMD_AVX2
/* The pixels' view-space positions and their frames scaled by R (obs_sso_position, obs_onb), for
 * the eight lanes of sso_span8. */
typedef struct span_frame {
  __m256 p0, p1, tx, ty, tz, bx, by, bz, ux, uy, uz;
} span_frame;

OBS_AVX2_INLINE void span_frame_make(const sso_job *j, int x, int y, __m256 zp, span_frame *f) {
  const obs_sso_push *pc = &j->pc;
  const size_t i = (size_t)y * (size_t)j->g->width + (size_t)x;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256 R = _mm256_set1_ps(pc->radius);
  const __m256 fx = _mm256_add_ps(_mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane)),
                                  _mm256_set1_ps(0.5f));
  const __m256 nxp = _mm256_sub_ps(_mm256_mul_ps(fx, _mm256_set1_ps(pc->two_inv_w)), one);
  const __m256 nyp = _mm256_set1_ps(1.0f - ((float)y + 0.5f) * pc->two_inv_h);
  f->p0 = _mm256_mul_ps(nxp, _mm256_set1_ps(pc->half_w));
  f->p1 = _mm256_mul_ps(nyp, _mm256_set1_ps(pc->half_h));
  if (!(pc->flags & OBS_SSO_FLAG_ORTHO)) {
    f->p0 = _mm256_mul_ps(f->p0, zp);
    f->p1 = _mm256_mul_ps(f->p1, zp);
  }
  const __m256i i3 = _mm256_mullo_epi32(lane, _mm256_set1_epi32(3));
  const float *nb = j->g->normal + 3 * i;
  const __m256 n0 = obs_avx2_gather(j->loads, nb, i3), n1 = obs_avx2_gather(j->loads, nb + 1, i3);
  const __m256 n2 = obs_avx2_gather(j->loads, nb + 2, i3);
  /* obs_onb lane by lane: a component within OBS_ONB_FLAT of 0 is +0, then the sign of z. */
  const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 flat = _mm256_set1_ps(OBS_ONB_FLAT), neg = _mm256_set1_ps(-0.0f);
  const __m256 gx = _mm256_andnot_ps(_mm256_cmp_ps(_mm256_and_ps(n0, absmask), flat, _CMP_LT_OQ), n0);
  const __m256 gy = _mm256_andnot_ps(_mm256_cmp_ps(_mm256_and_ps(n1, absmask), flat, _CMP_LT_OQ), n1);
  const __m256 gz = _mm256_andnot_ps(_mm256_cmp_ps(_mm256_and_ps(n2, absmask), flat, _CMP_LT_OQ), n2);
  const __m256 sign = _mm256_blendv_ps(one, _mm256_set1_ps(-1.0f), _mm256_cmp_ps(gz, zero, _CMP_LT_OQ));
  const __m256 a = _mm256_div_ps(_mm256_set1_ps(-1.0f), _mm256_add_ps(sign, gz));
  const __m256 c = _mm256_mul_ps(_mm256_mul_ps(gx, gy), a);
  const __m256 t0 = _mm256_add_ps(one, _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(sign, gx), gx), a));
  const __m256 t1 = _mm256_mul_ps(sign, c), t2 = _mm256_mul_ps(_mm256_xor_ps(sign, neg), gx);
  const __m256 b1 = _mm256_add_ps(sign, _mm256_mul_ps(_mm256_mul_ps(gy, gy), a));
  f->tx = _mm256_mul_ps(t0, R);
  f->ty = _mm256_mul_ps(t1, R);
  f->tz = _mm256_mul_ps(t2, R);
  f->bx = _mm256_mul_ps(c, R);
  f->by = _mm256_mul_ps(b1, R);
  f->bz = _mm256_mul_ps(_mm256_xor_ps(gy, neg), R);
  f->ux = _mm256_mul_ps(n0, R);
  f->uy = _mm256_mul_ps(n1, R);
  f->uz = _mm256_mul_ps(n2, R);
}

/* obs_sso_pixel for pixels x..x+7 of row y (all inside the image): the same operations per lane,
 * every branch of the scalar code a mask. */
OBS_AVX2_FN static void sso_span8(const sso_job *j, int x, int y, float *dst) {
  const obs_gbuffer *g = j->g;
  const obs_sso_push *pc = &j->pc;
  const int w = g->width;
  const size_t i = (size_t)y * (size_t)w + (size_t)x;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f);
  const __m256 zp = _mm256_loadu_ps(g->depth + i);
  const __m256 covered = _mm256_cmp_ps(zp, zero, _CMP_GT_OQ);
  if (!_mm256_movemask_ps(covered)) {
    _mm256_storeu_ps(dst, one);
    return;
  }
  const int ortho = pc->flags & OBS_SSO_FLAG_ORTHO;
  span_frame f;
  span_frame_make(j, x, y, zp, &f);
  const __m256 p0 = f.p0, p1 = f.p1, tx = f.tx, ty = f.ty, tz = f.tz, bx = f.bx, by = f.by;
  const __m256 bz = f.bz, ux = f.ux, uy = f.uy, uz = f.uz;
  const __m256 hwv = _mm256_set1_ps(pc->half_w), hhv = _mm256_set1_ps(pc->half_h);
  const __m256 tiw = _mm256_set1_ps(pc->two_inv_w), tih = _mm256_set1_ps(pc->two_inv_h);
  const __m256 R = _mm256_set1_ps(pc->radius);
  const __m256 ihw = _mm256_set1_ps(pc->inv_half_w), ihh = _mm256_set1_ps(pc->inv_half_h);
  const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const float *lt = j->lanes + (size_t)(((y & 3) << 2) | (x & 3)) *
                                   ((size_t)pc->samples * SSO_LANE_VALUES + 1) * 8;
  const __m256 hw = _mm256_set1_ps(0.5f * (float)w), hh = _mm256_set1_ps(0.5f * (float)g->height);
  const __m256 xmax = _mm256_set1_ps((float)(w - 1)), ymax = _mm256_set1_ps((float)(g->height - 1));
  const __m256 slackf = _mm256_set1_ps((float)OBS_SSO_SLACK);
  const __m256i wv = _mm256_set1_epi32(w);
  __m256 closed = zero;
  for (int k = 0; k < pc->samples; k++) {
    const float *o = lt + (size_t)k * (SSO_LANE_VALUES * 8);
    const __m256 ox = _mm256_loadu_ps(o), oy = _mm256_loadu_ps(o + 8);
    const __m256 oz = _mm256_loadu_ps(o + 16), ow = _mm256_loadu_ps(o + 24);
    const __m256 sx = _mm256_add_ps(p0, _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ox, tx),
                                                                    _mm256_mul_ps(oy, bx)),
                                                      _mm256_mul_ps(oz, ux)));
    const __m256 sy = _mm256_add_ps(p1, _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ox, ty),
                                                                    _mm256_mul_ps(oy, by)),
                                                      _mm256_mul_ps(oz, uy)));
    const __m256 sz = _mm256_add_ps(zp, _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ox, tz),
                                                                    _mm256_mul_ps(oy, bz)),
                                                      _mm256_mul_ps(oz, uz)));
    __m256 u, v, live = covered;
    if (ortho) {
      u = _mm256_mul_ps(sx, ihw);
      v = _mm256_mul_ps(sy, ihh);
    } else {
      live = _mm256_and_ps(live, _mm256_cmp_ps(sz, zero, _CMP_GT_OQ));
      const __m256 rz = _mm256_div_ps(one, sz);
      u = _mm256_mul_ps(_mm256_mul_ps(sx, rz), ihw);
      v = _mm256_mul_ps(_mm256_mul_ps(sy, rz), ihh);
    }
    /* obs_sso_texel: max_ps(f, 0) is f > 0 ? f : 0 (NaN to 0), min_ps(f, n-1) f < n-1 ? f : n-1. */
    __m256 qxf = _mm256_floor_ps(_mm256_mul_ps(_mm256_add_ps(u, one), hw));
    __m256 qyf = _mm256_floor_ps(_mm256_mul_ps(_mm256_sub_ps(one, v), hh));
    qxf = _mm256_min_ps(_mm256_max_ps(qxf, zero), xmax);
    qyf = _mm256_min_ps(_mm256_max_ps(qyf, zero), ymax);
    const __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(qyf), wv),
                                         _mm256_cvttps_epi32(qxf));
    const __m256 zq = obs_avx2_gather(j->loads, g->depth, idx);
    live = _mm256_and_ps(live, _mm256_cmp_ps(zq, zero, _CMP_GT_OQ));
    live = _mm256_andnot_ps(_mm256_cmp_ps(_mm256_sub_ps(sz, zq), R, _CMP_GT_OQ), live);
    if (!_mm256_movemask_ps(live)) continue;
    const __m256 qnx = _mm256_sub_ps(_mm256_mul_ps(_mm256_add_ps(qxf, half), tiw), one);
    const __m256 qny = _mm256_sub_ps(one, _mm256_mul_ps(_mm256_add_ps(qyf, half), tih));
    __m256 s0 = _mm256_mul_ps(qnx, hwv), s1 = _mm256_mul_ps(qny, hhv);
    if (!ortho) {
      s0 = _mm256_mul_ps(s0, zq);
      s1 = _mm256_mul_ps(s1, zq);
    }
    const __m256i q3 = _mm256_add_epi32(_mm256_add_epi32(idx, idx), idx);
    const __m256 m0 = obs_avx2_gather(j->loads, g->normal, q3);
    const __m256 m1 = obs_avx2_gather(j->loads, g->normal + 1, q3);
    const __m256 m2 = obs_avx2_gather(j->loads, g->normal + 2, q3);
    const __m256 d = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_sub_ps(sx, s0), m0),
                      _mm256_mul_ps(_mm256_sub_ps(sy, s1), m1)),
        _mm256_mul_ps(_mm256_sub_ps(sz, zq), m2));
    const __m256 mag = _mm256_add_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_and_ps(s0, absmask), _mm256_and_ps(s1, absmask)), zq),
        R);
    const __m256 neg_slack = _mm256_xor_ps(_mm256_mul_ps(slackf, mag), _mm256_set1_ps(-0.0f));
    const __m256 shut = _mm256_and_ps(live, _mm256_cmp_ps(d, neg_slack, _CMP_LT_OQ));
    /* closed + 0 is closed: it starts at +0 and only grows. */
    closed = _mm256_add_ps(closed, _mm256_and_ps(ow, shut));
  }
  const __m256 inv = _mm256_loadu_ps(lt + (size_t)pc->samples * SSO_LANE_VALUES * 8);
  __m256 r = _mm256_sub_ps(one, _mm256_mul_ps(closed, inv));
  r = _mm256_blendv_ps(r, zero, _mm256_cmp_ps(r, zero, _CMP_LT_OQ));
  _mm256_storeu_ps(dst, _mm256_blendv_ps(one, r, covered));
}
#endif

OBS_HOT_INLINE int ao_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  sso_job *j = user;
  const size_t w = (size_t)j->g->width;
  for (int y = y0; y < y1; y++) {
    int x = x0;
#if OBS_SIMD_AVX2
    if (j->simd)
      for (; x + 8 <= x1; x += 8) sso_span8(j, x, y, j->out + (size_t)y * w + (size_t)x);
#endif
    for (; x < x1; x++)
      j->out[(size_t)y * w + (size_t)x] =
          obs_sso_pixel(&j->pc, j->g->depth, j->g->normal, &j->t->offsets[0][0][0], x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(ao_tile)

/* The 4x4 average of the interleaved pattern over neighbours within R in depth, as the mean of
 * the closed shares 1 - W, so that an open neighbourhood reads exactly 1. */
OBS_HOT_INLINE float avg_pixel(const sso_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const int w = g->width, h = g->height;
  const float zc = g->depth[(size_t)y * (size_t)w + (size_t)x];
  if (!(zc > 0.0f)) return 1.0f;
  const float lim = j->pc.radius;
  float sum = 0.0f;
  int cnt = 0;
  for (int dy = OBS_SSO_AVG_LO; dy <= OBS_SSO_AVG_HI; dy++)
    for (int dx = OBS_SSO_AVG_LO; dx <= OBS_SSO_AVG_HI; dx++) {
      int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      size_t k = (size_t)yy * (size_t)w + (size_t)xx;
      float zn = g->depth[k];
      if (zn > 0.0f && fabsf(zn - zc) <= lim) {
        sum += 1.0f - j->raw[k];
        cnt++;
      }
    }
  /* cnt >= 1: the centre always passes. */
  float r = 1.0f - sum * j->t->inv_count[cnt];
  return r < 0.0f ? 0.0f : r;
}

#if OBS_SIMD_AVX2
/* avg_pixel for pixels x..x+7 of row y, whose 4x4 windows lie inside the image horizontally. */
OBS_AVX2_FN static void avg_span8(const sso_job *j, int x, int y, float *dst) {
  const obs_gbuffer *g = j->g;
  const int w = g->width, h = g->height;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 zc = _mm256_loadu_ps(g->depth + (size_t)y * (size_t)w + (size_t)x);
  const __m256 covered = _mm256_cmp_ps(zc, zero, _CMP_GT_OQ);
  if (!_mm256_movemask_ps(covered)) {
    _mm256_storeu_ps(dst, one);
    return;
  }
  const __m256 lim = _mm256_set1_ps(j->pc.radius);
  __m256 sum = zero;
  __m256i cnt = _mm256_setzero_si256();
  for (int dy = OBS_SSO_AVG_LO; dy <= OBS_SSO_AVG_HI; dy++) {
    int yy = y + dy;
    if (yy < 0 || yy >= h) continue;
    const float *zr = g->depth + (size_t)yy * (size_t)w + (size_t)x;
    const float *ar = j->raw + (size_t)yy * (size_t)w + (size_t)x;
    for (int dx = OBS_SSO_AVG_LO; dx <= OBS_SSO_AVG_HI; dx++) {
      __m256 zn = _mm256_loadu_ps(zr + dx);
      __m256 ok = _mm256_and_ps(
          _mm256_cmp_ps(_mm256_and_ps(_mm256_sub_ps(zn, zc), absmask), lim, _CMP_LE_OQ),
          _mm256_cmp_ps(zn, zero, _CMP_GT_OQ));
      /* sum + 0 is sum: it starts at +0 and only grows (1 - raw >= +0). */
      sum = _mm256_add_ps(sum, _mm256_and_ps(_mm256_sub_ps(one, _mm256_loadu_ps(ar + dx)), ok));
      cnt = _mm256_sub_epi32(cnt, _mm256_castps_si256(ok));
    }
  }
  __m256 r = _mm256_sub_ps(one, _mm256_mul_ps(sum, obs_avx2_gather(j->loads, j->t->inv_count, cnt)));
  r = _mm256_blendv_ps(r, zero, _mm256_cmp_ps(r, zero, _CMP_LT_OQ));
  _mm256_storeu_ps(dst, _mm256_blendv_ps(one, r, covered));
}
#endif

OBS_HOT_INLINE int avg_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  sso_job *j = user;
  const int w = j->g->width;
  for (int y = y0; y < y1; y++) {
    float *row = j->out + (size_t)y * (size_t)w;
    int x = x0;
#if OBS_SIMD_AVX2
    if (j->simd) {
      /* Left of x = 2 and at x = w - 1 the window leaves the image: scalar there. */
      for (; x < x1 && x < -OBS_SSO_AVG_LO; x++) row[x] = avg_pixel(j, x, y);
      const int hi = w - OBS_SSO_AVG_HI; /* spans inside [2, hi) */
      for (; x + 8 <= x1 && x + 8 <= hi; x += 8) avg_span8(j, x, y, row + x);
    }
#endif
    for (; x < x1; x++) row[x] = avg_pixel(j, x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(avg_tile)

/* The two passes, within a render (r, where they record their stages) or outside one. */
static int sso_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_sso_params *p, float *ao,
                      float *ao_raw, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SSO_CPU_STAGES; k++) stage_ms[k] = 0.0;
  int rc = obs_sso_params_valid(p, err);
  if (rc) return rc;
  if (!g || !ao || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: missing G-buffer or output");
  size_t n = (size_t)g->width * (size_t)g->height;
  /* The vector kernels index with 32-bit lanes (3 per pixel for the normals). */
  const int isa = obs_simd_isa();
  int simd = obs_simd_avx2() && n <= (size_t)INT32_MAX / 3;
  /* The raw pass writes where its result is wanted; scratch only when it is not. */
  float *raw = p->interleave ? ao_raw : ao, *own = raw ? NULL : malloc(n * sizeof *own);
  float *lanes = simd ? malloc(lanes_size(p->samples) * sizeof *lanes) : NULL;
  obs_sso_tables *t = malloc(sizeof *t);
  if (!t || (!raw && !own) || (simd && !lanes)) {
    free(t);
    free(lanes);
    free(own);
    return obs_err_set(err, OBS_ENOMEM, "ss_obscurance: %dx%d: out of memory", g->width,
                       g->height);
  }
  if (!raw) raw = own;
  obs_sso_tables_make(p, t);
  if (lanes) lanes_make(t, p->samples, lanes);
  sso_job j = {.g = g, .p = p, .t = t, .raw = raw, .out = raw, .simd = simd,
               .loads = obs_simd_gather_loads(), .lanes = lanes};
  obs_sso_push_make(p, g->width, g->height, g->ortho, g->half_w, g->half_h, &j.pc);
  r->passes = p->interleave ? 2 : 1;
  double t0 = obs_now_ms();
  rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(ao_tile, isa), &j);
  double t1 = obs_now_ms();
  if (!rc && p->interleave) {
    j.out = ao;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(avg_tile, isa), &j);
  } else if (!rc && ao_raw) {
    memcpy(ao_raw, ao, n * sizeof *ao);
  }
  double t2 = obs_now_ms();
  if (!rc) obs_screen_cpu_stage(r, "ao", t1 - t0);
  if (!rc && p->interleave) obs_screen_cpu_stage(r, "blur", t2 - t1);
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = p->interleave ? t2 - t1 : 0.0;
  }
  free(own);
  free(lanes);
  free(t);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ss_obscurance: CPU passes failed");
  return rc;
}

int obs_sso_cpu_apply(const obs_gbuffer *g, const obs_sso_params *p, int threads, float *ao,
                      float *ao_raw, double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return sso_passes(&r, g, p, ao, ao_raw, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  return sso_passes(r, g, params, ao, ao_raw, NULL, err);
}

int obs_ss_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
