/* The technique registry: the one table of techniques; a new technique adds one line here. */
#include <jansson.h>
#include <string.h>

#include "obscura/technique.h"
#include "techniques.h"

static const obs_technique *const table[] = {
    &obs_technique_rt_ao,
    &obs_technique_ssao,
    &obs_technique_hbao,
    &obs_technique_path_trace,
};

size_t obs_technique_count(void) { return sizeof table / sizeof table[0]; }

const obs_technique *obs_technique_at(size_t i) {
  return i < obs_technique_count() ? table[i] : NULL;
}

const obs_technique *obs_technique_find(const char *name) {
  for (size_t i = 0; name && i < obs_technique_count(); i++)
    if (!strcmp(table[i]->name, name)) return table[i];
  return NULL;
}

int obs_technique_has_backend(const obs_technique *t, obs_backend b) {
  return obs_backend_runs(b, t);
}

int obs_technique_pick_backend(const obs_technique *t, obs_backend requested, obs_backend *out,
                               obs_err *err) {
  if (requested != OBS_BACKEND_AUTO) {
    if (!obs_technique_has_backend(t, requested)) {
      if (requested == OBS_BACKEND_VULKAN && t->run[requested])
        return obs_err_set(err, OBS_EUNSUPPORTED,
                           "technique \"%s\": no Vulkan device found on this machine (install "
                           "mesa-vulkan-drivers for lavapipe, or use backend \"cpu\")",
                           t->name);
      return obs_err_set(err, OBS_EUNSUPPORTED, "technique \"%s\" has no %s backend", t->name,
                         obs_backend_name(requested));
    }
    *out = requested;
    return 0;
  }
  /* Static rule until stored timings can decide: raster techniques (those that need a G-buffer)
   * go to Vulkan when a device exists; everything else, and the fallback, is the CPU. */
  if ((t->needs & OBS_NEED_GBUFFER) && obs_technique_has_backend(t, OBS_BACKEND_VULKAN)) {
    *out = OBS_BACKEND_VULKAN;
    return 0;
  }
  for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
    if (obs_technique_has_backend(t, (obs_backend)b)) {
      *out = (obs_backend)b;
      return 0;
    }
  }
  return obs_err_set(err, OBS_EUNSUPPORTED, "technique \"%s\" has no backend in this build",
                     t->name);
}

json_t *obs_technique_registry_json(void) {
  json_t *arr = json_array();
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = table[i];
    json_t *o = json_object();
    json_object_set_new(o, "name", json_string(t->name));
    json_object_set_new(o, "description", json_string(t->description));
    json_t *be = json_array();
    for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++)
      if (t->run[b]) json_array_append_new(be, json_string(obs_backend_name((obs_backend)b)));
    json_object_set_new(o, "backends", be);
    json_object_set_new(o, "params_schema", obs_technique_params_schema(t));
    json_object_set_new(o, "cost", json_string(t->cost_rule ? t->cost_rule : "1"));
    json_t *needs = json_array();
    if (t->needs & OBS_NEED_BVH) json_array_append_new(needs, json_string("bvh"));
    if (t->needs & OBS_NEED_MATERIALS) json_array_append_new(needs, json_string("materials"));
    if (t->needs & OBS_NEED_LIGHTS) json_array_append_new(needs, json_string("lights"));
    if (t->needs & OBS_NEED_GBUFFER) json_array_append_new(needs, json_string("gbuffer"));
    json_object_set_new(o, "needs", needs);
    json_t *outs = json_array();
    for (const char *const *s = t->outputs; s && *s; s++) json_array_append_new(outs, json_string(*s));
    json_object_set_new(o, "outputs", outs);
    json_t *ranges = json_object();
    for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++)
      if (t->run[b] && t->range[b].size_max > 0)
        json_object_set_new(ranges, obs_backend_name((obs_backend)b), obs_range_json(&t->range[b]));
    json_object_set_new(o, "ranges", ranges);
    json_array_append_new(arr, o);
  }
  return arr;
}
