/* ss_radiosity on Vulkan: the gather and blur compute passes (ss_radiosity*.comp.glsl, their push
 * blocks in layout.h, shared with the shaders) over the device G-buffer, a plan for the Vulkan
 * pass driver (plan_vk.h) run by the Vulkan screen-space driver (screen_vk.h). The direct pass is
 * the CPU's (cpu_direct.c, Embree), uploaded as an image, so both twins gather from the same
 * bits. The CPU twin is cpu.c. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ss_radiosity.h"
#include "techniques.h"

static const char *const stages[OBS_SRAD_VK_STAGES] = {"gather", "blur", "readback"};

static int srad_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj, const float *direct,
                    const float *probes, int nprobes, const obs_ss_radiosity_params *p,
                    float *raw_host, float *out_host, obs_vk_plan_times *times, obs_err *err) {
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
  obs_srad_gather_push gp;
  obs_ss_radiosity_push_make(p, g->width, g->height, proj->ortho, proj->half_w, proj->half_h, &gp);
  gp.nprobes = nprobes;
  obs_srad_blur_push bp = {
      .width = g->width, .height = g->height, .threshold = p->blur_depth_threshold};
  memcpy(bp.inv_count, t.inv_count, sizeof bp.inv_count);
  /* The shader always binds the probe buffer; without probes it holds one unread entry. */
  static const float no_probe[4] = {0, 0, 0, 0};
  obs_vk_data *pdata = NULL;
  int rc = obs_vk_data_create(vk, nprobes ? probes : no_probe,
                              (size_t)(nprobes ? nprobes : 1) * 4 * sizeof(float), &pdata, err);
  if (rc) return rc;
  enum { ROT = OBS_VK_PLAN_IMAGE0, OFF, DIR, RAW, RES };
  obs_vk_plan plan = {
      .technique = "ss_radiosity",
      .images = {[ROT] = {.width = 4, .height = 4, .channels = 4, .data = &t.rotation[0][0]},
                 [OFF] = {.width = p->samples, .height = 1, .channels = 4,
                          .data = &t.offsets[0][0]},
                 [DIR] = {.channels = 4, .data = direct},
                 [RAW] = {.channels = 4},
                 [RES] = {.channels = 4}},
      .passes = {{.stage = "gather", OBS_VK_SPIRV(ss_radiosity_gather_comp), OBS_VK_PUSH(gp),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, OBS_VK_PLAN_ALBEDO, DIR, ROT,
                             OFF, RAW},
                  .data = pdata},
                 {.stage = "blur", OBS_VK_SPIRV(ss_radiosity_blur_comp), OBS_VK_PUSH(bp),
                  .images = {OBS_VK_PLAN_DEPTH, RAW, RES}, .skip = !p->blur}},
      .downloads = {{RAW, raw_host}, {RES, p->blur ? out_host : NULL}}};
  rc = obs_vk_plan_run(vk, g, &plan, times, err);
  obs_vk_data_free(vk, pdata);
  return rc;
}

int obs_ss_radiosity_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                              const float *direct, const float *probes, int nprobes,
                              const obs_ss_radiosity_params *p, float *raw_host, float *out_host,
                              double *stage_ms, obs_err *err) {
  obs_vk_plan_times t = {0};
  int rc = srad_run(vk, g, proj, direct, probes, nprobes, p, raw_host, out_host, &t, err);
  obs_vk_plan_stage_ms(&t, stages, OBS_SRAD_VK_STAGES, stage_ms);
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
  double dms[2];
  obs_vk_plan_times t = {0};
  int rc = obs_ss_radiosity_direct(ctx->scene, p, ctx->threads, ctx->cancel, direct, dms, err);
  if (!rc) {
    obs_driver_stage_add(ctx, "bvh", dms[0]);
    obs_driver_stage_add(ctx, "direct", dms[1]);
    int np = obs_ss_radiosity_probes_make(ctx->scene, probes);
    rc = srad_run(vk, dev, host, direct, probes, np, p, raw, res, &t, err);
  }
  if (!rc) {
    obs_vk_plan_record(ctx, &t);
    obs_ss_radiosity_export(host, direct, raw, p->blur ? res : raw, ao, ao_raw, extra);
  }
  free(buf);
  return rc;
}

static const obs_screen_extra srad_extra = {OBS_SRAD_EXTRA, obs_ss_radiosity_extra_names};

int obs_ss_radiosity_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run_ex(ctx, "ss_radiosity", passes, &srad_extra, ctx->bound, out, err);
}
