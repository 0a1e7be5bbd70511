/* Job submission: turns a POST body (an inline scene, or a bundled scene file with a technique)
 * into a fully validated job, checking the wrapper keys, the renderer's scene rules, the backend
 * and the server's per-job limits, and collecting every problem with its JSON pointer. */
#include <ctype.h>
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "geometry.h"
#include "json_util.h"
#include "obscurad.h"

#define MAX_LABEL 256
#define MAX_SETS 64

void srv_submission_free(srv_submission *s) {
  free(s->label);
  free(s->scene);
  free(s->doc);
  free(s->technique);
  free(s->backend_requested);
  memset(s, 0, sizeof *s);
}

/* A bare scene file name: no directory part, no leading dot, ends in .json. */
static int scene_name_ok(const char *n) {
  size_t len = strlen(n);
  if (len < 6 || len > 133 || strcmp(n + len - 5, ".json")) return 0;
  if (!isalnum((unsigned char)n[0]) && n[0] != '_') return 0;
  for (const char *p = n; *p; p++)
    if (!isalnum((unsigned char)*p) && *p != '_' && *p != '.' && *p != '-') return 0;
  return 1;
}

/* Reads scenes_dir/name; every way of leaving the directory (symlinks included) is refused. */
static json_t *load_bundled(srv_app *app, obs_jpath *p, const json_t *v) {
  const char *name = json_string_value(v);
  size_t m = obs_jpath_push_key(p, "scene_file");
  json_t *doc = NULL;
  char joined[PATH_MAX + 200], real[PATH_MAX];
  struct stat st;
  if (!name) {
    obs_jpath_fail(p, "must be a string (got %s)", obs_json_brief(v));
  } else if (!scene_name_ok(name)) {
    obs_jpath_fail(p, "must be the bare name of a .json file in the scenes directory, like "
                      "\"cornell_box.json\" (got %s)", obs_json_brief(v));
  } else if ((size_t)snprintf(joined, sizeof joined, "%s/%s", app->scenes_real, name) >=
                 sizeof joined ||
             !realpath(joined, real) || stat(real, &st) || !S_ISREG(st.st_mode)) {
    obs_jpath_fail(p, "no such bundled scene (got %s; GET /api/v1/scenes lists them)",
                   obs_json_brief(v));
  } else if (!srv_path_inside(app->scenes_real, real)) {
    obs_jpath_fail(p, "must stay inside the scenes directory (got %s)", obs_json_brief(v));
  } else {
    json_error_t je;
    doc = json_load_file(real, JSON_REJECT_DUPLICATES, &je);
    if (!doc)
      obs_err_set(p->err, OBS_EINVAL, "%s: line %d, column %d: invalid JSON: %s", name, je.line,
                  je.column, je.text);
  }
  obs_jpath_pop(p, m);
  return doc;
}

/* Escapes a JSON pointer for use as one reference token (RFC 6901: ~ -> ~0, / -> ~1). */
static void escape_token(const char *in, char *out, size_t n) {
  size_t k = 0;
  for (; *in && k + 3 < n; in++) {
    if (*in == '~' || *in == '/') {
      out[k++] = '~';
      out[k++] = *in == '~' ? '0' : '1';
    } else {
      out[k++] = *in;
    }
  }
  out[k] = '\0';
}

static void apply_sets(obs_jpath *p, const json_t *sets, json_t *doc) {
  const char *key;
  json_t *v;
  json_object_foreach((json_t *)sets, key, v) {
    char tok[600];
    escape_token(key, tok, sizeof tok);
    char *text = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(17));
    obs_err e = OBS_ERR_INIT;
    if (key[0] != '/')
      obs_err_set(p->err, OBS_EINVAL, "%s: /set/%s: must be a JSON pointer starting with \"/\"",
                  p->doc, tok);
    else if (!text || obs_json_pointer_set(doc, key, text, &e))
      obs_err_set(p->err, OBS_EINVAL, "%s: /set/%s: %s", p->doc, tok,
                  text ? obs_err_message(&e) : "cannot encode the value");
    obs_err_free(&e);
    free(text);
  }
}

/* Samples per pixel sample, the factor of `max-work` beyond width x height x spp. */
static double samples_of(const json_t *params) {
  long long a, b;
  if (obs_json_as_int(json_object_get(params, "samples"), &a)) return (double)a;
  if (obs_json_as_int(json_object_get(params, "directions"), &a) &&
      obs_json_as_int(json_object_get(params, "steps"), &b))
    return (double)a * (double)b;
  return 1;
}

static double triangles_of(const obs_scene *sc, obs_err *err) {
  double n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_object *o = &sc->objects[i];
    switch (o->shape) {
      case OBS_SHAPE_QUAD: n += 2; break;
      case OBS_SHAPE_TRIANGLE: n += 1; break;
      case OBS_SHAPE_BOX: n += 12; break;
      case OBS_SHAPE_DISPLACED_SPHERE: n += ldexp(1.0, 2 * o->subdivisions); break;
      case OBS_SHAPE_MESH: {
        obs_mesh m;
        char where[96];
        snprintf(where, sizeof where, "%s: /objects/%zu/shape/file", sc->name, i);
        if (obs_geometry_import_mesh(o->mesh_path, sc->base_dir, &m, err, where) == 0) {
          n += (double)m.ntris;
          obs_geometry_mesh_free(&m);
        }
        break;
      }
      default: break;
    }
  }
  return n;
}

static void check_limits(srv_app *app, const obs_scene *sc, obs_err *problems) {
  const srv_config *c = &app->cfg;
  const char *d = sc->name;
  double pixels = (double)sc->width * sc->height;
  if (pixels > (double)c->max_pixels)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /image: width x height = %.0f pixels exceeds the server's limit max-pixels "
                "= %lld",
                d, pixels, (long long)c->max_pixels);
  double samples = samples_of(sc->params);
  double work = pixels * sc->spp * samples;
  if (work > c->max_work)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /technique/params: work = width x height x spp x samples = %.0f x %d x %.0f "
                "= %.4g exceeds the server's limit max-work = %.4g",
                d, pixels, sc->spp, samples, work, c->max_work);
  double tris = triangles_of(sc, problems);
  if (tris > (double)c->max_triangles)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /objects: %.0f triangles exceed the server's limit max-triangles = %lld", d,
                tris, (long long)c->max_triangles);
}

int srv_pick_backend(const obs_technique *t, obs_backend requested, int vulkan_lane,
                     obs_backend *out, obs_err *err) {
  int rc = obs_technique_pick_backend(t, requested, out, err);
  if (rc || *out != OBS_BACKEND_VULKAN || vulkan_lane) return rc;
  if (requested == OBS_BACKEND_AUTO && obs_technique_has_backend(t, OBS_BACKEND_CPU)) {
    *out = OBS_BACKEND_CPU;
    return 0;
  }
  return obs_err_set(err, OBS_EUNSUPPORTED,
                     "this server runs no Vulkan lane (started with --no-vulkan); use \"cpu\"");
}

unsigned srv_submit_parse(srv_app *app, const char *body, size_t len, srv_submission *s,
                          const char **message, obs_err *problems) {
  memset(s, 0, sizeof *s);
  if (!body || len == 0) {
    *message = "request body is empty (send a scene document or {\"scene_file\": ...})";
    return 400;
  }
  json_error_t je;
  json_t *req = json_loadb(body, len, JSON_REJECT_DUPLICATES | JSON_DECODE_ANY, &je);
  if (!req) {
    *message = "request body is not valid JSON";
    obs_err_set(problems, OBS_EINVAL, "request: line %d, column %d: %s", je.line, je.column,
                je.text);
    return 400;
  }
  obs_jpath p;
  obs_jpath_init(&p, "request", problems);
  unsigned status = 0;
  json_t *doc = NULL;
  char *text = NULL;
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
  *message = "request is not a valid job";
  if (!json_is_object(req)) {
    obs_jpath_fail(&p, "must be a JSON object: a scene document or {\"scene_file\": ...} (got %s)",
                   obs_json_brief(req));
    status = 422;
    goto out;
  }
  long long priority = 50;
  obs_json_get_int(&p, req, "priority", 0, 0, 100, &priority);
  const char *label = NULL;
  if (obs_json_get_string(&p, req, "label", 0, NULL, &label) == 0 && label &&
      strlen(label) > MAX_LABEL) {
    size_t m = obs_jpath_push_key(&p, "label");
    obs_jpath_fail(&p, "must be at most %d bytes (got %zu)", MAX_LABEL, strlen(label));
    obs_jpath_pop(&p, m);
    label = NULL;
  }
  int absent = 0;
  json_t *sets = obs_json_get_object(&p, req, "set", 0, &absent);
  if (sets && json_object_size(sets) > MAX_SETS) {
    size_t m = obs_jpath_push_key(&p, "set");
    obs_jpath_fail(&p, "must have at most %d entries (got %zu)", MAX_SETS, json_object_size(sets));
    obs_jpath_pop(&p, m);
    sets = NULL;
  }
  const char *docname = "inline";
  json_t *file = json_object_get(req, "scene_file");
  if (file) {
    static const char *const keys[] = {"scene_file", "technique", "set", "priority", "label",
                                       NULL};
    obs_json_check_keys(&p, req, keys);
    doc = load_bundled(app, &p, file);
    if (json_is_string(file)) docname = json_string_value(file);
    json_t *tech = json_object_get(req, "technique");
    if (tech && !json_is_object(tech)) {
      size_t m = obs_jpath_push_key(&p, "technique");
      obs_jpath_fail(&p, "must be an object like {\"name\": \"rt_ao\", \"params\": {...}} (got %s)",
                     obs_json_brief(tech));
      obs_jpath_pop(&p, m);
    } else if (tech && doc && json_is_object(doc)) {
      json_object_set_new(doc, "technique", json_deep_copy(tech));
    }
  } else {
    doc = json_deep_copy(req);
    json_object_del(doc, "priority");
    json_object_del(doc, "label");
    json_object_del(doc, "set");
  }
  /* Wrapper problems do not stop here: the scene is validated too, so one answer lists all. */
  if (sets && doc) apply_sets(&p, sets, doc);
  int before = problems->count;
  text = doc ? json_dumps(doc, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
  int loaded = text && !obs_scene_load_string(&sc, text, docname, app->scenes_real, NULL, 0,
                                             problems);
  if (problems->count) {
    if (problems->count > before && before == 0) *message = "scene is not valid";
    status = 422;
    goto out;
  }
  if (!loaded) {
    *message = "out of memory";
    status = 503;
    goto out;
  }
  obs_backend be;
  obs_err e = OBS_ERR_INIT;
  if (srv_pick_backend(sc.technique, sc.backend, app->vulkan_lane, &be, &e))
    obs_err_set(problems, OBS_EINVAL, "%s: /technique/backend: %s", docname, obs_err_message(&e));
  obs_err_free(&e);
  if (problems->count) {
    *message = "backend not available";
    status = 422;
    goto out;
  }
  check_limits(app, &sc, problems);
  if (problems->count) {
    *message = "job exceeds a server limit";
    status = 422;
    goto out;
  }
  s->priority = (int)priority;
  s->label = label ? strdup(label) : NULL;
  s->scene = strdup(docname);
  s->doc = text;
  text = NULL;
  s->technique = strdup(sc.technique->name);
  s->backend_requested = strdup(obs_backend_name(sc.backend));
  s->lane = be == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU;
  s->width = sc.width;
  s->height = sc.height;
  s->spp = sc.spp;
  if (!s->scene || !s->technique || !s->backend_requested || (label && !s->label)) {
    srv_submission_free(s);
    *message = "out of memory";
    status = 503;
  }
out:
  obs_scene_free(&sc);
  free(text);
  json_decref(doc);
  json_decref(req);
  return status;
}
