/* ss_obscurance's offset tables: the article's kernel, a cosine-distributed direction times a
 * distance drawn from the membership's density d mu / dr, precomputed as tangent-space offsets in
 * units of R (or uniform directions and distances carrying the kernel as a weight), both backends
 * reading the same floats. The derivation is in docs/techniques/ss_obscurance.md. */
#include <math.h>
#include <string.h>

#include "obscurance.h"
#include "sampling.h"
#include "ss_obscurance.h"

double obs_sso_membership(int membership, double tau, double rho) {
  if (!(rho < 1.0)) return 1.0;
  if (rho < 0.0) rho = 0.0;
  switch (membership) {
    case OBS_FALLOFF_BINARY: return 0.0;
    case OBS_FALLOFF_SQRT: return sqrt(rho);
    default: return -expm1(-tau * rho);
  }
}

/* mu is a distribution function of distances in units of R: continuous on [0, 1) (sqrt, exp)
 * with the rest of its mass at 1 (all of it for binary, exp(-tau) for exp: mu jumps to 1 at R,
 * as rt_ao's truncated falloff does). */
double obs_sso_membership_inverse(int membership, double tau, double xi) {
  switch (membership) {
    case OBS_FALLOFF_BINARY: return 1.0;
    case OBS_FALLOFF_SQRT: return xi * xi;
    default: {
      double at_r = -expm1(-tau); /* mu just below R */
      if (!(xi < at_r)) return 1.0;
      double rho = -log1p(-xi) / tau;
      return rho < 1.0 ? rho : 1.0;
    }
  }
}

/* Radical inverse of k in base b: the Halton coordinates of the offsets' directions. */
static double radical_inverse(uint32_t k, uint32_t b) {
  double inv = 1.0 / (double)b, f = inv, r = 0.0;
  for (; k; k /= b, f *= inv) r += f * (double)(k % b);
  return r;
}

static double frac(double x) { return x - floor(x); }

/* Shirley and Chiu's concentric map of the unit square onto the unit disc: it keeps the
 * stratification of the points where the article's rejection of the square's corners would
 * drop points of the set. */
static void concentric_disc(double u, double v, double *x, double *y) {
  double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0, r, phi;
  const double quarter_pi = 0.78539816339744830962;
  if (a == 0.0 && b == 0.0) {
    *x = *y = 0.0;
    return;
  }
  if (fabs(a) > fabs(b)) {
    r = a;
    phi = quarter_pi * (b / a);
  } else {
    r = b;
    phi = 2.0 * quarter_pi - quarter_pi * (a / b);
  }
  *x = r * cos(phi);
  *y = r * sin(phi);
}

void obs_sso_tables_make(const obs_sso_params *p, obs_sso_tables *t) {
  memset(t, 0, sizeof *t);
  const int n = p->samples;
  t->cells = p->interleave ? OBS_SSO_CELLS : 1;
  for (int c = 0; c < t->cells; c++) {
    /* A Cranley-Patterson shift of the 3D Hammersley set per cell: every cell's set is as
     * uniform as the unshifted one, and the 16 cells' errors are independent. */
    uint32_t h = obs_hash_combine(p->seed, (uint32_t)c);
    double s0 = obs_u32_to_unit(obs_hash32(h ^ 0x9e3779b9U));
    double s1 = obs_u32_to_unit(obs_hash32(h ^ 0x85ebca6bU));
    double s2 = obs_u32_to_unit(obs_hash32(h ^ 0xc2b2ae35U));
    double wsum = 0.0;
    for (int k = 0; k < n; k++) {
      double xi = frac(((double)k + 0.5) / (double)n + s0);
      double u = frac(radical_inverse((uint32_t)k, 2) + s1);
      double v = frac(radical_inverse((uint32_t)k, 3) + s2);
      double d[3], rho, w;
      if (p->sampling == OBS_SSO_UNIFORM) {
        /* Uniform directions (density 1 / 2 pi) and distances (density 1 on [0, 1)): the weight
         * is the kernel over that density, 2 cos(theta) d mu / d rho; for sqrt
         * d mu / d rho = 1 / (2 sqrt rho). rho is kept above 2^-24 so the weight stays finite. */
        double st = sqrt(1.0 - u * u), phi = 6.283185307179586477 * v;
        d[0] = st * cos(phi);
        d[1] = st * sin(phi);
        d[2] = u;
        rho = xi > 0x1p-24 ? xi : 0x1p-24;
        w = d[2] / sqrt(rho);
      } else {
        /* A uniform point of the unit disc lifted to the hemisphere has density cos / pi. */
        concentric_disc(u, v, &d[0], &d[1]);
        double z2 = 1.0 - d[0] * d[0] - d[1] * d[1];
        d[2] = z2 > 0.0 ? sqrt(z2) : 0.0;
        rho = obs_sso_membership_inverse(p->membership, p->tau, xi);
        w = 1.0;
      }
      for (int a = 0; a < 3; a++) t->offsets[c][k][a] = (float)(d[a] * rho);
      t->offsets[c][k][3] = (float)w;
      wsum += (double)(float)w;
    }
    t->offsets[c][n][0] = (float)(1.0 / wsum);
  }
  for (int k = 1; k <= 16; k++) t->inv_count[k] = 1.0f / (float)k;
}

int obs_sso_params_valid(const obs_sso_params *p, obs_err *err) {
  if (!p) return obs_err_set(err, OBS_EINVAL, "ss_obscurance: missing parameters");
  if (p->samples < 4 || p->samples > OBS_SSO_MAX_SAMPLES)
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: samples must be in [4, %d] (got %d)",
                       OBS_SSO_MAX_SAMPLES, p->samples);
  if (!(p->radius > 0.0f) || !isfinite(p->radius))
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: radius must be a positive number (got %g)",
                       (double)p->radius);
  if (p->membership < OBS_FALLOFF_BINARY || p->membership > OBS_FALLOFF_EXP)
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: membership %d is not binary, sqrt or exp",
                       p->membership);
  if (p->membership == OBS_FALLOFF_EXP && !(p->tau > 0.0 && isfinite(p->tau)))
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: tau must be a positive number (got %g)",
                       p->tau);
  if (p->sampling == OBS_SSO_UNIFORM && p->membership != OBS_FALLOFF_SQRT)
    return obs_err_set(err, OBS_EINVAL,
                       "ss_obscurance: sampling uniform needs membership sqrt (got %s)",
                       obs_falloff_names[p->membership]);
  if (p->sampling != OBS_SSO_IMPORTANCE && p->sampling != OBS_SSO_UNIFORM)
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: sampling %d is not importance or uniform",
                       p->sampling);
  return 0;
}

void obs_sso_push_make(const obs_sso_params *p, int width, int height, int ortho, float half_w,
                       float half_h, obs_sso_push *pc) {
  memset(pc, 0, sizeof *pc);
  pc->width = width;
  pc->height = height;
  pc->samples = p->samples;
  pc->flags = (ortho ? OBS_SSO_FLAG_ORTHO : 0) | (p->interleave ? OBS_SSO_FLAG_INTERLEAVE : 0);
  pc->half_w = half_w;
  pc->half_h = half_h;
  pc->radius = p->radius;
  pc->two_inv_w = 2.0f / (float)width;
  pc->two_inv_h = 2.0f / (float)height;
  pc->inv_half_w = 1.0f / half_w;
  pc->inv_half_h = 1.0f / half_h;
}
