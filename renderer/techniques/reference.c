/* Reference definitions: the dispatcher of the techniques' reference hooks (which reference
 * technique, with which settings, defines the same quantity as a candidate) and the response
 * curves a reference is mapped through. */
#include <jansson.h>
#include <math.h>
#include <string.h>

#include "obscura/technique.h"

int obs_technique_reference(const obs_technique *t, const obs_scene *scene, const json_t *params,
                            obs_reference_facts *facts, obs_reference_def *def, obs_err *err) {
  memset(def, 0, sizeof *def);
  if (!t || (!t->reference && !(t->reference_same && t->reference_keys)))
    return obs_err_set(err, OBS_EUNSUPPORTED, "technique \"%s\" has no reference definition, so "
                       "it cannot be compared", t ? t->name : "?");
  obs_reference_facts local;
  memset(&local, 0, sizeof local);
  def->params = json_object();
  if (!def->params) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  int rc = 0;
  if (t->reference) rc = t->reference(scene, params, facts ? facts : &local, def, err);
  else obs_reference_def_same(def, t->reference_same, params, t->reference_keys);
  if (!rc && (!def->technique || !def->technique->reference_quality))
    rc = obs_err_set(err, OBS_EUNSUPPORTED, "technique \"%s\": its reference technique \"%s\" "
                     "cannot serve as a reference (no quality parameter)", t->name,
                     def->technique ? def->technique->name : "?");
  if (rc) obs_reference_def_free(def);
  return rc;
}

static const obs_reference_alt *find_alt(const obs_technique *t, const char *name) {
  for (const obs_reference_alt *a = t->reference_alts; a && a->technique; a++)
    if (!strcmp(a->technique->name, name)) return a;
  return NULL;
}

int obs_technique_reference_against(const obs_technique *t, const obs_scene *scene,
                                    const json_t *params, const char *against,
                                    obs_reference_facts *facts, obs_reference_def *def,
                                    obs_err *err) {
  if (!against) return obs_technique_reference(t, scene, params, facts, def, err);
  memset(def, 0, sizeof *def);
  const obs_reference_alt *a = find_alt(t, against);
  if (!a) {
    char list[256] = "";
    for (const obs_reference_alt *x = t->reference_alts; x && x->technique; x++) {
      size_t l = strlen(list);
      snprintf(list + l, sizeof list - l, ", \"%s\"", x->technique->name);
    }
    return obs_err_set(err, OBS_EINVAL,
                       "technique \"%s\" cannot be compared against \"%s\" (it can be: null, "
                       "its own reference%s)",
                       t->name, against, list);
  }
  if (a->needs_false && json_is_true(json_object_get(params, a->needs_false)))
    return obs_err_set(err, OBS_EINVAL,
                       "/technique/params/%s: comparing %s's \"%s\" against \"%s\" needs %s "
                       "false (with it the two are not the same quantity)",
                       a->needs_false, t->name, a->output, against, a->needs_false);
  def->params = json_object();
  if (!def->params) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  def->technique = a->technique;
  def->response = OBS_RESPONSE_IDENTITY;
  def->output = a->output;
  for (const char *const *k = a->keys; k && k[0]; k += 2) {
    json_t *v = json_object_get(params, k[0]);
    if (v && !json_is_null(v)) json_object_set_new(def->params, k[1], json_deep_copy(v));
  }
  (void)scene;
  (void)facts;
  return 0;
}

const obs_output *obs_technique_compared_output(const obs_technique *t, const obs_technique *ref) {
  const obs_reference_alt *a = ref ? find_alt(t, ref->name) : NULL;
  const obs_output *o = a ? obs_technique_output(t, a->output) : NULL;
  return o ? o : obs_technique_primary(t);
}

void obs_reference_def_free(obs_reference_def *def) {
  if (!def) return;
  json_decref(def->params);
  memset(def, 0, sizeof *def);
}

void obs_reference_def_same(obs_reference_def *def, const obs_technique *t, const json_t *params,
                            const char *const *keys) {
  def->technique = t;
  def->response = OBS_RESPONSE_IDENTITY;
  for (const char *const *k = keys; *k; k++) {
    json_t *v = json_object_get(params, *k);
    if (v) json_object_set_new(def->params, *k, json_deep_copy(v));
  }
}

static const char *const response_names[OBS_RESPONSE_COUNT] = {"identity", "ssao_sphere",
                                                               "ssao_hemi"};

const char *obs_response_name(obs_response r) {
  return r >= 0 && r < OBS_RESPONSE_COUNT ? response_names[r] : "?";
}

int obs_response_parse(const char *name, obs_response *out) {
  for (int i = 0; name && i < OBS_RESPONSE_COUNT; i++)
    if (!strcmp(name, response_names[i])) {
      *out = (obs_response)i;
      return 0;
    }
  return -1;
}

/* The curves of docs/techniques/ssao.md: the fraction of ssao's offset points that pass the depth
 * test, as a function of the obscurance W of a sqrt-falloff reference. */
float obs_response_map(obs_response r, float w) {
  switch (r) {
    case OBS_RESPONSE_SSAO_SPHERE: return w * w / 4.0f + w / 2.0f;
    case OBS_RESPONSE_SSAO_HEMI: {
      float v = w * w + w;
      return v < 1.0f ? v : 1.0f;
    }
    default: return w;
  }
}

static float response_slope(obs_response r, float w) {
  switch (r) {
    case OBS_RESPONSE_SSAO_SPHERE: return w / 2.0f + 0.5f;
    case OBS_RESPONSE_SSAO_HEMI: return w * w + w < 1.0f ? 2.0f * w + 1.0f : 0.0f;
    default: return 1.0f;
  }
}

int obs_response_apply(obs_response r, obs_image *img, obs_err *err) {
  if (r == OBS_RESPONSE_IDENTITY) return 0;
  float *ao = obs_image_channel(img, "ao"), *se = obs_image_channel(img, "ao_stderr");
  if (!ao) return obs_err_set(err, OBS_ENOTFOUND, "reference image has no channel \"ao\"");
  size_t n = (size_t)img->width * (size_t)img->height;
  for (size_t i = 0; i < n; i++) {
    if (se) se[i] *= fabsf(response_slope(r, ao[i]));
    ao[i] = obs_response_map(r, ao[i]);
  }
  return 0;
}
