/* ibl_shadows on Vulkan: the shadow maps rasterised by depth-only render passes (the device
 * layer's obs_vk_depth_maps, one layer of a depth array texture a map), then the fit and blur
 * compute passes (ibl_shadows_fit.comp.glsl, ibl_shadows_blur.comp.glsl, their push blocks in
 * layout.h) over the device G-buffer, as two plans for the Vulkan pass driver (plan_vk.h) run by
 * the Vulkan screen-space driver (screen_vk.h). The shading of the coefficients is the host's
 * (ibl_maps.c), as on the CPU. The CPU twin is cpu.c; its maps are ray cast, so the backends
 * differ where a silhouette crosses a map texel; fed the host's maps, the fit and blur match it
 * bit for bit. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "extent.h"
#include "geometry.h"
#include "ibl_shadows.h"
#include "obscura/render.h"
#include "plan_vk.h"
#include "raytrace.h"
#include "screen_vk.h"
#include "shaders.h"
#include "techniques.h"

/* Map m's window for obs_vk_depth_maps: its texel axes over the radius, and the distance from
 * the maps' plane over the depth range (the fit scales a map's depth back by that range). */
static void map_rows(const obs_ibl_frame *f, double (*rows)[3][4]) {
  const double r = f->radius, range = OBS_IBL_DEPTH_RANGE * f->radius;
  for (int m = 0; m < f->s.m; m++) {
    for (int k = 0; k < 3; k++) {
      rows[m][0][k] = f->axis[m][0][k] / r;
      rows[m][1][k] = f->axis[m][1][k] / r;
      rows[m][2][k] = -f->s.dir[m][k] / range;
    }
    rows[m][0][3] = rows[m][1][3] = 0;
    rows[m][2][3] = f->start / range;
  }
}

/* The fit into the caller's four raw images over `maps`, then the blur of each group into the
 * result. */
static int ibl_run(obs_vk *vk, obs_vk_gbuffer *g, const obs_ibl_frame *f,
                   const obs_ibl_shadows_params *p, obs_vk_texture *maps, obs_vk_image *raw[4],
                   float *raw_host, float *res_host, obs_vk_plan_times *t, obs_err *err) {
  const int groups = (f->s.n + 3) / 4;
  const size_t N = (size_t)g->width * (size_t)g->height;
  obs_vk_data *table = NULL;
  int rc = obs_vk_data_create(vk, &f->table, sizeof f->table, &table, err);
  enum { R0 = OBS_VK_PLAN_IMAGE0, R1, R2, R3, TMP, S0, S1, S2, S3 };
  if (!rc) {
    obs_vk_plan fit = {
        .technique = "ibl_shadows",
        .images = {[R0] = {.channels = 4, .use = raw[0]}, [R1] = {.channels = 4, .use = raw[1]},
                   [R2] = {.channels = 4, .use = raw[2]}, [R3] = {.channels = 4, .use = raw[3]}},
        .passes = {{.stage = "fit", OBS_VK_SPIRV(ibl_shadows_fit_comp), OBS_VK_PUSH(f->fit),
                    .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, R0, R1, R2, R3},
                    .textures = {maps}, .ntextures = 1, .data = table}}};
    for (int k = 0; k < OBS_IBL_GROUPS; k++) fit.downloads[k] = (obs_vk_plan_download){R0 + k,
                                                                   raw_host + 4 * N * (size_t)k};
    rc = obs_vk_plan_run(vk, g, &fit, t, err);
  }
  if (!rc && p->blur) {
    obs_ibl_blur_push h = {.width = g->width, .height = g->height, .horizontal = 1}, v = h;
    obs_ibl_blur_weights(h.weights);
    memcpy(v.weights, h.weights, sizeof v.weights);
    v.horizontal = 0;
    obs_vk_plan blur = {.technique = "ibl_shadows", .images = {[TMP] = {.channels = 4}}};
    for (int k = 0; k < OBS_IBL_GROUPS; k++) {
      blur.images[R0 + k] = (obs_vk_plan_image){.channels = 4, .use = raw[k]};
      blur.images[S0 + k] = (obs_vk_plan_image){.channels = 4};
      blur.passes[2 * k] = (obs_vk_plan_pass){
          .stage = "blur", OBS_VK_SPIRV(ibl_shadows_blur_comp), OBS_VK_PUSH(h),
          .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, R0 + k, TMP}, .skip = k >= groups};
      blur.passes[2 * k + 1] = (obs_vk_plan_pass){
          .stage = "blur", OBS_VK_SPIRV(ibl_shadows_blur_comp), OBS_VK_PUSH(v),
          .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, TMP, S0 + k}, .skip = k >= groups};
      blur.downloads[k] =
          (obs_vk_plan_download){S0 + k, k < groups ? res_host + 4 * N * (size_t)k : NULL};
    }
    obs_vk_plan_times tb = {0};
    rc = obs_vk_plan_run(vk, g, &blur, &tb, err);
    for (int i = 0; !rc && i < tb.n && t->n < OBS_VK_PLAN_PASSES + 1; i++) {
      int k = 0;
      while (k < t->n && strcmp(t->stage[k], tb.stage[i])) k++;
      if (k == t->n) t->stage[t->n++] = tb.stage[i], t->ms[k] = 0;
      t->ms[k] += tb.ms[i];
    }
  }
  obs_vk_data_free(vk, table);
  return rc;
}

/* The maps on the device: uploaded from the host's ray casts (`rt`) or rasterised from `geo`;
 * f->fit.depth_scale set to match. */
static int make_maps(obs_vk *vk, obs_ibl_frame *f, const obs_rt *rt, const obs_geometry *geo,
                     int threads, obs_vk_texture **maps, double *ms, obs_err *err) {
  const int m = f->s.m, S = f->fit.size;
  double t0 = obs_now_ms();
  int rc;
  if (rt) {
    obs_vk_texture_desc desc = {.type = OBS_VK_TEXTURE_2D_ARRAY, .width = S, .height = S,
                                .depth = m, .channels = 1, .linear = 0};
    rc = obs_ibl_maps_cast(f, rt, threads, NULL, err);
    if (!rc) rc = obs_vk_texture_create(vk, &desc, maps, err);
    if (!rc) {
      const int at[3] = {0, 0, 0}, size[3] = {S, S, m};
      rc = obs_vk_texture_upload(vk, *maps, at, size, f->maps, err);
    }
    *ms = obs_now_ms() - t0;
    return rc;
  }
  double(*rows)[3][4] = malloc((size_t)m * sizeof *rows);
  if (!rows) return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: out of memory");
  map_rows(f, rows);
  f->fit.depth_scale = (float)(OBS_IBL_DEPTH_RANGE * f->radius);
  rc = obs_vk_depth_maps(vk, geo, f->centre, (const double(*)[3][4])rows, m, S, 2 * f->radius / S,
                         maps, ms, err);
  free(rows);
  return rc;
}

static const char *const stages[OBS_IBL_VK_STAGES] = {"setup", "shadow_maps", "fit", "blur",
                                                      "readback", "shade"};

int obs_ibl_shadows_vk_apply(obs_vk *vk, obs_vk_gbuffer *dev, const obs_scene *sc,
                             const obs_rt *rt, const obs_env *env, const obs_gbuffer *g,
                             const obs_ibl_shadows_params *p, int host_maps, int threads,
                             float *ao, float *ao_raw, float *extra, double *stage_ms,
                             obs_err *err) {
  double st[OBS_IBL_VK_STAGES] = {0, 0, 0, 0, 0, 0};
  if (stage_ms) memcpy(stage_ms, st, sizeof st);
  if (!vk || !dev || !g || !p || !ao || !ao_raw || !extra || dev->width != g->width ||
      dev->height != g->height)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: missing device, G-buffer or output");
  obs_rt own;
  obs_geometry geo;
  const obs_geometry *gp = rt ? &rt->geo : &geo;
  int built = 0, rc = 0;
  double t0 = obs_now_ms();
  if (!rt && host_maps) {
    rc = obs_rt_build_ex(sc, &own, threads, OBS_RT_FRAME_GEOMETRY, err);
    rt = &own, gp = &own.geo, built = 1;
  } else if (!rt) {
    /* Built about the scene's centre, so the float vertices keep their precision at any
     * translation. */
    obs_extent ex;
    double at[3] = {0, 0, 0};
    rc = obs_scene_extent(sc, &ex, err);
    for (int k = 0; !rc && !ex.empty && k < 3; k++) at[k] = 0.5 * (ex.bounds[0][k] + ex.bounds[1][k]);
    if (!rc) rc = obs_geometry_build_at(sc, at, &geo, err);
    built = 2;
  }
  if (rc) return rc;
  obs_ibl_frame *f = calloc(1, sizeof *f);
  const size_t N = (size_t)g->width * (size_t)g->height, plane = 4 * N * OBS_IBL_GROUPS;
  float *buf = malloc(2 * plane * sizeof *buf);
  obs_vk_image *raw[4] = {NULL, NULL, NULL, NULL};
  obs_vk_texture *maps = NULL;
  if (!f || !buf)
    rc = obs_err_set(err, OBS_ENOMEM, "ibl_shadows: %dx%d: out of memory", g->width, g->height);
  else if (!(rc = obs_ibl_frame_make(sc, gp, env, g, p, f, err))) {
    st[0] = obs_now_ms() - t0;
    rc = make_maps(vk, f, host_maps ? rt : NULL, gp, threads, &maps, &st[1], err);
  }
  for (int k = 0; !rc && k < 4; k++) rc = obs_vk_image_create(vk, g->width, g->height, 4, &raw[k], err);
  if (!rc) {
    obs_vk_plan_times t = {0};
    memset(buf, 0, 2 * plane * sizeof *buf);
    rc = ibl_run(vk, dev, f, p, maps, raw, buf, buf + plane, &t, err);
    double vs[3];
    static const char *const names[3] = {"fit", "blur", "readback"};
    obs_vk_plan_stage_ms(&t, names, 3, vs);
    st[2] = vs[0], st[3] = vs[1], st[4] = vs[2];
  }
  if (!rc) {
    double t1 = obs_now_ms();
    obs_ibl_export(f, g, env, buf, p->blur ? buf + plane : buf, threads, ao, ao_raw, extra);
    st[5] = obs_now_ms() - t1;
  }
  for (int k = 0; k < 4; k++)
    if (raw[k]) obs_vk_image_free(vk, raw[k]);
  obs_vk_texture_free(vk, maps);
  if (f) obs_ibl_frame_free(f);
  free(f);
  free(buf);
  if (built == 1) obs_rt_free(&own);
  if (built == 2) obs_geometry_free(&geo);
  if (stage_ms) memcpy(stage_ms, st, sizeof st);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, float *extra, obs_err *err) {
  const obs_ibl_shadows_params *p = params;
  obs_env dark;
  const obs_env *env;
  int rc = obs_ibl_env_of(ctx, &dark, &env, err);
  if (rc) return rc;
  double st[OBS_IBL_VK_STAGES];
  rc = obs_ibl_shadows_vk_apply(vk, dev, ctx->scene, ctx->rt, env, host, p, 0, ctx->threads,
                                ao, ao_raw, extra, st, err);
  obs_env_free(&dark);
  if (!rc)
    for (int k = 0; k < OBS_IBL_VK_STAGES; k++)
      if (k != 3 || p->blur) obs_driver_stage_add(ctx, stages[k], st[k]);
  return rc;
}

static const obs_screen_extra ibl_extra = {OBS_IBL_EXTRA, obs_ibl_shadows_extra_names};

int obs_ibl_shadows_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run_ex(ctx, "ibl_shadows", passes, &ibl_extra, ctx->bound, out, err);
}
