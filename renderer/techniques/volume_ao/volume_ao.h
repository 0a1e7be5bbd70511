/* volume_ao's parameters as its backends read them (bound from the descriptor's table). */
#ifndef OBS_VOLUME_AO_H
#define OBS_VOLUME_AO_H

#include <stdint.h>

#include "obscura/technique.h"

/* How the environment lights the surface (the report's bent-normal lookup, a diffuse SH
 * convolution at the bent normal, or the Monte-Carlo integral it approximates). */
typedef enum {
  OBS_IBL_NONE,
  OBS_IBL_BENT_NORMAL_LOOKUP,
  OBS_IBL_IRRADIANCE,
  OBS_IBL_REFERENCE
} obs_ibl_kind;

typedef struct obs_volume_ao_tparams {
  uint32_t samples;                 /* AO directions per hit */
  double start, step, max_distance; /* object-space units of the volume hit (longest side 1) */
  int crossing;                     /* obs_volume_crossing */
  int blinn_phong;                  /* shading: 0 lambert, 1 blinn_phong */
  double shininess, specular;
  int ibl;     /* obs_ibl_kind */
  int sampler; /* obs_sampler_kind */
  uint32_t seed;
  double exposure; /* EV; final.png only */
} obs_volume_ao_tparams;

/* The image both backends write, channel by channel (the outputs' EXR channels in this order). */
enum {
  CH_R, CH_G, CH_B, CH_AO, CH_AOSE, CH_BX, CH_BY, CH_BZ, CH_NX, CH_NY, CH_NZ, CH_DEPTH, CH_ALPHA,
  CH_COUNT
};
extern const char *const obs_volume_ao_channels[CH_COUNT];
/* The AO's standard-error channel and its value channel, for the pooled prior both backends apply
 * (driver.h, obs_pixel_prior). */
extern const int obs_volume_ao_se[1], obs_volume_ao_value[1];

/* The warnings both backends give for a render of `sc` with `p`: quad lights ignored, and an AO
 * march that is empty, cut short or a single step. */
struct obs_render_ctx;
struct obs_scene;
void obs_volume_ao_warn(struct obs_render_ctx *ctx, const struct obs_scene *sc,
                        const obs_volume_ao_tparams *p);

/* The run of each backend (cpu.c and vulkan.c), named by the descriptor's `run`. */
int obs_volume_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_volume_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
