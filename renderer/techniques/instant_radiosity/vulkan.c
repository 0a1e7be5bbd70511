/* instant_radiosity on Vulkan: the gather and filter compute passes
 * (instant_radiosity*.comp.glsl, their push blocks in layout.h, shared with the shaders) over the
 * device G-buffer, a plan for the Vulkan pass driver (plan_vk.h) run by the Vulkan screen-space
 * driver (screen_vk.h). The photon walk and the emission are the host's (irad_light.c, Embree),
 * uploaded as they are, so both twins gather from the same bits, as are approximate visibility's
 * depth pyramid and distance cube (irad_approx.c). The loader refuses `exact` on this backend.
 * The CPU twin is cpu.c. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "instant_radiosity.h"
#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "techniques.h"

static const char *const stages[OBS_IRAD_VK_STAGES] = {"gather", "filter", "readback"};

static int irad_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                    const obs_irad_light *l, const obs_instant_radiosity_params *p,
                    float *raw_host, float *out_host, obs_vk_plan_times *times, obs_err *err) {
  if (!vk || !g || !g->depth || !g->normal || !proj || !l || !p || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: missing device, G-buffer or light");
  if (p->visibility == OBS_IRAD_VIS_EXACT)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "instant_radiosity: visibility \"exact\" runs on the cpu backend only");
  const int approx = p->visibility == OBS_IRAD_VIS_APPROX;
  if (approx && (!l->pyramid || !l->cube))
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: approximate visibility needs its "
                                        "pyramid and cube (obs_irad_approx_make)");
  obs_irad_gather_push gp;
  obs_irad_gather_push_make(p, l, g->width, g->height, proj->ortho, proj->half_w, proj->half_h,
                            &gp);
  obs_irad_filter_push fp;
  obs_irad_filter_push_make(p, g->width, g->height, proj->ortho, proj->half_w, proj->half_h,
                            &fp);
  /* The shader always binds the VPL buffer; without VPLs it holds one unread record. */
  static const float no_vpl[4 * OBS_IRAD_VPL_VEC4] = {0};
  const size_t rec = 4 * OBS_IRAD_VPL_VEC4 * sizeof(float);
  obs_vk_data *vdata = NULL;
  int rc = obs_vk_data_create(vk, l->vpls.n ? l->vpls.rec : no_vpl,
                              (size_t)(l->vpls.n ? l->vpls.n : 1) * rec, &vdata, err);
  if (rc) return rc;
  /* The gather always binds the pyramid and the cube; without approximate visibility they are
   * one unread texel each. */
  static const float none[1] = {0.0f};
  enum { RAW = OBS_VK_PLAN_IMAGE0, RES, PYR, CUBE };
  obs_vk_plan plan = {
      .technique = "instant_radiosity",
      .images = {[RAW] = {.channels = 4},
                 [RES] = {.channels = 4},
                 [PYR] = {.width = approx ? l->pyr_w : 1, .height = approx ? l->pyr_h : 1,
                          .channels = 1, .data = approx ? l->pyramid : none},
                 [CUBE] = {.width = approx ? 6 * OBS_IRAD_CUBE : 1,
                           .height = approx ? OBS_IRAD_CUBE : 1, .channels = 1,
                           .data = approx ? l->cube : none}},
      .passes = {{.stage = "gather", OBS_VK_SPIRV(instant_radiosity_gather_comp), OBS_VK_PUSH(gp),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, RAW, PYR, CUBE},
                  .data = vdata},
                 {.stage = "filter", OBS_VK_SPIRV(instant_radiosity_filter_comp),
                  OBS_VK_PUSH(fp), .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, RAW, RES},
                  .skip = !p->filter}},
      .downloads = {{RAW, raw_host}, {RES, p->filter ? out_host : NULL}}};
  rc = obs_vk_plan_run(vk, g, &plan, times, err);
  obs_vk_data_free(vk, vdata);
  return rc;
}

int obs_irad_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                      const obs_irad_light *l, const obs_instant_radiosity_params *p,
                      float *raw_host, float *out_host, double *stage_ms, obs_err *err) {
  obs_vk_plan_times t = {0};
  int rc = irad_run(vk, g, proj, l, p, raw_host, out_host, &t, err);
  obs_vk_plan_stage_ms(&t, stages, OBS_IRAD_VK_STAGES, stage_ms);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, float *extra, obs_err *err) {
  const obs_instant_radiosity_params *p = params;
  size_t n = (size_t)host->width * (size_t)host->height;
  float *buf = malloc(2 * 4 * n * sizeof *buf);
  if (!buf)
    return obs_err_set(err, OBS_ENOMEM, "instant_radiosity: %dx%d: out of memory", host->width,
                       host->height);
  float *raw = buf, *res = buf + 4 * n;
  obs_vk_plan_times t = {0};
  obs_irad_light l;
  int rc = obs_irad_light_render(ctx, p, &l, err);
  if (!rc && p->visibility == OBS_IRAD_VIS_APPROX) rc = obs_irad_approx_render(ctx, host, &l, err);
  if (!rc) rc = irad_run(vk, dev, host, &l, p, raw, res, &t, err);
  if (!rc) {
    obs_vk_plan_record(ctx, &t);
    obs_irad_export(host, l.emission, raw, p->filter ? res : raw, ao, ao_raw, extra);
  }
  obs_irad_light_free(&l);
  free(buf);
  return rc;
}

static const obs_screen_extra irad_extra = {OBS_IRAD_EXTRA, obs_irad_extra_names};

int obs_instant_radiosity_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run_ex(ctx, "instant_radiosity", passes, &irad_extra, ctx->bound, out,
                              err);
}
