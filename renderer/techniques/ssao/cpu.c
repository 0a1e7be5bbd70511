/* ssao on the CPU: the twin of ssao*.comp.glsl beside it, operation for operation.
 *
 * Both sides must give the same bits on the same G-buffer, so this file keeps to float32, performs
 * each expression in the shader's order (the C build is ISO C, so nothing is contracted to FMA;
 * the shaders mark the same expressions `precise`) and divides only where the shader divides. The
 * definition itself is in docs/techniques/ssao.md. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "gbuffer_cpu.h"
#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"
#include "simd.h"
#include "ssao.h"
#include "techniques.h"

typedef struct ssao_job {
  const obs_gbuffer *g;
  const obs_ssao_params *p;
  const obs_ssao_tables *t;
  const float *raw; /* blur input */
  float *out;
  int simd;  /* run the AVX2 spans (simd.h) */
  int loads; /* their gathers as scalar loads (obs_simd_gather_loads) */
  /* For the AVX2 spans: each lane's reflected offset per sample, computed once with ssao_pixel's
   * operations, so a load gives the same bits as the expression. 16 cells ((y & 3) * 4 + (x & 3)
   * of the span's first pixel) x samples x (ox, oy, oz, ox w, oy h) x 8 lanes. */
  const float *lanes;
} ssao_job;

#define SSAO_LANE_VALUES 5

/* ssao_job.lanes for width w and height h (see there). */
static void ssao_lanes_make(const obs_ssao_tables *t, int samples, int w, int h, float *out) {
  const float fw = (float)w, fh = (float)h;
  for (int ph = 0; ph < 16; ph++)
    for (int k = 0; k < samples; k++)
      for (int l = 0; l < 8; l++) {
        const float *rot = t->rotation[(ph & ~3) | ((ph + l) & 3)];
        const float *v = t->offsets[k];
        float d = rot[0] * v[0] + rot[1] * v[1] + rot[2] * v[2];
        float tt = 2.0f * d;
        float o[SSAO_LANE_VALUES] = {v[0] - tt * rot[0], v[1] - tt * rot[1], v[2] - tt * rot[2], 0, 0};
        o[3] = o[0] * fw;
        o[4] = o[1] * fh;
        for (int c = 0; c < SSAO_LANE_VALUES; c++)
          out[(((size_t)ph * (size_t)samples + (size_t)k) * SSAO_LANE_VALUES + (size_t)c) * 8 + (size_t)l] = o[c];
      }
}

/* floor(v) clamped to [0, n-1]: the texel a sample lands on, clamp-to-edge. The clamp comes before
 * the conversion, as in the shader, so huge offsets never overflow an int. */
OBS_HOT_INLINE int texel(float v, int n) {
  float f = floorf(v);
  if (f < 0.0f) f = 0.0f;
  if (f > (float)(n - 1)) f = (float)(n - 1);
  return (int)f;
}

OBS_HOT_INLINE float ssao_pixel(const ssao_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const obs_ssao_tables *t = j->t;
  const int w = g->width, h = g->height;
  const size_t i = (size_t)y * (size_t)w + (size_t)x;
  const float zp = g->depth[i];
  if (!(zp > 0.0f)) return 1.0f;
  const float *rot = t->rotation[(y & 3) * 4 + (x & 3)];
  const float fx = (float)x + 0.5f, fy = (float)y + 0.5f, fw = (float)w, fh = (float)h;
  /* A texture-coordinate offset (ox, oy, oz) is the view-space vector
   * (2 half_w s ox, -2 half_h s oy, 2 z_p oz), s = z_p (perspective) or 1 (orthographic): the
   * screen spans 2 half_w s across at depth z_p, and texture v grows downwards. */
  const float s = g->ortho ? 1.0f : zp;
  const float kx = 2.0f * g->half_w * s, ky = -2.0f * g->half_h * s, kz = 2.0f * zp;
  const float *n = g->normal + 3 * i;
  float sum = 0.0f;
  for (int k = 0; k < j->p->samples; k++) {
    const float *v = t->offsets[k];
    /* reflect(v, rot) = v - 2 dot(rot, v) rot */
    float d = rot[0] * v[0] + rot[1] * v[1] + rot[2] * v[2];
    float tt = 2.0f * d;
    float ox = v[0] - tt * rot[0], oy = v[1] - tt * rot[1], oz = v[2] - tt * rot[2];
    if (j->p->normal_oriented) {
      float dn = ox * kx * n[0] + oy * ky * n[1] + oz * kz * n[2];
      if (dn < 0.0f) {
        ox = -ox;
        oy = -oy;
        oz = -oz;
      }
    }
    int sx = texel(fx + ox * fw, w), sy = texel(fy + oy * fh, h);
    float zs = g->depth[(size_t)sy * (size_t)w + (size_t)sx];
    /* Background is infinitely far: the sample is in free space and its range is valid. */
    if (!(zs > 0.0f)) {
      sum += 1.0f;
      continue;
    }
    float sz = zp + oz * zp * 2.0f;
    float vis = zs > sz ? 1.0f : 0.0f;
    float f = (zp - zs) / zs;
    f = f < 0.0f ? 0.0f : f > 1.0f ? 1.0f : f;
    sum += vis + f * (0.5f - vis);
  }
  float a = sum * t->inv_samples;
  float c = a * a + a;
  return c < 0.0f ? 0.0f : c > 1.0f ? 1.0f : c;
}

#if OBS_SIMD_AVX2
/* ssao_pixel for pixels x..x+7 of row y (all inside the image), same operations per lane. */
OBS_AVX2_FN static void ssao_span8(const ssao_job *j, int x, int y, float *dst) {
  const obs_gbuffer *g = j->g;
  const obs_ssao_tables *t = j->t;
  const int w = g->width, h = g->height;
  const size_t i = (size_t)y * (size_t)w + (size_t)x;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 two = _mm256_set1_ps(2.0f), half = _mm256_set1_ps(0.5f);
  const __m256 zp = _mm256_loadu_ps(g->depth + i);
  const __m256 covered = _mm256_cmp_ps(zp, zero, _CMP_GT_OQ);
  if (!_mm256_movemask_ps(covered)) {
    _mm256_storeu_ps(dst, one);
    return;
  }
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const float *lt = j->lanes + (size_t)(((y & 3) << 2) | (x & 3)) * (size_t)j->p->samples *
                                   (SSAO_LANE_VALUES * 8);
  const __m256 fx = _mm256_add_ps(_mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane)),
                                  half);
  const __m256 fy = _mm256_set1_ps((float)y + 0.5f);
  const __m256 xmax = _mm256_set1_ps((float)(w - 1)), ymax = _mm256_set1_ps((float)(h - 1));
  const __m256 s = g->ortho ? one : zp;
  const __m256 kx = _mm256_mul_ps(_mm256_set1_ps(2.0f * g->half_w), s);
  const __m256 ky = _mm256_mul_ps(_mm256_set1_ps(-2.0f * g->half_h), s);
  const __m256 kz = _mm256_mul_ps(two, zp);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  __m256 n0 = zero, n1 = zero, n2 = zero;
  if (j->p->normal_oriented) {
    const __m256i i3 = _mm256_mullo_epi32(lane, _mm256_set1_epi32(3));
    const float *nb = g->normal + 3 * i;
    n0 = obs_avx2_gather(j->loads, nb, i3);
    n1 = obs_avx2_gather(j->loads, nb + 1, i3);
    n2 = obs_avx2_gather(j->loads, nb + 2, i3);
  }
  const __m256i wv = _mm256_set1_epi32(w);
  __m256 sum = zero;
  for (int k = 0; k < j->p->samples; k++) {
    const float *o = lt + (size_t)k * (SSAO_LANE_VALUES * 8);
    __m256 ox = _mm256_loadu_ps(o), oy = _mm256_loadu_ps(o + 8), oz = _mm256_loadu_ps(o + 16);
    __m256 oxw = _mm256_loadu_ps(o + 24), oyh = _mm256_loadu_ps(o + 32);
    if (j->p->normal_oriented) {
      __m256 dn = _mm256_add_ps(
          _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(ox, kx), n0),
                        _mm256_mul_ps(_mm256_mul_ps(oy, ky), n1)),
          _mm256_mul_ps(_mm256_mul_ps(oz, kz), n2));
      /* Rounding is symmetric: (-ox) w is -(ox w). */
      __m256 flip = _mm256_and_ps(_mm256_cmp_ps(dn, zero, _CMP_LT_OQ), sign);
      oz = _mm256_xor_ps(oz, flip);
      oxw = _mm256_xor_ps(oxw, flip);
      oyh = _mm256_xor_ps(oyh, flip);
    }
    __m256 sxf = _mm256_floor_ps(_mm256_add_ps(fx, oxw));
    __m256 syf = _mm256_floor_ps(_mm256_add_ps(fy, oyh));
    sxf = _mm256_min_ps(_mm256_max_ps(sxf, zero), xmax);
    syf = _mm256_min_ps(_mm256_max_ps(syf, zero), ymax);
    __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(syf), wv),
                                   _mm256_cvttps_epi32(sxf));
    __m256 zs = obs_avx2_gather(j->loads, g->depth, idx);
    __m256 bg = _mm256_cmp_ps(zs, zero, _CMP_NGT_UQ);
    __m256 sz = _mm256_add_ps(zp, _mm256_mul_ps(_mm256_mul_ps(oz, zp), two));
    __m256 vis = _mm256_and_ps(_mm256_cmp_ps(zs, sz, _CMP_GT_OQ), one);
    __m256 f = _mm256_div_ps(_mm256_sub_ps(zp, zs), zs);
    f = _mm256_min_ps(_mm256_max_ps(f, zero), one);
    __m256 c = _mm256_add_ps(vis, _mm256_mul_ps(f, _mm256_sub_ps(half, vis)));
    sum = _mm256_add_ps(sum, _mm256_blendv_ps(c, one, bg));
  }
  __m256 a = _mm256_mul_ps(sum, _mm256_set1_ps(t->inv_samples));
  __m256 c = _mm256_add_ps(_mm256_mul_ps(a, a), a);
  c = _mm256_min_ps(_mm256_max_ps(c, zero), one);
  _mm256_storeu_ps(dst, _mm256_blendv_ps(one, c, covered));
}

/* blur_pixel for pixels x..x+7 of row y, whose 4x4 windows lie inside the image horizontally.
 * test_zero 0 drops blur_pixel's test zn > 0, which cannot decide where the threshold is at most
 * 1/2: lim = thr zc rounds to at most zc / 2, while zn <= 0 gives |zn - zc| >= zc (rounding is
 * monotonic and zc is a float), so such a tap fails the depth test anyway. */
OBS_AVX2_INLINE void blur_span8_body(const ssao_job *j, int x, int y, float *dst, int test_zero) {
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
  const __m256 lim = _mm256_mul_ps(_mm256_set1_ps(j->p->blur_depth_threshold), zc);
  __m256 sum = zero;
  __m256i cnt = _mm256_setzero_si256();
  for (int dy = OBS_SSAO_BLUR_LO; dy <= OBS_SSAO_BLUR_HI; dy++) {
    int yy = y + dy;
    if (yy < 0 || yy >= h) continue;
    const float *zr = g->depth + (size_t)yy * (size_t)w + (size_t)x;
    const float *ar = j->raw + (size_t)yy * (size_t)w + (size_t)x;
    for (int dx = OBS_SSAO_BLUR_LO; dx <= OBS_SSAO_BLUR_HI; dx++) {
      __m256 zn = _mm256_loadu_ps(zr + dx);
      __m256 ok = _mm256_cmp_ps(_mm256_and_ps(_mm256_sub_ps(zn, zc), absmask), lim, _CMP_LE_OQ);
      if (test_zero) ok = _mm256_and_ps(ok, _mm256_cmp_ps(zn, zero, _CMP_GT_OQ));
      /* sum + 0 is sum: it starts at +0 and only grows. */
      sum = _mm256_add_ps(sum, _mm256_and_ps(_mm256_loadu_ps(ar + dx), ok));
      cnt = _mm256_sub_epi32(cnt, _mm256_castps_si256(ok));
    }
  }
  __m256 r = _mm256_mul_ps(sum, obs_avx2_gather(j->loads, j->t->inv_count, cnt));
  r = _mm256_min_ps(r, one);
  _mm256_storeu_ps(dst, _mm256_blendv_ps(one, r, covered));
}

OBS_AVX2_FN static void blur_span8(const ssao_job *j, int x, int y, float *dst) {
  if (j->p->blur_depth_threshold <= 0.5f)
    blur_span8_body(j, x, y, dst, 0);
  else
    blur_span8_body(j, x, y, dst, 1);
}
#endif

OBS_HOT_INLINE int ao_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  ssao_job *j = user;
  const size_t w = (size_t)j->g->width;
  for (int y = y0; y < y1; y++) {
    int x = x0;
#if OBS_SIMD_AVX2
    if (j->simd)
      for (; x + 8 <= x1; x += 8) ssao_span8(j, x, y, j->out + (size_t)y * w + (size_t)x);
#endif
    for (; x < x1; x++) j->out[(size_t)y * w + (size_t)x] = ssao_pixel(j, x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(ao_tile)

OBS_HOT_INLINE float blur_pixel(const ssao_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const int w = g->width, h = g->height;
  const float zc = g->depth[(size_t)y * (size_t)w + (size_t)x];
  if (!(zc > 0.0f)) return 1.0f;
  const float lim = j->p->blur_depth_threshold * zc;
  float sum = 0.0f;
  int cnt = 0;
  for (int dy = OBS_SSAO_BLUR_LO; dy <= OBS_SSAO_BLUR_HI; dy++)
    for (int dx = OBS_SSAO_BLUR_LO; dx <= OBS_SSAO_BLUR_HI; dx++) {
      int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      size_t k = (size_t)yy * (size_t)w + (size_t)xx;
      float zn = g->depth[k];
      if (zn > 0.0f && fabsf(zn - zc) <= lim) {
        sum += j->raw[k];
        cnt++;
      }
    }
  /* cnt >= 1: the centre always passes. */
  float r = sum * j->t->inv_count[cnt];
  return r > 1.0f ? 1.0f : r;
}

OBS_HOT_INLINE int blur_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  ssao_job *j = user;
  const int w = j->g->width;
  for (int y = y0; y < y1; y++) {
    float *row = j->out + (size_t)y * (size_t)w;
    int x = x0;
#if OBS_SIMD_AVX2
    if (j->simd) {
      /* Left of x = 2 and at x = w - 1 the window leaves the image: scalar there. */
      for (; x < x1 && x < -OBS_SSAO_BLUR_LO; x++) row[x] = blur_pixel(j, x, y);
      const int lo = -OBS_SSAO_BLUR_LO, hi = w - OBS_SSAO_BLUR_HI; /* spans inside [lo, hi) */
      for (; x + 8 <= x1 && x + 8 <= hi; x += 8) blur_span8(j, x, y, row + x);
      /* The rest of the run as one span overlapping the previous one (the same bits per pixel
       * whichever span computes it), where it stays inside the tile and the image. */
      const int e = x1 < hi ? x1 : hi;
      if (x < e && e - 8 >= lo && e - 8 >= x0) {
        blur_span8(j, e - 8, y, row + e - 8);
        x = e;
      }
    }
#endif
    for (; x < x1; x++) row[x] = blur_pixel(j, x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(blur_tile)

/* The AO pass and the blur: obs_ssao_cpu_apply_ex within a render (r) or outside one. */
static int ssao_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_ssao_params *p,
                       float *ao, float *ao_raw, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SSAO_CPU_STAGES; k++) stage_ms[k] = 0.0;
  if (!g || !p || !ao || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ssao: missing G-buffer, parameters or output");
  if (p->samples != 8 && p->samples != 16 && p->samples != 24)
    return obs_err_set(err, OBS_EINVAL, "ssao: samples must be 8, 16 or 24 (got %d)", p->samples);
  obs_ssao_tables t;
  obs_ssao_tables_make(p, &t);
  size_t n = (size_t)g->width * (size_t)g->height;
  float *raw = ao_raw;
  if (p->blur && !raw && !(raw = malloc(n * sizeof *raw)))
    return obs_err_set(err, OBS_ENOMEM, "ssao: %dx%d: out of memory", g->width, g->height);
  /* The vector kernels index with 32-bit lanes. */
  const int isa = obs_simd_isa();
  int simd = obs_simd_avx2() && n <= (size_t)INT32_MAX;
  float *lanes = NULL;
  if (simd) {
    lanes = malloc((size_t)16 * (size_t)p->samples * SSAO_LANE_VALUES * 8 * sizeof *lanes);
    if (!lanes) {
      if (raw != ao_raw) free(raw);
      return obs_err_set(err, OBS_ENOMEM, "ssao: %dx%d: out of memory", g->width, g->height);
    }
    ssao_lanes_make(&t, p->samples, g->width, g->height, lanes);
  }
  ssao_job j = {.g = g,
                .p = p,
                .t = &t,
                .raw = raw,
                .out = p->blur ? raw : ao,
                .simd = simd,
                .loads = obs_simd_gather_loads(),
                .lanes = lanes};
  r->passes = p->blur ? 2 : 1;
  double t0 = obs_now_ms();
  int rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(ao_tile, isa), &j);
  double t1 = obs_now_ms();
  if (!rc && p->blur) {
    j.out = ao;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(blur_tile, isa), &j);
  } else if (!rc && ao_raw) {
    memcpy(ao_raw, ao, n * sizeof *ao);
  }
  double t2 = obs_now_ms();
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = p->blur ? t2 - t1 : 0.0;
  }
  if (raw != ao_raw) free(raw);
  free(lanes);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ssao: CPU passes failed");
  return rc;
}

int obs_ssao_cpu_apply_ex(const obs_gbuffer *g, const obs_ssao_params *p, int threads, float *ao,
                          float *ao_raw, double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return ssao_passes(&r, g, p, ao, ao_raw, stage_ms, err);
}

int obs_ssao_cpu_apply(const obs_gbuffer *g, const obs_ssao_params *p, int threads, float *ao,
                       double *stage_ms, obs_err *err) {
  return obs_ssao_cpu_apply_ex(g, p, threads, ao, NULL, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const obs_ssao_params *p = params;
  double st[OBS_SSAO_CPU_STAGES];
  int rc = ssao_passes(r, g, p, ao, ao_raw, st, err);
  if (rc) return rc;
  obs_screen_cpu_stage(r, "ao", st[0]);
  if (p->blur) obs_screen_cpu_stage(r, "blur", st[1]);
  return 0;
}

int obs_ssao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
