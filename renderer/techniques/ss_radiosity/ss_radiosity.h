/* ss_radiosity (Briney, Ceitelis, Cremoux, ShaderX7 6.4, "Fast Fake Global Illumination"):
 * parameters, the tables both backends share bit for bit, the direct pass and the passes' entry
 * points for tests and benchmarks. The model is docs/techniques/ss_radiosity.md. */
#ifndef OBS_SS_RADIOSITY_H
#define OBS_SS_RADIOSITY_H

#include <stdatomic.h>
#include <stdint.h>

#include "gbuffer.h"
#include "layout.h"
#include "obscura/error.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

/* Bound from the descriptor's parameter table. */
typedef struct obs_ss_radiosity_params {
  int samples;       /* 1..OBS_SRAD_MAX_SAMPLES */
  float kernel_size; /* sampling radius in scene units at depth 0 */
  float directivity; /* 0: the hemisphere about the normal; 1: along the normal only */
  float attenuation; /* per scene unit: the radius is kernel_size / (1 + attenuation z) */
  float bias;        /* depth difference (scene units) at which a sample stops counting */
  float strength;    /* scale of the gathered bounce */
  int exclude_self;  /* samples on the pixel's own object gather nothing */
  int blur;          /* 4x4 depth-aware blur of bounce and ao */
  int probe_add;     /* AO probes combined additively (else multiplicatively) */
  float blur_depth_threshold;
  uint32_t light_samples; /* emitter points per pixel of the direct pass */
  uint32_t seed;
  double exposure;
} obs_ss_radiosity_params;

/* Entries of stage_ms in the apply functions: gather, blur (0 when off); Vulkan adds readback. */
#define OBS_SRAD_CPU_STAGES 2
#define OBS_SRAD_VK_STAGES 3

/* Constant inputs of the gather, made once on the host and uploaded as they are. */
typedef struct obs_ss_radiosity_tables {
  float offsets[OBS_SRAD_MAX_SAMPLES][4]; /* points in the unit ball (xyz), w = 0 */
  float rotation[16][4];                  /* 4x4 unit reflection normals, (y & 3) * 4 + (x & 3) */
  float inv_count[17];                    /* 1 / n for the blur's count n in 1..16 */
} obs_ss_radiosity_tables;

void obs_ss_radiosity_tables_make(const obs_ss_radiosity_params *p, obs_ss_radiosity_tables *t);

/* The scene's AO probes for the gather: 4 floats each, the centre in the camera's view space
 * (G-buffer frame) and the visible area pi r^2; at most OBS_SRAD_MAX_PROBES (the loader's check
 * refuses more). Returns how many were written. */
int obs_ss_radiosity_probes_make(const obs_scene *sc, float *out);
/* The gather pass's push block for a G-buffer of w x h with that projection. */
void obs_ss_radiosity_push_make(const obs_ss_radiosity_params *p, int w, int h, int ortho,
                                float half_w, float half_h, obs_srad_gather_push *out);

/* The direct pass (CPU, Embree): per pixel, 4 floats: the radiance leaving the surface the camera
 * ray through the pixel centre hits toward the camera (emission plus light_samples emitter points
 * with shadow rays, as path_trace's next-event estimation), and in w the index + 1 of the object
 * hit (0: none). Quad lights the ray crosses before the surface add their emission. Both backends
 * gather from this buffer. `ms` (may be NULL) receives the BVH build and the pass. */
int obs_ss_radiosity_direct(const obs_scene *sc, const obs_ss_radiosity_params *p, int threads,
                            const atomic_int *cancel, float *direct, double ms[2], obs_err *err);

/* The gather and blur passes on the CPU: `direct` as above, `probes` (nprobes of them, may be
 * NULL when 0) from obs_ss_radiosity_probes_make; `raw` and `out` (w x h x 4: bounce
 * RGB, ao) before and after the blur (out may equal NULL when p->blur is 0: raw is the result).
 * stage_ms (may be NULL): OBS_SRAD_CPU_STAGES entries. */
int obs_ss_radiosity_cpu_apply(const obs_gbuffer *g, const float *direct, const float *probes,
                               int nprobes, const obs_ss_radiosity_params *p, int threads,
                               float *raw, float *out, double *stage_ms, obs_err *err);
/* The same on the device, over a device G-buffer with the host G-buffer's projection `proj`
 * (ortho, half_w, half_h taken from it). raw_host / out_host as above, downloaded. */
int obs_ss_radiosity_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                              const float *direct, const float *probes, int nprobes,
                              const obs_ss_radiosity_params *p, float *raw_host, float *out_host,
                              double *stage_ms, obs_err *err);

/* The technique's extra channels (after the screen drivers' fixed set), in this order. */
enum { OBS_SRAD_FINAL, OBS_SRAD_BOUNCE = 3, OBS_SRAD_DIRECT = 6, OBS_SRAD_EXTRA = 9 };
extern const char *const obs_ss_radiosity_extra_names[OBS_SRAD_EXTRA];
/* Writes the outputs from the passes' results: ao and ao_raw planes, and the extra planes
 * (final = direct + bounce, bounce, direct), for a w x h image; uncovered pixels (depth 0) get
 * ao 1 and zero radiance. `res` is the blurred result (or raw without blur). */
void obs_ss_radiosity_export(const obs_gbuffer *g, const float *direct, const float *raw,
                             const float *res, float *ao, float *ao_raw, float *extra);

/* The run functions the descriptor names (obs_technique_run_fn). */
int obs_ss_radiosity_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ss_radiosity_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
