/* The dispatcher of the techniques' reference hooks: which reference technique, with which
 * settings, defines the same quantity as a candidate, or as another technique it is compared
 * against (reference_def.c holds the definitions and their response curves). */
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
