/* ss_obscurance (Toth, Szirmay-Kalos and Umenhoffer, ShaderX7 3.1): its parameters, the offset
 * tables both backends read bit for bit, and the entry points of its CPU and Vulkan passes. */
#ifndef OBS_SS_OBSCURANCE_H
#define OBS_SS_OBSCURANCE_H

#include <stdint.h>

#include "gbuffer.h"
#include "layout.h"
#include "obscura/error.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

/* Entries of stage_ms: the CPU fills "ao" and "blur" (the 4x4 average); Vulkan adds "readback". */
#define OBS_SSO_CPU_STAGES 2
#define OBS_SSO_VK_STAGES 3

/* `sampling`: how the offsets are drawn. */
enum { OBS_SSO_IMPORTANCE = 0, OBS_SSO_UNIFORM = 1 };

/* Bound from the descriptor's parameter table (obs_params_bind with obs_technique_ss_obscurance). */
typedef struct obs_sso_params {
  int samples;    /* offsets per pixel, 4..OBS_SSO_MAX_SAMPLES */
  float radius;   /* R, scene units */
  int membership; /* obs_falloff_kind: binary, sqrt, exp */
  double tau;     /* exp: mu(d) = 1 - exp(-tau d / R), per R */
  int sampling;   /* OBS_SSO_IMPORTANCE or OBS_SSO_UNIFORM */
  int interleave; /* 16 offset sets over a 4x4 pattern, then the 4x4 average */
  uint32_t seed;  /* of the cells' shifts */
} obs_sso_params;

/* The constant inputs of the passes, computed once on the host in double and rounded once, so no
 * backend recomputes them with its own rounding. Cell c's offsets are offsets[c][0..samples);
 * without interleave every pixel reads cell 0. */
typedef struct obs_sso_tables {
  int cells;                                             /* 16 with interleave, else 1 */
  float offsets[OBS_SSO_CELLS][OBS_SSO_MAX_SAMPLES + 1][4]; /* xyz / R, weight; see layout.h */
  float inv_count[17];                                   /* 1 / n for the average's count n */
} obs_sso_tables;

/* Fills `t` for `p` (samples within range; the membership and sampling pair accepted by the
 * descriptor's check). */
void obs_sso_tables_make(const obs_sso_params *p, obs_sso_tables *t);

/* 0, or OBS_EINVAL naming the parameter when `p` is outside the table's ranges or pairs uniform
 * sampling with another membership than sqrt (callers outside a render bind params themselves). */
int obs_sso_params_valid(const obs_sso_params *p, obs_err *err);

/* The obscurance pass's constants for a width x height G-buffer with that projection. */
void obs_sso_push_make(const obs_sso_params *p, int width, int height, int ortho, float half_w,
                       float half_h, obs_sso_push *pc);

/* The membership's inverse: the distance, in units of R, at which mu reaches xi in [0, 1). */
double obs_sso_membership_inverse(int membership, double tau, double xi);
/* The membership itself at distance rho in units of R (1 from rho = 1 on). */
double obs_sso_membership(int membership, double tau, double rho);

/* The passes on a CPU G-buffer with `threads` threads. `ao` receives the final value (after the
 * 4x4 average with interleave), `ao_raw` (may be NULL) the value before it; width*height floats
 * each, 1 where a pixel is uncovered. stage_ms (may be NULL) receives OBS_SSO_CPU_STAGES entries:
 * the obscurance pass, the average (0 without interleave). */
int obs_sso_cpu_apply(const obs_gbuffer *g, const obs_sso_params *p, int threads, float *ao,
                      float *ao_raw, double *stage_ms, obs_err *err);

/* The camera projection of a G-buffer, which obs_vk_gbuffer does not carry. */
typedef struct obs_sso_projection {
  int ortho;
  float half_w, half_h;
} obs_sso_projection;

/* The same passes on the device; ao_host / ao_raw_host (may be NULL) downloaded. stage_ms (may be
 * NULL) receives OBS_SSO_VK_STAGES entries: obscurance pass, average (0 without interleave),
 * readback. */
int obs_sso_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_sso_projection *proj,
                     const obs_sso_params *p, float *ao_host, float *ao_raw_host,
                     double *stage_ms, obs_err *err);

/* The run functions the descriptor names (obs_technique_run_fn). */
int obs_ss_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ss_obscurance_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
