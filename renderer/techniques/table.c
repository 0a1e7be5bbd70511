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
    &obs_technique_obscurance,
    &obs_technique_obscurance_map,
    &obs_technique_volume_ao,
    &obs_technique_proximity_ao,
    &obs_technique_ssao_variance,
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

/* The registry's plain "outputs" list: every EXR channel name, then every image and patch file. */
static json_t *outputs_flat_json(const obs_technique *t) {
  json_t *outs = json_array();
  char ch[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX], files[16][OBS_OUTPUT_FILE_MAX];
  for (const obs_output *x = t->outputs; x && x->name; x++)
    for (int c = 0, n = obs_output_channels(x, ch); c < n; c++)
      json_array_append_new(outs, json_string(ch[c]));
  size_t nf = obs_technique_files(t, files, 16);
  for (size_t i = 0; i < nf; i++)
    if (strcmp(files[i], "summary.json") && !strstr(files[i], ".exr"))
      json_array_append_new(outs, json_string(files[i]));
  return outs;
}

/* The declared outputs with their kinds, display, files and EXR channels (the dashboard's
 * captions and the metrics' channel come from here). */
static json_t *outputs_typed_json(const obs_technique *t) {
  json_t *arr = json_array();
  char ch[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX], file[OBS_OUTPUT_FILE_MAX];
  for (const obs_output *x = t->outputs; x && x->name; x++) {
    json_t *o = json_object(), *chs = json_array();
    json_object_set_new(o, "name", json_string(x->name));
    json_object_set_new(o, "kind", json_string(obs_output_kind_name(x->kind)));
    json_object_set_new(o, "show", json_string(obs_output_show_name(x->show)));
    json_object_set_new(o, "png", x->png ? json_string(x->png) : json_null());
    if (x->kind == OBS_OUTPUT_PATCH) {
      obs_output_patch_file(x, file, sizeof file);
      json_object_set_new(o, "file", json_string(file));
    }
    json_object_set_new(o, "description", json_string(x->description ? x->description : ""));
    json_object_set_new(o, "primary", json_boolean(x->flags & OBS_OUTPUT_PRIMARY));
    if (x->stderr_of) json_object_set_new(o, "stderr_of", json_string(x->stderr_of));
    if (x->exposure) json_object_set_new(o, "exposure_param", json_string(x->exposure));
    for (int c = 0, n = obs_output_channels(x, ch); c < n; c++)
      json_array_append_new(chs, json_string(ch[c]));
    json_object_set_new(o, "channels", chs);
    json_array_append_new(arr, o);
  }
  return arr;
}

/* Every OBS_NEED_* flag as the registry names it. */
static const struct {
  unsigned flag;
  const char *name;
} need_names[] = {{OBS_NEED_BVH, "bvh"},
                  {OBS_NEED_MATERIALS, "materials"},
                  {OBS_NEED_LIGHTS, "lights"},
                  {OBS_NEED_GBUFFER, "gbuffer"},
                  {OBS_NEED_BVH_FRAME_GEOMETRY, "bvh_frame_geometry"},
                  {OBS_NEED_MOTION, "motion"},
                  {OBS_NEED_VOLUME, "volume"},
                  {OBS_NEED_PUNCTUAL_LIGHTS, "punctual_lights"},
                  {OBS_NEED_ENV_MAP, "environment_map"},
                  {OBS_NEED_PROXIMITY, "proximity_fields"}};

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
    json_t *alts = json_array();
    for (const obs_reference_alt *a = t->reference_alts; a && a->technique; a++)
      json_array_append_new(alts, json_pack("{s:s, s:s, s:o}", "technique", a->technique->name,
                                            "output", a->output, "needs_false",
                                            a->needs_false ? json_string(a->needs_false)
                                                           : json_null()));
    json_object_set_new(o, "against", alts);
    json_t *pairs = json_array();
    for (const obs_output_pair *q = t->compared_outputs; q && q->output; q++)
      json_array_append_new(pairs, json_pack("{s:s, s:s}", "output", q->output,
                                             "reference_output", q->reference_output));
    json_object_set_new(o, "compared_outputs", pairs);
    json_t *needs = json_array();
    for (size_t k = 0; k < sizeof need_names / sizeof need_names[0]; k++)
      if (t->needs & need_names[k].flag)
        json_array_append_new(needs, json_string(need_names[k].name));
    json_object_set_new(o, "needs", needs);
    json_object_set_new(o, "outputs", outputs_flat_json(t));
    json_object_set_new(o, "typed_outputs", outputs_typed_json(t));
    char exr[OBS_OUTPUT_FILE_MAX];
    obs_technique_exr_name(t, exr, sizeof exr);
    json_object_set_new(o, "exr", json_string(exr));
    json_t *ranges = json_object();
    for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++)
      if (t->run[b] && t->range[b].size_max > 0)
        json_object_set_new(ranges, obs_backend_name((obs_backend)b), obs_range_json(&t->range[b]));
    json_object_set_new(o, "ranges", ranges);
    json_array_append_new(arr, o);
  }
  return arr;
}
