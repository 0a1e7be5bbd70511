/* The registry's own declarations: the backend layers' operations tables it lists
 * (backends.c), and a backend's guaranteed range as the registry's JSON (ranges.c). */
#ifndef OBS_REGISTRY_H
#define OBS_REGISTRY_H

#include <jansson.h>

#include "driver.h"
#include "obscura/backend.h"
#include "obscura/technique.h"
#include "technique_list.h"

/* Each backend layer's operations table (renderer/cpu/backend.c, renderer/vulkan/device.c). */
extern const obs_backend_ops obs_backend_cpu_ops;
extern const obs_backend_ops obs_backend_vulkan_ops;

/* The builder of `backend`, or NULL when the backend builds nothing ahead of its runs (its
 * drivers build what they need). */
const obs_needs_builder *obs_backend_needs_builder(obs_backend backend);
/* Whether `backend` wants its volumes' cell sides (obs_backend_ops.volume_sides). */
int obs_backend_volume_sides(obs_backend backend);

/* One backend's guaranteed range as the registry's JSON (ranges.c). */
json_t *obs_range_json(const obs_range *r);

#endif
