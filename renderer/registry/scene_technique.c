/* The technique block of a scene document, read by the registry: the technique by name, the
 * backend among those it runs on, its params resolved against its table, and the scene held
 * against its needs (lights, materials, volumes, motion, environment maps) and its rules. The
 * public loaders pass it to core's reader (scene_read.h). */
#include <jansson.h>
#include <stdio.h>
#include <string.h>

#include "json_util.h"
#include "obscura/backend.h"
#include "obscura/scene.h"
#include "obscura/technique.h"
#include "params.h"
#include "scene_read.h"

static void load_technique(obs_jpath *p, const json_t *doc, obs_scene *sc) {
  json_t *t = obs_json_get_object(p, doc, "technique", 1, NULL);
  if (!t) return;
  size_t m = obs_jpath_push_key(p, "technique");
  static const char *const k[] = {"name", "backend", "params", NULL};
  obs_json_check_keys(p, t, k);
  const char *name = NULL;
  if (obs_json_get_string(p, t, "name", 1, NULL, &name) == 0 && name) {
    sc->technique = obs_technique_find(name);
    if (!sc->technique) {
      char list[512] = "";
      for (size_t i = 0; i < obs_technique_count(); i++) {
        size_t l = strlen(list);
        snprintf(list + l, sizeof list - l, "%s\"%s\"", l ? ", " : "", obs_technique_at(i)->name);
      }
      size_t mk = obs_jpath_push_key(p, "name");
      obs_jpath_fail(p, "must be one of %s (got \"%s\")", list, name);
      obs_jpath_pop(p, mk);
    }
  }
  const char *backends[OBS_BACKEND_COUNT + 1] = {NULL};
  for (int b = 0; b < OBS_BACKEND_COUNT; b++)
    backends[b] = obs_backend_name((obs_backend)((b + 1) % OBS_BACKEND_COUNT)); /* "auto" last */
  const char *be = NULL;
  sc->backend = OBS_BACKEND_AUTO;
  if (obs_json_get_string(p, t, "backend", 0, backends, &be) == 0 && be) {
    obs_backend_parse(be, &sc->backend);
    if (sc->technique && sc->backend != OBS_BACKEND_AUTO && !sc->technique->run[sc->backend]) {
      char list[128] = "";
      for (int b = 1; b < OBS_BACKEND_COUNT; b++) {
        if (!sc->technique->run[b]) continue;
        size_t l = strlen(list);
        snprintf(list + l, sizeof list - l, "%s\"%s\"", l ? ", " : "", obs_backend_name(b));
      }
      size_t mk = obs_jpath_push_key(p, "backend");
      obs_jpath_fail(p, "technique \"%s\" has no %s backend; available: %s, \"auto\"",
                     sc->technique->name, be, list);
      obs_jpath_pop(p, mk);
    }
  }
  if (sc->technique) {
    size_t mk = obs_jpath_push_key(p, "params");
    sc->params = obs_params_resolve(p, sc->technique, json_object_get(t, "params"));
    obs_jpath_pop(p, mk);
  }
  obs_jpath_pop(p, m);
}

/* The registered techniques with every bit of `need`, as "\"a\", \"b\"" into list. */
static const char *techniques_with(unsigned need, char *list, size_t n) {
  list[0] = '\0';
  for (size_t k = 0; k < obs_technique_count(); k++) {
    const obs_technique *m = obs_technique_at(k);
    size_t l = strlen(list);
    if ((m->needs & need) == need)
      snprintf(list + l, n - l, "%s\"%s\"", l ? ", " : "", m->name);
  }
  return list;
}

/* Every name a list-of-names parameter gives must name an object of the scene. */
static void check_names(obs_jpath *p, const obs_scene *sc) {
  const obs_technique *t = sc->technique;
  for (size_t k = 0; k < t->params_size; k++) {
    const json_t *v = json_object_get(sc->params, t->params[k].name);
    if (t->params[k].type != OBS_PARAM_NAMES || !json_is_array(v)) continue;
    for (size_t i = 0; i < json_array_size(v); i++) {
      const char *name = json_string_value(json_array_get(v, i));
      size_t j = 0;
      while (j < sc->nobjects && strcmp(sc->objects[j].name, name)) j++;
      if (j == sc->nobjects)
        obs_err_set(p->err, OBS_EINVAL,
                    "%s: /technique/params/%s/%zu: no object of the scene is named \"%s\"",
                    p->doc, t->params[k].name, i, name);
    }
  }
}

/* Feature requirements and technique-specific cross-field rules, once the basics are valid. */
static void check_needs(obs_jpath *p, const obs_scene *sc) {
  const obs_technique *t = sc->technique;
  char list[256];
  if (t->needs & OBS_NEED_LIGHTS && sc->nlights == 0)
    obs_err_set(p->err, OBS_EINVAL, "%s: /lights: technique \"%s\" needs at least one light",
                p->doc, t->name);
  for (size_t i = 0; i < sc->nlights; i++)
    if (sc->lights[i].type != OBS_LIGHT_QUAD && !(t->needs & OBS_NEED_PUNCTUAL_LIGHTS))
      obs_err_set(p->err, OBS_EINVAL,
                  "%s: /lights/%zu/type: technique \"%s\" lights with quad lights only; point "
                  "and directional lights are for shading techniques (%s)",
                  p->doc, i, t->name, techniques_with(OBS_NEED_PUNCTUAL_LIGHTS, list, sizeof list));
  if (sc->has_environment && sc->env.kind != OBS_ENV_COLOR && !(t->needs & OBS_NEED_ENV_MAP))
    obs_err_set(p->err, OBS_EINVAL,
                "%s: /environment/map: technique \"%s\" takes a constant environment "
                "(\"color\"); environment maps light %s",
                p->doc, t->name, techniques_with(OBS_NEED_ENV_MAP, list, sizeof list));
  size_t nmedium = 0;
  for (size_t i = 0; i < sc->nobjects; i++) nmedium += sc->objects[i].has_medium;
  if (t->needs & OBS_NEED_MEDIUM && nmedium == 0)
    obs_err_set(p->err, OBS_EINVAL,
                "%s: /objects: technique \"%s\" scatters light inside media, and no object of the "
                "scene has one (material.medium)",
                p->doc, t->name);
  size_t nvol = 0;
  for (size_t i = 0; i < sc->nobjects; i++) nvol += sc->objects[i].shape.type == OBS_SHAPE_VOLUME;
  if (t->needs & OBS_NEED_VOLUME && nvol == 0)
    obs_err_set(p->err, OBS_EINVAL,
                "%s: /objects: technique \"%s\" renders volumes, and the scene has none (an "
                "object with shape type \"volume\")",
                p->doc, t->name);
  /* A surface technique renders a volume as its isosurface's mesh (the geometry build's), so a
   * scene of volumes alone is one it renders. */
  if (t->needs & OBS_NEED_MATERIALS) {
    for (size_t i = 0; i < sc->nobjects; i++) {
      if (!sc->objects[i].has_material)
        obs_err_set(p->err, OBS_EINVAL,
                    "%s: /objects/%zu/material: technique \"%s\" needs a material on every object",
                    p->doc, i, t->name);
    }
  }
  if (sc->frames > 1 && !(t->needs & OBS_NEED_MOTION)) {
    techniques_with(OBS_NEED_MOTION, list, sizeof list);
    for (size_t i = 0; i < sc->nobjects; i++)
      if (sc->objects[i].nmotion)
        obs_err_set(p->err, OBS_EINVAL,
                    "%s: /objects/%zu/motion: technique \"%s\" renders one frame; moving objects "
                    "need a technique that renders frames (%s)",
                    p->doc, i, t->name, list);
  } else if (sc->frames > 1 && sc->backend != OBS_BACKEND_AUTO &&
             !(t->motion_backends & (1u << sc->backend))) {
    char list[64] = "";
    for (int b = 1; b < OBS_BACKEND_COUNT; b++) {
      size_t l = strlen(list);
      if (t->motion_backends & (1u << b))
        snprintf(list + l, sizeof list - l, "%s%s", l ? " or " : "", obs_backend_name(b));
    }
    obs_err_set(p->err, OBS_EINVAL,
                "%s: /technique/backend: moving objects (motion) render on the %s backend only",
                p->doc, list);
  }
  check_names(p, sc);
  obs_params_check_rules(t, sc->params, p->doc, p->err);
  if (t->check) t->check(sc, sc->params, p->doc, p->err);
}

/* The whole block: the technique, then its rules once it and its params loaded. */
static void technique_block(obs_jpath *p, const json_t *doc, obs_scene *sc) {
  load_technique(p, doc, sc);
  if (sc->technique && sc->params) check_needs(p, sc);
}

int obs_scene_validate_json(const json_t *doc, const char *name, const char *base_dir,
                            obs_err *err) {
  return obs_scene_check_json(doc, name, base_dir, technique_block, err);
}

int obs_scene_load_json(obs_scene *sc, json_t *doc, const char *name, const char *base_dir,
                        const obs_override *ov, size_t nov, obs_err *err) {
  return obs_scene_read_json(sc, doc, name, base_dir, ov, nov, technique_block, err);
}

int obs_scene_load_string(obs_scene *sc, const char *text, const char *name, const char *base_dir,
                          const obs_override *ov, size_t nov, obs_err *err) {
  return obs_scene_read_string(sc, text, name, base_dir, ov, nov, technique_block, err);
}

int obs_scene_load_file(obs_scene *sc, const char *path, const obs_override *ov, size_t nov,
                        obs_err *err) {
  return obs_scene_read_file(sc, path, ov, nov, technique_block, err);
}
