/* path_trace's parameters as its CPU backend reads them (bound from the descriptor's table). */
#ifndef OBS_PATH_TRACE_H
#define OBS_PATH_TRACE_H

#include <stdint.h>

#include "obscura/technique.h"

typedef struct obs_path_trace_params {
  int32_t samples;     /* paths per pixel sample */
  int32_t max_bounces; /* reflections a path may take; 0 = emitters seen directly only */
  int32_t rr_depth;    /* bounces before Russian roulette starts */
  int bsdf_only;       /* light_sampling "bsdf": no next-event estimation (a check of MIS) */
  int random;          /* sampler: 0 sobol, 1 random */
  uint32_t seed;
  double exposure;     /* EV; display only (final.png), not applied to radiance */
} obs_path_trace_params;

/* The run of each backend (cpu.c), named by the descriptor's `run`. */
int obs_path_trace_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
