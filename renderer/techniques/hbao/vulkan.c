/* hbao on Vulkan: the passes of cpu.c as compute shaders (hbao_*.comp.glsl)
 * over a device G-buffer, run by the Vulkan screen-space driver (screen_vk.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "gbuffer.h"
#include "hbao.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "techniques.h"
#include "vk.h"

/* Push-constant blocks, laid out as the shaders declare them (4-byte scalars, std430). */
typedef struct down_push {
  int32_t lw, lh;
} down_push;

typedef struct ao_push {
  int32_t lw, lh, s, width, height, ortho, directions, steps;
  float half_w, half_h, radius, cos_b, sin_b, scale, inv_r, depth_eps;
} ao_push;

typedef struct up_push {
  int32_t width, height, lw, lh;
  float max_rel_dz, upsample_k;
} up_push;

typedef struct blur_push {
  int32_t width, height, axis, radius;
  float falloff, sharpness, max_rel_dz;
} blur_push;

static uint32_t groups(int n) { return (uint32_t)((n + 7) / 8); }

static obs_vk_pass pass(const char *name, const uint32_t *spirv, size_t size, const void *push,
                        uint32_t push_size, int w, int h) {
  obs_vk_pass p;
  memset(&p, 0, sizeof p);
  p.name = name;
  p.spirv = spirv;
  p.spirv_size = size;
  p.push = push;
  p.push_size = push_size;
  p.groups_x = groups(w);
  p.groups_y = groups(h);
  return p;
}

int obs_hbao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                      const obs_hbao_params *p, float *ao_host, double *stage_ms, obs_err *err) {
  return obs_hbao_vk_apply_ex(vk, g, proj, p, ao_host, NULL, stage_ms, err);
}

int obs_hbao_vk_apply_ex(obs_vk *vk, obs_vk_gbuffer *g, const obs_hbao_projection *proj,
                         const obs_hbao_params *p, float *ao_host, float *ao_raw_host,
                         double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int i = 0; i <= OBS_HBAO_PASS_COUNT; i++) stage_ms[i] = 0.0;
  if (!proj || !g || !g->depth || !g->normal || !ao_host)
    return obs_err_set(err, OBS_EINVAL, "hbao: vulkan apply: no projection, G-buffer or output");
  int W = g->width, H = g->height, lw, lh;
  obs_hbao_level_size(p, W, H, &lw, &lh);
  size_t ntab = (size_t)OBS_HBAO_NOISE_CELLS * (size_t)p->directions * 4;
  float *table = malloc(ntab * sizeof(float));
  if (!table) return obs_err_set(err, OBS_ENOMEM, "hbao: out of memory");
  obs_hbao_directions(p, table);

  enum { I_TAB, I_HD, I_HN, I_HAO, I_RAW, I_TMP, I_OUT, I_COUNT };
  obs_vk_image *im[I_COUNT] = {0};
  int rc = obs_vk_image_create(vk, p->directions, OBS_HBAO_NOISE_CELLS, 4, &im[I_TAB], err);
  if (!rc) rc = obs_vk_image_upload(vk, im[I_TAB], table, err);
  free(table);
  if (!rc && p->half_res) {
    rc = obs_vk_image_create(vk, lw, lh, 1, &im[I_HD], err);
    if (!rc) rc = obs_vk_image_create(vk, lw, lh, 4, &im[I_HN], err);
    if (!rc) rc = obs_vk_image_create(vk, lw, lh, 1, &im[I_HAO], err);
  }
  if (!rc) rc = obs_vk_image_create(vk, W, H, 1, &im[I_RAW], err);
  if (!rc && p->blur_radius > 0) {
    rc = obs_vk_image_create(vk, W, H, 1, &im[I_TMP], err);
    if (!rc) rc = obs_vk_image_create(vk, W, H, 1, &im[I_OUT], err);
  }
  if (rc) goto done;

  down_push dp = {lw, lh};
  float sigma = ((float)p->blur_radius + 1.0f) * 0.5f;
  ao_push ap = {lw, lh, p->half_res ? 2 : 1, W, H, proj->ortho, p->directions, p->steps,
                proj->half_w, proj->half_h, p->radius, (float)cos((double)p->angle_bias),
                (float)sin((double)p->angle_bias), p->scale, obs_hbao_inv_radius(p),
                OBS_HBAO_DEPTH_EPS};
  up_push upp = {W, H, lw, lh, OBS_HBAO_MAX_REL_DZ, OBS_HBAO_UPSAMPLE_K};
  blur_push bx = {W, H, 0, p->blur_radius, 1.0f / (2.0f * sigma * sigma), p->blur_sharpness,
                  OBS_HBAO_MAX_REL_DZ};
  blur_push by = bx;
  by.axis = 1;

  obs_vk_pass ps[5];
  int kind[5], np = 0;
  if (p->half_res) {
    ps[np] = pass("hbao downsample", obs_spv_hbao_down_comp, obs_spv_hbao_down_comp_size, &dp,
                  sizeof dp, lw, lh);
    ps[np].images[0] = g->depth;
    ps[np].images[1] = g->normal;
    ps[np].images[2] = im[I_HD];
    ps[np].images[3] = im[I_HN];
    ps[np].nimages = 4;
    kind[np++] = OBS_HBAO_PASS_DOWNSAMPLE;
  }
  ps[np] = pass("hbao ao", obs_spv_hbao_ao_comp, obs_spv_hbao_ao_comp_size, &ap, sizeof ap, lw, lh);
  ps[np].images[0] = p->half_res ? im[I_HD] : g->depth;
  ps[np].images[1] = p->half_res ? im[I_HN] : g->normal;
  ps[np].images[2] = im[I_TAB];
  ps[np].images[3] = p->half_res ? im[I_HAO] : im[I_RAW];
  ps[np].nimages = 4;
  kind[np++] = OBS_HBAO_PASS_AO;
  if (p->half_res) {
    ps[np] = pass("hbao upsample", obs_spv_hbao_up_comp, obs_spv_hbao_up_comp_size, &upp,
                  sizeof upp, W, H);
    ps[np].images[0] = g->depth;
    ps[np].images[1] = im[I_HD];
    ps[np].images[2] = im[I_HAO];
    ps[np].images[3] = im[I_RAW];
    ps[np].nimages = 4;
    kind[np++] = OBS_HBAO_PASS_UPSAMPLE;
  }
  if (p->blur_radius > 0) {
    ps[np] = pass("hbao blur x", obs_spv_hbao_blur_comp, obs_spv_hbao_blur_comp_size, &bx,
                  sizeof bx, W, H);
    ps[np].images[0] = g->depth;
    ps[np].images[1] = im[I_RAW];
    ps[np].images[2] = im[I_TMP];
    ps[np].nimages = 3;
    kind[np++] = OBS_HBAO_PASS_BLUR;
    ps[np] = pass("hbao blur y", obs_spv_hbao_blur_comp, obs_spv_hbao_blur_comp_size, &by,
                  sizeof by, W, H);
    ps[np].images[0] = g->depth;
    ps[np].images[1] = im[I_TMP];
    ps[np].images[2] = im[I_OUT];
    ps[np].nimages = 3;
    kind[np++] = OBS_HBAO_PASS_BLUR;
  }
  double ms[5] = {0};
  if ((rc = obs_vk_run(vk, ps, np, ms, err))) goto done;
  if (stage_ms)
    for (int i = 0; i < np; i++) stage_ms[kind[i]] += ms[i];
  double t = obs_now_ms();
  rc = obs_vk_image_download(vk, p->blur_radius > 0 ? im[I_OUT] : im[I_RAW], ao_host, err);
  if (!rc && ao_raw_host) rc = obs_vk_image_download(vk, im[I_RAW], ao_raw_host, err);
  if (stage_ms) stage_ms[OBS_HBAO_PASS_COUNT] = obs_now_ms() - t;
done:
  for (int i = 0; i < I_COUNT; i++) obs_vk_image_free(vk, im[i]);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  const obs_hbao_params *p = params;
  obs_hbao_projection proj = obs_hbao_projection_of(host);
  double st[OBS_HBAO_PASS_COUNT + 1];
  int rc = obs_hbao_vk_apply_ex(vk, dev, &proj, p, ao, ao_raw, st, err);
  if (rc) return rc;
  for (int i = 0; i < OBS_HBAO_PASS_COUNT; i++)
    if (obs_hbao_pass_runs(p, i)) obs_driver_stage_add(ctx, obs_hbao_pass_names[i], st[i]);
  obs_driver_stage_add(ctx, "readback", st[OBS_HBAO_PASS_COUNT]);
  return 0;
}

int obs_hbao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "hbao", passes, ctx->bound, out, err);
}
