/* ssao on Vulkan: the AO and blur compute passes (ssao*.comp.glsl) over a device G-buffer,
 * run by the Vulkan screen-space driver (screen_vk.h). The CPU twin is cpu.c. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "gbuffer.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ssao.h"
#include "techniques.h"
#include "vk.h"

/* Push constants, laid out as the shaders' std430 blocks. */
typedef struct ao_push {
  int32_t width, height, samples, flags;
  float half_w, half_h, inv_samples;
} ao_push;

typedef struct blur_push {
  int32_t width, height;
  float threshold;
  float inv_count[17];
} blur_push;

int obs_ssao_vk_apply_ex(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_projection *proj,
                         const obs_ssao_params *p, float *ao_host, float *ao_raw_host,
                         double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SSAO_VK_STAGES; k++) stage_ms[k] = 0.0;
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
  obs_vk_image *rot = NULL, *off = NULL, *raw = NULL, *ao = NULL;
  int rc;
  if ((rc = obs_vk_image_create(vk, 4, 4, 4, &rot, err)) ||
      (rc = obs_vk_image_create(vk, p->samples, 1, 4, &off, err)) ||
      (rc = obs_vk_image_create(vk, g->width, g->height, 1, &raw, err)) ||
      (p->blur && (rc = obs_vk_image_create(vk, g->width, g->height, 1, &ao, err))) ||
      (rc = obs_vk_image_upload(vk, rot, &t.rotation[0][0], err)) ||
      (rc = obs_vk_image_upload(vk, off, &t.offsets[0][0], err)))
    goto done;
  ao_push ap = {.width = g->width,
                .height = g->height,
                .samples = p->samples,
                .flags = (p->normal_oriented ? 1 : 0) | (proj && proj->ortho ? 2 : 0),
                .half_w = proj ? proj->half_w : 0.0f,
                .half_h = proj ? proj->half_h : 0.0f,
                .inv_samples = t.inv_samples};
  blur_push bp = {.width = g->width, .height = g->height, .threshold = p->blur_depth_threshold};
  memcpy(bp.inv_count, t.inv_count, sizeof bp.inv_count);
  uint32_t gx = (uint32_t)(g->width + 7) / 8, gy = (uint32_t)(g->height + 7) / 8;
  obs_vk_pass passes[2] = {
      {.name = "ssao",
       .spirv = obs_spv_ssao_comp,
       .spirv_size = obs_spv_ssao_comp_size,
       .images = {g->depth, g->normal, rot, off, raw},
       .nimages = 5,
       .push = &ap,
       .push_size = sizeof ap,
       .groups_x = gx,
       .groups_y = gy},
      {.name = "ssao_blur",
       .spirv = obs_spv_ssao_blur_comp,
       .spirv_size = obs_spv_ssao_blur_comp_size,
       .images = {g->depth, raw, ao},
       .nimages = 3,
       .push = &bp,
       .push_size = sizeof bp,
       .groups_x = gx,
       .groups_y = gy}};
  double ms[2] = {0, 0};
  if ((rc = obs_vk_run(vk, passes, p->blur ? 2 : 1, ms, err))) goto done;
  double t0 = obs_now_ms();
  if (ao_host && (rc = obs_vk_image_download(vk, p->blur ? ao : raw, ao_host, err))) goto done;
  if (ao_raw_host && (rc = obs_vk_image_download(vk, raw, ao_raw_host, err))) goto done;
  if (stage_ms) {
    stage_ms[0] = ms[0];
    stage_ms[1] = p->blur ? ms[1] : 0.0;
    stage_ms[2] = obs_now_ms() - t0;
  }
done:
  obs_vk_image_free(vk, ao);
  obs_vk_image_free(vk, raw);
  obs_vk_image_free(vk, off);
  obs_vk_image_free(vk, rot);
  return rc;
}

int obs_ssao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_ssao_params *p, float *ao_host,
                      double *stage_ms, obs_err *err) {
  return obs_ssao_vk_apply_ex(vk, g, NULL, p, ao_host, NULL, stage_ms, err);
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  const obs_ssao_params *p = params;
  obs_ssao_projection proj = obs_ssao_projection_of(host);
  double st[OBS_SSAO_VK_STAGES];
  int rc = obs_ssao_vk_apply_ex(vk, dev, &proj, p, ao, ao_raw, st, err);
  if (rc) return rc;
  obs_driver_stage_add(ctx, "ao", st[0]);
  if (p->blur) obs_driver_stage_add(ctx, "blur", st[1]);
  obs_driver_stage_add(ctx, "readback", st[2]);
  return 0;
}

int obs_ssao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "ssao", passes, ctx->bound, out, err);
}
