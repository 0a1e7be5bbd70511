/* A Vulkan render's device session: what every Vulkan run does around its own work (the shared
 * device, its acquisition timed as a stage of its own, the validation layer's verdict, the
 * release), so that a technique's Vulkan run holds its work and nothing of the device's. The
 * screen-space driver (screen_vk.h) runs its techniques' work through it too. Internal to the
 * Vulkan backend. */
#ifndef OBS_SESSION_VK_H
#define OBS_SESSION_VK_H

#include "obscura/technique.h"
#include "vk.h"

/* A technique's work on the device `vk`, with its own state in `job`; it frees what it made on
 * the device before returning, whatever it returns. */
typedef int (*obs_vk_session_fn)(obs_render_ctx *ctx, obs_vk *vk, void *job, obs_err *err);

/* Acquires the process's render device (obs_vk_acquire, with validation when
 * $OBSCURA_VK_VALIDATION asks; stage "device", in neither build nor render, since only the first
 * use in a process opens it), runs fn, fails a render the validation layer complained about
 * (OBS_EINTERNAL naming ctx's scene and `technique`), reports progress 1 after a success and
 * releases the device. Returns fn's code, or the verdict's. */
int obs_vk_session_run(obs_render_ctx *ctx, const char *technique, obs_vk_session_fn fn,
                       void *job, obs_err *err);

#endif
