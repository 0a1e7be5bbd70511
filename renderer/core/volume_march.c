/* Marching a scalar volume: first isosurface hits with macrocell skipping, gradient normals and
 * ray-marched AO with bent normals (volume_march.h). */
#include "volume_march.h"

#include <math.h>

#include "sampling.h"

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

static double field_at(const obs_volume *v, const double o[3], const double d[3], double t) {
  double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
  return obs_volume_sample(v, p);
}

/* When the macrocell holding o + t d cannot reach iso (its max is below it), the parameter where
 * the ray leaves that cell; else t. Cells span voxel centres c cell ... (c + 1) cell, the first
 * and last reaching the volume's faces (where the field is held). */
static double skip_cell(const obs_volume_iso *s, const double o[3], const double d[3], double t) {
  const obs_volume *v = s->v;
  const obs_volume_cells *c = s->cells;
  int ci[3];
  double lo[3], hi[3];
  for (int a = 0; a < 3; a++) {
    double x = o[a] + t * d[a], sp = v->spacing[a];
    double u = fmin(fmax(x / sp - 0.5, 0), v->n[a] > 1 ? v->n[a] - 1 : 0);
    ci[a] = (int)(u / c->cell);
    if (ci[a] >= c->n[a]) ci[a] = c->n[a] - 1;
    lo[a] = ci[a] == 0 ? -INFINITY : (ci[a] * c->cell + 0.5) * sp;
    hi[a] = ci[a] == c->n[a] - 1 ? INFINITY : ((ci[a] + 1) * c->cell + 0.5) * sp;
  }
  size_t at = ((size_t)ci[2] * (size_t)c->n[1] + (size_t)ci[1]) * (size_t)c->n[0] + (size_t)ci[0];
  if (!(c->max[at] < s->iso)) return t;
  double exit = INFINITY;
  for (int a = 0; a < 3; a++) {
    if (d[a] > 0 && isfinite(hi[a])) exit = fmin(exit, (hi[a] - o[a]) / d[a]);
    if (d[a] < 0 && isfinite(lo[a])) exit = fmin(exit, (lo[a] - o[a]) / d[a]);
  }
  return exit;
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
  double ta = t0, fa = field_at(v, o, d, ta);
  if (fa >= s->iso) {
    *t = ta;
    return 1;
  }
  while (ta < t1) {
    if (s->cells) {
      double exit = skip_cell(s, o, d, ta);
      if (exit > ta) { /* nothing reaches iso before the cell's exit */
        if (exit >= t1) return 0;
        ta = fmax(exit, ta + 1e-6 * dt);
        fa = field_at(v, o, d, ta);
        if (fa >= s->iso) { /* only by rounding at the boundary: the crossing is here */
          *t = ta;
          return 1;
        }
        continue;
      }
    }
    double tb = fmin(ta + dt, t1);
    if (!(tb > ta)) return 0; /* a step too small for t's precision: the ray cannot go on */
    double fb = field_at(v, o, d, tb);
    if (fb >= s->iso) {
      /* The root between ta (below) and tb (at or above), to tol or to adjacent doubles. */
      while (tb - ta > tol) {
        double tm = 0.5 * (ta + tb);
        if (!(tm > ta && tm < tb)) break;
        if (field_at(v, o, d, tm) >= s->iso)
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

/* The data-space box of the macrocell holding q, and whether the field stays below iso in it. */
static int cell_below(const obs_volume_iso *s, const double q[3], double lo[3], double hi[3]) {
  const obs_volume *v = s->v;
  const obs_volume_cells *c = s->cells;
  int ci[3];
  for (int a = 0; a < 3; a++) {
    double sp = v->spacing[a];
    double u = fmin(fmax(q[a] / sp - 0.5, 0), v->n[a] > 1 ? v->n[a] - 1 : 0);
    ci[a] = (int)(u / c->cell);
    if (ci[a] >= c->n[a]) ci[a] = c->n[a] - 1;
    lo[a] = ci[a] == 0 ? -INFINITY : (ci[a] * c->cell + 0.5) * sp;
    hi[a] = ci[a] == c->n[a] - 1 ? INFINITY : ((ci[a] + 1) * c->cell + 0.5) * sp;
  }
  size_t at = ((size_t)ci[2] * (size_t)c->n[1] + (size_t)ci[1]) * (size_t)c->n[0] + (size_t)ci[0];
  return c->max[at] < s->iso;
}

static int crosses(obs_volume_crossing how, double prev, double cur, double iso) {
  return how == OBS_VOLUME_CROSS_RISING ? prev < iso && cur > iso : (prev < iso) != (cur < iso);
}

int obs_volume_grid_crossing(const obs_volume_iso *s, const double o[3], const double d[3],
                             const obs_volume_ao_params *a) {
  const obs_volume *v = s->v;
  if (!(a->step > 0) || !(a->max_distance >= a->start) || !isfinite(a->max_distance)) return 0;
  double last = floor((a->max_distance - a->start) / a->step + 1e-9);
  if (!(last <= OBS_VOLUME_AO_MAX_STEPS)) last = OBS_VOLUME_AO_MAX_STEPS;
  double t0 = a->start, t1 = a->start + last * a->step;
  if (!clip_box(v, o, d, &t0, &t1)) return 0; /* 0 all along: no crossing */
  /* Grid indices inside the box; the samples before and after read 0. */
  int64_t ia = (int64_t)ceil((t0 - a->start) / a->step),
          ib = (int64_t)floor((t1 - a->start) / a->step);
  if (ia < 0) ia = 0;
  if (ib > (int64_t)last) ib = (int64_t)last;
  double prev = 0;
  if (ia == 0) prev = field_at(v, o, d, a->start), ia = 1;
  /* Up to t = known the ray stays in a cell that reaches iso: no cell test is needed there. */
  double known = -INFINITY;
  for (int64_t i = ia; i <= ib; i++) {
    double t = a->start + (double)i * a->step;
    double q[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
    double lo[3], hi[3];
    if (s->cells && prev < s->iso && t > known) {
      int below = cell_below(s, q, lo, hi);
      double exit = INFINITY;
      for (int k = 0; k < 3; k++) {
        if (d[k] > 0 && isfinite(hi[k])) exit = fmin(exit, (hi[k] - o[k]) / d[k]);
        if (d[k] < 0 && isfinite(lo[k])) exit = fmin(exit, (lo[k] - o[k]) / d[k]);
      }
      /* A cell below iso holds no end of a crossing: jump past its last grid sample, whose
       * value, below iso like prev's, is all the next test needs (the tests read only which
       * side of iso prev lies on, so any skipped samples give the same answer). */
      double last_in = floor((exit - a->start) / a->step);
      if (below && a->start + last_in * a->step > exit) last_in -= 1;
      if (!below) {
        known = exit;
      } else if (last_in > (double)i) {
        i = last_in >= (double)ib ? ib : (int64_t)last_in; /* the loop's i++ leaves the cell */
        prev = -1;
        continue;
      }
    }
    double cur = obs_volume_sample(v, q);
    if (crosses(a->crossing, prev, cur, s->iso)) return 1;
    prev = cur;
  }
  /* Past the box the field reads 0. */
  return ib < (int64_t)last && crosses(a->crossing, prev, 0, s->iso);
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
