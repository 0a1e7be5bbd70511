/* ssao_variance (Pesce, ShaderX7 6.7): parameters, the per-frame plan both backends share bit for
 * bit, and the passes' entry points for tests and benchmarks. The definition is in
 * docs/techniques/ssao_variance.md. */
#ifndef OBS_SSAO_VARIANCE_H
#define OBS_SSAO_VARIANCE_H

#include <stdint.h>

#include "gbuffer.h"
#include "layout.h"
#include "obscura/error.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

/* `method`, in the order of the parameter's choices. */
enum { OBS_SVAR_VARIANCE = 0, OBS_SVAR_DEPTH_UNSHARP = 1 };

/* Entries of stage_ms: the kernel's median depth, the moments pass, the AO pass; Vulkan adds the
 * readback (the depth download for the median included). */
#define OBS_SVAR_CPU_STAGES 3
#define OBS_SVAR_VK_STAGES 4

/* Bound from the descriptor's parameter table. */
typedef struct obs_ssao_variance_params {
  int method;            /* OBS_SVAR_VARIANCE or OBS_SVAR_DEPTH_UNSHARP */
  double radius;         /* R, scene units: the box's half-width at the median depth */
  float variance_weight; /* k: AO = 1 - s (1 - p) + k sigma^2 / R^2 */
  float strength;        /* lambda: AO = 1 - s lambda (z - mu) / R (depth_unsharp) */
  int taps;              /* the most taps per side of the box along each axis, 1..16 */
} obs_ssao_variance_params;

/* The camera projection of a G-buffer (obs_vk_gbuffer does not carry it). */
typedef struct obs_svar_projection {
  int ortho;
  float half_w;
} obs_svar_projection;

/* What both backends compute on the host from the depth buffer before the passes, so neither
 * rounds it its own way. */
typedef struct obs_svar_plan {
  double z_median; /* lower median of the sampled covered depths; 0 when nothing is covered */
  int radius_px;   /* R projected at z_median, rounded, clamped to half the image: 0 = all open */
  int stride, taps;
  float zscale; /* 2^-e with z_median in [2^e, 2^(e+1)): depths are scaled by it exactly */
  float rw;     /* see obs_svar_ao_push */
  float inv_count[OBS_SVAR_INV_COUNT]; /* 1/N rounded to float, inv_count[0] = 0 */
} obs_svar_plan;

/* The plan for params `p` on a width x height depth buffer (0 = uncovered) seen through `proj`. */
void obs_svar_plan_make(const obs_ssao_variance_params *p, const float *depth, int width,
                        int height, const obs_svar_projection *proj, obs_svar_plan *out);
/* The lower median of the covered depths on the sampling grid (every g-th pixel of every g-th
 * row, g the smallest step leaving at most 2^18 samples); 0 when none is covered. Exact: a radix
 * selection on the float bits. */
double obs_svar_median_depth(const float *depth, int width, int height);
/* The AO push block of a plan. */
void obs_svar_ao_push_make(const obs_ssao_variance_params *p, const obs_svar_plan *plan, int width,
                           int height, int ortho, obs_svar_ao_push *out);

/* The passes on the CPU: `ao` (width*height floats) receives the AO, 1 where uncovered; stage_ms
 * (may be NULL) OBS_SVAR_CPU_STAGES entries; plan_out (may be NULL) the plan used. */
int obs_svar_cpu_apply(const obs_gbuffer *g, const obs_ssao_variance_params *p, int threads,
                       float *ao, double *stage_ms, obs_svar_plan *plan_out, obs_err *err);
/* The same on the device; stage_ms (may be NULL) receives OBS_SVAR_VK_STAGES entries. */
int obs_svar_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_svar_projection *proj,
                      const obs_ssao_variance_params *p, float *ao_host, double *stage_ms,
                      obs_svar_plan *plan_out, obs_err *err);

/* The run functions the descriptor names (obs_technique_run_fn). */
int obs_ssao_variance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ssao_variance_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
