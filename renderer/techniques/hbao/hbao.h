/* hbao: the parameter struct and the definitions both backends must share bit for bit (direction table,
 * pass layout, constants), plus the CPU and Vulkan entry points (see docs/techniques/hbao.md). */
#ifndef OBS_HBAO_H
#define OBS_HBAO_H

#include <stdint.h>

#include "gbuffer.h"
#include "obscura/error.h"
#include "obscura/technique.h"

/* Bound from the descriptor's parameter table (obs_params_bind with obs_technique_hbao), which
 * holds the ranges below. */
typedef struct obs_hbao_params {
  float radius;         /* R in scene (view-space) units; 0 when the JSON value underflows float */
  int directions;       /* N_d, 1..32 */
  int steps;            /* N_s, 1..32 */
  float angle_bias;     /* radians, [0, pi/2) */
  float scale;          /* AO = 1 - scale * sum / N_d, >= 0 */
  int blur_radius;      /* pixels, 0..16; 0 = no blur */
  float blur_sharpness; /* depth weight exp(-sharpness (dz / z)^2), >= 0 */
  int half_res;         /* AO pass on every other texel, bilateral upsampling */
  uint32_t seed;        /* direction table */
} obs_hbao_params;

#define OBS_HBAO_MAX_DIRECTIONS 32
#define OBS_HBAO_MAX_STEPS 32
#define OBS_HBAO_MAX_BLUR_RADIUS 16
/* The direction table is tiled over the image in 4x4 cells. */
#define OBS_HBAO_NOISE_SIZE 4
#define OBS_HBAO_NOISE_CELLS (OBS_HBAO_NOISE_SIZE * OBS_HBAO_NOISE_SIZE)
/* Relative depth differences are clamped here before squaring so that sharpness * q^2 stays
 * finite (0 * inf would be NaN); exp(-1e8 * sharpness) is 0 anyway. */
#define OBS_HBAO_MAX_REL_DZ 1e4f
/* Bilateral upsampling weight 1 / (1 + K q^2), q = relative depth difference: K = 1e4 halves a
 * candidate's weight at 1 % depth difference. A rational weight, not exp, so both backends compute
 * it exactly alike. */
#define OBS_HBAO_UPSAMPLE_K 1e4f

/* Passes, in order; stage_ms arrays are indexed by these (unused passes get 0). BLUR is the
 * horizontal and the vertical pass together. */
enum {
  OBS_HBAO_PASS_DOWNSAMPLE,
  OBS_HBAO_PASS_AO,
  OBS_HBAO_PASS_UPSAMPLE,
  OBS_HBAO_PASS_BLUR,
  OBS_HBAO_PASS_COUNT
};
/* Stage names for obs_render_ctx_stage (static strings). */
extern const char *const obs_hbao_pass_names[OBS_HBAO_PASS_COUNT];
/* Whether pass `i` runs with `p` (the AO pass always; the others when their option is on). */
static inline int obs_hbao_pass_runs(const obs_hbao_params *p, int i) {
  return i == OBS_HBAO_PASS_AO || (i == OBS_HBAO_PASS_BLUR && p->blur_radius > 0) ||
         ((i == OBS_HBAO_PASS_DOWNSAMPLE || i == OBS_HBAO_PASS_UPSAMPLE) && p->half_res);
}

/* The direction table, an image `directions` wide and OBS_HBAO_NOISE_CELLS high with 4 floats per
 * texel: row c = (y % 4) * 4 + x % 4 of the AO texel, column i = direction, texel = (dx, dy,
 * jitter, 0) where (dx, dy) is the unit image-space direction (x right, y down) of angle
 * 2 pi (i + rotation_c) / N_d, and rotation_c, jitter_c in [0,1) come from obs_hash32 of (seed, c).
 * Made here once and uploaded, so the GPU never evaluates cos/sin itself. */
void obs_hbao_directions(const obs_hbao_params *p, float *table);

/* Sizes of the AO pass: full resolution, or ceil(w/2) x ceil(h/2) with half_res (texel (x, y)
 * reads the full-resolution texel (2x, 2y)). */
void obs_hbao_level_size(const obs_hbao_params *p, int width, int height, int *lw, int *lh);
/* 1 / radius in float, computed once on the host and handed to both backends, so their horizon
 * distances |S - P| / R, taken as |S - P| * (1 / R), round alike. */
static inline float obs_hbao_inv_radius(const obs_hbao_params *p) { return 1.0f / p->radius; }
/* Relative uncertainty assumed of each G-buffer depth (float rounding, ~2^-24, and the
 * rasteriser's interpolation, measured below 2^-21 in docs/vulkan.md): the horizon search moves
 * each sample away from the camera by OBS_HBAO_DEPTH_EPS * (z + zs), so a sample rises above the
 * tangent plane only by more than the two depths' rounding can explain. At tiny fields of view a
 * pixel's footprint shrinks to a few ulps of depth and that rounding alone looked like occlusion. */
#define OBS_HBAO_DEPTH_EPS 0x1p-22f

/* CPU twin: AO of G-buffer `g` into `ao` (width*height floats, finite, in [0,1], 1 where
 * uncovered). stage_ms (may be NULL) gets OBS_HBAO_PASS_COUNT entries. */
int obs_hbao_cpu_apply(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                       double *stage_ms, obs_err *err);
/* The same, also returning the AO before the blur (upsampled with half_res) in ao_raw (may be
 * NULL). */
int obs_hbao_cpu_apply_ex(const obs_gbuffer *g, const obs_hbao_params *p, int threads, float *ao,
                          float *ao_raw, double *stage_ms, obs_err *err);
int obs_hbao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

/* The camera projection of a G-buffer (obs_gbuffer's ortho, half_w, half_h). The horizon search
 * reconstructs view-space positions, and obs_vk_gbuffer does not carry the projection, so the
 * device apply takes it separately (an argument beyond the common apply signature). */
typedef struct obs_hbao_projection {
  int ortho;
  float half_w, half_h;
} obs_hbao_projection;

static inline obs_hbao_projection obs_hbao_projection_of(const obs_gbuffer *g) {
  obs_hbao_projection pr = {g->ortho, g->half_w, g->half_h};
  return pr;
}

/* Vulkan: the same passes as compute shaders on a device G-buffer with projection `proj`; ao_host
 * gets width*height floats, ao_raw_host (may be NULL) the AO before the blur. stage_ms (may be
 * NULL) gets OBS_HBAO_PASS_COUNT + 1 entries: the passes' device times, then the readback's wall
 * time. */
struct obs_vk;
struct obs_vk_gbuffer;
int obs_hbao_vk_apply(struct obs_vk *vk, struct obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                      const obs_hbao_params *p, float *ao_host, double *stage_ms, obs_err *err);
int obs_hbao_vk_apply_ex(struct obs_vk *vk, struct obs_vk_gbuffer *g,
                         const obs_hbao_projection *proj, const obs_hbao_params *p, float *ao_host,
                         float *ao_raw_host, double *stage_ms, obs_err *err);
int obs_hbao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
