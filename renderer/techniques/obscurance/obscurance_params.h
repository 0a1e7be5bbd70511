/* obscurance's parameters as its CPU backend reads them (bound from the descriptor's table; named
 * apart from core/obscurance.h, the shared model). */
#ifndef OBS_OBSCURANCE_PARAMS_H
#define OBS_OBSCURANCE_PARAMS_H

#include <stdint.h>

#include "obscura/technique.h"

/* Values of `sequence`: the indices of its choices in the table. */
enum { OBS_OBSCURANCE_HALTON, OBS_OBSCURANCE_SOBOL };

typedef struct obs_obscurance_params {
  uint32_t samples;       /* obscurance rays per pixel sample */
  double d_max;           /* the falloff's distance, scene units */
  int falloff;            /* obs_falloff_kind */
  double tau;             /* exp falloff's rate per scene unit */
  int color_bleeding;     /* W weighs each direction by the reflectivity it sees */
  double ambient[3];      /* I_A override (RGB); all < 0 when null: the sky's or the closed
                             environment's I_A */
  uint32_t light_samples; /* emitter points per pixel sample for the direct term */
  int sequence;           /* OBS_OBSCURANCE_HALTON or _SOBOL */
  uint32_t seed;
  double exposure;        /* EV; display only (the PNGs of radiances) */
} obs_obscurance_params;

/* The run of each backend (cpu.c), named by the descriptor's `run`. */
int obs_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
