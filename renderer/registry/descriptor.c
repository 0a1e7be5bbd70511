/* The registry's functions of one descriptor: its parameter schema and self-check, its cost and
 * work, the backend a moving scene runs on, the parameters it starts from on a scene (lengths
 * fitted to the scene's size), and its output files. Core reads descriptors as data; what
 * compares a descriptor with the backends or the other techniques lives here, above them. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "extent.h"
#include "json_util.h"
#include "obscura/backend.h"
#include "obscura/render.h"
#include "obscura/technique.h"
#include "params.h"

json_t *obs_technique_params_schema(const obs_technique *t) {
  json_t *props = json_object();
  for (size_t i = 0; t && i < t->params_size; i++)
    json_object_set_new(props, t->params[i].name, obs_param_schema(&t->params[i]));
  return json_pack("{sssbso}", "type", "object", "additionalProperties", 0, "properties", props);
}

double obs_technique_cost(const obs_technique *t, const json_t *params) {
  if (!t || !t->cost) return 1.0;
  void *b = NULL;
  if (obs_params_bind_new(t, params, &b, NULL)) return 1.0;
  double c = t->cost(b);
  free(b);
  return c;
}

double obs_scene_work(const obs_scene *sc) {
  const obs_technique *t = sc->technique;
  double frames = sc->frames > 1 ? sc->frames : 1;
  void *b = NULL;
  if (frames > 1 && t && t->frames_cost && !obs_params_bind_new(t, sc->params, &b, NULL))
    frames = t->frames_cost(b, sc->frames);
  free(b);
  return (double)sc->width * sc->height * sc->spp * obs_technique_cost(t, sc->params) * frames;
}

obs_backend obs_technique_motion_backend(const obs_technique *t, const obs_scene *sc,
                                         obs_backend be) {
  if (sc->frames <= 1 || (be > 0 && (t->motion_backends & (1u << be)))) return be;
  for (int b = 1; b < OBS_BACKEND_COUNT; b++)
    if ((t->motion_backends & (1u << b)) && obs_technique_has_backend(t, (obs_backend)b))
      return (obs_backend)b;
  return be;
}

int obs_technique_params_check(const obs_technique *t, obs_err *err) {
  int before = err ? err->count : 0, bad = 0;
  char doc[96];
  snprintf(doc, sizeof doc, "%s params", t->name);
  if (t->params_size && (!t->params || !t->bound_size))
    return obs_err_set(err, OBS_EINVAL, "%s: a table without a struct size", doc);
  for (size_t i = 0; i < t->params_size; i++) {
    const obs_param *d = &t->params[i];
    char why[200];
    if (!d->name || !*d->name) {
      bad = obs_err_set(err, OBS_EINVAL, "%s: entry %zu has no name", doc, i);
      continue;
    }
    for (size_t j = 0; j < i; j++)
      if (t->params[j].name && !strcmp(t->params[j].name, d->name))
        bad = obs_err_set(err, OBS_EINVAL, "%s: /%s: declared twice", doc, d->name);
    if (obs_param_entry_fault(d, t->bound_size, why, sizeof why)) {
      bad = obs_err_set(err, OBS_EINVAL, "%s: /%s: %s", doc, d->name, why);
      continue;
    }
    /* A scale-derived default is stated in scene sizes, which only a length has. */
    if (d->size_default != 0 &&
        (!(d->size_default > 0) || obs_technique_param_size_power(t, d->name) != 1))
      bad = obs_err_set(err, OBS_EINVAL,
                        "%s: /%s: size_default %g needs a positive value and a range entry with "
                        "size_power 1",
                        doc, d->name, d->size_default);
    /* A derived default lands in every backend's guaranteed range (obs_technique_defaults_for
     * rounds it toward the inside), so the render it starts from carries no range warning. */
    for (int be = 0; be < OBS_BACKEND_COUNT && d->size_default > 0; be++)
      for (const obs_param_range *r = t->range[be].params; r->name; r++)
        if (!strcmp(r->name, d->name) &&
            !(d->size_default >= r->min && d->size_default <= r->max))
          bad = obs_err_set(err, OBS_EINVAL,
                            "%s: /%s: size_default %g lies outside [%g, %g], the range %s "
                            "guarantees",
                            doc, d->name, d->size_default, r->min, r->max,
                            obs_backend_name((obs_backend)be));
    /* The default must pass the same check as a document's value. */
    char where[160];
    snprintf(where, sizeof where, "%s default", doc);
    obs_jpath p;
    obs_jpath_init(&p, where, err);
    json_t *def = obs_param_default_json(d);
    size_t m = obs_jpath_push_key(&p, d->name);
    if (d->type == OBS_PARAM_ENUM && json_is_null(def))
      bad = obs_jpath_fail(&p, "default index %g is not a choice", d->def);
    else if (obs_param_check(&p, d, def))
      bad = OBS_EINVAL;
    obs_jpath_pop(&p, m);
    json_decref(def);
  }
  if (!bad && t->cost) {
    void *b = NULL;
    if (obs_params_bind_new(t, NULL, &b, err)) return OBS_EINVAL;
    double c = t->cost(b);
    free(b);
    if (!(c > 0) || !isfinite(c))
      bad = obs_err_set(err, OBS_EINVAL,
                        "%s: the cost of the defaults is %g, not a positive "
                        "number",
                        doc, c);
  }
  return bad || (err && err->count != before) ? OBS_EINVAL : 0;
}

int obs_technique_param_size_power(const obs_technique *t, const char *name) {
  for (int be = 0; be < OBS_BACKEND_COUNT; be++)
    for (const obs_param_range *p = t->range[be].params; p->name; p++)
      if (!strcmp(p->name, name)) return p->size_power;
  return 0;
}

/* Whether a length x lies inside every declared range of parameter `name` of t for a scene of
 * size `size`, by check_params's own arithmetic (x times size^-1 against the bounds). */
static int length_in_ranges(const obs_technique *t, const char *name, double x, double size) {
  for (int be = 0; be < OBS_BACKEND_COUNT; be++)
    for (const obs_param_range *p = t->range[be].params; p->name; p++) {
      if (strcmp(p->name, name)) continue;
      double rel = x * pow(size, -p->size_power);
      if (!(rel >= p->min && rel <= p->max)) return 0;
    }
  return 1;
}

/* A length of `share` scene sizes rounded to 4 significant digits (a starting point people read
 * and edit). Where rounding to nearest leaves it outside a backend's guaranteed range of the
 * parameter (a share on a bound: obscurance_map's patch_size, 0.05 scene sizes, is Vulkan's
 * minimum, and 0.05 x 56.59 rounds to 2.829, under it), the 4-digit neighbour on the inside is
 * taken: a derived default never trips the range check. */
static double derived_length(const obs_technique *t, const char *name, double share,
                             double size) {
  char text[32];
  snprintf(text, sizeof text, "%.4g", share * size);
  double x = strtod(text, NULL);
  if (length_in_ranges(t, name, x, size)) return x;
  double unit = pow(10.0, floor(log10(fabs(x))) - 3);
  for (int s = -1; s <= 1; s += 2) {
    snprintf(text, sizeof text, "%.4g", x + s * unit);
    double y = strtod(text, NULL);
    if (length_in_ranges(t, name, y, size)) return y;
  }
  return x; /* a range narrower than the rounding: the check says so */
}

json_t *obs_technique_defaults_for(const obs_technique *t, const obs_scene *sc,
                                   const json_t *given, json_t *notes, obs_err *err) {
  json_t *out = json_object();
  if (!out) {
    obs_err_set(err, OBS_ENOMEM, "out of memory");
    return NULL;
  }
  if (sc->technique == t) {
    json_object_update(out, sc->params);
  } else {
    obs_extent ex;
    if (obs_scene_extent(sc, &ex, err)) {
      json_decref(out);
      return NULL;
    }
    for (size_t i = 0; i < t->params_size; i++) {
      const obs_param *d = &t->params[i];
      int power = obs_technique_param_size_power(t, d->name);
      if (!(d->size_default > 0) || power != 1 || ex.empty || !(ex.size > 0) ||
          json_object_get(given, d->name)) {
        json_object_set_new(out, d->name, obs_param_default_json(d));
        continue;
      }
      double x = derived_length(t, d->name, d->size_default, ex.size);
      json_object_set_new(out, d->name, json_real(x));
      if (notes) {
        json_t *def = obs_param_default_json(d);
        char *deftext = def ? json_dumps(def, JSON_ENCODE_ANY) : NULL;
        char note[320];
        snprintf(note, sizeof note,
                 "%s %s = %g derived from the scene's size: %g x %.4g (the diagonal of its "
                 "bounding box) instead of the fixed default %s",
                 t->name, d->name, x, d->size_default, ex.size, deftext ? deftext : "?");
        free(deftext);
        json_decref(def);
        json_array_append_new(notes, json_string(note));
      }
    }
  }
  if (json_is_object(given)) json_object_update(out, (json_t *)given); /* jansson reads it */
  return out;
}

const obs_output *obs_technique_primary(const obs_technique *t) {
  for (const obs_output *o = t ? t->outputs : NULL; o && o->name; o++)
    if (o->flags & OBS_OUTPUT_PRIMARY) return o;
  return NULL;
}

const char *obs_technique_stderr_name(const obs_technique *t, const char *of) {
  const char *se = NULL;
  for (const obs_output *x = t && of ? t->outputs : NULL; x && x->name; x++)
    if (x->stderr_of && !strcmp(x->stderr_of, of)) se = x->name;
  return se;
}

const obs_output *obs_technique_output(const obs_technique *t, const char *name) {
  for (const obs_output *o = t && name ? t->outputs : NULL; o && o->name; o++)
    if (!strcmp(o->name, name)) return o;
  return NULL;
}

void obs_technique_exr_name(const obs_technique *t, char *buf, size_t n) {
  const obs_output *p = obs_technique_primary(t);
  snprintf(buf, n, "%s.exr", p ? p->name : "image");
}

/* Adds `name` to `names` unless it is there already. */
static void add_file(char names[][OBS_OUTPUT_FILE_MAX], size_t max, size_t *n, const char *name) {
  for (size_t i = 0; i < *n; i++)
    if (!strcmp(names[i], name)) return;
  if (*n >= max) return;
  size_t len = strnlen(name, OBS_OUTPUT_FILE_MAX - 1);
  memcpy(names[*n], name, len);
  names[(*n)++][len] = '\0';
}

size_t obs_technique_files(const obs_technique *t, char names[][OBS_OUTPUT_FILE_MAX], size_t max) {
  size_t n = 0;
  char buf[OBS_OUTPUT_FILE_MAX];
  obs_technique_exr_name(t, buf, sizeof buf);
  add_file(names, max, &n, buf);
  for (const obs_output *o = t->outputs; o && o->name; o++) {
    if (o->png) add_file(names, max, &n, o->png);
    if (o->kind == OBS_OUTPUT_PATCH) {
      obs_output_patch_file(o, buf, sizeof buf);
      add_file(names, max, &n, buf);
    }
  }
  add_file(names, max, &n, "summary.json");
  return n;
}

size_t obs_output_file_names(char names[][OBS_OUTPUT_FILE_MAX], size_t max) {
  size_t n = 0;
  char one[16][OBS_OUTPUT_FILE_MAX];
  for (size_t i = 0; i < obs_technique_count(); i++) {
    size_t k = obs_technique_files(obs_technique_at(i), one, 16);
    for (size_t j = 0; j < k; j++) add_file(names, max, &n, one[j]);
  }
  return n;
}
