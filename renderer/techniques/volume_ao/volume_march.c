/* Marching a scalar volume: first isosurface hits with macrocell skipping, gradient normals and
 * ray-marched AO with bent normals (volume_march.h). */
#include "volume_march.h"

#include <math.h>

#include "sampling.h"
#include "simd.h"

/* The ray's parameter range inside the box [0, n s] (slabs in double); 0 when it misses. */
static int clip_box(const obs_volume *v, const double o[3], const double d[3], double *t0,
                    double *t1) {
  for (int a = 0; a < 3; a++) {
    double hi = v->n[a] * v->spacing[a];
    if (d[a] == 0) {
      if (o[a] < 0 || o[a] > hi) return 0;
      continue;
    }
    double ta = (0 - o[a]) / d[a], tb = (hi - o[a]) / d[a];
    if (ta > tb) {
      double x = ta;
      ta = tb;
      tb = x;
    }
    if (ta > *t0) *t0 = ta;
    if (tb < *t1) *t1 = tb;
  }
  return *t0 <= *t1;
}

/* The field along the ray, or an infinity on the side of iso of a voxel cell wholly on one side
 * (the tests read only the side). */
static double field_at(const obs_volume_iso *s, const double o[3], const double d[3], double t) {
  double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
  return s->sides ? obs_volume_sample_sided(s->v, s->sides, p) : obs_volume_sample(s->v, p);
}

/* Where the ray o + t d leaves the macrocell holding o + t d (*exit), and whether that cell
 * cannot reach iso (its max is below it). Cells span voxel centres c cell ... (c + 1) cell, the
 * first and last reaching the volume's faces (where the field is held). */
static int skip_cell(const obs_volume_iso *s, const double o[3], const double d[3], double t,
                     double *exit) {
  const obs_volume *v = s->v;
  const obs_volume_cells *c = s->cells;
  int ci[3];
  double e = INFINITY;
  for (int a = 0; a < 3; a++) {
    double x = o[a] + t * d[a], sp = v->spacing[a], top = v->n[a] > 1 ? v->n[a] - 1 : 0;
    double u = x / sp - 0.5;
    u = u > 0 ? u : 0;
    u = u < top ? u : top;
    ci[a] = (int)(u / c->cell);
    if (ci[a] >= c->n[a]) ci[a] = c->n[a] - 1;
    double f = INFINITY;
    if (d[a] > 0 && ci[a] < c->n[a] - 1)
      f = (((ci[a] + 1) * c->cell + 0.5) * sp - o[a]) / d[a];
    else if (d[a] < 0 && ci[a] > 0)
      f = ((ci[a] * c->cell + 0.5) * sp - o[a]) / d[a];
    e = f < e ? f : e;
  }
  *exit = e;
  size_t at = ((size_t)ci[2] * (size_t)c->n[1] + (size_t)ci[1]) * (size_t)c->n[0] + (size_t)ci[0];
  return c->max[at] < s->iso;
}

int obs_volume_first_hit(const obs_volume_iso *s, const double o[3], const double d[3], double t0,
                         double t1, double *t) {
  const obs_volume *v = s->v;
  for (int a = 0; a < 3; a++)
    if (!isfinite(o[a]) || !isfinite(d[a])) return 0;
  if (!clip_box(v, o, d, &t0, &t1) || !isfinite(t0) || !isfinite(t1)) return 0;
  double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  double smin = fmin(v->spacing[0], fmin(v->spacing[1], v->spacing[2]));
  if (!(len > 0)) return 0;
  /* Half the smallest voxel side, but never more than OBS_VOLUME_HIT_MAX_STEPS steps across the
   * box's diagonal: a voxel far thinner than the volume (spacing [1, 1, 1e-12]) must not make a
   * camera ray take 1e12 steps. */
  double diag = 0;
  for (int a = 0; a < 3; a++) diag += pow(v->n[a] * v->spacing[a], 2);
  double dt = fmax(0.5 * smin, sqrt(diag) / OBS_VOLUME_HIT_MAX_STEPS) / len,
         tol = 1e-3 * smin / len;
  double ta = t0, fa = field_at(s, o, d, ta);
  if (fa >= s->iso) {
    *t = ta;
    return 1;
  }
  /* Before t = known the ray stays in a cell that reaches iso: no cell test is needed there. */
  double known = -INFINITY;
  while (ta < t1) {
    double exit;
    if (s->cells && ta >= known) {
      if (!skip_cell(s, o, d, ta, &exit)) {
        known = exit;
      } else if (exit > ta) { /* nothing reaches iso before the cell's exit */
        if (exit >= t1) return 0;
        ta = fmax(exit, ta + 1e-6 * dt);
        fa = field_at(s, o, d, ta);
        if (fa >= s->iso) { /* only by rounding at the boundary: the crossing is here */
          *t = ta;
          return 1;
        }
        continue;
      }
    }
    double tb = fmin(ta + dt, t1);
    if (!(tb > ta)) return 0; /* a step too small for t's precision: the ray cannot go on */
    double fb = field_at(s, o, d, tb);
    if (fb >= s->iso) {
      /* The root between ta (below) and tb (at or above), to tol or to adjacent doubles. */
      while (tb - ta > tol) {
        double tm = 0.5 * (ta + tb);
        if (!(tm > ta && tm < tb)) break;
        if (field_at(s, o, d, tm) >= s->iso)
          tb = tm;
        else
          ta = tm;
      }
      *t = tb;
      return 1;
    }
    ta = tb;
    fa = fb;
  }
  return 0;
}

void obs_volume_normal(const obs_volume *v, const double p[3], double n[3]) {
  double g[3];
  for (int a = 0; a < 3; a++) {
    double h = 0.5 * v->spacing[a], q[3] = {p[0], p[1], p[2]}, r[3] = {p[0], p[1], p[2]};
    q[a] += h;
    r[a] -= h;
    g[a] = ((double)obs_volume_sample(v, q) - obs_volume_sample(v, r)) / (2 * h);
  }
  double l = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
  if (!(l > 0) || !isfinite(l)) {
    n[0] = n[1] = 0, n[2] = 1;
    return;
  }
  for (int a = 0; a < 3; a++) n[a] = -g[a] / l;
}

/* A volume as the AO march reads it: in index space, where voxel (i, j, k)'s centre lies at
 * u = (i, j, k), so a sample costs no division; float, as the Vulkan twin's march. */
typedef struct grid {
  const float *data;
  float hi[3];       /* n - 1: the field is held beyond the outer centres */
  int top[3];        /* the largest lower corner: n - 2, 0 on a 1-voxel axis */
  size_t row[3];     /* 1, n0, n0 n1 */
  size_t up[3];      /* the upper corner's offset: row, 0 on a 1-voxel axis (its weight is 0) */
  const obs_volume_sides *sides; /* NULL: none */
} grid;

static void grid_init(const obs_volume *v, const obs_volume_sides *sides, grid *g) {
  g->data = v->data;
  g->sides = sides;
  size_t row = 1;
  for (int a = 0; a < 3; a++) {
    g->hi[a] = (float)(v->n[a] - 1);
    g->top[a] = v->n[a] > 1 ? v->n[a] - 2 : 0;
    g->row[a] = row;
    g->up[a] = v->n[a] > 1 ? row : 0;
    row *= (size_t)v->n[a];
  }
}

/* Where index-space point u falls: its cell's lower corner i and the upper corners' weights. */
static inline void grid_locate(const grid *g, const float u[3], int i[3], float w[3]) {
  for (int a = 0; a < 3; a++) {
    float x = u[a] > 0 ? u[a] : 0; /* NaN too */
    x = x < g->hi[a] ? x : g->hi[a];
    i[a] = (int)x;
    if (i[a] > g->top[a]) i[a] = g->top[a];
    w[a] = x - (float)i[a];
  }
}

static inline float grid_lerp(const grid *g, const int i[3], const float w[3]) {
  const float *p = g->data + (size_t)i[0] + (size_t)i[1] * g->row[1] + (size_t)i[2] * g->row[2];
  size_t sx = g->up[0], sy = g->up[1], sz = g->up[2];
  float c00 = p[0] + w[0] * (p[sx] - p[0]);
  float c10 = p[sy] + w[0] * (p[sy + sx] - p[sy]);
  float c01 = p[sz] + w[0] * (p[sz + sx] - p[sz]);
  float c11 = p[sz + sy] + w[0] * (p[sz + sy + sx] - p[sz + sy]);
  float c0 = c00 + w[1] * (c10 - c00), c1 = c01 + w[1] * (c11 - c01);
  return c0 + w[2] * (c1 - c0);
}

/* The trilinear field at index-space point u (obs_volume_sample's field, in float). */
static inline float grid_sample(const grid *g, const float u[3]) {
  int i[3];
  float w[3];
  grid_locate(g, u, i, w);
  return grid_lerp(g, i, w);
}

/* The same where it may reach iso; where u's voxel cell lies wholly on one side of it (g->sides),
 * an infinity on that side instead: the crossing tests read only the side. */
static inline float grid_side_sample(const grid *g, const float u[3]) {
  int i[3];
  float w[3];
  grid_locate(g, u, i, w);
  int side = obs_volume_side(g->sides, i[0], i[1], i[2]);
  if (side) return side == OBS_VOLUME_BELOW ? -INFINITY : INFINITY;
  return grid_lerp(g, i, w);
}

/* The step (in voxels along the axis it moves most) from which an AO march with cell sides
 * takes every sample instead of walking macrocells. */
#define OBS_VOLUME_SIDES_STEP 1.0f

/* A 3D-DDA over the macrocells along u0 + t du (index space): the cell the ray is in and, per
 * axis, the t where it crosses into the next cell (infinite where it never does: du is 0 there,
 * or the cell is the outer one on that side, which reaches past the volume's faces). */
typedef struct cell_walk {
  const obs_volume_cells *c;
  const float *u0, *inv; /* inv: 1 / du per axis, 0 where du is 0 */
  int ci[3];
  float next[3];
} cell_walk;

static void walk_face(cell_walk *w, int a) {
  const obs_volume_cells *c = w->c;
  w->next[a] = INFINITY;
  if (w->inv[a] > 0 && w->ci[a] < c->n[a] - 1)
    w->next[a] = ((float)((w->ci[a] + 1) * c->cell) - w->u0[a]) * w->inv[a];
  else if (w->inv[a] < 0 && w->ci[a] > 0)
    w->next[a] = ((float)(w->ci[a] * c->cell) - w->u0[a]) * w->inv[a];
}

/* Starts the walk in the cell holding index-space point q. A point on a face between two cells
 * lies in both (the field there is within either's bounds), so the index may round either way. */
static void walk_init(cell_walk *w, const grid *g, const float q[3]) {
  const obs_volume_cells *c = w->c;
  float inv_cell = 1.0f / (float)c->cell;
  for (int a = 0; a < 3; a++) {
    float x = q[a] > 0 ? q[a] : 0;
    x = x < g->hi[a] ? x : g->hi[a];
    w->ci[a] = (int)(x * inv_cell);
    if (w->ci[a] >= c->n[a]) w->ci[a] = c->n[a] - 1;
    walk_face(w, a);
  }
}

static float walk_exit(const cell_walk *w) {
  float e = w->next[0] < w->next[1] ? w->next[0] : w->next[1];
  return e < w->next[2] ? e : w->next[2];
}

static void walk_step(cell_walk *w) {
  int a = w->next[0] <= w->next[1] ? 0 : 1;
  if (w->next[2] < w->next[a]) a = 2;
  w->ci[a] += w->inv[a] > 0 ? 1 : -1;
  walk_face(w, a);
}

static int crosses(obs_volume_crossing how, float prev, float cur, float iso) {
  return how == OBS_VOLUME_CROSS_RISING ? prev < iso && cur > iso : (prev < iso) != (cur < iso);
}

/* The march's grid: samples at t = start + i step for i = ia ... ib, all inside the box. */
typedef struct march {
  const grid *g;
  float u0[3], du[3], inv[3], iso;
  double start, step, inv_step;
  int64_t ia, ib;
  obs_volume_crossing how;
  int simd, loads; /* eight samples at a time (cell sides and AVX2), their loads as loads */
  double inv_step_voxels; /* 1 / the step along the axis it moves most, in voxels */
} march;

/* Grid sample i's index-space point. */
static inline void march_point(const march *m, int64_t i, float q[3]) {
  float t = (float)(m->start + (double)i * m->step);
  for (int a = 0; a < 3; a++) q[a] = m->u0[a] + t * m->du[a];
}

static inline float march_sample(const march *m, int64_t i) {
  float q[3];
  march_point(m, i, q);
  return m->g->sides ? grid_side_sample(m->g, q) : grid_sample(m->g, q);
}

/* How many samples from i on (i included, at most to ib) lie in bricks wholly on the side of iso
 * that sample i's brick is on, by its distance to the nearest other brick (obs_volume_sides.far),
 * with that side's value in *value; 0 when it says nothing. Bricks are 8 voxel cells a side, so a
 * point less than 8 (dist - 1) voxels (Chebyshev) from sample i lies in a brick nearer than dist;
 * a voxel of margin covers the rounding of the samples' points. */
static inline int64_t far_run(const march *m, int64_t i, float *value) {
  const obs_volume_sides *sd = m->g->sides;
  float q[3], w[3];
  int c[3];
  march_point(m, i, q);
  grid_locate(m->g, q, c, w);
  int far = sd->far[obs_volume_brick_index(sd, c[0], c[1], c[2])], dist = far >> 2;
  if (dist < 2) return 0;
  *value = (far & 3) == OBS_VOLUME_BELOW ? -INFINITY : INFINITY;
  /* The reciprocal's roundings are far inside the 1e-6 taken off. */
  double run = floor((8.0 * (dist - 1) - 1) * m->inv_step_voxels * (1 - 1e-6)) + 1;
  double left = (double)(m->ib - i + 1);
  return (int64_t)(run < left ? run : left); /* run is +inf for a step of 0: all at one point */
}

/* Settles the run of samples far_run finds at i: 1 when it ends a crossing, else *i moves past it
 * (unchanged when there is none). */
static inline int far_skip(const march *m, int64_t *i, float *prev, int *crossed) {
  float v;
  int64_t run = far_run(m, *i, &v);
  if (run < 2) return 0;
  *crossed = crosses(m->how, *prev, v, m->iso);
  *prev = v;
  *i += run;
  return 1;
}

#if OBS_SIMD_AVX2
/* bits[byte[l]] for the 8 lanes l, as 32-bit lanes (the sides array has 3 bytes of slack). */
OBS_AVX2_INLINE __m256i gather_bytes(int loads, const uint8_t *bits, __m256i byte) {
  if (!loads) return _mm256_and_si256(_mm256_i32gather_epi32((const int *)bits, byte, 1),
                                      _mm256_set1_epi32(0xff));
  int at[8];
  _mm256_storeu_si256((__m256i *)at, byte);
  return _mm256_setr_epi32(bits[at[0]], bits[at[1]], bits[at[2]], bits[at[3]], bits[at[4]],
                           bits[at[5]], bits[at[6]], bits[at[7]]);
}

/* grid_side_sample at eight index-space points (x, y, z), lane for lane the scalar code's
 * operations: the clamps, truncation, weights and the lerps in the same order. */
OBS_AVX2_INLINE __m256 side_sample8(const grid *g, int loads, const __m256 u[3]) {
  __m256i i[3];
  __m256 w[3];
  for (int a = 0; a < 3; a++) {
    __m256 x = _mm256_min_ps(_mm256_max_ps(u[a], _mm256_setzero_ps()), _mm256_set1_ps(g->hi[a]));
    i[a] = _mm256_min_epi32(_mm256_cvttps_epi32(x), _mm256_set1_epi32(g->top[a]));
    w[a] = _mm256_sub_ps(x, _mm256_cvtepi32_ps(i[a]));
  }
  /* obs_volume_side_index, lane by lane. */
  const __m256i seven = _mm256_set1_epi32(7);
  __m256i brick = _mm256_add_epi32(
      _mm256_mullo_epi32(
          _mm256_add_epi32(_mm256_mullo_epi32(_mm256_srli_epi32(i[2], 3),
                                              _mm256_set1_epi32(g->sides->bricks[1])),
                           _mm256_srli_epi32(i[1], 3)),
          _mm256_set1_epi32(g->sides->bricks[0])),
      _mm256_srli_epi32(i[0], 3));
  __m256i cell = _mm256_or_si256(
      _mm256_slli_epi32(brick, 9),
      _mm256_or_si256(_mm256_slli_epi32(_mm256_and_si256(i[2], seven), 6),
                      _mm256_or_si256(_mm256_slli_epi32(_mm256_and_si256(i[1], seven), 3),
                                      _mm256_and_si256(i[0], seven))));
  __m256i byte = gather_bytes(loads, g->sides->bits, _mm256_srli_epi32(cell, 2));
  __m256i side = _mm256_and_si256(
      _mm256_srlv_epi32(byte, _mm256_slli_epi32(_mm256_and_si256(cell, _mm256_set1_epi32(3)), 1)),
      _mm256_set1_epi32(3));
  __m256 above = _mm256_castsi256_ps(_mm256_cmpeq_epi32(side, _mm256_set1_epi32(OBS_VOLUME_ABOVE)));
  __m256 settled = _mm256_blendv_ps(_mm256_set1_ps(-INFINITY), _mm256_set1_ps(INFINITY), above);
  __m256 open = _mm256_castsi256_ps(_mm256_cmpeq_epi32(side, _mm256_setzero_si256()));
  int open_lanes = _mm256_movemask_ps(open);
  if (!open_lanes) return settled;
  /* Few lanes reach iso (the surface is thin): those take grid_lerp's scalar loads and lerps. */
  int ii[3][8];
  float ww[3][8], out[8];
  for (int a = 0; a < 3; a++) {
    _mm256_storeu_si256((__m256i *)ii[a], i[a]);
    _mm256_storeu_ps(ww[a], w[a]);
  }
  _mm256_storeu_ps(out, settled);
  for (; open_lanes; open_lanes &= open_lanes - 1) {
    int l = __builtin_ctz((unsigned)open_lanes);
    const int li[3] = {ii[0][l], ii[1][l], ii[2][l]};
    const float lw[3] = {ww[0][l], ww[1][l], ww[2][l]};
    out[l] = grid_lerp(g, li, lw);
  }
  return _mm256_loadu_ps(out);
}

/* march_plain eight samples at a time: every sample's point is march_point's (t in double, then
 * float), and a crossing between any two neighbours, the first one against *prev, answers. */
OBS_AVX2_FN static int march_plain8(const march *m, float *prev) {
  const __m256d step = _mm256_set1_pd(m->step), start = _mm256_set1_pd(m->start);
  const __m256 iso = _mm256_set1_ps(m->iso);
  const __m256i shift = _mm256_setr_epi32(7, 0, 1, 2, 3, 4, 5, 6);
  /* The march starts at a surface; far bricks are asked only once a group found its eight samples
   * settled on one side. */
  int settled = 0;
  for (int64_t i = m->ia; i <= m->ib; i += 8) {
    int crossed = 0;
    while (settled && i <= m->ib && far_skip(m, &i, prev, &crossed))
      if (crossed) return 1;
    if (i > m->ib) break;
    double base = (double)i;
    __m256d k0 = _mm256_add_pd(_mm256_set1_pd(base), _mm256_setr_pd(0, 1, 2, 3));
    __m256d k1 = _mm256_add_pd(_mm256_set1_pd(base), _mm256_setr_pd(4, 5, 6, 7));
    __m256 t = _mm256_set_m128(_mm256_cvtpd_ps(_mm256_add_pd(start, _mm256_mul_pd(k1, step))),
                               _mm256_cvtpd_ps(_mm256_add_pd(start, _mm256_mul_pd(k0, step))));
    __m256 u[3];
    for (int a = 0; a < 3; a++)
      u[a] = _mm256_add_ps(_mm256_set1_ps(m->u0[a]), _mm256_mul_ps(t, _mm256_set1_ps(m->du[a])));
    __m256 v = side_sample8(m->g, m->loads, u);
    __m256 pv = _mm256_blend_ps(_mm256_permutevar8x32_ps(v, shift), _mm256_set1_ps(*prev), 1);
    __m256 below_before = _mm256_cmp_ps(pv, iso, _CMP_LT_OQ);
    __m256 hit = m->how == OBS_VOLUME_CROSS_RISING
                     ? _mm256_and_ps(below_before, _mm256_cmp_ps(v, iso, _CMP_GT_OQ))
                     : _mm256_xor_ps(below_before, _mm256_cmp_ps(v, iso, _CMP_LT_OQ));
    int64_t left = m->ib - i + 1;
    int lanes = left < 8 ? (int)left : 8, valid = (1 << lanes) - 1;
    if (_mm256_movemask_ps(hit) & valid) return 1;
    float last[8];
    _mm256_storeu_ps(last, v);
    *prev = last[lanes - 1];
    __m256 same = _mm256_cmp_ps(v, _mm256_set1_ps(*prev), _CMP_EQ_OQ);
    settled = isinf(*prev) && (_mm256_movemask_ps(same) & valid) == valid;
  }
  return 0;
}
#endif

/* Samples ia ... ib one by one; *prev is the value before ia and the last on return. */
static int march_plain(const march *m, float *prev) {
#if OBS_SIMD_AVX2
  if (m->simd) return march_plain8(m, prev);
#endif
  for (int64_t i = m->ia; i <= m->ib; i++) {
    int crossed = 0;
    if (m->g->sides && isinf(*prev)) {
      while (i <= m->ib && far_skip(m, &i, prev, &crossed))
        if (crossed) return 1;
      if (i > m->ib) break;
    }
    float cur = march_sample(m, i);
    if (crosses(m->how, *prev, cur, m->iso)) return 1;
    *prev = cur;
  }
  return 0;
}

/* The same answer cell by cell: a cell wholly below or wholly above iso decides its samples from
 * its bounds (the tests read only which side of iso each value lies on), a cell that reaches iso
 * is sampled. */
static int march_cells(const march *m, const obs_volume_cells *c, float *prev) {
  float q[3];
  march_point(m, m->ia, q);
  cell_walk w = {c, m->u0, m->inv, {0, 0, 0}, {0, 0, 0}};
  walk_init(&w, m->g, q);
  for (int64_t i = m->ia; i <= m->ib; walk_step(&w)) {
    /* The cell's last sample: the last grid t at or before its exit. */
    float exit = walk_exit(&w);
    int64_t j = m->ib;
    if (exit < INFINITY) {
      /* The quotient by a reciprocal may round across an integer: the grid itself decides. */
      double last_in = floor((exit - m->start) * m->inv_step);
      if (m->start + last_in * m->step > exit)
        last_in -= 1;
      else if (m->start + (last_in + 1) * m->step <= exit)
        last_in += 1;
      if (last_in < (double)j) j = (int64_t)last_in;
    }
    if (j < i) continue; /* no sample in this cell */
    size_t at = ((size_t)w.ci[2] * (size_t)c->n[1] + (size_t)w.ci[1]) * (size_t)c->n[0] +
                (size_t)w.ci[0];
    if (c->max[at] < m->iso) {
      if (crosses(m->how, *prev, -INFINITY, m->iso)) return 1;
      *prev = -INFINITY;
    } else if (c->min[at] > m->iso) {
      if (crosses(m->how, *prev, INFINITY, m->iso)) return 1;
      *prev = INFINITY;
    } else {
      march sub = *m;
      sub.ia = i, sub.ib = j;
      if (march_plain(&sub, prev)) return 1;
    }
    i = j + 1;
  }
  return 0;
}

static inline __attribute__((always_inline)) int grid_crossing_body(
    const obs_volume_iso *s, const double o[3], const double d[3], const obs_volume_ao_params *a) {
  const obs_volume *v = s->v;
  if (!(a->step > 0) || !(a->max_distance >= a->start) || !isfinite(a->max_distance)) return 0;
  double last = floor((a->max_distance - a->start) / a->step + 1e-9);
  if (!(last <= OBS_VOLUME_AO_MAX_STEPS)) last = OBS_VOLUME_AO_MAX_STEPS;
  double t0 = a->start, t1 = a->start + last * a->step;
  if (!clip_box(v, o, d, &t0, &t1)) return 0; /* 0 all along: no crossing */
  grid g;
  grid_init(v, s->sides, &g);
  march m = {.g = &g, .iso = s->iso, .start = a->start, .step = a->step,
             .inv_step = 1 / a->step, .how = a->crossing,
             .simd = s->sides && a->isa >= OBS_ISA_AVX2, .loads = a->gather_loads};
  for (int k = 0; k < 3; k++) {
    m.u0[k] = (float)(o[k] / v->spacing[k] - 0.5);
    m.du[k] = (float)(d[k] / v->spacing[k]);
  }
  /* Grid indices inside the box; the samples before and after read 0. */
  m.ia = (int64_t)ceil((t0 - a->start) / a->step);
  m.ib = (int64_t)floor((t1 - a->start) / a->step);
  if (m.ia < 0) m.ia = 0;
  if (m.ib > (int64_t)last) m.ib = (int64_t)last;
  /* Macrocells pay where several samples share one; cell sides settle a sample for a byte. */
  float reach = 0;
  for (int k = 0; k < 3; k++) {
    float r = fabsf(m.du[k]) * (float)a->step;
    reach = r > reach ? r : reach;
  }
  m.inv_step_voxels = 1.0 / reach;
  int by_cells = s->cells && !(s->sides && reach >= OBS_VOLUME_SIDES_STEP);
  if (by_cells)
    for (int k = 0; k < 3; k++) m.inv[k] = m.du[k] != 0 ? 1 / m.du[k] : 0;
  float prev = 0;
  if (m.ia == 0) prev = march_sample(&m, 0), m.ia = 1;
  if (m.ia <= m.ib && (by_cells ? march_cells(&m, s->cells, &prev) : march_plain(&m, &prev)))
    return 1;
  /* Past the box the field reads 0. */
  return m.ib < (int64_t)last && crosses(a->crossing, prev, 0, s->iso);
}

/* The set-up's double arithmetic is the same IEEE operations at either level (no contraction);
 * x86-64-v3 rounds with roundsd and keeps more in registers. */
static int grid_crossing_base(const obs_volume_iso *s, const double o[3], const double d[3],
                              const obs_volume_ao_params *a) {
  return grid_crossing_body(s, o, d, a);
}

#if OBS_SIMD_AVX2
OBS_V3_FN static int grid_crossing_v3(const obs_volume_iso *s, const double o[3], const double d[3],
                                      const obs_volume_ao_params *a) {
  return grid_crossing_body(s, o, d, a);
}
#endif

int obs_volume_grid_crossing(const obs_volume_iso *s, const double o[3], const double d[3],
                             const obs_volume_ao_params *a) {
#if OBS_SIMD_AVX2
  if (a->isa >= OBS_ISA_AVX2) return grid_crossing_v3(s, o, d, a);
#endif
  return grid_crossing_base(s, o, d, a);
}

double obs_volume_ao(const obs_volume_iso *s, const double p[3], const double n[3],
                     const obs_volume_ao_params *a, const float *u, double bent[3]) {
  float nf[3] = {(float)n[0], (float)n[1], (float)n[2]}, t1[3], t2[3];
  obs_onb(nf, t1, t2);
  double sum[3] = {0, 0, 0};
  uint32_t blocked = 0;
  for (uint32_t i = 0; i < a->samples; i++) {
    float l[3];
    obs_sample_cosine(u[2 * i], u[2 * i + 1], l);
    double dir[3];
    for (int k = 0; k < 3; k++) dir[k] = l[0] * (double)t1[k] + l[1] * (double)t2[k] + l[2] * n[k];
    if (obs_volume_grid_crossing(s, p, dir, a)) {
      blocked++;
    } else {
      for (int k = 0; k < 3; k++) sum[k] += dir[k];
    }
  }
  double len = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
  for (int k = 0; k < 3; k++) bent[k] = len > 0 ? sum[k] / len : n[k];
  return a->samples ? 1.0 - (double)blocked / a->samples : 1.0;
}
