/* rt_ao's parameters as its CPU backend reads them (bound from the descriptor's table). */
#ifndef OBS_RT_AO_H
#define OBS_RT_AO_H

#include <stdint.h>

#include "obscura/technique.h"
#include "obscurance.h"

typedef struct obs_rt_ao_params {
  uint32_t samples;    /* occlusion rays per pixel sample */
  double max_distance; /* d_max; INFINITY when null */
  int falloff;         /* obs_falloff_kind (core/obscurance.h) */
  double tau;          /* exp falloff's rate per scene unit */
  int uniform;         /* weighting: 0 cosine, 1 uniform */
  int sampler;         /* obs_sampler_kind: 0 sobol, 1 halton, 2 random */
  uint32_t seed;
} obs_rt_ao_params;

/* The run of each backend (cpu.c), named by the descriptor's `run`. */
int obs_rt_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
