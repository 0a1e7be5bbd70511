/* proximity_ao's parameters as its backends read them (bound from the descriptor's table), and
 * the layout and reconstruction settings they imply. */
#ifndef OBS_PROXIMITY_AO_H
#define OBS_PROXIMITY_AO_H

#include <stdint.h>

#include "obscura/technique.h"

#include "proximity.h"

typedef struct obs_proximity_ao_params {
  double range;                /* R as a fraction of the propagation radius r_p */
  int32_t steps;               /* N */
  int32_t volume_res;
  int32_t min_res;
  double propagation_fraction;
  int propagation_box;         /* OBS_PROX_BOX_MAXIMAL, _LARGEST, _UNION */
  int reconstruction;          /* OBS_PROX_THESIS_CODE, OBS_PROX_CORRECTED */
  int combine;                 /* OBS_PROX_ADDITIVE, OBS_PROX_MULTIPLICATIVE */
  int self_occlusion;
  float stop_value, scale_before, scale_after;
  uint32_t seed;
} obs_proximity_ao_params;

/* The outputs' channels in image order, as both backends write them: ao, fields, depth.Z,
 * normal.X/Y/Z, alpha. */
#define OBS_PROX_CHANNELS 7
extern const char *const obs_proximity_ao_channels[OBS_PROX_CHANNELS];

/* The grid layout the parameters ask for. */
void obs_proximity_ao_layout(const obs_proximity_ao_params *p, obs_prox_layout *out);
/* The walk the parameters ask for (obs_prox_recon_init with their steps, reconstruction,
 * constants and seed). */
void obs_proximity_ao_recon(const obs_proximity_ao_params *p, obs_prox_recon *out);
/* The walk's reach R = range x r_p, and its step R / N, in world units, for fields of
 * propagation radius `rp`. */
double obs_proximity_ao_reach(const obs_proximity_ao_params *p, double rp);
double obs_proximity_ao_step(const obs_proximity_ao_params *p, double rp);

/* What proximity_ao prepares before its run (technique.c's prepare hook, ctx->prepared): every
 * surface object's proximity field, voxelised and flooded (on the device for Vulkan). */
struct obs_prepared {
  obs_prox_fields fields;
};

/* The run of each backend (cpu.c and vulkan.c), named by the descriptor's `run`. */
int obs_proximity_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_proximity_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
