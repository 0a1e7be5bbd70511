/* hbao on the CPU: the twin of vulkan.c and its shaders, operation for operation.
 *
 * Every float expression here is written in the order the GLSL writes it, in float32 (no double in
 * per-pixel math, no FMA contraction in ISO C mode), so that both backends give the same bits on the
 * same G-buffer except where noted (exp in the blur). The definition is in docs/techniques/hbao.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "hbao.h"
#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"
#include "simd.h"
#include "techniques.h"

#include "hbao_cpu.h"

/* Elevation (sin, cos) over the view plane z = const of the tangent plane (normal n) along the image
 * direction D = (dx, dy) (view-space, y up) seen from the pixel whose ray is r (r.z = 1; nr = n.r).
 * The tangent line is the tangent plane cut by the plane through the eye that contains the pixel's
 * ray and D: L = (n.D) r - (n.r) D, oriented to move along +D in the image. A planar surface's
 * samples therefore lie exactly on L whatever the perspective. */
OBS_HOT_INLINE void tangent(const float n[3], const float r[3], float nr, float dx, float dy, float *sin_t,
                    float *cos_t) {
  float nd = n[0] * dx + n[1] * dy;
  float lx = nd * r[0] - nr * dx;
  float ly = nd * r[1] - nr * dy;
  float lz = nd;
  if (!(nr < 0.0f)) { /* back-facing by rounding: keep the orientation along +D */
    lx = -lx;
    ly = -ly;
    lz = -lz;
  }
  float h2 = lx * lx + ly * ly;
  float l = sqrtf(h2 + lz * lz);
  if (!(l > 0.0f)) {
    *sin_t = 0.0f;
    *cos_t = 1.0f;
    return;
  }
  *sin_t = -lz / l;
  *cos_t = sqrtf(h2) / l;
}

/* 2^-e and 2^e for the binary exponent e of m > 0 (clamped so both are normal floats). Scaling by
 * them is exact: offsets S - P scaled by the pixel's depth's 2^-e are squared without over- or
 * underflow at any scene scale or radius (while |S - P| < ~1e19 z; the depth-uncertainty shift
 * keeps it above ~1e-7 z). */
OBS_HOT_INLINE void pow2_scale(float m, float *down, float *up) {
  uint32_t b;
  memcpy(&b, &m, sizeof b);
  uint32_t e = (b >> 23) & 0xffu;
  e = e < 1u ? 1u : e > 253u ? 253u : e;
  uint32_t d = (254u - e) << 23, u = e << 23;
  memcpy(down, &d, sizeof d);
  memcpy(up, &u, sizeof u);
}

OBS_HOT_INLINE float ao_texel(const hbao_job *jb, int ax, int ay) {
  const hbao_level *lv = &jb->lv;
  const obs_hbao_params *p = jb->p;
  const obs_gbuffer *g = jb->g;
  size_t ci = (size_t)ay * (size_t)lv->w + (size_t)ax;
  float z = lv->depth[ci];
  if (!(z > 0.0f)) return 1.0f;
  float R = p->radius;
  if (!(R > 0.0f)) return 1.0f;
  float fx = (float)(lv->s * ax) + 0.5f, fy = (float)(lv->s * ay) + 0.5f;
  float P[3];
  obs_gbuffer_position(g, fx, fy, z, P);
  float r[3] = {0.0f, 0.0f, 1.0f};
  if (!g->ortho) {
    r[0] = (2.0f * fx / (float)g->width - 1.0f) * g->half_w;
    r[1] = (1.0f - 2.0f * fy / (float)g->height) * g->half_h;
  }
  /* Projected radius in texels; under one texel nothing can be sampled (early exit). */
  float num = R * (0.5f * (float)g->width);
  float rpx = g->ortho ? num / g->half_w : num / (g->half_w * z);
  float rl = rpx / (float)lv->s;
  if (!(rl >= 1.0f)) return 1.0f;
  /* Beyond the screen samples would only repeat edge texels: march at most across it. */
  float cap = (float)(lv->w > lv->h ? lv->w : lv->h);
  if (rl > cap) rl = cap;
  float st = rl / (float)(p->steps + 1);
  const float *n = lv->normal + 3 * ci;
  float nr = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
  const float *row = jb->table + (size_t)((ay & 3) * 4 + (ax & 3)) * (size_t)p->directions * 4;
  float cx = (float)ax + 0.5f, cy = (float)ay + 0.5f;
  float down, up;
  pow2_scale(z, &down, &up);
  float rscale = up * jb->inv_r; /* exact: a power of two times 1/R */
  float sum = 0.0f;
  for (int i = 0; i < p->directions; i++) {
    float dx = row[4 * i], dy = row[4 * i + 1], jit = row[4 * i + 2];
    float sin_t, cos_t;
    tangent(n, r, nr, dx, -dy, &sin_t, &cos_t);
    /* Horizon starts at t + bias; past the zenith nothing can rise above it. */
    if (!(cos_t * jb->cos_b - sin_t * jb->sin_b > 0.0f)) continue;
    float sin_h = sin_t * jb->cos_b + cos_t * jb->sin_b;
    for (int k = 1; k <= p->steps; k++) {
      float o = ((float)k + jit) * st;
      float sx = cx + o * dx, sy = cy + o * dy;
      int ix = (int)floorf(sx), iy = (int)floorf(sy);
      ix = ix < 0 ? 0 : ix > lv->w - 1 ? lv->w - 1 : ix;
      iy = iy < 0 ? 0 : iy > lv->h - 1 ? lv->h - 1 : iy;
      if (ix == ax && iy == ay) continue;
      float zs = lv->depth[(size_t)iy * (size_t)lv->w + (size_t)ix];
      if (!(zs > 0.0f)) continue; /* background */
      float S[3];
      obs_gbuffer_position(g, (float)(lv->s * ix) + 0.5f, (float)(lv->s * iy) + 0.5f, zs, S);
      /* The sample moved away by its depth's uncertainty (OBS_HBAO_DEPTH_EPS), scaled by the
       * pixel's power of two; the distance in units of R uses the host's reciprocal of R. */
      float dx = S[0] - P[0], dy = S[1] - P[1], dz = (S[2] - P[2]) + jb->depth_eps * (zs + z);
      float qx = dx * down, qy = dy * down, qz = dz * down;
      float len = sqrtf(qx * qx + qy * qy + qz * qz);
      if (!(len > 0.0f)) continue;
      float dist = len * rscale;
      if (!(dist < 1.0f)) continue;
      float d2 = dist * dist;
      float sin_s = -qz / len;
      /* Texel snapping moves the sample off the direction's slice; measure its elevation against
       * the tangent in its own slice and re-base it on this direction's tangent, so points of the
       * tangent plane never count as horizon (the article hides this with the bias alone). */
      float sin_ts, cos_ts;
      tangent(n, r, nr, (float)(ix - ax), -(float)(iy - ay), &sin_ts, &cos_ts);
      float e = sin_s - sin_ts + sin_t;
      if (e > 1.0f) e = 1.0f;
      if (e > sin_h) {
        sum += (1.0f - d2) * (e - sin_h);
        sin_h = e;
      }
    }
  }
  float ao = 1.0f - p->scale * sum / (float)p->directions;
  return ao > 1.0f ? 1.0f : ao > 0.0f ? ao : 0.0f;
}


OBS_HOT_INLINE int ao_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  for (int y = y0; y < y1; y++) {
    float *row = jb->out + (size_t)y * (size_t)jb->lv.w;
    int x = x0;
#if OBS_SIMD_AVX2
    if (jb->simd) {
      for (; x + 32 <= x1; x += 32) /* four interleaved spans of stride 4 */
        for (int q = 0; q < 4; q++) obs_hbao_ao_span8(jb, x + q, 4, y, row + x + q);
      for (; x + 8 <= x1; x += 8) obs_hbao_ao_span8(jb, x, 1, y, row + x);
    }
#endif
    for (; x < x1; x++) row[x] = ao_texel(jb, x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(ao_tile)

/* exp(x) for the blur's weights, x <= 0, written once for the scalar and once for the AVX2 path
 * with the same operations, each a fused multiply-add where the formula has one (fmaf: an FMA
 * instruction in the x86-64-v3 loops, libm's correctly rounded fmaf in the baseline ones), so both
 * CPU paths give the same bits. Cephes' expf: x = n ln2 + r with n the integer nearest x log2(e)
 * (|r| <= ln2 / 2 and a little), a degree-7 polynomial for e^r, 2^n from the exponent bits; within
 * 2 ulp of expf. x is first raised to -88, where n = -127 gives 2^n's bits 0: the weight is +0
 * below about -87.7, a normal float above.
 * exp(0) is exactly 1, which the blur's centre tap relies on. The GLSL twin keeps the device's exp:
 * the two backends differ by ~1e-7 in the blurred AO. */
#define EXP_LO (-88.0f)
#define EXP_LOG2E 1.44269504088896341f
/* 1.5 * 2^23: x log2(e) + EXP_ROUND is rounded once to the integer n nearest x log2(e), which
 * then sits in the low mantissa bits (two's complement), so (bits + 127) << 23 is 2^n's bits. */
#define EXP_ROUND 12582912.0f
#define EXP_C1 0.693359375f
#define EXP_C2 (-2.12194440e-4f)
#define EXP_P0 1.9875691500e-4f
#define EXP_P1 1.3981999507e-3f
#define EXP_P2 8.3334519073e-3f
#define EXP_P3 4.1665795894e-2f
#define EXP_P4 1.6666665459e-1f
#define EXP_P5 5.0000001201e-1f
/* The blur's clamp of the squared relative depth difference: OBS_HBAO_MAX_REL_DZ^2 (1e8, exact). */
#define BLUR_MAX_Q2 (OBS_HBAO_MAX_REL_DZ * OBS_HBAO_MAX_REL_DZ)
/* Centre depths below BLUR_TINY_Z would overflow 1 / zc (from 2^-128 on): the depth difference and
 * zc are both scaled by BLUR_TINY_SCALE first, which is exact and leaves their ratio as it was. */
#define BLUR_TINY_Z 0x1p-100f
#define BLUR_TINY_SCALE 0x1p64f

OBS_HOT_INLINE float blur_exp(float x) {
  x = x > EXP_LO ? x : EXP_LO;
  const float m = fmaf(x, EXP_LOG2E, EXP_ROUND);
  const float n = m - EXP_ROUND;
  float r = fmaf(n, -EXP_C1, x);
  r = fmaf(n, -EXP_C2, r);
  float y = fmaf(EXP_P0, r, EXP_P1);
  y = fmaf(y, r, EXP_P2);
  y = fmaf(y, r, EXP_P3);
  y = fmaf(y, r, EXP_P4);
  y = fmaf(y, r, EXP_P5);
  y = fmaf(y, r * r, r) + 1.0f;
  uint32_t bits;
  memcpy(&bits, &m, sizeof bits);
  bits = (bits + 127u) << 23;
  float two_n;
  memcpy(&two_n, &bits, sizeof two_n);
  return y * two_n;
}

/* Relative depth difference, clamped so that its square times any allowed sharpness is finite. */
OBS_HOT_INLINE float rel_dz(float z, float zc) {
  float q = fabsf(z - zc) / zc;
  return q < OBS_HBAO_MAX_REL_DZ ? q : OBS_HBAO_MAX_REL_DZ;
}

/* Depth-aware bilinear upsampling of the half-resolution AO (jb->in) to full resolution. */
static int up_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  const obs_gbuffer *g = jb->g;
  const hbao_level *lv = &jb->lv;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      float zc = g->depth[i];
      if (!(zc > 0.0f)) {
        jb->out[i] = 1.0f;
        continue;
      }
      int hx[2] = {x >> 1, (x >> 1) + (x & 1)}, hy[2] = {y >> 1, (y >> 1) + (y & 1)};
      if (hx[1] > lv->w - 1) hx[1] = lv->w - 1;
      if (hy[1] > lv->h - 1) hy[1] = lv->h - 1;
      float bx[2] = {(x & 1) ? 0.5f : 1.0f, (x & 1) ? 0.5f : 0.0f};
      float by[2] = {(y & 1) ? 0.5f : 1.0f, (y & 1) ? 0.5f : 0.0f};
      float sw = 0.0f, sa = 0.0f;
      for (int c = 0; c < 4; c++) {
        int a = c & 1, b = c >> 1;
        float wb = bx[a] * by[b];
        if (!(wb > 0.0f)) continue;
        size_t j = (size_t)hy[b] * (size_t)lv->w + (size_t)hx[a];
        float z = lv->depth[j];
        if (!(z > 0.0f)) continue;
        float q = rel_dz(z, zc);
        float w = wb / (1.0f + OBS_HBAO_UPSAMPLE_K * (q * q));
        sw += w;
        sa += w * jb->in[j];
      }
      /* All four neighbours uncovered (a sliver thinner than two pixels): no information. */
      float v = sw > 0.0f ? sa / sw : 1.0f;
      jb->out[i] = v > 1.0f ? 1.0f : v > 0.0f ? v : 0.0f;
    }
  return 0;
}

#if OBS_SIMD_AVX2
/* The blur's AVX2 code uses FMA, which every CPU with the AVX2 level has (simd.h). */
#define BLUR_AVX2_INLINE static inline __attribute__((target("avx2,fma"), always_inline))
#define BLUR_AVX2_FN __attribute__((target("avx2,fma")))

BLUR_AVX2_INLINE __m256 blur_exp8(__m256 x) {
  x = _mm256_max_ps(x, _mm256_set1_ps(EXP_LO));
  const __m256 m = _mm256_fmadd_ps(x, _mm256_set1_ps(EXP_LOG2E), _mm256_set1_ps(EXP_ROUND));
  const __m256 n = _mm256_sub_ps(m, _mm256_set1_ps(EXP_ROUND));
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(EXP_C1), x);
  r = _mm256_fnmadd_ps(n, _mm256_set1_ps(EXP_C2), r);
  __m256 y = _mm256_fmadd_ps(_mm256_set1_ps(EXP_P0), r, _mm256_set1_ps(EXP_P1));
  y = _mm256_fmadd_ps(y, r, _mm256_set1_ps(EXP_P2));
  y = _mm256_fmadd_ps(y, r, _mm256_set1_ps(EXP_P3));
  y = _mm256_fmadd_ps(y, r, _mm256_set1_ps(EXP_P4));
  y = _mm256_fmadd_ps(y, r, _mm256_set1_ps(EXP_P5));
  y = _mm256_add_ps(_mm256_fmadd_ps(y, _mm256_mul_ps(r, r), r), _mm256_set1_ps(1.0f));
  const __m256i e = _mm256_slli_epi32(
      _mm256_add_epi32(_mm256_castps_si256(m), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(y, _mm256_castsi256_ps(e));
}

/* blur_tile's pixel for x..x+7 of row y, whose taps along the axis all lie inside the image
 * horizontally (rows outside it are skipped as in the scalar code). */
BLUR_AVX2_FN static void blur_span8(const hbao_job *jb, int x, int y, float *dst) {
  const obs_gbuffer *g = jb->g;
  const int rad = jb->p->blur_radius, W = g->width, H = g->height;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 maxq2 = _mm256_set1_ps(BLUR_MAX_Q2);
  const __m256 sharp = _mm256_set1_ps(jb->p->blur_sharpness);
  const size_t i = (size_t)y * (size_t)W + (size_t)x;
  const __m256 zc = _mm256_loadu_ps(g->depth + i);
  const __m256 covered = _mm256_cmp_ps(zc, zero, _CMP_GT_OQ);
  if (!_mm256_movemask_ps(covered)) {
    _mm256_storeu_ps(dst, _mm256_loadu_ps(jb->in + i));
    return;
  }
  /* Below 2^-100 the depths are scaled up by 2^64 (exactly) so 1 / zc stays finite. */
  const __m256 zs = _mm256_blendv_ps(one, _mm256_set1_ps(BLUR_TINY_SCALE),
                                     _mm256_cmp_ps(zc, _mm256_set1_ps(BLUR_TINY_Z), _CMP_LT_OQ));
  const __m256 rz = _mm256_div_ps(one, _mm256_mul_ps(zc, zs));
  const size_t step = jb->axis ? (size_t)W : 1;
  __m256 sw = zero, sa = zero;
  for (int k = -rad; k <= rad; k++) {
    int qy = jb->axis ? y + k : y;
    if (qy < 0 || qy >= H) continue;
    const size_t j = i + (size_t)(ptrdiff_t)k * step;
    if (k == 0) { /* exp(-0) = 1: the centre tap's weight, as blur_pixel */
      sw = _mm256_add_ps(sw, one);
      sa = _mm256_add_ps(sa, _mm256_loadu_ps(jb->in + j));
      continue;
    }
    const __m256 z = _mm256_loadu_ps(g->depth + j);
    const __m256 ok = _mm256_cmp_ps(z, zero, _CMP_GT_OQ);
    const __m256 q = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(z, zc), zs), rz);
    const __m256 q2 = _mm256_min_ps(_mm256_mul_ps(q, q), maxq2);
    const __m256 a = _mm256_fnmadd_ps(sharp, q2, _mm256_set1_ps(jb->blur_nkf[k + rad]));
    const __m256 w = _mm256_and_ps(blur_exp8(a), ok);
    /* A skipped tap adds +0 and +0 * a: the sums' bits stay, as they start at +0 and grow. */
    sw = _mm256_add_ps(sw, w);
    sa = _mm256_fmadd_ps(w, _mm256_loadu_ps(jb->in + j), sa);
  }
  __m256 v = _mm256_div_ps(sa, sw);
  v = _mm256_min_ps(_mm256_max_ps(v, zero), one);
  _mm256_storeu_ps(dst, _mm256_blendv_ps(_mm256_loadu_ps(jb->in + i), v, covered));
}
#endif

/* One pixel of one direction of the separable cross-bilateral blur. The relative depth difference
 * is (z - zc) times the pixel's 1 / zc, squared and clamped (BLUR_MAX_Q2); the weight is
 * exp(fma(-sharpness, q^2, -k^2 falloff)), the spatial term from the job's table. */
OBS_HOT_INLINE void blur_pixel(const hbao_job *jb, int x, int y) {
  const obs_gbuffer *g = jb->g;
  const int rad = jb->p->blur_radius, W = g->width, H = g->height;
  size_t i = (size_t)y * (size_t)W + (size_t)x;
  float zc = g->depth[i];
  if (!(zc > 0.0f)) {
    jb->out[i] = jb->in[i];
    return;
  }
  const float zs = zc < BLUR_TINY_Z ? BLUR_TINY_SCALE : 1.0f;
  const float rz = 1.0f / (zc * zs), sharp = jb->p->blur_sharpness;
  float sw = 0.0f, sa = 0.0f;
  for (int k = -rad; k <= rad; k++) {
    int qx = jb->axis ? x : x + k, qy = jb->axis ? y + k : y;
    if (qx < 0 || qx >= W || qy < 0 || qy >= H) continue;
    size_t j = (size_t)qy * (size_t)W + (size_t)qx;
    if (k == 0) { /* blur_exp(-0) is exactly 1 and 1 * a = a: the same sums, without the exp */
      sw += 1.0f;
      sa += jb->in[j];
      continue;
    }
    float z = g->depth[j];
    if (!(z > 0.0f)) continue;
    float q = ((z - zc) * zs) * rz;
    float q2 = q * q;
    q2 = q2 < BLUR_MAX_Q2 ? q2 : BLUR_MAX_Q2;
    /* The one transcendental that the backends evaluate differently (see blur_exp). */
    float w = blur_exp(fmaf(-sharp, q2, jb->blur_nkf[k + rad]));
    sw += w;
    sa = fmaf(w, jb->in[j], sa);
  }
  float v = sa / sw; /* the centre tap has weight exp(0) = 1 */
  jb->out[i] = v > 1.0f ? 1.0f : v > 0.0f ? v : 0.0f;
}

OBS_HOT_INLINE int blur_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  hbao_job *jb = user;
  const int W = jb->g->width;
  for (int y = y0; y < y1; y++) {
    int x = x0;
#if OBS_SIMD_AVX2
    if (jb->simd) {
      const int rad = jb->p->blur_radius;
      const int lo = jb->axis ? 0 : rad, hi = jb->axis ? W : W - rad; /* taps stay in [0, W) */
      for (; x < x1 && x < lo; x++) blur_pixel(jb, x, y);
      float *row = jb->out + (size_t)y * (size_t)W;
      for (; x + 8 <= x1 && x + 8 <= hi; x += 8) blur_span8(jb, x, y, row + x);
      /* The rest of the run, up to the last pixel whose taps stay inside, as one span that
       * overlaps the previous one: a pixel's bits do not depend on which span computes them. */
      const int e = x1 < hi ? x1 : hi;
      if (x < e && e - 8 >= lo && e - 8 >= x0) {
        blur_span8(jb, e - 8, y, row + e - 8);
        x = e;
      }
    }
#endif
    for (; x < x1; x++) blur_pixel(jb, x, y);
  }
  return 0;
}
OBS_TILE_KERNELS(blur_tile)

int obs_hbao_cpu_apply(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                       double *stage_ms, obs_err *err) {
  return obs_hbao_cpu_apply_ex(g, p, threads, ao, NULL, stage_ms, err);
}

/* The host-made tables of the AO pass: the direction table (obs_hbao_directions), its per-lane
 * copy for the AVX2 kernel's contiguous spans (hbao_job.dirs8), and the position factors per
 * level column and row (hbao_job.colf, rowf). */
static void job_tables(const obs_gbuffer *g, const obs_hbao_params *p, int lw, int lh,
                       float *table, float *dirs8, float *colf, float *rowf) {
  obs_hbao_directions(p, table);
  for (int ph = 0; ph < OBS_HBAO_NOISE_CELLS; ph++)
    for (int i = 0; i < p->directions; i++)
      for (int c = 0; c < 3; c++)
        for (int l = 0; l < 8; l++) {
          int cell = (ph & ~3) | ((ph + l) & 3);
          dirs8[((size_t)ph * (size_t)p->directions + (size_t)i) * 24 + (size_t)(8 * c + l)] =
              table[((size_t)cell * (size_t)p->directions + (size_t)i) * 4 + (size_t)c];
        }
  int s = p->half_res ? 2 : 1;
  for (int x = 0; x < lw; x++) {
    float fx = (float)(s * x) + 0.5f;
    colf[x] = (2.0f * fx / (float)g->width - 1.0f) * g->half_w;
  }
  for (int y = 0; y < lh; y++) {
    float fy = (float)(s * y) + 0.5f;
    rowf[y] = (1.0f - 2.0f * fy / (float)g->height) * g->half_h;
  }
}

/* The passes: obs_hbao_cpu_apply_ex within a render (r) or outside one. */
static int hbao_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_hbao_params *p,
                       float *ao, float *ao_raw, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int i = 0; i < OBS_HBAO_PASS_COUNT; i++) stage_ms[i] = 0.0;
  if (g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "hbao: G-buffer %dx%d is empty", g->width, g->height);
  size_t n = (size_t)g->width * (size_t)g->height;
  int lw, lh;
  obs_hbao_level_size(p, g->width, g->height, &lw, &lh);
  size_t ln = (size_t)lw * (size_t)lh;
  /* One allocation: table, half-resolution depth+normal+AO (if any), raw AO, blur temporary. */
  size_t ntab = (size_t)OBS_HBAO_NOISE_CELLS * (size_t)p->directions * 4;
  size_t ntab8 = (size_t)OBS_HBAO_NOISE_CELLS * (size_t)p->directions * 24;
  size_t nhalf = p->half_res ? 5 * ln : 0;
  float *mem = malloc((ntab + ntab8 + nhalf + 2 * n + (size_t)lw + (size_t)lh) * sizeof(float));
  if (!mem) return obs_err_set(err, OBS_ENOMEM, "hbao: %dx%d: out of memory", g->width, g->height);
  float *table = mem, *dirs8 = mem + ntab, *half = dirs8 + ntab8, *raw = half + nhalf, *tmp = raw + n;
  float *colf = tmp + n, *rowf = colf + lw;
  job_tables(g, p, lw, lh, table, dirs8, colf, rowf);
  hbao_job jb;
  memset(&jb, 0, sizeof jb);
  jb.g = g;
  jb.p = p;
  jb.table = table;
  jb.dirs8 = dirs8;
  jb.colf = colf;
  jb.rowf = rowf;
  /* The vector kernels index with 32-bit lanes. */
  jb.simd = obs_simd_avx2() && n <= (size_t)INT32_MAX;
  jb.loads = obs_simd_gather_loads();
  const obs_tile_fn ao_fn = obs_simd_tile_pick(ao_tile, obs_simd_isa());
  const obs_tile_fn blur_fn = obs_simd_tile_pick(blur_tile, obs_simd_isa());
  jb.inv_r = obs_hbao_inv_radius(p);
  jb.depth_eps = OBS_HBAO_DEPTH_EPS;
  jb.cos_b = (float)cos((double)p->angle_bias);
  jb.sin_b = (float)sin((double)p->angle_bias);
  float sigma = ((float)p->blur_radius + 1.0f) * 0.5f;
  jb.falloff = 1.0f / (2.0f * sigma * sigma);
  for (int k = -p->blur_radius; k <= p->blur_radius; k++)
    jb.blur_nkf[k + p->blur_radius] = -((float)(k * k) * jb.falloff);
  jb.lv = (hbao_level){g->width, g->height, 1, g->depth, g->normal};

  r->passes = 1 + (p->half_res ? 1 : 0) + (p->blur_radius > 0 ? 2 : 0);
  double t = obs_now_ms();
  if (p->half_res) {
    /* The top-left texel of each 2x2 (not the minimum depth): its depth and normal stay those of
     * one real surface point, at a known pixel centre. */
    float *hd = half, *hn = half + ln;
    for (int y = 0; y < lh; y++)
      for (int x = 0; x < lw; x++) {
        size_t j = (size_t)y * (size_t)lw + (size_t)x;
        size_t i = (size_t)(2 * y) * (size_t)g->width + (size_t)(2 * x);
        hd[j] = g->depth[i];
        for (int k = 0; k < 3; k++) hn[3 * j + k] = g->normal[3 * i + k];
      }
    jb.lv = (hbao_level){lw, lh, 2, hd, hn};
    if (stage_ms) stage_ms[OBS_HBAO_PASS_DOWNSAMPLE] = obs_now_ms() - t;
    t = obs_now_ms();
  }
  float *level_ao = p->half_res ? half + 4 * ln : raw;
  jb.out = level_ao;
  int rc = obs_screen_cpu_tiles(r, lw, lh, ao_fn, &jb);
  if (stage_ms) stage_ms[OBS_HBAO_PASS_AO] = obs_now_ms() - t;
  if (!rc && p->half_res) {
    t = obs_now_ms();
    jb.in = level_ao;
    jb.out = raw;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, up_tile, &jb);
    if (stage_ms) stage_ms[OBS_HBAO_PASS_UPSAMPLE] = obs_now_ms() - t;
  }
  if (!rc && ao_raw) memcpy(ao_raw, raw, n * sizeof(float));
  if (!rc && p->blur_radius > 0) {
    t = obs_now_ms();
    jb.in = raw;
    jb.out = tmp;
    jb.axis = 0;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, blur_fn, &jb);
    if (!rc) {
      jb.in = tmp;
      jb.out = ao;
      jb.axis = 1;
      rc = obs_screen_cpu_tiles(r, g->width, g->height, blur_fn, &jb);
    }
    if (stage_ms) stage_ms[OBS_HBAO_PASS_BLUR] = obs_now_ms() - t;
  } else if (!rc) {
    memcpy(ao, raw, n * sizeof(float));
  }
  free(mem);
  if (rc && rc != OBS_ECANCELED)
    return obs_err_set(err, rc, "hbao: %dx%d: CPU passes failed", g->width, g->height);
  return rc;
}

int obs_hbao_cpu_apply_ex(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                          float *ao_raw, double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return hbao_passes(&r, g, p, ao, ao_raw, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const obs_hbao_params *p = params;
  double st[OBS_HBAO_PASS_COUNT];
  int rc = hbao_passes(r, g, p, ao, ao_raw, st, err);
  if (rc) return rc;
  for (int i = 0; i < OBS_HBAO_PASS_COUNT; i++)
    if (obs_hbao_pass_runs(p, i)) obs_screen_cpu_stage(r, obs_hbao_pass_names[i], st[i]);
  return 0;
}

int obs_hbao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
