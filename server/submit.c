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
#include "shapes.h"
#include "obscurad.h"

/* Whether jansson refused a document for a number it cannot hold (its texts in jansson 2.x). */
static int number_range_error(const json_error_t *je) {
  return strstr(je->text, "overflow") || strstr(je->text, "too big");
}

#define MAX_LABEL 256
#define MAX_SETS 64

void srv_submission_free(srv_submission *s) {
  free(s->label);
  free(s->scene_name);
  free(s->scene);
  free(s->doc);
  free(s->technique);
  free(s->backend_requested);
  free(s->backend_reason);
  json_decref(s->choice);
  json_decref(s->notes);
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
json_t *srv_submit_get_sets(obs_jpath *p, const json_t *req) {
  int absent = 0;
  json_t *sets = obs_json_get_object(p, req, "set", 0, &absent);
  if (sets && json_object_size(sets) > MAX_SETS) {
    size_t m = obs_jpath_push_key(p, "set");
    obs_jpath_fail(p, "must have at most %d entries (got %zu)", MAX_SETS, json_object_size(sets));
    obs_jpath_pop(p, m);
    sets = NULL;
  }
  return sets;
}

json_t *srv_submit_load_bundled(srv_app *app, obs_jpath *p, const json_t *v) {
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
  } else if (!obs_path_is_inside(app->scenes_real, real)) {
    obs_jpath_fail(p, "must stay inside the scenes directory (got %s)", obs_json_brief(v));
  } else {
    /* The scenes directory is the operator's, but its files are held to the same depth bound as
     * requests: a document deeper than that could not be submitted anyway. */
    static const obs_json_limits lim = {OBS_JSON_MAX_DEPTH, 0, 0};
    char *text = NULL;
    size_t len = 0;
    if (!obs_json_read_file(real, (size_t)64 << 20, &text, &len, p->err) &&
        !obs_json_prescan(text, len, &lim, name, p->err, NULL)) {
      json_error_t je;
      doc = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
      if (!doc && !(number_range_error(&je) &&
                    obs_json_prescan_strict(text, len, &lim, name, p->err, NULL)))
        obs_err_set(p->err, OBS_EINVAL, "%s: line %d, column %d: invalid JSON: %s", name, je.line,
                    je.column, je.text);
      /* Parsed: a number jansson stored as another value (1e-99999 as 0) is refused too. */
      if (doc && obs_json_prescan_exact(text, len, &lim, name, p->err, NULL)) {
        json_decref(doc);
        doc = NULL;
      }
    }
    free(text);
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

void srv_submit_apply_sets(obs_jpath *p, const json_t *sets, json_t *doc) {
  const char *key;
  json_t *v;
  json_object_foreach((json_t *)sets, key, v) {
    char tok[600], buf[164];
    escape_token(key, tok, sizeof tok);
    const char *clip = obs_json_clip(tok, buf, sizeof buf);
    obs_err e = OBS_ERR_INIT;
    /* A copy: a later pointer may go through this value, which must not change the request. The
     * request passed the depth pre-scan, so the copy's recursion is bounded. */
    json_t *val = json_deep_copy(v);
    if (key[0] != '/')
      obs_err_set(p->err, OBS_EINVAL, "%s: /set/%s: must be a JSON pointer starting with \"/\"",
                  p->doc, clip);
    else if (!val || obs_json_pointer_put(doc, key, json_incref(val), &e))
      obs_err_set(p->err, OBS_EINVAL, "%s: /set/%s: %s", p->doc, clip,
                  val ? obs_err_message(&e) : "out of memory");
    json_decref(val);
    obs_err_free(&e);
  }
}

unsigned srv_submit_read_body(const char *body, size_t len, const char *shape, json_t **out,
                              const char **message, obs_err *problems) {
  static const obs_json_limits lim = {OBS_JSON_MAX_DEPTH, SRV_MAX_REQUEST_VALUES,
                                      SRV_MAX_REQUEST_STRING};
  *out = NULL;
  /* Before jansson: a parsed value costs ~20x its text, and deep documents recurse when dumped,
   * copied or freed. */
  if (obs_json_prescan(body, len, &lim, "request", problems, NULL)) {
    *message = "request exceeds the server's input limits";
    return 422;
  }
  json_error_t je;
  json_t *req = json_loadb(body, len, JSON_REJECT_DUPLICATES | JSON_DECODE_ANY, &je);
  /* jansson names an out-of-range number by line and column only; the strict walk, run only when
   * that is jansson's reason (a syntax error elsewhere must be reported as one), names it by its
   * pointer. */
  if (!req && number_range_error(&je) &&
      obs_json_prescan_strict(body, len, &lim, "request", problems, NULL)) {
    *message = "request has a number outside what a double or a 64-bit integer holds";
    return 422;
  }
  /* Only once it parsed (a syntax error is reported as one): numbers that jansson stored as
   * another value than the text says, 1e-99999 as 0 or 9007199254740993 as 9007199254740992. */
  if (req && obs_json_prescan_exact(body, len, &lim, "request", problems, NULL)) {
    json_decref(req);
    *message = "request has a number that a double would hold as another value";
    return 422;
  }
  if (!req) {
    *message = "request body is not valid JSON";
    obs_err_set(problems, OBS_EINVAL, "request: line %d, column %d: %s", je.line, je.column,
                je.text);
    return 400;
  }
  if (!json_is_object(req)) {
    obs_err_set(problems, OBS_EINVAL, "request: /: must be a JSON object: %s (got %s)", shape,
                obs_json_brief(req));
    json_decref(req);
    return 422;
  }
  *out = req;
  return 0;
}

static double triangles_of(const obs_scene *sc, obs_err *err) {
  double n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_shape *s = &sc->objects[i].shape;
    /* A volume technique reads samples (srv_scene_voxels), never a volume's mesh. */
    if (s->type == OBS_SHAPE_VOLUME && sc->technique->needs & OBS_NEED_VOLUME) continue;
    char where[256];
    snprintf(where, sizeof where, "%s: /objects/%zu/shape/file", sc->name, i);
    n += obs_shape_kind_of(s->type)->triangles(s, sc->base_dir, err, where);
  }
  return n;
}

double srv_scene_voxels(const obs_scene *sc) {
  if (!(sc->technique->needs & OBS_NEED_VOLUME)) return 0;
  double n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_shape *s = &sc->objects[i].shape;
    if (s->type == OBS_SHAPE_VOLUME)
      n += (double)s->volume.dims[0] * s->volume.dims[1] * s->volume.dims[2];
  }
  return n;
}

/* A per-process amount (pixels, triangles, volume samples) that fits its limit alone but not as
 * many times as renderer processes of the job run on this machine: each MPI rank loads the scene,
 * builds its own BVH and volumes and holds a whole image. */
static void check_ranks_hold(int ranks, double amount, const char *what, int64_t limit,
                             const char *option, obs_err *problems) {
  if (ranks > 1 && amount <= (double)limit && amount * ranks > (double)limit)
    obs_err_set(problems, OBS_EINVAL,
                "request: /ranks: %d ranks on this machine each hold the scene's %.0f %s, %.0f in "
                "all, beyond the server's limit %s = %lld",
                ranks, amount, what, amount * ranks, option, (long long)limit);
}

void srv_submit_check_limits(srv_app *app, const obs_scene *sc, int ranks, obs_err *problems) {
  const srv_config *c = &app->cfg;
  const char *d = sc->name;
  /* Without a hostfile every rank runs here; with one, mpirun places them. */
  int here = c->hostfile ? 1 : ranks;
  double pixels = (double)sc->width * sc->height;
  if (pixels > (double)c->max_pixels)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /image: width x height = %.0f pixels exceeds the server's limit max-pixels "
                "= %lld",
                d, pixels, (long long)c->max_pixels);
  check_ranks_hold(here, pixels, "pixels", c->max_pixels, "max-pixels", problems);
  double samples = obs_technique_cost(sc->technique, sc->params);
  double work = obs_scene_work(sc);
  /* A moving scene: the frames' cost in whole maps (the technique's frames_cost). */
  char frames[80] = "";
  double per = pixels * sc->spp * samples;
  if (sc->frames > 1 && per > 0)
    snprintf(frames, sizeof frames, " x %.6g (%d frames)", work / per, sc->frames);
  if (work > c->max_work)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /technique/params: work = width x height x spp x samples%s = %.0f x %d x "
                "%.0f%s = %.4g exceeds the server's limit max-work = %.4g",
                d, sc->frames > 1 ? " x frames" : "", pixels, sc->spp, samples, frames, work,
                c->max_work);
  double tris = triangles_of(sc, problems);
  if (tris > (double)c->max_triangles)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /objects: %.0f triangles exceed the server's limit max-triangles = %lld", d,
                tris, (long long)c->max_triangles);
  check_ranks_hold(here, tris, "triangles", c->max_triangles, "max-triangles", problems);
  double voxels = srv_scene_voxels(sc);
  if (voxels > (double)c->max_voxels)
    obs_err_set(problems, OBS_EINVAL,
                "%s: /objects: %.0f volume samples exceed the server's limit max-voxels = %lld", d,
                voxels, (long long)c->max_voxels);
  check_ranks_hold(here, voxels, "volume samples", c->max_voxels, "max-voxels", problems);
  if (work <= c->max_work) srv_submit_check_estimate(app, sc, problems);
}

void srv_submit_set_technique(srv_app *app, json_t *doc, const char *docname,
                              const json_t *tech, json_t *notes) {
  json_t *mine = json_object_get(doc, "technique");
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(tech, "name")));
  json_t *given = json_object_get(tech, "params");
  json_t *out = json_deep_copy(tech);
  if (!out) return;
  /* An unknown technique or a params member that is not an object: the scene's validation
   * names the fault, so the request's technique goes in as it is. */
  if (t && (!given || json_is_object(given)) && json_is_object(mine)) {
    /* The scene as it is, to know its params and its size. */
    json_t *copy = json_deep_copy(doc);
    obs_scene sc;
    memset(&sc, 0, sizeof sc);
    obs_err e = OBS_ERR_INIT;
    if (copy && !obs_scene_load_json(&sc, copy, docname, app->scenes_real, NULL, 0, &e)) {
      json_t *params = obs_technique_defaults_for(t, &sc, given, notes, &e);
      if (params) json_object_set_new(out, "params", params);
    }
    obs_scene_free(&sc);
    obs_err_free(&e);
    json_decref(copy);
  }
  json_object_set_new(doc, "technique", out);
}

unsigned srv_submit_parse(srv_app *app, const char *body, size_t len, srv_submission *s,
                          const char **message, obs_err *problems) {
  memset(s, 0, sizeof *s);
  if (!body || len == 0) {
    *message = "request body is empty (send a scene document or {\"scene_file\": ...})";
    return 400;
  }
  *message = "request is not a valid job";
  json_t *req = NULL;
  unsigned status = srv_submit_read_body(body, len, "a scene document or {\"scene_file\": ...}",
                                         &req, message, problems);
  if (status) return status;
  obs_jpath p;
  obs_jpath_init(&p, "request", problems);
  json_t *doc = NULL;
  char *text = NULL;
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
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
  /* An inline scene's name: the file it came from (the CLI and the form send it). */
  const char *scene_name = NULL;
  if (obs_json_get_string(&p, req, "scene_name", 0, NULL, &scene_name) == 0 && scene_name &&
      (strlen(scene_name) > MAX_LABEL || !scene_name[0])) {
    size_t m = obs_jpath_push_key(&p, "scene_name");
    obs_jpath_fail(&p, "must be 1 to %d bytes (got %zu)", MAX_LABEL, strlen(scene_name));
    obs_jpath_pop(&p, m);
    scene_name = NULL;
  }
  /* Open MPI ranks (mpi_jobs.c): checked against the daemon and the scene once it is loaded. */
  long long ranks = 1;
  obs_json_get_int(&p, req, "ranks", 0, 1, SRV_MAX_RANKS, &ranks);
  json_t *sets = srv_submit_get_sets(&p, req);
  const char *docname = "inline";
  json_t *file = json_object_get(req, "scene_file");
  int budget_mode = 0;
  double budget_ms = 0;
  if (file) {
    static const char *const keys[] = {"scene_file", "technique", "set", "priority", "label",
                                       "time_budget_ms", "ranks", NULL};
    obs_json_check_keys(&p, req, keys);
    doc = srv_submit_load_bundled(app, &p, file);
    if (json_is_string(file)) docname = json_string_value(file);
    json_t *tech = json_object_get(req, "technique");
    json_t *budget = json_object_get(req, "time_budget_ms");
    /* Time-budget mode: {"technique": "auto", "time_budget_ms": B} picks the configuration. */
    budget_mode = json_is_string(tech) && !strcmp(json_string_value(tech), "auto");
    if (budget_mode) {
      if (obs_json_get_number(&p, req, "time_budget_ms", 1, 0, 1e9, 1, 0, &budget_ms))
        budget_mode = 0;
    } else if (budget) {
      size_t m = obs_jpath_push_key(&p, "time_budget_ms");
      obs_jpath_fail(&p, "only allowed with \"technique\": \"auto\" (got technique %s)",
                     tech ? obs_json_brief(tech) : "absent");
      obs_jpath_pop(&p, m);
    }
    if (budget_mode || (json_is_string(tech) && !strcmp(json_string_value(tech), "auto"))) {
      /* chosen below, once the overrides are applied */
    } else if (tech && !json_is_object(tech)) {
      size_t m = obs_jpath_push_key(&p, "technique");
      obs_jpath_fail(&p, "must be an object like {\"name\": \"rt_ao\", \"params\": {...}}, or "
                         "\"auto\" with time_budget_ms (got %s)",
                     obs_json_brief(tech));
      obs_jpath_pop(&p, m);
    } else if (tech && doc && json_is_object(doc)) {
      s->notes = json_array();
      srv_submit_set_technique(app, doc, docname, tech, s->notes);
    }
  } else {
    /* The wrapper keys removed from a shallow copy: the scene's values are shared, not copied
     * (overrides may change them in place; the request is not read again). */
    doc = json_copy(req);
    json_object_del(doc, "priority");
    json_object_del(doc, "label");
    json_object_del(doc, "set");
    json_object_del(doc, "scene_name");
    json_object_del(doc, "ranks");
  }
  /* Wrapper problems do not stop here: the scene is validated too, so one answer lists all. */
  if (sets && doc) srv_submit_apply_sets(&p, sets, doc);
  if (budget_mode && doc && json_is_object(doc) && !problems->count) {
    json_t *img = json_object_get(doc, "image");
    long long w = 0, h = 0, spp = 1;
    obs_json_as_int(json_object_get(img, "width"), &w);
    obs_json_as_int(json_object_get(img, "height"), &h);
    if (json_object_get(img, "spp")) obs_json_as_int(json_object_get(img, "spp"), &spp);
    json_t *choice = NULL;
    if (srv_compare_budget_choice(app, docname, (double)w * (double)h * (double)spp, budget_ms,
                                  &choice, problems)) {
      *message = "no measured configuration fits the time budget";
      status = 422;
      goto out;
    }
    json_object_set_new(doc, "technique",
                        json_pack("{s:O, s:O, s:O}", "name", json_object_get(choice, "technique"),
                                  "backend", json_object_get(choice, "backend"), "params",
                                  json_object_get(choice, "params")));
    s->choice = choice;
  }
  int before = problems->count;
  int loaded = doc && !obs_scene_load_json(&sc, doc, docname, app->scenes_real, NULL, 0,
                                           problems);
  if (problems->count) {
    if (problems->count > before && before == 0) *message = "scene is not valid";
    status = 422;
    goto out;
  }
  /* Stored as the renderer will read it back (obs_scene_load_string at render time). */
  text = loaded ? json_dumps(sc.doc, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
  if (!text) {
    *message = "out of memory";
    status = 503;
    goto out;
  }
  obs_backend be;
  obs_err e = OBS_ERR_INIT;
  char reason[512];
  double work = obs_scene_work(&sc);
  if (srv_pick_backend_learned(app, sc.technique, sc.backend, work, &be, reason, sizeof reason,
                               &e))
    obs_err_set(problems, OBS_EINVAL, "%s: /technique/backend: %s", docname, obs_err_message(&e));
  obs_backend mb = problems->count ? be : obs_technique_motion_backend(sc.technique, &sc, be);
  if (mb != be) { /* timings of still scenes may favour a backend that renders no frames */
    snprintf(reason, sizeof reason, "moving objects: %s renders frames on %s", sc.technique->name,
             obs_backend_name(mb));
    be = mb;
  }
  obs_err_free(&e);
  if (problems->count) {
    *message = "backend not available";
    status = 422;
    goto out;
  }
  /* Both lists in one answer: what keeps the daemon from running ranks, and the limits every
   * rank's process counts against. */
  int no_mpi = ranks > 1 && srv_mpi_check(app, &sc, be, (int)ranks, problems);
  srv_submit_check_limits(app, &sc, (int)ranks, problems);
  if (no_mpi) {
    *message = "job cannot run on Open MPI ranks";
    status = 422;
    goto out;
  }
  if (problems->count) {
    *message = "job exceeds a server limit";
    status = 422;
    goto out;
  }
  s->priority = (int)priority;
  s->ranks = (int)ranks;
  s->label = label ? strdup(label) : NULL;
  s->scene = strdup(docname);
  s->scene_name = scene_name && !file ? strdup(scene_name) : NULL;
  s->doc = text;
  text = NULL;
  s->technique = strdup(sc.technique->name);
  s->backend_requested = strdup(obs_backend_name(sc.backend));
  s->lane = be == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU;
  s->width = sc.width;
  s->height = sc.height;
  s->spp = sc.spp;
  s->work = work;
  /* A time-budget job says why this configuration; any other job why this backend. */
  s->backend_reason = strdup(s->choice ? json_string_value(json_object_get(s->choice, "reason"))
                                       : reason);
  if (!s->scene || !s->technique || !s->backend_requested || (label && !s->label) ||
      (scene_name && !file && !s->scene_name) ||
      !s->backend_reason) {
    srv_submission_free(s);
    *message = "out of memory";
    status = 503;
  }
out:
  if (status) srv_submission_free(s);
  obs_scene_free(&sc);
  free(text);
  json_decref(doc);
  json_decref(req);
  return status;
}
