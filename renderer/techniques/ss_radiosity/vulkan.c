/* ss_radiosity on Vulkan: the gather and blur compute passes (ss_radiosity*.comp.glsl) over the
 * device G-buffer, run by the Vulkan screen-space driver. The direct pass is the CPU's
 * (cpu_direct.c, Embree), uploaded as an image, so both twins gather from the same bits. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ss_radiosity.h"
#include "techniques.h"
#include "vk.h"

int obs_ss_radiosity_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                              const float *direct, const float *probes, int nprobes,
                              const obs_ss_radiosity_params *p, float *raw_host, float *out_host,
                              double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SRAD_VK_STAGES; k++) stage_ms[k] = 0.0;
  if (!vk || !g || !g->depth || !g->normal || !g->albedo || !proj || !direct || !p ||
      g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: missing device, G-buffer or parameters");
  if (nprobes < 0 || nprobes > OBS_SRAD_MAX_PROBES || (nprobes && !probes))
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: %d probes (at most %d)", nprobes,
                       OBS_SRAD_MAX_PROBES);
  if (p->samples < 1 || p->samples > OBS_SRAD_MAX_SAMPLES)
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: samples must be 1..%d (got %d)",
                       OBS_SRAD_MAX_SAMPLES, p->samples);
  obs_ss_radiosity_tables t;
  obs_ss_radiosity_tables_make(p, &t);
  obs_vk_image *rot = NULL, *off = NULL, *dir = NULL, *raw = NULL, *res = NULL;
  obs_vk_data *pdata = NULL;
  /* The shader always binds the probe buffer; without probes it holds one unread entry. */
  static const float no_probe[4] = {0, 0, 0, 0};
  int rc;
  if ((rc = obs_vk_image_create(vk, 4, 4, 4, &rot, err)) ||
      (rc = obs_vk_image_create(vk, p->samples, 1, 4, &off, err)) ||
      (rc = obs_vk_image_create(vk, g->width, g->height, 4, &dir, err)) ||
      (rc = obs_vk_image_create(vk, g->width, g->height, 4, &raw, err)) ||
      (p->blur && (rc = obs_vk_image_create(vk, g->width, g->height, 4, &res, err))) ||
      (rc = obs_vk_image_upload(vk, rot, &t.rotation[0][0], err)) ||
      (rc = obs_vk_image_upload(vk, off, &t.offsets[0][0], err)) ||
      (rc = obs_vk_image_upload(vk, dir, direct, err)) ||
      (rc = obs_vk_data_create(vk, nprobes ? probes : no_probe,
                               (size_t)(nprobes ? nprobes : 1) * 4 * sizeof(float), &pdata, err)))
    goto done;
  obs_srad_gather_push gp;
  obs_ss_radiosity_push_make(p, g->width, g->height, proj->ortho, proj->half_w, proj->half_h, &gp);
  gp.nprobes = nprobes;
  obs_srad_blur_push bp = {
      .width = g->width, .height = g->height, .threshold = p->blur_depth_threshold};
  memcpy(bp.inv_count, t.inv_count, sizeof bp.inv_count);
  uint32_t gx = (uint32_t)(g->width + 7) / 8, gy = (uint32_t)(g->height + 7) / 8;
  obs_vk_pass passes[2] = {{.name = "ss_radiosity_gather",
                            .spirv = obs_spv_ss_radiosity_gather_comp,
                            .spirv_size = obs_spv_ss_radiosity_gather_comp_size,
                            .images = {g->depth, g->normal, g->albedo, dir, rot, off, raw},
                            .nimages = 7,
                            .push = &gp,
                            .push_size = sizeof gp,
                            .groups_x = gx,
                            .groups_y = gy,
                            .data = pdata},
                           {.name = "ss_radiosity_blur",
                            .spirv = obs_spv_ss_radiosity_blur_comp,
                            .spirv_size = obs_spv_ss_radiosity_blur_comp_size,
                            .images = {g->depth, raw, res},
                            .nimages = 3,
                            .push = &bp,
                            .push_size = sizeof bp,
                            .groups_x = gx,
                            .groups_y = gy}};
  double ms[2] = {0, 0};
  if ((rc = obs_vk_run(vk, passes, p->blur ? 2 : 1, ms, err))) goto done;
  double t0 = obs_now_ms();
  if (raw_host && (rc = obs_vk_image_download(vk, raw, raw_host, err))) goto done;
  if (p->blur && out_host && (rc = obs_vk_image_download(vk, res, out_host, err))) goto done;
  if (stage_ms) {
    stage_ms[0] = ms[0];
    stage_ms[1] = p->blur ? ms[1] : 0.0;
    stage_ms[2] = obs_now_ms() - t0;
  }
done:
  obs_vk_data_free(vk, pdata);
  obs_vk_image_free(vk, res);
  obs_vk_image_free(vk, raw);
  obs_vk_image_free(vk, dir);
  obs_vk_image_free(vk, off);
  obs_vk_image_free(vk, rot);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, float *extra, obs_err *err) {
  const obs_ss_radiosity_params *p = params;
  size_t n = (size_t)host->width * (size_t)host->height;
  float *buf = malloc((3 * 4 * n + 4 * OBS_SRAD_MAX_PROBES) * sizeof *buf);
  if (!buf)
    return obs_err_set(err, OBS_ENOMEM, "ss_radiosity: %dx%d: out of memory", host->width,
                       host->height);
  float *direct = buf, *raw = buf + 4 * n, *res = buf + 8 * n, *probes = buf + 12 * n;
  double dms[2], st[OBS_SRAD_VK_STAGES];
  int rc = obs_ss_radiosity_direct(ctx->scene, p, ctx->threads, ctx->cancel, direct, dms, err);
  if (!rc) {
    obs_driver_stage_add(ctx, "bvh", dms[0]);
    obs_driver_stage_add(ctx, "direct", dms[1]);
    int np = obs_ss_radiosity_probes_make(ctx->scene, probes);
    rc = obs_ss_radiosity_vk_apply(vk, dev, host, direct, probes, np, p, raw, res, st, err);
  }
  if (!rc) {
    obs_driver_stage_add(ctx, "gather", st[0]);
    if (p->blur) obs_driver_stage_add(ctx, "blur", st[1]);
    obs_driver_stage_add(ctx, "readback", st[2]);
    obs_ss_radiosity_export(host, direct, raw, p->blur ? res : raw, ao, ao_raw, extra);
  }
  free(buf);
  return rc;
}

static const obs_screen_vk_extra srad_extra = {OBS_SRAD_EXTRA, obs_ss_radiosity_extra_names};

int obs_ss_radiosity_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run_ex(ctx, "ss_radiosity", passes, &srad_extra, ctx->bound, out, err);
}
