/* ss_obscurance on Vulkan: the obscurance pass and the 4x4 average (ss_obscurance*.comp.glsl,
 * their push blocks and bindings in layout.h, shared with the shaders) over a device G-buffer, a
 * plan for the Vulkan pass driver (plan_vk.h) run by the Vulkan screen-space driver
 * (screen_vk.h). The CPU twin is cpu.c. */
#include <stdlib.h>
#include <string.h>

#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "ss_obscurance.h"
#include "techniques.h"

static const char *const stages[OBS_SSO_VK_STAGES] = {"ao", "blur", "readback"};

static int sso_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_sso_projection *proj,
                   const obs_sso_params *p, float *ao_host, float *ao_raw_host,
                   obs_vk_plan_times *times, obs_err *err) {
  int rc = obs_sso_params_valid(p, err);
  if (rc) return rc;
  if (!vk || !g || !g->depth || !g->normal || !proj || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL,
                       "ss_obscurance: missing device, G-buffer or camera projection");
  obs_sso_tables *t = malloc(sizeof *t);
  if (!t) return obs_err_set(err, OBS_ENOMEM, "ss_obscurance: out of memory for the offset table");
  obs_sso_tables_make(p, t);
  obs_sso_push ap;
  obs_sso_push_make(p, g->width, g->height, proj->ortho, proj->half_w, proj->half_h, &ap);
  obs_sso_avg_push bp = {.width = g->width, .height = g->height, .radius = p->radius};
  memcpy(bp.inv_count, t->inv_count, sizeof bp.inv_count);
  /* The table is uploaded as the host holds it, every cell's row OBS_SSO_MAX_SAMPLES + 1 texels
   * wide; the pass reads the first samples + 1 of them. */
  enum { OFF = OBS_VK_PLAN_IMAGE0, RAW, AO };
  obs_vk_plan plan = {
      .technique = "ss_obscurance",
      .images = {[OFF] = {.width = OBS_SSO_MAX_SAMPLES + 1, .height = t->cells, .channels = 4,
                          .data = &t->offsets[0][0][0]},
                 [RAW] = {.channels = 1},
                 [AO] = {.channels = 1}},
      .passes = {{.stage = "ao", OBS_VK_SPIRV(ss_obscurance_comp), OBS_VK_PUSH(ap),
                  .images = {[OBS_SSO_B_DEPTH] = OBS_VK_PLAN_DEPTH,
                             [OBS_SSO_B_NORMAL] = OBS_VK_PLAN_NORMAL,
                             [OBS_SSO_B_OFFSETS] = OFF, [OBS_SSO_B_RAW] = RAW}},
                 {.stage = "blur", OBS_VK_SPIRV(ss_obscurance_avg_comp), OBS_VK_PUSH(bp),
                  .images = {[OBS_SSO_A_DEPTH] = OBS_VK_PLAN_DEPTH, [OBS_SSO_A_RAW] = RAW,
                             [OBS_SSO_A_OUT] = AO},
                  .skip = !p->interleave}},
      .downloads = {{p->interleave ? AO : RAW, ao_host}, {RAW, ao_raw_host}}};
  rc = obs_vk_plan_run(vk, g, &plan, times, err);
  free(t);
  return rc;
}

int obs_sso_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_sso_projection *proj,
                     const obs_sso_params *p, float *ao_host, float *ao_raw_host,
                     double *stage_ms, obs_err *err) {
  obs_vk_plan_times t = {0};
  int rc = sso_run(vk, g, proj, p, ao_host, ao_raw_host, &t, err);
  obs_vk_plan_stage_ms(&t, stages, OBS_SSO_VK_STAGES, stage_ms);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  obs_sso_projection proj = {host->ortho, host->half_w, host->half_h};
  obs_vk_plan_times t = {0};
  int rc = sso_run(vk, dev, &proj, params, ao, ao_raw, &t, err);
  if (!rc) obs_vk_plan_record(ctx, &t);
  return rc;
}

int obs_ss_obscurance_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "ss_obscurance", passes, ctx->bound, out, err);
}
