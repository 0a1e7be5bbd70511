/* sss_single's parameters as its backends read them, and the closed forms its estimators share:
 * the Henyey-Greenstein phase function, Schlick's Fresnel transmittance, refraction and the
 * refracted light path length of ShaderX7 6.5 (Eq. 6.5.6, after Jensen et al. 2001). */
#ifndef OBS_SSS_SINGLE_H
#define OBS_SSS_SINGLE_H

#include <math.h>
#include <stdint.h>

#include "obscura/technique.h"

enum { OBS_SSS_SHADOW_MAPS = 0, OBS_SSS_TRACE = 1 };

typedef struct obs_sss_single_params {
  int method;           /* OBS_SSS_SHADOW_MAPS or OBS_SSS_TRACE */
  uint32_t samples;     /* path samples M per light (shadow_maps); paths per pixel sample (trace) */
  int adaptive;         /* shadow_maps: 2M samples where 20-85 % of the samples are dim */
  double jitter;        /* shadow_maps: jitter of the map lookups, in texels (0: none) */
  uint32_t map_size;    /* shadow_maps: light-view map resolution (square) */
  double unit_length;   /* scene length of the unit the medium coefficients are per */
  uint32_t seed;
  double exposure;      /* EV, final.png only */
} obs_sss_single_params;

/* The article's adaptive rule: a sample is dim when its light, relative to the light's own
 * irradiance, has luminance below 0.05; a pixel whose share of dim samples lies in [0.2, 0.85]
 * is a shadow boundary and takes twice the samples. */
#define OBS_SSS_DIM 0.05
#define OBS_SSS_DIM_LO 0.20
#define OBS_SSS_DIM_HI 0.85

int obs_sss_single_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_sss_single_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

/* Henyey-Greenstein phase function of the cosine between the propagation directions before and
 * after scattering; integrates to 1 over the sphere. */
static inline double obs_sss_hg(double cos_theta, double g) {
  double d = 1.0 + g * g - 2.0 * g * cos_theta;
  return (1.0 - g * g) / (4.0 * M_PI * d * sqrt(d));
}

/* Schlick's approximation of the Fresnel reflectance at the cosine of the angle on the outer
 * (less dense) side, and its transmittance 1 - F. */
static inline double obs_sss_schlick_t(double cos_outer, double eta) {
  double r0 = (eta - 1.0) / (eta + 1.0);
  r0 *= r0;
  double c = 1.0 - fabs(cos_outer);
  if (c < 0) c = 0;
  double c2 = c * c;
  return 1.0 - (r0 + (1.0 - r0) * c2 * c2 * c);
}

/* The direction of `d` (unit, travelling toward the surface whose unit normal `n` faces against
 * it) refracted into the denser side with relative index eta >= 1: always exists. */
static inline void obs_sss_refract(const double d[3], const double n[3], double eta,
                                   double out[3]) {
  double ci = -(d[0] * n[0] + d[1] * n[1] + d[2] * n[2]);
  if (ci < 0) ci = 0;
  double r = 1.0 / eta, k = 1.0 - r * r * (1.0 - ci * ci);
  double ct = sqrt(k > 0 ? k : 0);
  for (int i = 0; i < 3; i++) out[i] = r * d[i] + (r * ci - ct) * n[i];
  double l = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
  for (int i = 0; i < 3; i++) out[i] /= l;
}

/* Eq. 6.5.6: the refracted light path s_i' from the observed distance s_i to the entry point and
 * the cosine between the light's direction and the entry normal. */
static inline double obs_sss_refracted_length(double s_i, double cos_i, double eta) {
  double c = fabs(cos_i), r = 1.0 / eta;
  return s_i * c / sqrt(1.0 - r * r * (1.0 - c * c));
}

#endif
