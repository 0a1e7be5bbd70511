/* ssao_variance's AVX2 rows (svar_cpu.h): eight pixels per register, every tap accumulated in
 * registers, each lane the scalar rows' operations in their order (cpu.c), so the bits are the
 * same. Lanes outside the image or a tap outside a pixel's symmetric box load through a mask and
 * read 0, an uncovered depth, whose terms add +-0 and leave the sums as they were. */
#include "svar_cpu.h"

#if OBS_SIMD_AVX2

/* Lanes x .. x+7 that lie in [lo, hi]. */
OBS_AVX2_INLINE __m256i lanes_in(int x, int lo, int hi) {
  const __m256i lane =
      _mm256_add_epi32(_mm256_set1_epi32(x), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
  const __m256i ge = _mm256_cmpgt_epi32(lane, _mm256_set1_epi32(lo - 1));
  const __m256i le = _mm256_cmpgt_epi32(_mm256_set1_epi32(hi + 1), lane);
  return _mm256_and_si256(ge, le);
}

/* One tap into one chunk's sums: the covered lanes' d, d^2 and count (an uncovered lane's terms
 * are +0, which leaves a sum as it was). */
OBS_AVX2_INLINE void moments_tap(__m256 zt, __m256 c, __m256 *n, __m256 *h1, __m256 *h2) {
  const __m256 cov = _mm256_cmp_ps(zt, _mm256_setzero_ps(), _CMP_GT_OQ);
  const __m256 d = _mm256_and_ps(cov, _mm256_sub_ps(zt, c));
  *n = _mm256_add_ps(*n, _mm256_and_ps(cov, _mm256_set1_ps(1.0f)));
  *h1 = _mm256_add_ps(*h1, d);
  *h2 = _mm256_add_ps(*h2, _mm256_mul_ps(d, d));
}

/* Tap k of the lanes x .. x+7 of a row of scaled depths zr: a plain load where every lane's box
 * holds the tap, else a masked one that reads 0 (uncovered) elsewhere. */
OBS_AVX2_INLINE __m256 tap_load(const float *zr, int w, int x, int k, int s) {
  const int a = (k < 0 ? -k : k) * s;
  const float *p = zr + x + k * s;
  if (x >= a && x + 7 <= w - 1 - a) return _mm256_loadu_ps(p);
  return _mm256_maskload_ps(p, lanes_in(x, a, w - 1 - a));
}

OBS_AVX2_FN void obs_svar_moments_row_avx2(const obs_svar_rows *r, int y, float *zrow) {
  const int w = r->w, s = r->stride, K = r->taps;
  const size_t row = (size_t)y * (size_t)w;
  const __m256 zs = _mm256_set1_ps(r->zscale), zero = _mm256_setzero_ps();
  /* The row scaled once: the scale is a power of two, so the products are the taps' own. */
  for (int x = 0; x < w; x += 8) {
    const __m256i in = lanes_in(x, 0, w - 1);
    _mm256_maskstore_ps(zrow + x, in,
                        _mm256_mul_ps(_mm256_maskload_ps(r->depth + row + x, in), zs));
  }
  const int x1 = r->chi;
  int x = r->clo;
  /* Two chunks at a time: their sums are independent chains, which hides the adds' latency. */
  for (; x + 16 <= x1; x += 16) {
    const __m256 c0 = _mm256_loadu_ps(r->mc + row + x), c1 = _mm256_loadu_ps(r->mc + row + x + 8);
    __m256 n0 = zero, a0 = zero, b0 = zero, n1 = zero, a1 = zero, b1 = zero;
    for (int k = -K; k <= K; k++) {
      moments_tap(tap_load(zrow, w, x, k, s), c0, &n0, &a0, &b0);
      moments_tap(tap_load(zrow, w, x + 8, k, s), c1, &n1, &a1, &b1);
    }
    _mm256_storeu_ps(r->mn + row + x, n0);
    _mm256_storeu_ps(r->m1 + row + x, a0);
    _mm256_storeu_ps(r->m2 + row + x, b0);
    _mm256_storeu_ps(r->mn + row + x + 8, n1);
    _mm256_storeu_ps(r->m1 + row + x + 8, a1);
    _mm256_storeu_ps(r->m2 + row + x + 8, b1);
  }
  for (; x < x1; x += 8) {
    const __m256i in = lanes_in(x, 0, x1 - 1);
    const __m256 c = _mm256_maskload_ps(r->mc + row + x, in);
    __m256 n = zero, h1 = zero, h2 = zero;
    for (int k = -K; k <= K; k++) moments_tap(tap_load(zrow, w, x, k, s), c, &n, &h1, &h2);
    _mm256_maskstore_ps(r->mn + row + x, in, n);
    _mm256_maskstore_ps(r->m1 + row + x, in, h1);
    _mm256_maskstore_ps(r->m2 + row + x, in, h2);
  }
}

/* svar_estimate_row (cpu.c) for eight lanes. */
OBS_AVX2_INLINE __m256 estimate8(const obs_svar_ao_push *ap, __m256 z, __m256 n, __m256 t1,
                                 __m256 t2, __m256 taps) {
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 iv =
      _mm256_div_ps(one, _mm256_blendv_ps(one, n, _mm256_cmp_ps(n, zero, _CMP_GT_OQ)));
  const __m256 mo = _mm256_mul_ps(t1, iv);
  const __m256 e2 = _mm256_mul_ps(t2, iv);
  __m256 var = _mm256_sub_ps(e2, _mm256_mul_ps(mo, mo));
  var = _mm256_and_ps(var, _mm256_cmp_ps(var, zero, _CMP_GT_OQ));
  const __m256 share = _mm256_mul_ps(n, _mm256_div_ps(one, taps));
  const __m256 dd =
      _mm256_sub_ps(_mm256_sub_ps(zero, mo), _mm256_mul_ps(_mm256_set1_ps(ap->tol), z));
  const __m256 rw = _mm256_set1_ps(ap->rw);
  const __m256 R = ap->ortho ? rw : _mm256_mul_ps(rw, z);
  __m256 v;
  if (ap->method == OBS_SVAR_VARIANCE) {
    const __m256 den = _mm256_add_ps(var, _mm256_mul_ps(dd, dd));
    const __m256 pos = _mm256_cmp_ps(den, zero, _CMP_GT_OQ);
    const __m256 vis =
        _mm256_blendv_ps(one, _mm256_div_ps(var, _mm256_blendv_ps(one, den, pos)), pos);
    const __m256 q = _mm256_div_ps(var, _mm256_mul_ps(R, R));
    const __m256 ov = _mm256_sub_ps(one, vis);
    v = _mm256_add_ps(_mm256_sub_ps(one, _mm256_mul_ps(share, ov)),
                      _mm256_mul_ps(_mm256_set1_ps(ap->weight), q));
  } else {
    const __m256 u = _mm256_div_ps(dd, R);
    v = _mm256_sub_ps(one, _mm256_mul_ps(share, _mm256_mul_ps(_mm256_set1_ps(ap->strength), u)));
  }
  v = _mm256_blendv_ps(one, v, _mm256_cmp_ps(dd, zero, _CMP_GT_OQ));
  /* v > 0 ? (v < 1 ? v : 1) : 0: min(v, 1) returns v where v < 1. */
  v = _mm256_and_ps(_mm256_min_ps(v, one), _mm256_cmp_ps(v, zero, _CMP_GT_OQ));
  return _mm256_blendv_ps(one, v, _mm256_cmp_ps(z, zero, _CMP_GT_OQ));
}

OBS_AVX2_FN int obs_svar_ao_row_avx2(const obs_svar_rows *r, const obs_svar_ao_push *ap, int y,
                                     int lo, int hi, float *scratch, float *out) {
  const int w = r->w, h = r->h, s = r->stride, K = r->taps, we = lo + ((hi - lo) & ~7);
  const int m = y < h - 1 - y ? y : h - 1 - y;
  const size_t row = (size_t)y * (size_t)w;
  float *z0 = scratch, *nn = scratch + w, *t1 = nn + w, *t2 = t1 + w;
  const __m256 zs = _mm256_set1_ps(r->zscale), zero = _mm256_setzero_ps();
  const __m256 two = _mm256_set1_ps(2.0f);
  for (int x = lo; x < we; x += 8) {
    _mm256_storeu_ps(z0 + x, _mm256_mul_ps(_mm256_loadu_ps(r->depth + row + x), zs));
    _mm256_storeu_ps(nn + x, zero);
    _mm256_storeu_ps(t1 + x, zero);
    _mm256_storeu_ps(t2 + x, zero);
  }
  /* Tap rows outer, pixels inner: each tap row streams through once, the sums stay in L1 (the
   * other order, taps inner, measured 1.5x slower: 4 x 33 streams at once defeat prefetching). */
  for (int k = -K; k <= K; k++) {
    if ((k < 0 ? -k : k) * s > m) continue;
    const size_t at = (size_t)(y + k * s) * (size_t)w;
    const float *pn = r->mn + at, *p1 = r->m1 + at, *p2 = r->m2 + at, *pc = r->mc + at;
    for (int x = lo; x < we; x += 8) {
      const __m256 an = _mm256_loadu_ps(pn + x), a1 = _mm256_loadu_ps(p1 + x);
      const __m256 dl = _mm256_sub_ps(_mm256_loadu_ps(pc + x), _mm256_loadu_ps(z0 + x));
      const __m256 an_d = _mm256_mul_ps(an, dl);
      _mm256_storeu_ps(t1 + x, _mm256_add_ps(_mm256_loadu_ps(t1 + x), _mm256_add_ps(a1, an_d)));
      const __m256 tw = _mm256_mul_ps(two, dl);
      const __m256 inner = _mm256_add_ps(
          _mm256_add_ps(_mm256_loadu_ps(p2 + x), _mm256_mul_ps(tw, a1)), _mm256_mul_ps(an_d, dl));
      _mm256_storeu_ps(t2 + x, _mm256_add_ps(_mm256_loadu_ps(t2 + x), inner));
      _mm256_storeu_ps(nn + x, _mm256_add_ps(_mm256_loadu_ps(nn + x), an));
    }
  }
  const __m256 ty = _mm256_set1_ps((float)(2 * (K < m / s ? K : m / s) + 1));
  for (int x = lo; x < we; x += 8)
    _mm256_storeu_ps(out + x, estimate8(ap, _mm256_loadu_ps(z0 + x), _mm256_loadu_ps(nn + x),
                                        _mm256_loadu_ps(t1 + x), _mm256_loadu_ps(t2 + x),
                                        _mm256_mul_ps(_mm256_loadu_ps(r->taps_x + x), ty)));
  return we;
}

#else
typedef int obs_svar_cpu_avx2_empty; /* ISO C wants a translation unit to declare something */
#endif
