/* The Vulkan screen-space driver (screen_vk.h): the skeleton every screen-space technique shares
 * on Vulkan. */
#include "screen_vk.h"

#include <string.h>

#include "camera.h"
#include "driver.h"
#include "geometry.h"
#include "obscura/render.h"
#include "session_vk.h"

static void progress(obs_render_ctx *ctx, double fraction) {
  if (ctx->progress) ctx->progress(ctx->progress_user, fraction);
}

/* A render's work on the device (exactly one of passes, passes_ex is set). */
typedef struct screen_job {
  obs_screen_vk_passes_fn passes;
  obs_screen_vk_passes_ex_fn passes_ex;
  const void *params;
  obs_image *out;
  const obs_region *region;
} screen_job;

/* The G-buffer, the passes, the readback and the export, inside the device session. */
static int screen_work(obs_render_ctx *ctx, obs_vk *vk, void *job, obs_err *err) {
  const screen_job *j = job;
  const obs_scene *sc = ctx->scene;
  obs_image *out = j->out;
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  obs_geometry geo;
  obs_vk_gbuffer dev;
  obs_gbuffer host;
  memset(&geo, 0, sizeof geo);
  memset(&dev, 0, sizeof dev);
  memset(&host, 0, sizeof host);
  double gb_ms = 0, t0 = obs_now_ms();
  int rc;
  if ((rc = obs_geometry_build_at(sc, rig.origin, &geo, err))) goto done;
  if ((rc = obs_vk_gbuffer_render(vk, sc, &geo, &dev, &gb_ms, err))) goto done;
  double t1 = obs_now_ms();
  ctx->build_ms += t1 - t0;
  obs_driver_stage_add(ctx, "gbuffer", gb_ms);
  /* The triangles in the camera's frame and their upload, around the G-buffer's passes. */
  obs_driver_stage_add(ctx, "geometry", t1 - t0 - gb_ms);
  progress(ctx, 1.0 / 3.0);
  /* The host copy is made now so its projection (floats from the rig) is the one the passes use,
   * exactly as on the CPU. */
  if ((rc = obs_gbuffer_alloc(&host, sc->width, sc->height, &rig, err))) goto done;
  if ((rc = obs_driver_cancelled(ctx, err))) goto done;
  size_t plane = (size_t)sc->width * (size_t)sc->height;
  float *ao = out->data + OBS_SCREEN_AO * plane, *ao_raw = out->data + OBS_SCREEN_AO_RAW * plane;
  double t2 = obs_now_ms();
  if (j->passes_ex) {
    if ((rc = obs_vk_gbuffer_download(vk, &dev, &host, 1, err))) goto done;
    obs_driver_stage_add(ctx, "readback", obs_now_ms() - t2);
    rc = j->passes_ex(ctx, vk, &dev, &host, j->params, ao, ao_raw,
                      out->data + OBS_SCREEN_CHANNELS * plane, err);
  } else {
    rc = j->passes(ctx, vk, &dev, &host, j->params, ao, ao_raw, err);
  }
  if (rc) goto done;
  progress(ctx, 2.0 / 3.0);
  if ((rc = obs_driver_cancelled(ctx, err))) goto done;
  /* The depth and normal outputs come from the device G-buffer, so they match the AO. */
  t2 = obs_now_ms();
  if (!j->passes_ex && (rc = obs_vk_gbuffer_download(vk, &dev, &host, 0, err))) goto done;
  if (!j->passes_ex) obs_driver_stage_add(ctx, "readback", obs_now_ms() - t2);
  obs_screen_rule_check(ctx, OBS_BACKEND_VULKAN, &host);
  obs_gbuffer_export(&host, &rig, out);
  obs_driver_clear_outside(out, j->region);
  ctx->render_ms = obs_now_ms() - t1;
  ctx->rays = 0;
done:
  obs_gbuffer_free(&host);
  obs_vk_gbuffer_free(vk, &dev);
  obs_geometry_free(&geo);
  return rc;
}

/* The driver for either kind of passes: the image, then the work in a device session (which
 * acquires the device as stage "device", judges the validation layer and reports the end). */
static int screen_vk_run(obs_render_ctx *ctx, const char *technique, obs_screen_vk_passes_fn passes,
                         obs_screen_vk_passes_ex_fn passes_ex, const obs_screen_extra *extra,
                         const void *params, obs_image *out, obs_err *err) {
  obs_region region;
  const char *names[OBS_SCREEN_CHANNELS + OBS_SCREEN_EXTRA_MAX];
  int nextra = extra ? extra->n : 0;
  if (nextra < 0 || nextra > OBS_SCREEN_EXTRA_MAX)
    return obs_err_set(err, OBS_EINVAL, "screen: %d extra channels (at most %d)", nextra,
                       OBS_SCREEN_EXTRA_MAX);
  for (int c = 0; c < OBS_SCREEN_CHANNELS; c++) names[c] = obs_screen_channel_names[c];
  for (int c = 0; c < nextra; c++) names[OBS_SCREEN_CHANNELS + c] = extra->names[c];
  int rc = obs_driver_image(ctx, OBS_SCREEN_CHANNELS + nextra, names, out, &region, err);
  if (rc) return rc;
  screen_job job = {passes, passes_ex, params, out, &region};
  rc = obs_vk_session_run(ctx, technique, screen_work, &job, err);
  if (rc) obs_image_free(out);
  return rc;
}

int obs_screen_vk_run(obs_render_ctx *ctx, const char *technique, obs_screen_vk_passes_fn passes,
                      const void *params, obs_image *out, obs_err *err) {
  return screen_vk_run(ctx, technique, passes, NULL, NULL, params, out, err);
}

int obs_screen_vk_run_ex(obs_render_ctx *ctx, const char *technique,
                         obs_screen_vk_passes_ex_fn passes, const obs_screen_extra *extra,
                         const void *params, obs_image *out, obs_err *err) {
  return screen_vk_run(ctx, technique, NULL, passes, extra, params, out, err);
}
