/* ssao (Kajalin, ShaderX7 6.1): parameters and the tables both backends must share bit for bit. */
#ifndef OBS_SSAO_H
#define OBS_SSAO_H

#include <stdint.h>

#include "obscura/technique.h"

#include "gbuffer.h"
#include "obscura/error.h"
#include "obscura/scene.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

#define OBS_SSAO_MAX_SAMPLES 24
/* Entries of stage_ms: the CPU fills "ao" and "blur"; Vulkan adds "readback". */
#define OBS_SSAO_CPU_STAGES 2
#define OBS_SSAO_VK_STAGES 3
/* The blur's footprint: pixels (x + dx, y + dy) for dx, dy in [-2, 1]. An even 4x4 window is what
 * cancels the 4x4 tiled rotation pattern: away from image edges it sees every rotation once. */
#define OBS_SSAO_BLUR_LO (-2)
#define OBS_SSAO_BLUR_HI 1

/* Bound from the descriptor's parameter table (obs_params_bind with obs_technique_ssao). */
typedef struct obs_ssao_params {
  int samples;                /* 8, 16 or 24 */
  float radius;               /* base offset length in texture coordinates (0.01 in the article) */
  int normal_oriented;        /* hemisphere about the normal instead of the whole sphere */
  int blur;                   /* 4x4 depth-aware blur after the AO pass */
  float blur_depth_threshold; /* relative: |z_n - z_c| <= t z_c mixes */
  uint32_t seed;              /* of the 4x4 rotation texture */
} obs_ssao_params;

/* Constant inputs of the AO pass, computed once on the host and uploaded to the GPU as they are,
 * so no backend recomputes them with its own rounding. */
typedef struct obs_ssao_tables {
  float offsets[OBS_SSAO_MAX_SAMPLES][4]; /* xyz: the article's cube-corner offsets; w = 0 */
  float rotation[16][4];                  /* 4x4 texture, index (y & 3) * 4 + (x & 3); unit xyz */
  float inv_samples;                      /* 1 / samples rounded to float */
  float inv_count[17];                    /* 1 / n for the blur's pixel count n in 1..16 */
} obs_ssao_tables;

void obs_ssao_tables_make(const obs_ssao_params *p, obs_ssao_tables *t);

/* The AO and blur passes on a G-buffer, multi-threaded with obs_parallel_tiles. `ao` receives the
 * final value (after the blur when p->blur), `ao_raw` (may be NULL) the value before the blur; both
 * width*height floats, 1 where the pixel is uncovered. stage_ms (may be NULL) receives
 * OBS_SSAO_CPU_STAGES entries: the AO pass, the blur (0 when off). */
int obs_ssao_cpu_apply(const obs_gbuffer *g, const obs_ssao_params *p, int threads, float *ao,
                       double *stage_ms, obs_err *err);
int obs_ssao_cpu_apply_ex(const obs_gbuffer *g, const obs_ssao_params *p, int threads, float *ao,
                          float *ao_raw, double *stage_ms, obs_err *err);

/* The camera projection of a G-buffer (obs_gbuffer's ortho, half_w, half_h). normal_oriented needs
 * it to turn a texture-coordinate offset into a view-space vector; obs_vk_gbuffer does not carry
 * it, so the device apply takes it separately. */
typedef struct obs_ssao_projection {
  int ortho;
  float half_w, half_h;
} obs_ssao_projection;

static inline obs_ssao_projection obs_ssao_projection_of(const obs_gbuffer *g) {
  obs_ssao_projection pr = {g->ortho, g->half_w, g->half_h};
  return pr;
}

/* The same passes on the device. ao_host / ao_raw_host (may be NULL) as above, downloaded;
 * stage_ms (may be NULL) receives OBS_SSAO_VK_STAGES entries: AO pass, blur (0 when off), readback.
 * `proj` may be NULL unless p->normal_oriented (obs_ssao_vk_apply passes NULL). */
int obs_ssao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_params *p, float *ao_host,
                      double *stage_ms, obs_err *err);
int obs_ssao_vk_apply_ex(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_projection *proj,
                         const obs_ssao_params *p, float *ao_host, float *ao_raw_host,
                         double *stage_ms, obs_err *err);

/* The run of each backend (cpu.c and vulkan.c), named by the descriptor's `run`. */
int obs_ssao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ssao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
