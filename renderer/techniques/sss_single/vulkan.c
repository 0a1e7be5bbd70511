/* sss_single on Vulkan (method shadow_maps). The device rasterises each light's view with the
 * G-buffer pipeline (renderer/vulkan/gbuffer_vk.c, the light's projection as the camera) and a
 * compute pass (sss_maps.comp.glsl) turns it into the light-view maps, copied into the layers of
 * a 2D array texture. The host builds the BVH for each pixel sample's camera hits (sss_maps.c,
 * the same as the CPU's), and one compute pass per pixel sample (sss_single.comp.glsl) runs
 * Listing 6.5.1 over them, the maps read by texelFetch, the media and lights in the parameter
 * buffer (layout.h). The pixel samples' radiances are averaged on the host. */
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "layout.h"
#include "obscura/render.h"
#include "session_vk.h"
#include "shaders.h"
#include "sss_host.h"
#include "sss_single.h"
#include "techniques.h"
#include "vk.h"

_Static_assert(sizeof(obs_sss_push) <= OBS_VK_PUSH_MAX, "push constants past the device layer's");
_Static_assert(sizeof(obs_sss_maps_push) <= OBS_VK_PUSH_MAX, "push constants past the layer's");

enum { CH_R, CH_G, CH_B, CH_SR, CH_SG, CH_SB, CH_ALPHA, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {
    "radiance.R", "radiance.G", "radiance.B", "radiance_stderr.R", "radiance_stderr.G",
    "radiance_stderr.B", "alpha"};

typedef struct vk_job {
  obs_image *out;
  obs_region rg;
} vk_job;

/* The device's objects of one run. */
typedef struct dev {
  obs_vk_image *img[OBS_SSS_BINDINGS];
  obs_vk_image *map[OBS_SSS_LAYERS]; /* one light's maps as the maps pass writes them */
  obs_vk_texture *maps;
  obs_vk_data *table;
} dev;

static void dev_free(obs_vk *vk, dev *d) {
  for (int i = 0; i < OBS_SSS_BINDINGS; i++) obs_vk_image_free(vk, d->img[i]);
  for (int i = 0; i < OBS_SSS_LAYERS; i++) obs_vk_image_free(vk, d->map[i]);
  obs_vk_texture_free(vk, d->maps);
  obs_vk_data_free(vk, d->table);
}

/* The parameter buffer, and every light's maps rasterised on the device into the texture's
 * layers; *ms receives the device time of the rasters and the maps passes. */
static int build_maps(obs_vk *vk, const obs_scene *sc, const obs_sss_host *h, int size, dev *d,
                      double *ms, obs_err *err) {
  int nl = obs_sss_host_nlights(h), layers = nl * OBS_SSS_LAYERS;
  obs_vk_texture_desc td = {OBS_VK_TEXTURE_2D_ARRAY, size, size, layers, 4, 0};
  int rc = obs_vk_texture_create(vk, &td, &d->maps, err);
  size_t rows;
  const float *t = obs_sss_host_table(h, &rows);
  if (!rc) rc = obs_vk_data_create(vk, t, rows * 4 * sizeof(float), &d->table, err);
  for (int i = 0; i < OBS_SSS_LAYERS && !rc; i++)
    rc = obs_vk_image_create(vk, size, size, 4, &d->map[i], err);
  *ms = 0;
  for (int l = 0; l < nl && !rc; l++) {
    obs_camera_rig rig;
    obs_sss_host_light_rig(h, l, &rig);
    obs_vk_gbuffer gb;
    double gms = 0, pms = 0;
    rc = obs_vk_gbuffer_render_rig(vk, sc, obs_sss_host_geometry(h), &rig, &gb, &gms, err);
    if (rc) break;
    obs_sss_maps_push pc = {.size = size, .light = l, .nobjects = obs_sss_host_nobjects(h)};
    obs_vk_pass pass = {.name = "sss_single maps", .spirv = obs_spv_sss_maps_comp,
                        .spirv_size = obs_spv_sss_maps_comp_size,
                        .nimages = OBS_SSS_M_BINDINGS, .push = &pc, .push_size = sizeof pc,
                        .groups_x = (uint32_t)(size + 7) / 8, .groups_y = (uint32_t)(size + 7) / 8,
                        .groups_z = 1, .data = d->table};
    pass.images[OBS_SSS_M_DEPTH] = gb.depth;
    pass.images[OBS_SSS_M_NORMAL] = gb.normal;
    pass.images[OBS_SSS_M_ALBEDO] = gb.albedo;
    for (int i = 0; i < OBS_SSS_LAYERS; i++) pass.images[OBS_SSS_M_POS + i] = d->map[i];
    rc = obs_vk_run(vk, &pass, 1, &pms, err);
    obs_vk_gbuffer_free(vk, &gb);
    for (int i = 0; i < OBS_SSS_LAYERS && !rc; i++)
      rc = obs_vk_texture_copy_image(vk, d->maps, l * OBS_SSS_LAYERS + i, d->map[i], err);
    *ms += gms + pms;
  }
  return rc;
}

static int work(obs_render_ctx *ctx, obs_vk *vk, void *user, obs_err *err) {
  vk_job *jb = user;
  const obs_scene *sc = ctx->scene;
  const obs_sss_single_params *p = ctx->bound;
  const int w = sc->width, hgt = sc->height;
  size_t npx = (size_t)w * hgt;
  obs_sss_host *h = NULL;
  dev d;
  memset(&d, 0, sizeof d);
  float *buf = malloc(npx * 4 * 4 * sizeof(float)), *alpha = calloc(npx, sizeof(float));
  double *acc = calloc(npx * 3, sizeof(double));
  int rc = buf && alpha && acc ? 0 : obs_err_set(err, OBS_ENOMEM, "%s: sss_single: out of memory",
                                                 sc->name);
  double t0 = obs_now_ms(); /* the host's BVH and camera rays are this run's work too */
  if (!rc) rc = obs_sss_host_open(ctx, &h, err);
  double maps_ms = 0;
  if (!rc) rc = build_maps(vk, sc, h, (int)p->map_size, &d, &maps_ms, err);
  if (!rc) obs_driver_stage_add(ctx, "light_maps", maps_ms);
  for (int i = 0; i < OBS_SSS_BINDINGS && !rc; i++)
    rc = obs_vk_image_create(vk, w, hgt, 4, &d.img[i], err);
  double shade_ms = 0;
  for (int s = 0; s < sc->spp && !rc; s++) {
    float *pos = buf, *nrm = buf + 4 * npx, *dir = buf + 8 * npx, *rad = buf + 12 * npx;
    double t1 = obs_now_ms();
    ctx->rays += obs_sss_host_hits(h, s, pos, nrm, dir, alpha);
    obs_driver_stage_add(ctx, "camera_rays", obs_now_ms() - t1);
    rc = obs_vk_image_upload(vk, d.img[OBS_SSS_B_POS], pos, err);
    if (!rc) rc = obs_vk_image_upload(vk, d.img[OBS_SSS_B_NRM], nrm, err);
    if (!rc) rc = obs_vk_image_upload(vk, d.img[OBS_SSS_B_DIR], dir, err);
    obs_sss_push pc = {.width = w, .height = hgt, .nobjects = obs_sss_host_nobjects(h),
                       .nlights = obs_sss_host_nlights(h), .samples = (int)p->samples,
                       .adaptive = p->adaptive, .seed = p->seed, .pixel_sample = s,
                       .map_size = (int)p->map_size, .jitter = (float)p->jitter};
    obs_vk_pass pass = {.name = "sss_single", .spirv = obs_spv_sss_single_comp,
                        .spirv_size = obs_spv_sss_single_comp_size, .nimages = OBS_SSS_BINDINGS,
                        .push = &pc, .push_size = sizeof pc, .groups_x = (uint32_t)(w + 7) / 8,
                        .groups_y = (uint32_t)(hgt + 7) / 8, .groups_z = 1, .ntextures = 1,
                        .data = d.table};
    for (int i = 0; i < OBS_SSS_BINDINGS; i++) pass.images[i] = d.img[i];
    pass.textures[0] = d.maps;
    double ms = 0;
    if (!rc) rc = obs_vk_run(vk, &pass, 1, &ms, err);
    shade_ms += ms;
    if (!rc) rc = obs_vk_image_download(vk, d.img[OBS_SSS_B_OUT], rad, err);
    for (size_t i = 0; i < npx && !rc; i++)
      for (int c = 0; c < 3; c++) acc[3 * i + c] += rad[4 * i + c];
  }
  if (!rc) {
    obs_driver_stage_add(ctx, "shade", shade_ms);
    ctx->render_ms += obs_now_ms() - t0;
    for (size_t i = 0; i < npx; i++) {
      int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w);
      if (x < jb->rg.x0 || x >= jb->rg.x1 || y < jb->rg.y0 || y >= jb->rg.y1) continue;
      for (int c = 0; c < 3; c++)
        obs_image_channel(jb->out, channel_names[CH_R + c])[i] = (float)(acc[3 * i + c] / sc->spp);
      obs_image_channel(jb->out, "alpha")[i] = alpha[i] / (float)sc->spp;
    }
  }
  dev_free(vk, &d);
  obs_sss_host_close(h);
  free(buf);
  free(alpha);
  free(acc);
  return rc;
}

int obs_sss_single_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  vk_job jb = {out, {0, 0, 0, 0}};
  int rc = obs_driver_image(ctx, CH_COUNT, channel_names, out, &jb.rg, err);
  if (rc) return rc;
  if ((rc = obs_vk_session_run(ctx, "sss_single", work, &jb, err))) obs_image_free(out);
  return rc;
}
