/* ssao_variance on Vulkan: the moments and AO passes (ssao_variance_*.comp.glsl, their push
 * blocks and bindings in layout.h, shared with the shaders) over a device G-buffer, a plan for the
 * Vulkan pass driver (plan_vk.h) run by the Vulkan screen-space driver (screen_vk.h). The
 * per-frame box is the host's (svar_plan.c), made from the downloaded depth, so both backends use
 * the same one. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "obscura/render.h"
#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ssao_variance.h"
#include "techniques.h"

int obs_svar_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_svar_projection *proj,
                      const obs_ssao_variance_params *p, float *ao_host, double *stage_ms,
                      obs_svar_plan *plan_out, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SVAR_VK_STAGES; k++) stage_ms[k] = 0.0;
  if (!vk || !g || !g->depth || !proj || !p || !ao_host || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ssao_variance: missing device, G-buffer or parameters");
  const int w = g->width, h = g->height;
  const size_t n = (size_t)w * (size_t)h;
  obs_svar_plan *plan = malloc(sizeof *plan);
  float *depth = malloc(n * sizeof *depth);
  obs_vk_plan_times t = {0};
  int rc = 0;
  if (!plan || !depth) {
    rc = obs_err_set(err, OBS_ENOMEM, "ssao_variance: %dx%d: out of memory", w, h);
    goto done;
  }
  /* The box depends on the frame's median depth, so the depth comes back before the passes. */
  double t0 = obs_now_ms();
  if ((rc = obs_vk_image_download(vk, g->depth, depth, err))) goto done;
  double t1 = obs_now_ms();
  obs_svar_plan_make(p, depth, w, h, proj, plan);
  double t2 = obs_now_ms();
  if (!plan->taps) {
    for (size_t i = 0; i < n; i++) ao_host[i] = 1.0f;
  } else {
    obs_svar_moments_push mp = {.width = w,
                                .height = h,
                                .stride = plan->stride,
                                .taps = plan->taps,
                                .zscale = plan->zscale};
    obs_svar_ao_push ap;
    obs_svar_ao_push_make(p, plan, w, h, proj->ortho, &ap);
    enum { MOM = OBS_VK_PLAN_IMAGE0, INV, AO };
    obs_vk_plan vp = {
        .technique = "ssao_variance",
        .images = {[MOM] = {.channels = 4},
                   [INV] = {.width = OBS_SVAR_INV_COUNT, .height = 1, .channels = 1,
                            .data = plan->inv_count},
                   [AO] = {.channels = 1}},
        .passes = {{.stage = "moments", OBS_VK_SPIRV(ssao_variance_moments_comp), OBS_VK_PUSH(mp),
                    .images = {[OBS_SVAR_M_DEPTH] = OBS_VK_PLAN_DEPTH, [OBS_SVAR_M_MOMENTS] = MOM}},
                   {.stage = "ao", OBS_VK_SPIRV(ssao_variance_ao_comp), OBS_VK_PUSH(ap),
                    .images = {[OBS_SVAR_A_DEPTH] = OBS_VK_PLAN_DEPTH, [OBS_SVAR_A_MOMENTS] = MOM,
                               [OBS_SVAR_A_INV] = INV, [OBS_SVAR_A_AO] = AO}}},
        .downloads = {{AO, ao_host}}};
    if ((rc = obs_vk_plan_run(vk, g, &vp, &t, err))) goto done;
  }
  if (stage_ms) {
    stage_ms[0] = t2 - t1;
    stage_ms[1] = obs_vk_plan_ms(&t, "moments");
    stage_ms[2] = obs_vk_plan_ms(&t, "ao");
    stage_ms[3] = (t1 - t0) + obs_vk_plan_ms(&t, "readback");
  }
  if (plan_out) *plan_out = *plan;
done:
  free(depth);
  free(plan);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  obs_svar_projection proj = {host->ortho, host->half_w};
  double st[OBS_SVAR_VK_STAGES];
  int rc = obs_svar_vk_apply(vk, dev, &proj, params, ao, st, NULL, err);
  if (rc) return rc;
  memcpy(ao_raw, ao, (size_t)dev->width * (size_t)dev->height * sizeof *ao);
  obs_driver_stage_add(ctx, "blur", st[0] + st[1]);
  obs_driver_stage_add(ctx, "ao", st[2]);
  obs_driver_stage_add(ctx, "readback", st[3]);
  return 0;
}

int obs_ssao_variance_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "ssao_variance", passes, ctx->bound, out, err);
}
