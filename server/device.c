/* Where a time came from: the device object every API answer that shows a time carries (jobs,
 * comparison candidates, the CSV's device column, health), with its label written here once. */
#include <jansson.h>
#include <stdio.h>
#include <string.h>

#include "obscurad.h"

json_t *srv_device_json(const char *backend, const json_t *machine) {
  if (!backend || !json_is_object(machine)) return json_null();
  int vk = !strcmp(backend, "vulkan");
  const char *name = json_string_value(json_object_get(machine, vk ? "vulkan_device" : "cpu_model"));
  const char *kind = vk ? json_string_value(json_object_get(machine, "vulkan_kind")) : "cpu";
  char label[512];
  if (vk)
    snprintf(label, sizeof label, "vulkan \xc2\xb7 %s (%s)", name ? name : "unknown device",
             !kind ? "kind unknown" : !strcmp(kind, "gpu") ? "GPU" : kind);
  else
    snprintf(label, sizeof label, "cpu \xc2\xb7 %s (%lld threads)", name ? name : "unknown CPU",
             (long long)json_integer_value(json_object_get(machine, "cores")));
  return json_pack("{s:s, s:o, s:o, s:s}", "backend", backend,
                   "name", name ? json_string(name) : json_null(),
                   "kind", kind ? json_string(kind) : json_null(), "label", label);
}

json_t *srv_devices_json(const srv_app *app) {
  const obs_backend_ops *cpu = obs_backend_ops_get(OBS_BACKEND_CPU);
  const obs_backend_ops *vk = obs_backend_ops_get(OBS_BACKEND_VULKAN);
  json_t *m = json_pack("{s:s, s:i}", "cpu_model", cpu->device_name(), "cores", app->cpu_threads);
  if (app->vulkan_lane) {
    json_object_set_new(m, "vulkan_device", json_string(vk->device_name()));
    json_object_set_new(m, "vulkan_kind",
                        app->vulkan_kind ? json_string(app->vulkan_kind) : json_null());
  }
  json_t *o = json_pack("{s:o, s:o}", "cpu", srv_device_json("cpu", m), "vulkan",
                        app->vulkan_lane ? srv_device_json("vulkan", m) : json_null());
  json_decref(m);
  return o;
}
