/* The backends and their one public operations table. Each backend layer (renderer/cpu,
 * renderer/vulkan) defines its table; the registry lists them, and everything above (the technique
 * registry, the renderer's core, the CLI, the server) asks a backend what it is, whether it runs
 * here and on which device only through it, never through the backend's own headers. */
#ifndef OBSCURA_BACKEND_H
#define OBSCURA_BACKEND_H

#include "obscura/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct json_t json_t; /* jansson */
struct obs_scene;
struct obs_gbuffer;
struct obs_technique;
struct obs_needs_builder;
struct obs_prox_field;

typedef enum { OBS_BACKEND_AUTO = 0, OBS_BACKEND_CPU = 1, OBS_BACKEND_VULKAN = 2 } obs_backend;
#define OBS_BACKEND_COUNT 3

/* The host G-buffer (renderer/core/gbuffer.h) of `scene`'s camera as this backend makes it;
 * build_ms and render_ms may be NULL. For the renderer's own use (reference hooks that need a
 * coarse view of the scene), not part of the stable API. */
typedef int (*obs_backend_gbuffer_fn)(const struct obs_scene *scene, struct obs_gbuffer *g,
                                      int threads, double *build_ms, double *render_ms,
                                      obs_err *err);


typedef struct obs_backend_ops {
  obs_backend id;
  const char *name; /* as scene documents, the CLI and the API spell it */
  /* Whether the backend can render on this machine. May probe a device the first time (then
   * cached for the process); safe from any thread. */
  int (*available)(void);
  /* The device renders use, in words (a CPU model, a Vulkan device name), or NULL when the
   * backend is not available. The string lives as long as the process. */
  const char *(*device_name)(void);
  /* What kind of device that is, so timings of one kind never stand for another: "cpu" (the CPU
   * backend), "gpu" (a Vulkan device of an integrated, discrete or virtual GPU type), "software"
   * (a Vulkan device of VK_PHYSICAL_DEVICE_TYPE_CPU, such as lavapipe's llvmpipe), "other"; NULL
   * when the backend is not available. */
  const char *(*device_kind)(void);
  /* A host G-buffer producer, or NULL when the backend has none. */
  obs_backend_gbuffer_fn gbuffer;
  /* What the backend builds for a technique's `needs` before its run (renderer/core/driver.h), or
   * NULL when its drivers build what they need themselves. */
  const struct obs_needs_builder *needs;
  /* 1 when the backend's volume marcher reads each voxel cell's side of the isovalue
   * (renderer/core/volume.h's obs_volume_sides): the renderer builds them with the volumes. */
  int volume_sides;
} obs_backend_ops;

/* The operations of a concrete backend; NULL for OBS_BACKEND_AUTO or an out-of-range value. */
const obs_backend_ops *obs_backend_ops_get(obs_backend b);
/* "cpu", "vulkan", or "auto". */
const char *obs_backend_name(obs_backend b);
/* The one parser of backend names: "cpu", "vulkan" or "auto" (exact, case-sensitive) into
 * *out; anything else (NULL included) is OBS_EINVAL and leaves *out unchanged. */
int obs_backend_parse(const char *name, obs_backend *out);
/* Whether backend `b` runs technique `t`: the technique has a run function for it (in this
 * build) and the backend is available on this machine. */
int obs_backend_runs(obs_backend b, const struct obs_technique *t);
/* The backends as a JSON array (new reference): per concrete backend its name, "available",
 * "device" (name or null) and "techniques" (the names of the techniques it runs here). */
json_t *obs_backend_registry_json(void);

#ifdef __cplusplus
}
#endif
#endif
