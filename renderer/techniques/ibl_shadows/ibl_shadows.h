/* ibl_shadows (Colbert and Krivanek, ShaderX7 4.3, "Real-Time Dynamic Shadows for Image-Based
 * Lighting"): parameters, the set-up both the run and the tests use (the importance-sampled
 * shadow directions, the regularised pseudo-inverse, the environment's SH) and the CPU entry
 * point. The model is docs/techniques/ibl_shadows.md. */
#ifndef OBS_IBL_SHADOWS_H
#define OBS_IBL_SHADOWS_H

#include <stdatomic.h>
#include <stdint.h>

#include "camera.h"
#include "environment.h"
#include "gbuffer.h"
#include "obscura/error.h"
#include "layout.h"
#include "obscura/technique.h"

struct obs_rt;
typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

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

/* The table both backends' fit reads (its std430 layout in layout.h). */
typedef struct obs_ibl_table {
  float dir[OBS_IBL_MAX_MAPS][4];
  float tax[OBS_IBL_MAX_MAPS][4];
  float bax[OBS_IBL_MAX_MAPS][4];
  float yplus[OBS_SH_MAX_COEFFS * OBS_IBL_MAX_MAPS];
} obs_ibl_table;

/* Everything a render's passes share, made once on the host (ibl_maps.c): the set-up, where the
 * maps look from, the fit's push block and table, the camera and, on the CPU, the shadow maps
 * (size x size per direction, stacked: map m's row r is row m size + r; the distance from the
 * maps' plane to the first surface, OBS_IBL_FAR where none). */
typedef struct obs_ibl_frame {
  obs_ibl_setup s;
  obs_camera_rig rig;
  double centre[3]; /* world centre of the bounding sphere */
  double radius;    /* its radius: the maps' half extent */
  double start;     /* the maps' plane, this far from the centre along each direction */
  double axis[OBS_IBL_MAX_MAPS][2][3];
  obs_ibl_fit_push fit;
  obs_ibl_table table;
  float *maps; /* owned; NULL until obs_ibl_maps_cast */
} obs_ibl_frame;

/* Makes the frame, without maps, for G-buffer `g` of scene `sc` (its camera) and geometry `geo`
 * (any frame: its bounds place the maps). Free with obs_ibl_frame_free. */
int obs_ibl_frame_make(const obs_scene *sc, const obs_geometry *geo, const obs_env *env,
                       const obs_gbuffer *g, const obs_ibl_shadows_params *p, obs_ibl_frame *f,
                       obs_err *err);
/* The CPU's shadow maps into f->maps: orthographic rays from each texel centre of the maps' plane
 * cast in `rt` with `threads` threads (cancellable). */
int obs_ibl_maps_cast(obs_ibl_frame *f, const struct obs_rt *rt, int threads,
                      const atomic_int *cancel, obs_err *err);
void obs_ibl_frame_free(obs_ibl_frame *f);
/* The environment a render lights with: the scene's, or, for a scene without one, a black
 * constant one made in `dark` (radiance 0; the ao and bent normal still come, from directions
 * uniform over the sphere), into *env. Free `dark` with obs_env_free after the run. Returns 0 or
 * the constructor's code. */
int obs_ibl_env_of(const obs_render_ctx *ctx, obs_env *dark, const obs_env **env, obs_err *err);
/* The blur's 1D window, exp(-i^2 / 10) for i = -4..4 (the article's). */
void obs_ibl_blur_weights(float w[9]);

/* Coefficients on the host: OBS_IBL_GROUPS planes of w x h x 4 floats, coefficient k of pixel i
 * at ((k / 4) w h + i) 4 + k % 4, as the device's four images download. */
static inline size_t obs_ibl_coef_at(size_t npix, size_t i, int k) {
  return ((size_t)(k >> 2) * npix + i) * 4 + (size_t)(k & 3);
}

/* The extra channels after the screen drivers' fixed set. */
enum { OBS_IBL_RADIANCE, OBS_IBL_BENT = 3, OBS_IBL_EXTRA = 6 };
extern const char *const obs_ibl_shadows_extra_names[OBS_IBL_EXTRA];

/* The outputs from the coefficients before (raw) and after (res) the blur, on both backends:
 * covered pixels shaded by obs_ibl_shade, the background the environment along the camera ray
 * (ao 1, bent normal 0). */
void obs_ibl_export(const obs_ibl_frame *f, const obs_gbuffer *g, const obs_env *env,
                    const float *raw, const float *res, int threads, float *ao, float *ao_raw,
                    float *extra);

/* The passes on each backend over G-buffer `g` (on Vulkan `dev`, with `g` its host copy),
 * writing the ao and ao_raw planes (w x h) and the extra planes (w x h each). stage_ms (may be
 * NULL): OBS_IBL_CPU_STAGES (set-up, shadow maps, fit, blur, shade) or OBS_IBL_VK_STAGES (set-up,
 * shadow maps, fit, blur, readback, shade). On Vulkan the maps are rasterised on the device by
 * depth-only passes (the geometry of `rt`, or built when `rt` is NULL), or with `host_maps` ray
 * cast on the host as the CPU's and uploaded (a BVH is built when `rt` is NULL): the twin test's
 * way to feed both fits the same maps. */
#define OBS_IBL_CPU_STAGES 5
#define OBS_IBL_VK_STAGES 6
int obs_ibl_shadows_cpu_apply(const obs_scene *sc, const struct obs_rt *rt, const obs_env *env,
                              const obs_gbuffer *g, const obs_ibl_shadows_params *p, int threads,
                              float *ao, float *ao_raw, float *extra, double *stage_ms,
                              obs_err *err);
int obs_ibl_shadows_vk_apply(obs_vk *vk, obs_vk_gbuffer *dev, const obs_scene *sc,
                             const struct obs_rt *rt, const obs_env *env, const obs_gbuffer *g,
                             const obs_ibl_shadows_params *p, int host_maps, int threads,
                             float *ao, float *ao_raw, float *extra, double *stage_ms,
                             obs_err *err);

int obs_ibl_shadows_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ibl_shadows_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
