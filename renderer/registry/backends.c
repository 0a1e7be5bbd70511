/* The backend registry: the one list of backends' operations tables, and the one spelling and
 * parser of backend names. A new backend adds its table here and its run functions to the
 * technique descriptors. */
#include <jansson.h>
#include <string.h>

#include "driver.h"
#include "obscura/backend.h"
#include "obscura/technique.h"
#include "registry.h"

static const obs_backend_ops *const backends[OBS_BACKEND_COUNT] = {
    [OBS_BACKEND_CPU] = &obs_backend_cpu_ops,
    [OBS_BACKEND_VULKAN] = &obs_backend_vulkan_ops,
};

const obs_backend_ops *obs_backend_ops_get(obs_backend b) {
  return b > OBS_BACKEND_AUTO && b < OBS_BACKEND_COUNT ? backends[b] : NULL;
}

const char *obs_backend_name(obs_backend b) {
  const obs_backend_ops *ops = obs_backend_ops_get(b);
  return ops ? ops->name : "auto";
}

int obs_backend_parse(const char *name, obs_backend *out) {
  if (!name) return OBS_EINVAL;
  for (int b = OBS_BACKEND_AUTO; b < OBS_BACKEND_COUNT; b++) {
    if (!strcmp(name, obs_backend_name((obs_backend)b))) {
      *out = (obs_backend)b;
      return 0;
    }
  }
  return OBS_EINVAL;
}

const obs_needs_builder *obs_backend_needs_builder(obs_backend b) {
  const obs_backend_ops *ops = obs_backend_ops_get(b);
  return ops ? ops->needs : NULL;
}

int obs_backend_volume_sides(obs_backend b) {
  const obs_backend_ops *ops = obs_backend_ops_get(b);
  return ops && ops->volume_sides;
}

int obs_backend_runs(obs_backend b, const obs_technique *t) {
  const obs_backend_ops *ops = obs_backend_ops_get(b);
  return ops && t && t->run[b] && ops->available();
}

json_t *obs_backend_registry_json(void) {
  json_t *arr = json_array();
  for (int b = OBS_BACKEND_AUTO + 1; b < OBS_BACKEND_COUNT; b++) {
    const obs_backend_ops *ops = backends[b];
    const char *dev = ops->device_name();
    json_t *techs = json_array();
    for (size_t i = 0; i < obs_technique_count(); i++)
      if (obs_backend_runs((obs_backend)b, obs_technique_at(i)))
        json_array_append_new(techs, json_string(obs_technique_at(i)->name));
    json_array_append_new(arr, json_pack("{s:s, s:b, s:o, s:o}", "name", ops->name, "available",
                                         ops->available(), "device",
                                         dev ? json_string(dev) : json_null(), "techniques",
                                         techs));
  }
  return arr;
}
