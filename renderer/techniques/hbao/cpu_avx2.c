/* The AVX2 kernel of the CPU hbao's AO pass: ao_texel (cpu.c) eight texels at a
 * time with the same float32 operations per lane, so every lane gives ao_texel's bits (simd.h);
 * how it orders and skips work is described in docs/techniques/hbao.md. */
#include <string.h>

#include "hbao_cpu.h"

#if OBS_SIMD_AVX2
/* tangent()'s oriented z and squared length (lz, h2 + lz^2, and h2) for eight directions. */
OBS_AVX2_INLINE __m256 tangent8_line(__m256 n0, __m256 n1, __m256 nr, __m256 r0, __m256 r1,
                                     __m256 dx, __m256 dy, __m256 *lz, __m256 *h2) {
  const __m256 zero = _mm256_setzero_ps(), sign = _mm256_set1_ps(-0.0f);
  __m256 nd = _mm256_add_ps(_mm256_mul_ps(n0, dx), _mm256_mul_ps(n1, dy));
  __m256 lx = _mm256_sub_ps(_mm256_mul_ps(nd, r0), _mm256_mul_ps(nr, dx));
  __m256 ly = _mm256_sub_ps(_mm256_mul_ps(nd, r1), _mm256_mul_ps(nr, dy));
  __m256 flip = _mm256_and_ps(_mm256_cmp_ps(nr, zero, _CMP_NLT_UQ), sign);
  lx = _mm256_xor_ps(lx, flip);
  ly = _mm256_xor_ps(ly, flip);
  *lz = _mm256_xor_ps(nd, flip);
  *h2 = _mm256_add_ps(_mm256_mul_ps(lx, lx), _mm256_mul_ps(ly, ly));
  return _mm256_add_ps(*h2, _mm256_mul_ps(*lz, *lz));
}

/* tangent() for eight directions at once, from tangent8_line's values; sin only when cos_t is
 * NULL. */
OBS_AVX2_INLINE void tangent8_finish(__m256 lz, __m256 l2, __m256 h2, __m256 *sin_t,
                                     __m256 *cos_t) {
  const __m256 zero = _mm256_setzero_ps(), sign = _mm256_set1_ps(-0.0f);
  __m256 l = _mm256_sqrt_ps(l2);
  __m256 degenerate = _mm256_cmp_ps(l, zero, _CMP_NGT_UQ);
  *sin_t = _mm256_andnot_ps(degenerate, _mm256_div_ps(_mm256_xor_ps(lz, sign), l));
  if (cos_t)
    *cos_t = _mm256_blendv_ps(_mm256_div_ps(_mm256_sqrt_ps(h2), l), _mm256_set1_ps(1.0f),
                              degenerate);
}

OBS_AVX2_INLINE void tangent8(__m256 n0, __m256 n1, __m256 nr, __m256 r0, __m256 r1, __m256 dx,
                              __m256 dy, __m256 *sin_t, __m256 *cos_t) {
  __m256 lz, h2;
  __m256 l2 = tangent8_line(n0, n1, nr, r0, r1, dx, dy, &lz, &h2);
  tangent8_finish(lz, l2, h2, sin_t, cos_t);
}

/* Whether a lane's sample can count, judged without division or square root: false only where
 * the exact test (dist < 1 and e > sin_h) is sure to fail. rsqrtps is within 1.5 2^-12 of 1/sqrt
 * for normal inputs, so the estimates of sin_s and sin_ts (both at most 1 in size) are within
 * 4e-4 each; squared lengths outside [1e-30, 1e30] are not judged. Skipping the exact work where
 * no lane can count leaves every bit as it was and spares the divider, which bounds this loop:
 * on the Cornell box 9 in 10 exact evaluations raise no horizon. */
#define HBAO_PRETEST_MARGIN 4e-3f
OBS_AVX2_INLINE __m256 may_count8(__m256 q2, __m256 qz, __m256 l2, __m256 lz, __m256 rs2,
                                  __m256 sin_t, __m256 sin_h) {
  const __m256 lo = _mm256_set1_ps(1e-30f), hi = _mm256_set1_ps(1e30f);
  __m256 valid = _mm256_and_ps(
      _mm256_and_ps(_mm256_cmp_ps(q2, lo, _CMP_GE_OQ), _mm256_cmp_ps(q2, hi, _CMP_LE_OQ)),
      _mm256_and_ps(_mm256_cmp_ps(l2, lo, _CMP_GE_OQ), _mm256_cmp_ps(l2, hi, _CMP_LE_OQ)));
  __m256 far = _mm256_cmp_ps(_mm256_mul_ps(q2, rs2), _mm256_set1_ps(1.01f), _CMP_GE_OQ);
  __m256 sa = _mm256_mul_ps(qz, _mm256_rsqrt_ps(q2));    /* -sin_s */
  __m256 sta = _mm256_mul_ps(lz, _mm256_rsqrt_ps(l2));   /* -sin_ts */
  __m256 ea = _mm256_add_ps(_mm256_sub_ps(sta, sa), sin_t);
  __m256 low = _mm256_cmp_ps(_mm256_add_ps(ea, _mm256_set1_ps(HBAO_PRETEST_MARGIN)), sin_h,
                             _CMP_LT_OQ);
  return _mm256_andnot_ps(_mm256_and_ps(valid, _mm256_or_ps(far, low)), _mm256_castsi256_ps(
                                                                            _mm256_set1_epi32(-1)));
}

/* One step of eight lanes along their directions: the sample's texel offset, depth and position
 * factors, and whether it is a sample at all (another texel, covered). */
typedef struct hbao_step8 {
  __m256i ox, oy;
  __m256 zs, S0, S1, ok;
} hbao_step8;

/* ao_span8's sample texels for every step of one direction, before any of them is used: the
 * gathers carry no branch between them, so their cache misses overlap instead of each one
 * stalling the branches on the previous sample. */
/* Eight floats at p[0], p[4], ..., p[28] (p[0..31] readable): four loads and four shuffles
 * where vgatherdps, or eight scalar loads, would take many more micro-ops. */
OBS_AVX2_INLINE __m256 load_stride4(const float *p) {
  __m256 a = _mm256_shuffle_ps(_mm256_loadu_ps(p), _mm256_loadu_ps(p + 8), 0x00);
  __m256 b = _mm256_shuffle_ps(_mm256_loadu_ps(p + 16), _mm256_loadu_ps(p + 24), 0x00);
  __m256 c = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0));
  return _mm256_permutevar8x32_ps(c, _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7));
}

/* With `strided` the lanes are texels 4 apart in one row (one noise cell): their samples then
 * usually sit 4 apart in one row too, and where gathers are emulated with scalar loads
 * (jb->loads: AMD, or the gather mitigation) that case reads depth and position factors with
 * load_stride4 and one broadcast instead of sixteen loads and two divisions; the values are the
 * same bits (colf and rowf hold what the divisions give). With hardware gathers the test for the
 * case costs more than it saves (measured: docs/performance.md), so it is not made. */
OBS_AVX2_INLINE void march8(const hbao_job *jb, __m256i ax, __m256i ay, __m256 cx, __m256 cy,
                            __m256 dx, __m256 dy, __m256 jit, __m256 st, __m256 act,
                            int strided, hbao_step8 *sp) {
  const hbao_level *lv = &jb->lv;
  const __m256 zero = _mm256_setzero_ps();
  const __m256i wmax = _mm256_set1_epi32(lv->w - 1), hmax = _mm256_set1_epi32(lv->h - 1);
  const __m256i izero = _mm256_setzero_si256(), lw = _mm256_set1_epi32(lv->w);
  const __m256i s2 = _mm256_set1_epi32(2 * lv->s), ione = _mm256_set1_epi32(1);
  const __m256 fw = _mm256_set1_ps((float)jb->g->width), fh = _mm256_set1_ps((float)jb->g->height);
  const __m256 hw = _mm256_set1_ps(jb->g->half_w), hh = _mm256_set1_ps(jb->g->half_h);
  const __m256 fone = _mm256_set1_ps(1.0f);
  const __m256i lane4 = _mm256_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28);
  for (int k = 1; k <= jb->p->steps; k++) {
    hbao_step8 *q = sp + (k - 1);
    __m256 o = _mm256_mul_ps(_mm256_add_ps(_mm256_set1_ps((float)k), jit), st);
    __m256 sx = _mm256_add_ps(cx, _mm256_mul_ps(o, dx));
    __m256 sy = _mm256_add_ps(cy, _mm256_mul_ps(o, dy));
    const __m256i rx = _mm256_cvttps_epi32(_mm256_floor_ps(sx));
    const __m256i ry = _mm256_cvttps_epi32(_mm256_floor_ps(sy));
    const __m256i ix = _mm256_min_epi32(_mm256_max_epi32(rx, izero), wmax);
    const __m256i iy = _mm256_min_epi32(_mm256_max_epi32(ry, izero), hmax);
    q->ox = _mm256_sub_epi32(ix, ax);
    q->oy = _mm256_sub_epi32(iy, ay);
    __m256 ok = _mm256_andnot_ps(
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_or_si256(q->ox, q->oy), izero)), act);
    const int ix0 = _mm256_cvtsi256_si32(ix), iy0 = _mm256_cvtsi256_si32(iy);
    const size_t base = (size_t)iy0 * (size_t)lv->w + (size_t)ix0;
    int row4 = 0;
    if (strided && jb->loads && ix0 + 32 <= lv->w &&
        base + 32 <= (size_t)lv->w * (size_t)lv->h) {
      /* Unclamped, one row, 4 apart. */
      __m256i same = _mm256_and_si256(
          _mm256_and_si256(_mm256_cmpeq_epi32(rx, ix), _mm256_cmpeq_epi32(ry, iy)),
          _mm256_and_si256(_mm256_cmpeq_epi32(iy, _mm256_set1_epi32(iy0)),
                           _mm256_cmpeq_epi32(ix, _mm256_add_epi32(_mm256_set1_epi32(ix0), lane4))));
      row4 = _mm256_movemask_epi8(same) == -1;
    }
    if (row4) {
      q->zs = load_stride4(lv->depth + base);
      q->S0 = load_stride4(jb->colf + ix0);
      q->S1 = _mm256_set1_ps(jb->rowf[iy0]);
    } else {
      q->zs = obs_avx2_gather(jb->loads, lv->depth,
                              _mm256_add_epi32(_mm256_mullo_epi32(iy, lw), ix));
      /* colf[ix] and rowf[iy] recomputed with their own operations (2 fx = 2 s i + 1 is
       * exact): the divider is idle here, while gathers compete with the depth gather for the
       * loads. */
      __m256 tx = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_mullo_epi32(ix, s2), ione));
      __m256 ty = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_mullo_epi32(iy, s2), ione));
      q->S0 = _mm256_mul_ps(_mm256_sub_ps(_mm256_div_ps(tx, fw), fone), hw);
      q->S1 = _mm256_mul_ps(_mm256_sub_ps(fone, _mm256_div_ps(ty, fh)), hh);
    }
    q->ok = _mm256_and_ps(ok, _mm256_cmp_ps(q->zs, zero, _CMP_GT_OQ));
    if (!jb->g->ortho) {
      q->S0 = _mm256_mul_ps(q->S0, q->zs);
      q->S1 = _mm256_mul_ps(q->S1, q->zs);
    }
  }
}

/* ao_span8's per-lane constants of its eight texels. */
typedef struct hbao_px8 {
  __m256i ax, ay;
  __m256 cx, cy, P0, P1, P2, r0, r1, n0, n1, nr, down, rscale, rs2, st, live;
} hbao_px8;

/* One direction of eight lanes: its image step, jitter, tangent elevation and starting horizon,
 * and which lanes search it. */
typedef struct hbao_dir8 {
  __m256 dx, dy, jit, sin_t, sin_h, act;
} hbao_dir8;

/* The constants of texels x..x+7 of level row y; 0 when no lane needs a search. */
OBS_AVX2_INLINE int px_setup8(const hbao_job *jb, int x, int stride, int y, hbao_px8 *px) {
  const hbao_level *lv = &jb->lv;
  const obs_hbao_params *p = jb->p;
  const obs_gbuffer *g = jb->g;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const size_t ci = (size_t)y * (size_t)lv->w + (size_t)x;
  const float R = p->radius;
  const __m256i lane = _mm256_mullo_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
                                          _mm256_set1_epi32(stride));
  const __m256 z = stride == 1 ? _mm256_loadu_ps(lv->depth + ci)
                               : obs_avx2_gather(jb->loads, lv->depth + ci, lane);
  __m256 live = _mm256_cmp_ps(z, zero, _CMP_GT_OQ);
  if (!(R > 0.0f) || !_mm256_movemask_ps(live)) return 0;
  px->ax = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
  px->ay = _mm256_set1_epi32(y);
  /* The tables hold nx half_w and ny half_h, which are r's x and y (perspective) and P's factors. */
  const __m256 cfx = stride == 1 ? _mm256_loadu_ps(jb->colf + x)
                                 : obs_avx2_gather(jb->loads, jb->colf + x, lane);
  const __m256 cfy = _mm256_set1_ps(jb->rowf[y]);
  px->r0 = px->r1 = zero;
  if (g->ortho) {
    px->P0 = cfx;
    px->P1 = cfy;
  } else {
    px->P0 = _mm256_mul_ps(cfx, z);
    px->P1 = _mm256_mul_ps(cfy, z);
    px->r0 = cfx;
    px->r1 = cfy;
  }
  px->P2 = z;
  /* pow2_scale of each lane's depth. */
  __m256i ex = _mm256_and_si256(_mm256_srli_epi32(_mm256_castps_si256(z), 23),
                                _mm256_set1_epi32(0xff));
  ex = _mm256_min_epi32(_mm256_max_epi32(ex, _mm256_set1_epi32(1)), _mm256_set1_epi32(253));
  px->down =
      _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_sub_epi32(_mm256_set1_epi32(254), ex), 23));
  px->rscale = _mm256_mul_ps(_mm256_castsi256_ps(_mm256_slli_epi32(ex, 23)),
                             _mm256_set1_ps(jb->inv_r));
  px->rs2 = _mm256_mul_ps(px->rscale, px->rscale); /* may_count8's bound only */
  const float num = R * (0.5f * (float)g->width);
  __m256 rpx = g->ortho ? _mm256_set1_ps(num / g->half_w)
                        : _mm256_div_ps(_mm256_set1_ps(num), _mm256_mul_ps(_mm256_set1_ps(g->half_w), z));
  __m256 rl = _mm256_div_ps(rpx, _mm256_set1_ps((float)lv->s));
  px->live = _mm256_and_ps(live, _mm256_cmp_ps(rl, one, _CMP_GE_OQ));
  if (!_mm256_movemask_ps(px->live)) return 0;
  const float cap = (float)(lv->w > lv->h ? lv->w : lv->h);
  rl = _mm256_blendv_ps(rl, _mm256_set1_ps(cap), _mm256_cmp_ps(rl, _mm256_set1_ps(cap), _CMP_GT_OQ));
  px->st = _mm256_div_ps(rl, _mm256_set1_ps((float)(p->steps + 1)));
  const __m256i i3 = _mm256_mullo_epi32(lane, _mm256_set1_epi32(3));
  const float *nb = lv->normal + 3 * ci;
  px->n0 = obs_avx2_gather(jb->loads, nb, i3);
  px->n1 = obs_avx2_gather(jb->loads, nb + 1, i3);
  const __m256 n2 = obs_avx2_gather(jb->loads, nb + 2, i3);
  px->nr = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(px->n0, px->r0), _mm256_mul_ps(px->n1, px->r1)),
                         _mm256_mul_ps(n2, one));
  px->cx = _mm256_add_ps(_mm256_cvtepi32_ps(px->ax), _mm256_set1_ps(0.5f));
  px->cy = _mm256_set1_ps((float)y + 0.5f);
  return 1;
}

/* Direction i of the lanes' rows of the direction table (jb->dirs8, see obs_hbao_cpu_apply_ex,
 * or with bcast one row of jb->table); 0 when no lane searches it. */
OBS_AVX2_INLINE int dir_setup8(const hbao_job *jb, const hbao_px8 *px, const float *d8, int bcast,
                               int i, hbao_dir8 *d) {
  const __m256 zero = _mm256_setzero_ps(), sign = _mm256_set1_ps(-0.0f);
  const __m256 cos_b = _mm256_set1_ps(jb->cos_b), sin_b = _mm256_set1_ps(jb->sin_b);
  if (bcast) { /* every lane in the same cell: d8 is that cell's row of jb->table */
    d->dx = _mm256_set1_ps(d8[4 * i]);
    d->dy = _mm256_set1_ps(d8[4 * i + 1]);
    d->jit = _mm256_set1_ps(d8[4 * i + 2]);
  } else {
    d->dx = _mm256_loadu_ps(d8 + 24 * i);
    d->dy = _mm256_loadu_ps(d8 + 24 * i + 8);
    d->jit = _mm256_loadu_ps(d8 + 24 * i + 16);
  }
  __m256 cos_t;
  tangent8(px->n0, px->n1, px->nr, px->r0, px->r1, d->dx, _mm256_xor_ps(d->dy, sign), &d->sin_t,
           &cos_t);
  d->act = _mm256_and_ps(
      px->live, _mm256_cmp_ps(_mm256_sub_ps(_mm256_mul_ps(cos_t, cos_b), _mm256_mul_ps(d->sin_t, sin_b)),
                              zero, _CMP_GT_OQ));
  d->sin_h = _mm256_add_ps(_mm256_mul_ps(d->sin_t, cos_b), _mm256_mul_ps(cos_t, sin_b));
  return _mm256_movemask_ps(d->act) != 0;
}

/* The horizon search of one direction over march8's samples: ao_texel's step loop, per lane. */
OBS_AVX2_INLINE __m256 horizon8(const hbao_job *jb, const hbao_px8 *px, const hbao_dir8 *d,
                                const hbao_step8 *sp, __m256 sum) {
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 sign = _mm256_set1_ps(-0.0f), eps = _mm256_set1_ps(jb->depth_eps);
  __m256 sin_h = d->sin_h;
  for (int k = 0; k < jb->p->steps; k++) {
    __m256 ok = sp[k].ok;
    if (!_mm256_movemask_ps(ok)) continue;
    const __m256 zs = sp[k].zs;
    /* ao_texel's scaled offset. */
    __m256 dx = _mm256_sub_ps(sp[k].S0, px->P0), dy = _mm256_sub_ps(sp[k].S1, px->P1);
    __m256 dz = _mm256_add_ps(_mm256_sub_ps(zs, px->P2), _mm256_mul_ps(eps, _mm256_add_ps(zs, px->P2)));
    __m256 qx = _mm256_mul_ps(dx, px->down), qy = _mm256_mul_ps(dy, px->down);
    __m256 qz = _mm256_mul_ps(dz, px->down);
    __m256 q2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(qx, qx), _mm256_mul_ps(qy, qy)),
                              _mm256_mul_ps(qz, qz));
    __m256 lz_s, h2_s;
    __m256 l2_s = tangent8_line(px->n0, px->n1, px->nr, px->r0, px->r1, _mm256_cvtepi32_ps(sp[k].ox),
                                _mm256_xor_ps(_mm256_cvtepi32_ps(sp[k].oy), sign), &lz_s, &h2_s);
    if (!_mm256_movemask_ps(
            _mm256_and_ps(ok, may_count8(q2, qz, l2_s, lz_s, px->rs2, d->sin_t, sin_h))))
      continue;
    __m256 len = _mm256_sqrt_ps(q2);
    __m256 dist = _mm256_mul_ps(len, px->rscale);
    ok = _mm256_and_ps(ok, _mm256_and_ps(_mm256_cmp_ps(len, zero, _CMP_GT_OQ),
                                         _mm256_cmp_ps(dist, one, _CMP_LT_OQ)));
    if (!_mm256_movemask_ps(ok)) continue;
    __m256 d2 = _mm256_mul_ps(dist, dist);
    __m256 sin_s = _mm256_div_ps(_mm256_xor_ps(qz, sign), len);
    __m256 sin_ts;
    tangent8_finish(lz_s, l2_s, h2_s, &sin_ts, NULL);
    __m256 e = _mm256_add_ps(_mm256_sub_ps(sin_s, sin_ts), d->sin_t);
    e = _mm256_blendv_ps(e, one, _mm256_cmp_ps(e, one, _CMP_GT_OQ));
    __m256 up = _mm256_and_ps(ok, _mm256_cmp_ps(e, sin_h, _CMP_GT_OQ));
    __m256 c = _mm256_mul_ps(_mm256_sub_ps(one, d2), _mm256_sub_ps(e, sin_h));
    sum = _mm256_blendv_ps(sum, _mm256_add_ps(sum, c), up);
    sin_h = _mm256_blendv_ps(sin_h, e, up);
  }
  return sum;
}

/* ao_texel for texels x + stride l (l = 0..7) of level row y (all inside the level), same
 * operations per lane. Stride 4 puts eight texels of one noise cell in the lanes: they search the
 * same directions, so each step's eight samples lie along one band of a few cache lines instead
 * of four directions' worth, and the depth gathers, which bound the pass, miss far less. The
 * next direction's samples are gathered before this one's search: a mispredicted branch of the
 * search then does not discard them, and their cache misses overlap it. */
OBS_AVX2_FN void obs_hbao_ao_span8(const hbao_job *jb, int x, int stride, int y, float *dst) {
  const obs_hbao_params *p = jb->p;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  hbao_px8 px;
  __m256 ao = one;
  if (px_setup8(jb, x, stride, y, &px)) {
    const int cell = ((y & 3) << 2) | (x & 3), bcast = stride == 4;
    const float *d8 = bcast ? jb->table + (size_t)cell * (size_t)p->directions * 4
                            : jb->dirs8 + (size_t)cell * (size_t)p->directions * 24;
    hbao_step8 sp[2][OBS_HBAO_MAX_STEPS];
    hbao_dir8 d[2];
    int use[2];
    use[0] = dir_setup8(jb, &px, d8, bcast, 0, &d[0]);
    if (use[0])
      march8(jb, px.ax, px.ay, px.cx, px.cy, d[0].dx, d[0].dy, d[0].jit, px.st, d[0].act, bcast,
             sp[0]);
    __m256 sum = zero;
    for (int i = 0; i < p->directions; i++) {
      const int c = i & 1, n = c ^ 1;
      if (i + 1 < p->directions && (use[n] = dir_setup8(jb, &px, d8, bcast, i + 1, &d[n])))
        march8(jb, px.ax, px.ay, px.cx, px.cy, d[n].dx, d[n].dy, d[n].jit, px.st, d[n].act, bcast,
               sp[n]);
      if (use[c]) sum = horizon8(jb, &px, &d[c], sp[c], sum);
    }
    ao = _mm256_sub_ps(one, _mm256_div_ps(_mm256_mul_ps(_mm256_set1_ps(p->scale), sum),
                                          _mm256_set1_ps((float)p->directions)));
    ao = _mm256_min_ps(_mm256_max_ps(ao, zero), one);
    ao = _mm256_blendv_ps(one, ao, px.live);
  }
  if (stride == 1) {
    _mm256_storeu_ps(dst, ao);
  } else {
    float v[8];
    _mm256_storeu_ps(v, ao);
    for (int l = 0; l < 8; l++) dst[stride * l] = v[l];
  }
}
#endif
#if !OBS_SIMD_AVX2
typedef int obs_hbao_avx2_unused; /* ISO C wants a declaration in every translation unit */
#endif
