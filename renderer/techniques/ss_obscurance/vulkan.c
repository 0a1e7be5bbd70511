/* ss_obscurance on Vulkan: the obscurance pass and the 4x4 average (ss_obscurance*.comp.glsl)
 * over a device G-buffer, run by the Vulkan screen-space driver. The CPU twin is cpu.c. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ss_obscurance.h"
#include "techniques.h"
#include "vk.h"

int obs_sso_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_sso_projection *proj,
                     const obs_sso_params *p, float *ao_host, float *ao_raw_host,
                     double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SSO_VK_STAGES; k++) stage_ms[k] = 0.0;
  int rc = obs_sso_params_valid(p, err);
  if (rc) return rc;
  if (!vk || !g || !g->depth || !g->normal || !proj || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL,
                       "ss_obscurance: missing device, G-buffer or camera projection");
  obs_sso_tables *t = malloc(sizeof *t);
  float *tex = NULL;
  const int tw = p->samples + 1;
  if (t) tex = malloc((size_t)OBS_SSO_CELLS * (size_t)tw * 4 * sizeof *tex);
  if (!t || !tex) {
    free(t);
    return obs_err_set(err, OBS_ENOMEM, "ss_obscurance: out of memory for the offset table");
  }
  obs_sso_tables_make(p, t);
  for (int c = 0; c < t->cells; c++)
    memcpy(tex + (size_t)c * (size_t)tw * 4, &t->offsets[c][0][0], (size_t)tw * 4 * sizeof *tex);
  obs_vk_image *off = NULL, *raw = NULL, *ao = NULL;
  if ((rc = obs_vk_image_create(vk, tw, t->cells, 4, &off, err)) ||
      (rc = obs_vk_image_create(vk, g->width, g->height, 1, &raw, err)) ||
      (p->interleave && (rc = obs_vk_image_create(vk, g->width, g->height, 1, &ao, err))) ||
      (rc = obs_vk_image_upload(vk, off, tex, err)))
    goto done;
  obs_sso_push ap;
  obs_sso_push_make(p, g->width, g->height, proj->ortho, proj->half_w, proj->half_h, &ap);
  obs_sso_avg_push bp = {.width = g->width, .height = g->height, .radius = p->radius};
  memcpy(bp.inv_count, t->inv_count, sizeof bp.inv_count);
  uint32_t gx = (uint32_t)(g->width + 7) / 8, gy = (uint32_t)(g->height + 7) / 8;
  obs_vk_pass passes[2] = {
      {.name = "ss_obscurance",
       .spirv = obs_spv_ss_obscurance_comp,
       .spirv_size = obs_spv_ss_obscurance_comp_size,
       .images = {[OBS_SSO_B_DEPTH] = g->depth, [OBS_SSO_B_NORMAL] = g->normal,
                  [OBS_SSO_B_OFFSETS] = off, [OBS_SSO_B_RAW] = raw},
       .nimages = 4,
       .push = &ap,
       .push_size = sizeof ap,
       .groups_x = gx,
       .groups_y = gy},
      {.name = "ss_obscurance_avg",
       .spirv = obs_spv_ss_obscurance_avg_comp,
       .spirv_size = obs_spv_ss_obscurance_avg_comp_size,
       .images = {[OBS_SSO_A_DEPTH] = g->depth, [OBS_SSO_A_RAW] = raw, [OBS_SSO_A_OUT] = ao},
       .nimages = 3,
       .push = &bp,
       .push_size = sizeof bp,
       .groups_x = gx,
       .groups_y = gy}};
  double ms[2] = {0, 0};
  if ((rc = obs_vk_run(vk, passes, p->interleave ? 2 : 1, ms, err))) goto done;
  double t0 = obs_now_ms();
  if (ao_host && (rc = obs_vk_image_download(vk, p->interleave ? ao : raw, ao_host, err)))
    goto done;
  if (ao_raw_host && (rc = obs_vk_image_download(vk, raw, ao_raw_host, err))) goto done;
  if (stage_ms) {
    stage_ms[0] = ms[0];
    stage_ms[1] = p->interleave ? ms[1] : 0.0;
    stage_ms[2] = obs_now_ms() - t0;
  }
done:
  obs_vk_image_free(vk, ao);
  obs_vk_image_free(vk, raw);
  obs_vk_image_free(vk, off);
  free(tex);
  free(t);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  const obs_sso_params *p = params;
  obs_sso_projection proj = {host->ortho, host->half_w, host->half_h};
  double st[OBS_SSO_VK_STAGES];
  int rc = obs_sso_vk_apply(vk, dev, &proj, p, ao, ao_raw, st, err);
  if (rc) return rc;
  obs_driver_stage_add(ctx, "ao", st[0]);
  if (p->interleave) obs_driver_stage_add(ctx, "blur", st[1]);
  obs_driver_stage_add(ctx, "readback", st[2]);
  return 0;
}

int obs_ss_obscurance_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "ss_obscurance", passes, ctx->bound, out, err);
}
