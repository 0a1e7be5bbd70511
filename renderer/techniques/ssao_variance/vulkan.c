/* ssao_variance on Vulkan: the moments and AO passes (ssao_variance_*.comp.glsl) over a device
 * G-buffer, run by the Vulkan screen-space driver. The per-frame plan is the host's
 * (svar_plan.c), made from the downloaded depth, so both backends use the same box. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ssao_variance.h"
#include "techniques.h"
#include "vk.h"

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
  obs_vk_image *mom = NULL, *inv = NULL, *ao = NULL;
  int rc = 0;
  if (!plan || !depth) {
    rc = obs_err_set(err, OBS_ENOMEM, "ssao_variance: %dx%d: out of memory", w, h);
    goto done;
  }
  double t0 = obs_now_ms();
  if ((rc = obs_vk_image_download(vk, g->depth, depth, err))) goto done;
  double t1 = obs_now_ms();
  obs_svar_plan_make(p, depth, w, h, proj, plan);
  double t2 = obs_now_ms(), ms[2] = {0, 0};
  if (!plan->taps) {
    for (size_t i = 0; i < n; i++) ao_host[i] = 1.0f;
  } else {
    if ((rc = obs_vk_image_create(vk, w, h, 4, &mom, err)) ||
        (rc = obs_vk_image_create(vk, OBS_SVAR_INV_COUNT, 1, 1, &inv, err)) ||
        (rc = obs_vk_image_create(vk, w, h, 1, &ao, err)) ||
        (rc = obs_vk_image_upload(vk, inv, plan->inv_count, err)))
      goto done;
    obs_svar_moments_push mp = {.width = w,
                                .height = h,
                                .stride = plan->stride,
                                .taps = plan->taps,
                                .zscale = plan->zscale};
    obs_svar_ao_push ap;
    obs_svar_ao_push_make(p, plan, w, h, proj->ortho, &ap);
    uint32_t gx = (uint32_t)(w + 7) / 8, gy = (uint32_t)(h + 7) / 8;
    obs_vk_pass passes[2] = {{.name = "ssao_variance_moments",
                              .spirv = obs_spv_ssao_variance_moments_comp,
                              .spirv_size = obs_spv_ssao_variance_moments_comp_size,
                              .images = {[OBS_SVAR_M_DEPTH] = g->depth, [OBS_SVAR_M_MOMENTS] = mom},
                              .nimages = 2,
                              .push = &mp,
                              .push_size = sizeof mp,
                              .groups_x = gx,
                              .groups_y = gy},
                             {.name = "ssao_variance_ao",
                              .spirv = obs_spv_ssao_variance_ao_comp,
                              .spirv_size = obs_spv_ssao_variance_ao_comp_size,
                              .images = {[OBS_SVAR_A_DEPTH] = g->depth,
                                         [OBS_SVAR_A_MOMENTS] = mom,
                                         [OBS_SVAR_A_INV] = inv,
                                         [OBS_SVAR_A_AO] = ao},
                              .nimages = 4,
                              .push = &ap,
                              .push_size = sizeof ap,
                              .groups_x = gx,
                              .groups_y = gy}};
    if ((rc = obs_vk_run(vk, passes, 2, ms, err))) goto done;
  }
  double t3 = obs_now_ms();
  if (ao && (rc = obs_vk_image_download(vk, ao, ao_host, err))) goto done;
  if (stage_ms) {
    stage_ms[0] = t2 - t1;
    stage_ms[1] = ms[0];
    stage_ms[2] = ms[1];
    stage_ms[3] = (t1 - t0) + (obs_now_ms() - t3);
  }
  if (plan_out) *plan_out = *plan;
done:
  obs_vk_image_free(vk, ao);
  obs_vk_image_free(vk, inv);
  obs_vk_image_free(vk, mom);
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
