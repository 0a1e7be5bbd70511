/* obscurance_map on Vulkan: the depth_peeling estimator (omap_peel.h) over the scene's geometry,
 * its per-patch output, and the image of the patch each pixel sees (rendered on the device with
 * the same numbering, since the Vulkan backend has no ray tracer). */
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "obscura/render.h"
#include "omap_peel.h"
#include "session_vk.h"
#include "techniques.h"

/* The channels of the technique's image, as its outputs (obscurance_map.c) name them. */
enum { CH_W, CH_SE, CH_R, CH_G, CH_B, CH_ALPHA, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {"obscurance",       "obscurance_stderr",
                                                    "obscurance_rgb.R", "obscurance_rgb.G",
                                                    "obscurance_rgb.B", "alpha"};

static int show(obs_render_ctx *ctx, const obs_omap_peel *m, obs_image *out, obs_err *err) {
  obs_region region;
  int rc = obs_driver_image(ctx, CH_COUNT, channel_names, out, &region, err);
  if (rc) return rc;
  size_t npx = (size_t)ctx->scene->width * (size_t)ctx->scene->height;
  for (size_t i = 0; i < npx; i++) {
    int32_t id = m->ids[i];
    int ok = id >= 0 && id < m->pm.count;
    const float *w = ok ? m->w + 3 * (size_t)id : NULL;
    for (int c = 0; c < 3; c++) out->data[(size_t)(CH_R + c) * npx + i] = ok ? w[c] : 0.0f;
    out->data[(size_t)CH_W * npx + i] = ok ? (w[0] + w[1] + w[2]) / 3.0f : 0.0f;
    /* The image's W is the mean of the channels: the mean of their errors bounds its error. */
    const float *se = ok ? m->se + 3 * (size_t)id : NULL;
    out->data[(size_t)CH_SE * npx + i] = ok ? (se[0] + se[1] + se[2]) / 3.0f : 0.0f;
    out->data[(size_t)CH_ALPHA * npx + i] = ok ? 1.0f : 0.0f;
  }
  obs_driver_clear_outside(out, &region);
  return 0;
}

/* The map on the device (obs_vk_session_fn) and the image of it; `user` is the render's image. */
static int render(obs_render_ctx *ctx, obs_vk *vk, void *user, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  const obs_obscurance_map_params *p = ctx->bound;
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  obs_geometry geo;
  obs_omap_peel m;
  memset(&geo, 0, sizeof geo);
  memset(&m, 0, sizeof m);
  double t0 = obs_now_ms(), ms = 0;
  /* The camera's frame, as the CPU's BVH keeps it for every scene the camera is near. */
  int rc = obs_geometry_build_at(sc, rig.origin, &geo, err);
  double t1 = obs_now_ms();
  ctx->build_ms += t1 - t0;
  if (!rc)
    rc = obs_omap_peel_compute(vk, sc, &geo, p, &rig, ctx->cancel, ctx->progress,
                               ctx->progress_user, &m, &ms, err);
  if (!rc) {
    obs_driver_stage_add(ctx, "map", ms);
    rc = obs_patch_mesh_publish(ctx, "obscurance", &m.pm, 3, m.w, err);
    if (!rc) rc = obs_patch_mesh_publish(ctx, "obscurance_stderr", &m.pm, 3, m.se, err);
  }
  if (!rc) rc = show(ctx, &m, user, err);
  ctx->render_ms += obs_now_ms() - t1;
  ctx->rays = 0;
  if (!rc && m.unsampled)
    obs_render_ctx_warn(ctx,
                        "%lld of %lld patches received no sample and show \"nothing within "
                        "d_max\"; raise directions or bundle_resolution",
                        (long long)m.unsampled, (long long)m.pm.count);
  if (!rc && m.capped)
    obs_render_ctx_warn(ctx, "%d directions had more than %d layers; deeper surfaces were skipped",
                        m.capped, OBS_PEEL_LAYERS_MAX);
  if (!rc) obs_patch_mesh_warn_capped(ctx, &m.pm);
  if (!rc) obs_omap_warn_stderr(ctx, OBS_OMAP_DEPTH_PEELING, p);
  obs_omap_peel_free(&m);
  obs_geometry_free(&geo);
  return rc;
}

int obs_obscurance_map_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  int rc = obs_vk_session_run(ctx, "obscurance_map", render, out, err);
  if (rc) {
    obs_image_free(out);
    for (int i = 0; i < ctx->npatches; i++) obs_patches_free(&ctx->patches[i]);
    ctx->npatches = 0;
  }
  return rc;
}
