/* A Vulkan render's device session (session_vk.h). */
#include "session_vk.h"

#include "driver.h"
#include "obscura/render.h"

int obs_vk_session_run(obs_render_ctx *ctx, const char *technique, obs_vk_session_fn fn,
                       void *job, obs_err *err) {
  const int validation = obs_vk_validation_requested();
  obs_vk *vk = NULL;
  double ta = obs_now_ms();
  int rc = obs_vk_acquire(&vk, validation, err);
  if (rc) return rc;
  obs_driver_stage_add(ctx, "device", obs_now_ms() - ta);
  rc = fn(ctx, vk, job, err);
  if (!rc) rc = obs_vk_validation_verdict(vk, validation, ctx->scene->name, technique, err);
  if (!rc && ctx->progress) ctx->progress(ctx->progress_user, 1.0);
  obs_vk_release(vk);
  return rc;
}
