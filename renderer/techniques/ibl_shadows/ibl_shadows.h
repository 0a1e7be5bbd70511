/* ibl_shadows (Colbert and Krivanek, ShaderX7 4.3, "Real-Time Dynamic Shadows for Image-Based
 * Lighting"): parameters, the set-up both the run and the tests use (the importance-sampled
 * shadow directions, the regularised pseudo-inverse, the environment's SH) and the CPU entry
 * point. The model is docs/techniques/ibl_shadows.md. */
#ifndef OBS_IBL_SHADOWS_H
#define OBS_IBL_SHADOWS_H

#include <stdint.h>

#include "environment.h"
#include "gbuffer.h"
#include "obscura/error.h"
#include "obscura/technique.h"

struct obs_rt;

#define OBS_IBL_MAX_MAPS 64

/* Bound from the descriptor's parameter table. */
typedef struct obs_ibl_shadows_params {
  int shadow_maps; /* importance-sampled directions, one orthographic shadow map each */
  int sh_order;    /* SH bands 1..4 (order^2 coefficients) */
  int map_size;    /* shadow-map side in texels */
  float tikhonov;  /* alpha of the regularised pseudo-inverse */
  float bias;      /* depth bias in shadow-map texels (slope-scaled) */
  int blur;        /* the article's 9 x 9 normal-weighted blur of the coefficients */
  double exposure; /* EV; display only */
} obs_ibl_shadows_params;

/* What the per-pixel passes need from the environment, made once per render. */
typedef struct obs_ibl_setup {
  int m, n;                              /* shadow maps, SH coefficients (sh_order^2) */
  double dir[OBS_IBL_MAX_MAPS][3];       /* unit directions toward the environment */
  float yplus[OBS_SH_MAX_COEFFS][OBS_IBL_MAX_MAPS]; /* the pseudo-inverse Y+ (n x m) */
  double env_sh[OBS_SH_MAX_COEFFS][3];   /* the environment's SH (RGB) */
} obs_ibl_setup;

/* The regularised pseudo-inverse (the article's Equations 4.3.5 to 4.3.7): with Y the m x n
 * matrix of the first n = bands^2 SH at the m unit directions, Y+ = V diag(1 / (s_i^2 + a^2)) V^T
 * Y^T over the eigenpairs (s_i^2, V) of Y^T Y whose s_i^2 exceeds 1e-12 of the largest (the
 * article's epsilon), which is V Sigma+ U^T of its SVD with sigma_i+ = s_i / (s_i^2 + a^2).
 * `yplus` receives n rows of m (row stride OBS_IBL_MAX_MAPS). */
int obs_ibl_pinv(const double (*dir)[3], int m, int bands, double alpha,
                 float yplus[OBS_SH_MAX_COEFFS][OBS_IBL_MAX_MAPS], obs_err *err);
/* Fills `s` for environment `env`: p->shadow_maps folded Hammersley points mapped through the
 * luminance x sin theta distribution (obs_env_dist) to directions, their pseudo-inverse and the
 * environment's SH of p->sh_order bands. */
int obs_ibl_setup_make(const obs_env *env, const obs_ibl_shadows_params *p, obs_ibl_setup *s,
                       obs_err *err);
/* From fitted coefficients w (n of them, of V cos): the outgoing radiance of albedo rho,
 * rho / pi sum_i w_i L_i (clamped at 0), the AO (1 / pi) int V cos = 2 w_0 / sqrt(pi) (clamped to
 * [0, 1]) and the bent normal, the direction of int V cos omega (w_3, w_1, w_2), or n_world when
 * it is zero or there is no band 1. */
void obs_ibl_shade(const obs_ibl_setup *s, const float *w, const float rho[3],
                   const float n_world[3], float rgb[3], float *ao, float bent[3]);

/* The extra channels after the screen drivers' fixed set. */
enum { OBS_IBL_RADIANCE, OBS_IBL_BENT = 3, OBS_IBL_EXTRA = 6 };
extern const char *const obs_ibl_shadows_extra_names[OBS_IBL_EXTRA];

/* The CPU passes over G-buffer `g` of scene `sc` (camera `sc->camera`), shadow maps ray cast in
 * `rt`, lit by `env`: ao and ao_raw planes (w x h) and the extra planes (w x h each). stage_ms
 * (may be NULL): shadow maps, fit, blur, shade. */
#define OBS_IBL_CPU_STAGES 4
int obs_ibl_shadows_cpu_apply(const obs_scene *sc, const struct obs_rt *rt, const obs_env *env,
                              const obs_gbuffer *g, const obs_ibl_shadows_params *p, int threads,
                              float *ao, float *ao_raw, float *extra, double *stage_ms,
                              obs_err *err);

int obs_ibl_shadows_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
