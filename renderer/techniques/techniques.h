/* Declarations of every technique descriptor and backend implementation named in table.c. */
#ifndef OBS_TECHNIQUES_H
#define OBS_TECHNIQUES_H

#include "driver.h"
#include "obscura/backend.h"
#include "obscura/technique.h"

/* Each backend layer's operations table (renderer/cpu/backend.c, renderer/vulkan/device.c). */
extern const obs_backend_ops obs_backend_cpu_ops;
extern const obs_backend_ops obs_backend_vulkan_ops;
/* What the CPU builds for a technique's needs (renderer/cpu/needs.c; its ops table's `needs`). */
extern const obs_needs_builder obs_cpu_needs_builder;

extern const obs_technique obs_technique_rt_ao;
int obs_rt_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
extern const obs_technique obs_technique_obscurance_map;
int obs_obscurance_map_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_obscurance_map_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

/* The outputs the screen-space drivers write (ssao.c), declared by ssao and hbao alike. */
extern const obs_output obs_screen_outputs[];

extern const obs_technique obs_technique_ssao;
int obs_ssao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_ssao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

extern const obs_technique obs_technique_hbao;
int obs_hbao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_hbao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

extern const obs_technique obs_technique_path_trace;
int obs_path_trace_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
extern const obs_technique obs_technique_obscurance;
int obs_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);

/* One backend's guaranteed range as the registry's JSON (ranges.c). */
json_t *obs_range_json(const obs_range *r);

#endif
