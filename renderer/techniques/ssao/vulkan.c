/* ssao on Vulkan: the AO and blur compute passes (ssao*.comp.glsl, their push blocks in layout.h,
 * shared with the shaders) over a device G-buffer, a plan for the Vulkan pass driver (plan_vk.h)
 * run by the Vulkan screen-space driver (screen_vk.h). The CPU twin is cpu.c. */
#include <string.h>

#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ssao.h"
#include "layout.h"
#include "techniques.h"

_Static_assert(sizeof(((obs_ssao_blur_push *)0)->inv_count) ==
                   sizeof(((obs_ssao_tables *)0)->inv_count),
               "the blur's reciprocal table as the host makes it");

static const char *const stages[OBS_SSAO_VK_STAGES] = {"ao", "blur", "readback"};

static int ssao_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_projection *proj,
                    const obs_ssao_params *p, float *ao_host, float *ao_raw_host,
                    obs_vk_plan_times *times, obs_err *err) {
  if (!vk || !g || !g->depth || !g->normal || !p || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ssao: missing device, G-buffer or parameters");
  if (p->samples != 8 && p->samples != 16 && p->samples != 24)
    return obs_err_set(err, OBS_EINVAL, "ssao: samples must be 8, 16 or 24 (got %d)", p->samples);
  if (p->normal_oriented && !proj)
    return obs_err_set(err, OBS_EINVAL,
                       "ssao: normal_oriented needs the camera projection (use "
                       "obs_ssao_vk_apply_ex)");
  obs_ssao_tables t;
  obs_ssao_tables_make(p, &t);
  obs_ssao_ao_push ap = {.width = g->width,
                         .height = g->height,
                         .samples = p->samples,
                         .flags = (p->normal_oriented ? OBS_SSAO_FLAG_NORMAL_ORIENTED : 0) |
                                  (proj && proj->ortho ? OBS_SSAO_FLAG_ORTHO : 0),
                         .half_w = proj ? proj->half_w : 0.0f,
                         .half_h = proj ? proj->half_h : 0.0f,
                         .inv_samples = t.inv_samples};
  obs_ssao_blur_push bp = {.width = g->width, .height = g->height,
                           .threshold = p->blur_depth_threshold};
  memcpy(bp.inv_count, t.inv_count, sizeof bp.inv_count);
  enum { ROT = OBS_VK_PLAN_IMAGE0, OFF, RAW, AO };
  obs_vk_plan plan = {
      .technique = "ssao",
      .images = {[ROT] = {.width = 4, .height = 4, .channels = 4, .data = &t.rotation[0][0]},
                 [OFF] = {.width = p->samples, .height = 1, .channels = 4,
                          .data = &t.offsets[0][0]},
                 [RAW] = {.channels = 1},
                 [AO] = {.channels = 1}},
      .passes = {{.stage = "ao", OBS_VK_SPIRV(ssao_comp), OBS_VK_PUSH(ap),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, ROT, OFF, RAW}},
                 {.stage = "blur", OBS_VK_SPIRV(ssao_blur_comp), OBS_VK_PUSH(bp),
                  .images = {OBS_VK_PLAN_DEPTH, RAW, AO}, .skip = !p->blur}},
      .downloads = {{p->blur ? AO : RAW, ao_host}, {RAW, ao_raw_host}}};
  return obs_vk_plan_run(vk, g, &plan, times, err);
}

int obs_ssao_vk_apply_ex(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_projection *proj,
                         const obs_ssao_params *p, float *ao_host, float *ao_raw_host,
                         double *stage_ms, obs_err *err) {
  obs_vk_plan_times t = {0};
  int rc = ssao_run(vk, g, proj, p, ao_host, ao_raw_host, &t, err);
  obs_vk_plan_stage_ms(&t, stages, OBS_SSAO_VK_STAGES, stage_ms);
  return rc;
}

int obs_ssao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_params *p, float *ao_host,
                      double *stage_ms, obs_err *err) {
  return obs_ssao_vk_apply_ex(vk, g, NULL, p, ao_host, NULL, stage_ms, err);
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  obs_ssao_projection proj = obs_ssao_projection_of(host);
  obs_vk_plan_times t = {0};
  int rc = ssao_run(vk, dev, &proj, params, ao, ao_raw, &t, err);
  if (!rc) obs_vk_plan_record(ctx, &t);
  return rc;
}

int obs_ssao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "ssao", passes, ctx->bound, out, err);
}
