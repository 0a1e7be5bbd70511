/* The CPU screen-space driver (screen.h): the skeleton every screen-space technique shares. */
#include "screen.h"

#include <string.h>

#include "camera.h"
#include "driver.h"
#include "gbuffer_cpu.h"
#include "obscura/render.h"

static void pass_progress(void *user, double fraction) {
  obs_screen_cpu *r = user;
  int passes = r->passes > r->done ? r->passes : r->done + 1;
  r->ctx->progress(r->ctx->progress_user, (r->done + fraction) / passes);
}

int obs_screen_cpu_tiles(obs_screen_cpu *r, int w, int h, obs_tile_fn fn, void *user) {
  int report = r->ctx && r->ctx->progress;
  int rc = obs_parallel_tiles(w, h, r->threads < 1 ? 1 : r->threads, fn, user, r->cancel,
                              report ? pass_progress : NULL, r);
  r->done++;
  return rc;
}

void obs_screen_cpu_stage(obs_screen_cpu *r, const char *name, double ms) {
  if (r->ctx) obs_driver_stage_add(r->ctx, name, ms);
}

/* The driver for either kind of passes (exactly one of passes, passes_ex is set). */
static int screen_cpu_run(obs_render_ctx *ctx, obs_screen_cpu_passes_fn passes,
                          obs_screen_cpu_passes_ex_fn passes_ex, const obs_screen_extra *extra,
                          const void *params, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
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
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  obs_gbuffer g;
  memset(&g, 0, sizeof g);
  double geo_ms = 0, gb_ms = 0, t0 = obs_now_ms();
  rc = obs_gbuffer_cpu(sc, &g, ctx->threads, &geo_ms, &gb_ms, err);
  double t1 = obs_now_ms();
  if (!rc) {
    ctx->build_ms += t1 - t0;
    obs_driver_stage_add(ctx, "gbuffer", gb_ms);
    rc = obs_driver_cancelled(ctx, err);
  }
  if (!rc) {
    obs_screen_cpu r = {.threads = ctx->threads, .cancel = ctx->cancel, .ctx = ctx};
    size_t plane = (size_t)sc->width * (size_t)sc->height;
    float *ao = out->data + OBS_SCREEN_AO * plane, *ao_raw = out->data + OBS_SCREEN_AO_RAW * plane;
    rc = passes ? passes(&r, &g, params, ao, ao_raw, err)
                : passes_ex(&r, &g, params, ao, ao_raw, out->data + OBS_SCREEN_CHANNELS * plane,
                            err);
    if (rc == OBS_ECANCELED) obs_err_set(err, rc, "%s: render cancelled", sc->name);
  }
  if (!rc) {
    obs_screen_rule_check(ctx, OBS_BACKEND_CPU, &g);
    obs_gbuffer_export(&g, &rig, out);
    obs_driver_clear_outside(out, &region);
    ctx->render_ms = obs_now_ms() - t1;
    /* One primary ray per pixel, however the G-buffer was made. */
    ctx->rays = (uint64_t)sc->width * (uint64_t)sc->height;
    if (ctx->progress) ctx->progress(ctx->progress_user, 1.0);
  }
  obs_gbuffer_free(&g);
  if (rc) obs_image_free(out);
  return rc;
}

int obs_screen_cpu_run(obs_render_ctx *ctx, obs_screen_cpu_passes_fn passes, const void *params,
                       obs_image *out, obs_err *err) {
  return screen_cpu_run(ctx, passes, NULL, NULL, params, out, err);
}

int obs_screen_cpu_run_ex(obs_render_ctx *ctx, obs_screen_cpu_passes_ex_fn passes,
                          const obs_screen_extra *extra, const void *params, obs_image *out,
                          obs_err *err) {
  return screen_cpu_run(ctx, NULL, passes, extra, params, out, err);
}
