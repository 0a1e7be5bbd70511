/* analytic_ao on Vulkan: a compute pass over the device G-buffer (analytic_ao.comp.glsl, its
 * push blocks in layout.h) reading the occluders from a storage buffer, each 8x8 work group
 * culling them against its receivers' box: the CPU twin's per-tile loop (cpu.c); at half
 * resolution the same pass over the half grid, the upsampling (analytic_ao_up.comp.glsl) and the
 * pass again over the pixels it marked, then under upsample push_pull the push-pull over those
 * samples (analytic_ao_pp.comp.glsl). Under method raster, the article's own method instead:
 * each occluder's bounding cube rasterised over the G-buffer with multiplicative blending
 * (raster_vk.c), the same product in the same order per pixel (docs/techniques/analytic_ao.md,
 * "Backends"). */
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "driver.h"
#include "layout.h"
#include "obscura/render.h"
#include "plan_vk.h"
#include "screen_vk.h"
#include "shaders.h"
#include "techniques.h"

_Static_assert(sizeof(obs_aao_occluder) == OBS_AAO_VEC4S * 4 * sizeof(float),
               "the shader reads an occluder as OBS_AAO_VEC4S vec4s");

/* Iterations of counted loops one occluder may cost an invocation where the compiler keeps them
 * (a box: six faces of clipping, normalising and summing up to 8 vertices), with the group's
 * reduction; the occluders of one dispatch stay under the device's loop limit with it. */
#define AAO_LOOPS_PER_OCCLUDER 160
#define AAO_LOOPS_FIXED 64

/* Runs pass `which` of `plan` alone (the others skipped) over the occluders, `chunk` per dispatch
 * (all at once for a pass that reads none), stopping between dispatches when the render is
 * cancelled. */
static int run_pass(obs_render_ctx *ctx, obs_vk_plan *plan, obs_vk_plan_state *st, int which,
                    obs_aao_push *pc, size_t nocc, size_t chunk, obs_err *err) {
  for (int i = 0; i < 4; i++) plan->passes[i].skip = i != which;
  size_t first = 0;
  int rc = 0;
  do {
    size_t n = nocc - first < chunk ? nocc - first : chunk;
    pc->first = (int)first;
    pc->count = (int)n;
    pc->accumulate = first > 0;
    rc = obs_vk_plan_dispatch(st, err);
    first += n;
    if (!rc && ctx && ctx->cancel && atomic_load(ctx->cancel)) rc = OBS_ECANCELED;
  } while (!rc && which != 1 && first < nocc);
  return rc;
}

/* The push-pull (pass 3 of `plan`, analytic_ao_pp.comp.glsl): one dispatch per level down the
 * pyramid, then one per level back up to the frame, as cpu.c's aao_push_pull loops. */
static int run_push_pull(obs_render_ctx *ctx, obs_vk_plan *plan, obs_vk_plan_state *st,
                         obs_aao_pp_push *pp, const obs_aao_pyramid *py, obs_err *err) {
  for (int i = 0; i < 4; i++) plan->passes[i].skip = i != 3;
  int rc = 0;
  for (int l = 1; !rc && l <= 2 * py->n; l++) {
    int push = l <= py->n, d = push ? l : 2 * py->n - l; /* the level written; 0: the frame */
    pp->mode = push ? (l == 1 ? OBS_AAO_PP_PUSH0 : OBS_AAO_PP_PUSH)
                    : (d == 0 ? OBS_AAO_PP_PULL0 : OBS_AAO_PP_PULL);
    int s = push ? l - 1 : d + 1;
    pp->sx = py->x[s], pp->sw = py->w[s], pp->sh = py->h[s];
    pp->dx = py->x[d], pp->dw = py->w[d], pp->dh = py->h[d];
    rc = obs_vk_plan_dispatch(st, err);
    if (!rc && ctx && ctx->cancel && atomic_load(ctx->cancel)) rc = OBS_ECANCELED;
  }
  return rc;
}

static int aao_run(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *host,
                   const obs_aao_occluder *occ, size_t nocc, const obs_analytic_ao_params *p,
                   float *ao_host, obs_vk_plan_times *times, obs_err *err) {
  if (!vk || !g || !host || !p || !ao_host || g->width < 1 || g->height < 1 || (nocc && !occ))
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: missing device, G-buffer or output");
  if (nocc > (size_t)INT32_MAX / OBS_AAO_VEC4S)
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: %zu occluders (at most %d)", nocc,
                       INT32_MAX / OBS_AAO_VEC4S);
  /* The shader always binds the buffer; without occluders it holds one unread entry. */
  static const obs_aao_occluder none;
  obs_vk_data *data = NULL;
  int rc = obs_vk_data_create(vk, nocc ? occ : &none, (nocc ? nocc : 1) * sizeof *occ, &data, err);
  if (rc) return rc;
  uint32_t limit = obs_vk_loop_limit(vk);
  size_t chunk = nocc ? nocc : 1;
  if (limit && limit <= AAO_LOOPS_FIXED + AAO_LOOPS_PER_OCCLUDER)
    chunk = 1;
  else if (limit && (limit - AAO_LOOPS_FIXED) / AAO_LOOPS_PER_OCCLUDER < chunk)
    chunk = (limit - AAO_LOOPS_FIXED) / AAO_LOOPS_PER_OCCLUDER;
  const int half = p->resolution == OBS_AAO_HALF;
  obs_aao_push pc = {.width = g->width, .height = g->height, .ortho = host->ortho,
                     .mode = half ? OBS_AAO_MODE_LOW : OBS_AAO_MODE_FULL,
                     .half_w = host->half_w, .half_h = host->half_h};
  obs_aao_push ep = pc;
  ep.mode = OBS_AAO_MODE_EDGES;
  const int lw = (g->width + 1) / 2, lh = (g->height + 1) / 2;
  obs_aao_up_push up = {.width = g->width, .height = g->height, .lw = lw, .lh = lh,
                        .depth_limit = OBS_AAO_UP_DEPTH};
  const int pushpull = half && p->upsample == OBS_AAO_PUSH_PULL;
  obs_aao_pyramid py;
  obs_aao_pyramid_make(g->width, g->height, &py);
  obs_aao_pp_push pp = {.width = g->width, .height = g->height};
  enum { AO = OBS_VK_PLAN_IMAGE0, LOW, MASK, NOMASK, ATLAS };
  obs_vk_plan plan = {
      .technique = "analytic_ao",
      .images = {[AO] = {.channels = 1},
                 [LOW] = {.width = lw, .height = lh, .channels = 1},
                 [MASK] = {.channels = 1},
                 [NOMASK] = {.width = 1, .height = 1, .channels = 1},
                 [ATLAS] = {.width = py.aw, .height = py.ah, .channels = 4}},
      .passes = {{.stage = "ao", OBS_VK_SPIRV(analytic_ao_comp), OBS_VK_PUSH(pc),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, half ? LOW : AO,
                             half ? MASK : NOMASK},
                  .grid = half ? LOW : 0, .data = data},
                 {.stage = "upsample", OBS_VK_SPIRV(analytic_ao_up_comp), OBS_VK_PUSH(up),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, LOW, AO, MASK},
                  .skip = !half},
                 {.stage = "ao_edges", OBS_VK_SPIRV(analytic_ao_comp), OBS_VK_PUSH(ep),
                  .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, AO, MASK}, .data = data,
                  .skip = !half},
                 {.stage = "upsample", OBS_VK_SPIRV(analytic_ao_pp_comp), OBS_VK_PUSH(pp),
                  .images = {OBS_VK_PLAN_DEPTH, MASK, LOW, AO, ATLAS}, .skip = !pushpull}},
      .downloads = {{AO, ao_host}}};
  obs_vk_plan_state st;
  rc = obs_vk_plan_open(vk, g, &plan, &st, err);
  if (!rc) {
    rc = run_pass(ctx, &plan, &st, 0, &pc, nocc, chunk, err);
    if (!rc && half) rc = run_pass(ctx, &plan, &st, 1, &pc, nocc, chunk, err);
    if (!rc && half) rc = run_pass(ctx, &plan, &st, 2, &ep, nocc, chunk, err);
    if (!rc && pushpull) rc = run_push_pull(ctx, &plan, &st, &pp, &py, err);
    rc = obs_vk_plan_close(&st, rc, times, err);
  }
  obs_vk_data_free(vk, data);
  return rc;
}

int obs_analytic_ao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *host,
                             const obs_aao_occluder *occ, size_t nocc,
                             const obs_analytic_ao_params *p, float *ao_host, double *stage_ms,
                             obs_err *err) {
  if (p && p->method == OBS_AAO_RASTER) {
    if (stage_ms)
      for (int i = 0; i < OBS_AAO_STAGES; i++) stage_ms[i] = 0;
    if (p->resolution != OBS_AAO_FULL)
      return obs_err_set(err, OBS_EINVAL, "analytic_ao: method raster runs at full resolution");
    return obs_analytic_ao_vk_raster(vk, g, host, occ, nocc, ao_host, stage_ms, err);
  }
  obs_vk_plan_times t = {0};
  int rc = aao_run(NULL, vk, g, host, occ, nocc, p, ao_host, &t, err);
  obs_vk_plan_stage_ms(&t, obs_aao_stage_names, OBS_AAO_STAGES, stage_ms);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  const obs_analytic_ao_params *p = params;
  obs_aao_occluder *occ;
  size_t nocc;
  int rc = obs_aao_render_occluders(ctx, host->width, host->height, p, &occ, &nocc, err);
  if (rc) return rc;
  if (p->method == OBS_AAO_RASTER) {
    double ms = 0;
    rc = obs_analytic_ao_vk_raster(vk, dev, host, occ, nocc, ao, &ms, err);
    free(occ);
    if (rc) return rc;
    obs_driver_stage_add(ctx, obs_aao_stage_names[0], ms);
  } else {
    obs_vk_plan_times t = {0};
    rc = aao_run(ctx, vk, dev, host, occ, nocc, p, ao, &t, err);
    free(occ);
    if (rc) return rc;
    obs_vk_plan_record(ctx, &t);
  }
  memcpy(ao_raw, ao, (size_t)host->width * (size_t)host->height * sizeof *ao);
  return 0;
}

int obs_analytic_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "analytic_ao", passes, ctx->bound, out, err);
}
