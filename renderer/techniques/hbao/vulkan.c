/* hbao on Vulkan: the passes of cpu.c as compute shaders (hbao_*.comp.glsl, their push blocks in
 * layout.h, shared with the shaders) over a device G-buffer, a plan for the Vulkan pass driver
 * (plan_vk.h) run by the Vulkan screen-space driver (screen_vk.h). */
#include <math.h>

#include "hbao.h"
#include "layout.h"
#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "techniques.h"

static int hbao_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                    const obs_hbao_params *p, float *ao_host, float *ao_raw_host,
                    obs_vk_plan_times *times, obs_err *err) {
  if (!proj || !g || !g->depth || !g->normal || !ao_host)
    return obs_err_set(err, OBS_EINVAL, "hbao: vulkan apply: no projection, G-buffer or output");
  int W = g->width, H = g->height, lw, lh, half = p->half_res, blur = p->blur_radius > 0;
  obs_hbao_level_size(p, W, H, &lw, &lh);
  float table[OBS_HBAO_NOISE_CELLS * OBS_HBAO_MAX_DIRECTIONS * 4];
  obs_hbao_directions(p, table);
  obs_hbao_down_push dp = {lw, lh};
  float sigma = ((float)p->blur_radius + 1.0f) * 0.5f;
  obs_hbao_ao_push ap = {lw, lh, half ? 2 : 1, W, H, proj->ortho, p->directions, p->steps,
                         proj->half_w, proj->half_h, p->radius, (float)cos((double)p->angle_bias),
                         (float)sin((double)p->angle_bias), p->scale, obs_hbao_inv_radius(p),
                         OBS_HBAO_DEPTH_EPS};
  obs_hbao_up_push up = {W, H, lw, lh, OBS_HBAO_MAX_REL_DZ, OBS_HBAO_UPSAMPLE_K};
  obs_hbao_blur_push bx = {W, H, 0, p->blur_radius, 1.0f / (2.0f * sigma * sigma),
                           p->blur_sharpness, OBS_HBAO_MAX_REL_DZ};
  obs_hbao_blur_push by = bx;
  by.axis = 1;
  enum { TAB = OBS_VK_PLAN_IMAGE0, HD, HN, HAO, RAW, TMP, OUT };
  const int D = OBS_VK_PLAN_DEPTH, N = OBS_VK_PLAN_NORMAL;
  const char *const *st = obs_hbao_pass_names;
  obs_vk_plan plan = {
      .technique = "hbao",
      .images = {[TAB] = {.width = p->directions, .height = OBS_HBAO_NOISE_CELLS, .channels = 4,
                          .data = table},
                 [HD] = {.width = lw, .height = lh, .channels = 1},
                 [HN] = {.width = lw, .height = lh, .channels = 4},
                 [HAO] = {.width = lw, .height = lh, .channels = 1},
                 [RAW] = {.channels = 1},
                 [TMP] = {.channels = 1},
                 [OUT] = {.channels = 1}},
      .passes = {{.stage = st[OBS_HBAO_PASS_DOWNSAMPLE], OBS_VK_SPIRV(hbao_down_comp),
                  OBS_VK_PUSH(dp), .images = {D, N, HD, HN}, .grid = HD, .skip = !half},
                 {.stage = st[OBS_HBAO_PASS_AO], OBS_VK_SPIRV(hbao_ao_comp), OBS_VK_PUSH(ap),
                  .images = {half ? HD : D, half ? HN : N, TAB, half ? HAO : RAW},
                  .grid = half ? HAO : RAW},
                 {.stage = st[OBS_HBAO_PASS_UPSAMPLE], OBS_VK_SPIRV(hbao_up_comp),
                  OBS_VK_PUSH(up), .images = {D, HD, HAO, RAW}, .skip = !half},
                 {.stage = st[OBS_HBAO_PASS_BLUR], OBS_VK_SPIRV(hbao_blur_comp), OBS_VK_PUSH(bx),
                  .images = {D, RAW, TMP}, .skip = !blur},
                 {.stage = st[OBS_HBAO_PASS_BLUR], OBS_VK_SPIRV(hbao_blur_comp), OBS_VK_PUSH(by),
                  .images = {D, TMP, OUT}, .skip = !blur}},
      .downloads = {{blur ? OUT : RAW, ao_host}, {RAW, ao_raw_host}}};
  return obs_vk_plan_run(vk, g, &plan, times, err);
}

int obs_hbao_vk_apply_ex(obs_vk *vk, obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                         const obs_hbao_params *p, float *ao_host, float *ao_raw_host,
                         double *stage_ms, obs_err *err) {
  static const char *const stages[OBS_HBAO_PASS_COUNT + 1] = {"downsample", "ao", "upsample",
                                                              "blur", "readback"};
  obs_vk_plan_times t = {0};
  int rc = hbao_run(vk, g, proj, p, ao_host, ao_raw_host, &t, err);
  obs_vk_plan_stage_ms(&t, stages, OBS_HBAO_PASS_COUNT + 1, stage_ms);
  return rc;
}

int obs_hbao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                      const obs_hbao_params *p, float *ao_host, double *stage_ms, obs_err *err) {
  return obs_hbao_vk_apply_ex(vk, g, proj, p, ao_host, NULL, stage_ms, err);
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  obs_hbao_projection proj = obs_hbao_projection_of(host);
  obs_vk_plan_times t = {0};
  int rc = hbao_run(vk, dev, &proj, params, ao, ao_raw, &t, err);
  if (!rc) obs_vk_plan_record(ctx, &t);
  return rc;
}

int obs_hbao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "hbao", passes, ctx->bound, out, err);
}
