/* The Vulkan side of proximity fields (proximity.h): the flood as compute passes
 * over 3D storage images, giving exactly the CPU flood's bits, and the backend's hook for it.
 * Internal to the Vulkan backend; tests and benchmarks call the flood directly. */
#ifndef OBS_PROXIMITY_VK_H
#define OBS_PROXIMITY_VK_H

#include "proximity.h"
#include "vk.h"

/* An obs_prox_flood_fn on Vulkan: floods `f` in place with the bits obs_prox_flood_cpu gives.
 * `user` is an open obs_vk, or NULL for the process's shared render device (acquired for the
 * call, with validation when obs_vk_validation_requested; a validation message fails it).
 * `threads` is unused. OBS_EUNSUPPORTED naming the object when a side of its grid is past the
 * device's 3D image limit; on any failure f->value is unchanged. */
int obs_prox_flood_vulkan(void *user, obs_prox_field *f, int threads, obs_err *err);

#endif
