/* The Vulkan screen-space driver: everything a screen-space technique shares on Vulkan (the
 * image, the device, the G-buffer built once, cancellation, progress, stage timings, readback of
 * the G-buffer and the channel export), so that a technique supplies its passes and nothing
 * else. Internal to the Vulkan backend; the CPU twin is renderer/cpu/screen.h. */
#ifndef OBS_SCREEN_VK_H
#define OBS_SCREEN_VK_H

#include "gbuffer.h"
#include "obscura/technique.h"
#include "vk.h"

/* A screen-space technique on Vulkan: its passes over the device G-buffer `dev` (`host` is the
 * host G-buffer of the same camera, not yet downloaded: its projection is the passes'), with the
 * params the run read, downloading the AO after and before its blur into `ao` and `ao_raw` (w x h
 * each), usually as one plan for the Vulkan pass driver (plan_vk.h). Records its stages on ctx
 * (obs_vk_plan_record or obs_driver_stage_add), the download as "readback". */
typedef int (*obs_screen_vk_passes_fn)(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev,
                                       const obs_gbuffer *host, const void *params, float *ao,
                                       float *ao_raw, obs_err *err);

/* Allocates `out` (obs_screen_channel_names), then in a device session (session_vk.h: the device
 * acquired as stage "device", a render the validation layer complained about failed) builds the
 * geometry and rasterises the device G-buffer (timed as build, stage "gbuffer"), runs the passes,
 * downloads the G-buffer (added to "readback") and exports its channels (passes to export timed
 * as render), clears the pixels outside ctx's region. On failure `out` is released. */
int obs_screen_vk_run(obs_render_ctx *ctx, const char *technique, obs_screen_vk_passes_fn passes,
                      const void *params, obs_image *out, obs_err *err);

/* The passes of a technique with extra channels (obs_screen_extra, gbuffer.h): `host` is the
 * device G-buffer already downloaded (albedo included) before the passes, for passes that also
 * need host work on it; `extra` holds the extra channels' planes (w x h each, in the order of the
 * names). */
typedef int (*obs_screen_vk_passes_ex_fn)(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev,
                                          const obs_gbuffer *host, const void *params, float *ao,
                                          float *ao_raw, float *extra, obs_err *err);

/* obs_screen_vk_run for a technique with extra channels; the G-buffer is downloaded before the
 * passes instead of after them. */
int obs_screen_vk_run_ex(obs_render_ctx *ctx, const char *technique,
                         obs_screen_vk_passes_ex_fn passes, const obs_screen_extra *extra,
                         const void *params, obs_image *out, obs_err *err);

#endif
