/* Strict loading of scene documents: parse, apply overrides, validate every rule, fill obs_scene;
 * the technique block is read by the caller's hook (scene_read.h). */
#include "obscura/scene.h"

#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "json_util.h"
#include "obscura/technique.h"
#include "obscura/path.h"
#include "params.h"
#include "scene_read.h"
#include "shapes.h"

#define COORD_MAX 1e30

static char *xstrdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

static void set_vec(obs_vec3 *v, const double a[3]) {
  v->x = a[0];
  v->y = a[1];
  v->z = a[2];
}

/* ---- camera ------------------------------------------------------------------------------- */

static void load_camera(obs_jpath *p, const json_t *doc, obs_camera *cam) {
  json_t *c = obs_json_get_object(p, doc, "camera", 1, NULL);
  if (!c) return;
  size_t m = obs_jpath_push_key(p, "camera");
  static const char *const types[] = {"perspective", "orthographic", NULL};
  const char *type = NULL;
  obs_json_get_string(p, c, "type", 1, types, &type);
  int ortho = type && !strcmp(type, "orthographic");
  static const char *const keys_p[] = {"type", "position", "look_at", "up", "fov_y", NULL};
  static const char *const keys_o[] = {"type", "position", "look_at", "up", "height", NULL};
  static const char *const keys_any[] = {"type",  "position", "look_at", "up",
                                         "fov_y", "height",   NULL};
  obs_json_check_keys(p, c, !type ? keys_any : ortho ? keys_o : keys_p);
  double pos[3] = {0, 0, 0}, at[3] = {0, 0, 1}, up[3] = {0, 1, 0};
  int bad = 0;
  bad |= obs_json_get_vec3(p, c, "position", 1, -COORD_MAX, COORD_MAX, pos) < 0;
  bad |= obs_json_get_vec3(p, c, "look_at", 1, -COORD_MAX, COORD_MAX, at) < 0;
  bad |= obs_json_get_vec3(p, c, "up", 0, -COORD_MAX, COORD_MAX, up) < 0;
  cam->type = ortho ? OBS_CAMERA_ORTHOGRAPHIC : OBS_CAMERA_PERSPECTIVE;
  if (type && !ortho) obs_json_get_number(p, c, "fov_y", 1, 0, 180, 1, 1, &cam->fov_y);
  /* Orthographic ray origins spread over the view: keep them inside the ray tracer's range. */
  if (type && ortho) obs_json_get_number(p, c, "height", 1, 0, 1e18, 1, 0, &cam->height);
  set_vec(&cam->position, pos);
  set_vec(&cam->look_at, at);
  set_vec(&cam->up, up);
  if (!bad) {
    /* Normalise by the largest component first so tiny (1e-300) or huge inputs neither underflow
     * nor overflow when squared. */
    double d[3] = {at[0] - pos[0], at[1] - pos[1], at[2] - pos[2]}, u[3] = {up[0], up[1], up[2]};
    double dm = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
    double um = fmax(fabs(u[0]), fmax(fabs(u[1]), fabs(u[2])));
    for (int k = 0; k < 3; k++) {
      d[k] = dm > 0 ? d[k] / dm : 0;
      u[k] = um > 0 ? u[k] / um : 0;
    }
    double dl = dm > 0 ? sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) : 0;
    double ul = um > 0 ? sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) : 0;
    double cx = d[1] * u[2] - d[2] * u[1], cy = d[2] * u[0] - d[0] * u[2],
           cz = d[0] * u[1] - d[1] * u[0];
    double cl = sqrt(cx * cx + cy * cy + cz * cz);
    size_t mk;
    if (!(dl > 0) || !isfinite(dl)) {
      mk = obs_jpath_push_key(p, "look_at");
      obs_jpath_fail(p, "must differ from /camera/position (got %s)",
                     obs_json_brief(json_object_get(c, "look_at")));
      obs_jpath_pop(p, mk);
    } else if (!(ul > 0) || !(cl > 1e-9 * dl * ul) || !isfinite(cl)) {
      mk = obs_jpath_push_key(p, "up");
      obs_jpath_fail(
          p, "must not be zero or parallel to the view direction (got %s)",
          json_object_get(c, "up") ? obs_json_brief(json_object_get(c, "up")) : "default [0,1,0]");
      obs_jpath_pop(p, mk);
    }
  }
  obs_jpath_pop(p, m);
}

/* ---- objects ------------------------------------------------------------------------------ */

static void load_shape(obs_jpath *p, const json_t *obj, const char *base_dir, obs_object *o) {
  json_t *s = obs_json_get_object(p, obj, "shape", 1, NULL);
  if (!s) return;
  size_t m = obs_jpath_push_key(p, "shape");
  const char *types[OBS_SHAPE_COUNT + 1];
  obs_shape_kind_names(types);
  const char *type = NULL;
  if (obs_json_get_string(p, s, "type", 1, types, &type) == 0 && type) {
    for (int t = 0; t < OBS_SHAPE_COUNT; t++)
      if (!strcmp(type, types[t])) o->shape.type = (obs_shape_type)t;
    const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
    obs_json_check_keys(p, s, k->keys);
    k->parse(p, s, base_dir, &o->shape);
  }
  obs_jpath_pop(p, m);
}

/* One transform document (at the path's top) into `t`; `analytic`: the object stays a sphere. */
static void parse_transform(obs_jpath *p, const json_t *tr, int analytic, obs_transform *t) {
  static const char *const k[] = {"scale", "rotate", "translate", NULL};
  obs_json_check_keys(p, tr, k);
  double s[3] = {1, 1, 1}, r[3] = {0, 0, 0}, x[3] = {0, 0, 0};
  int bad = obs_json_get_vec3(p, tr, "scale", 0, -COORD_MAX, COORD_MAX, s) < 0;
  obs_json_get_vec3(p, tr, "rotate", 0, -1e6, 1e6, r);
  obs_json_get_vec3(p, tr, "translate", 0, -COORD_MAX, COORD_MAX, x);
  set_vec(&t->scale, s);
  set_vec(&t->rotate, r);
  set_vec(&t->translate, x);
  t->present = 1;
  /* Spheres stay analytic, so only a uniform scale keeps them spheres. */
  if (!bad && analytic && !(fabs(s[0]) == fabs(s[1]) && fabs(s[1]) == fabs(s[2]))) {
    size_t mk = obs_jpath_push_key(p, "scale");
    obs_jpath_fail(p, "must be uniform for a sphere, which stays analytic (got %s)",
                   obs_json_brief(json_object_get(tr, "scale")));
    obs_jpath_pop(p, mk);
  }
}

static void load_transform(obs_jpath *p, const json_t *obj, obs_object *o) {
  obs_transform *t = &o->transform;
  double one[3] = {1, 1, 1}, zero[3] = {0, 0, 0};
  set_vec(&t->scale, one);
  set_vec(&t->rotate, zero);
  set_vec(&t->translate, zero);
  int absent = 0;
  json_t *tr = obs_json_get_object(p, obj, "transform", 0, &absent);
  if (!tr) return;
  size_t m = obs_jpath_push_key(p, "transform");
  parse_transform(p, tr, obs_shape_is_analytic(&o->shape), t);
  obs_jpath_pop(p, m);
}

/* `motion`: the object's transform in each later frame. Rigid, so that areas, patches and the
 * scene's average reflectivity stay those of frame 0; analytic spheres do not move. */
static void load_motion(obs_jpath *p, const json_t *obj, obs_object *o) {
  int absent = 0;
  json_t *arr = obs_json_get_array(p, obj, "motion", 0, &absent);
  if (!arr) return;
  size_t m = obs_jpath_push_key(p, "motion");
  size_t n = json_array_size(arr);
  if (n < 1 || n > OBS_MOTION_MAX) {
    obs_jpath_fail(p, "must list 1 to %d transforms, one per frame after the first (got %zu)",
                   OBS_MOTION_MAX, n);
  } else if (obs_shape_is_analytic(&o->shape)) {
    obs_jpath_fail(p, "an analytic sphere cannot move (use a displaced_sphere or a mesh)");
  } else if (o->shape.type == OBS_SHAPE_VOLUME) {
    obs_jpath_fail(p, "a volume cannot move (volume techniques render one frame)");
  } else if (!(o->motion = calloc(n, sizeof *o->motion))) {
    obs_err_set(p->err, OBS_ENOMEM, "%s: out of memory", p->doc);
  } else {
    o->nmotion = n;
    for (size_t i = 0; i < n; i++) {
      size_t mi = obs_jpath_push_index(p, i);
      json_t *tr = json_array_get(arr, i);
      if (!json_is_object(tr)) {
        obs_jpath_fail(p, "must be a transform object (got %s)", obs_json_brief(tr));
      } else {
        parse_transform(p, tr, 0, &o->motion[i]);
        const obs_vec3 *a = &o->motion[i].scale, *b = &o->transform.scale;
        if (a->x != b->x || a->y != b->y || a->z != b->z) {
          size_t mk = obs_jpath_push_key(p, "scale");
          obs_jpath_fail(p, "must equal the object's transform scale [%g, %g, %g]: motion is "
                         "rigid (got %s)", b->x, b->y, b->z,
                         obs_json_brief(json_object_get(tr, "scale")));
          obs_jpath_pop(p, mk);
        }
      }
      obs_jpath_pop(p, mi);
    }
  }
  obs_jpath_pop(p, m);
}

/* Every moving object moves through the same frames. */
static void check_frames(obs_jpath *p, obs_scene *sc) {
  sc->frames = 1;
  size_t first = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_object *o = &sc->objects[i];
    if (!o->nmotion) continue;
    if (sc->frames == 1) {
      sc->frames = 1 + (int)o->nmotion;
      first = i;
    } else if ((size_t)sc->frames != 1 + o->nmotion) {
      obs_err_set(p->err, OBS_EINVAL,
                  "%s: /objects/%zu/motion: lists %zu transforms but /objects/%zu/motion lists "
                  "%d: every moving object needs one per frame",
                  p->doc, i, o->nmotion, first, sc->frames - 1);
    }
  }
}

/* Geometry beyond the renderer's range around the camera: the check every geometry build runs,
 * made here so `validate` refuses what `render` would. Needs a valid camera. */
static void check_reach(obs_jpath *p, const obs_scene *sc, size_t i) {
  const obs_object *o = &sc->objects[i];
  if (o->shape.type == OBS_SHAPE_MESH && !o->shape.mesh.path)
    return; /* not imported: already refused */
  const double eye[3] = {sc->camera.position.x, sc->camera.position.y, sc->camera.position.z};
  obs_geometry_check_reach(sc, i, NULL, eye, p->doc, p->err);
}

/* The medium presets (per millimetre): Jensen et al. 2001, Table 1, which gives the reduced
 * scattering coefficient sigma_s' = sigma_s (1 - g); with g = 0 it is sigma_s. ShaderX7 6.5 renders
 * with "the marble coefficients". */
static const struct {
  const char *name;
  obs_medium m;
} medium_presets[] = {
    {"marble", {{0.0021, 0.0041, 0.0071}, {2.19, 2.62, 3.00}, 0.0, 1.5}},
};

/* material.medium: a preset's name or {sigma_a, sigma_s, g, eta}. */
static void load_medium(obs_jpath *p, const json_t *mat, obs_object *ob) {
  const json_t *v = json_object_get(mat, "medium");
  if (!v) return;
  size_t mk = obs_jpath_push_key(p, "medium");
  if (json_is_string(v)) {
    const char *name = json_string_value(v);
    size_t n = sizeof medium_presets / sizeof medium_presets[0], i = 0;
    while (i < n && strcmp(medium_presets[i].name, name)) i++;
    if (i == n) {
      obs_jpath_fail(p, "must be a preset name (\"marble\") or an object (got \"%s\")", name);
    } else {
      ob->medium = medium_presets[i].m;
      ob->has_medium = 1;
    }
  } else if (json_is_object(v)) {
    static const char *const keys[] = {"sigma_a", "sigma_s", "g", "eta", NULL};
    int before = p->err ? p->err->count : 0;
    obs_json_check_keys(p, v, keys);
    double a[3] = {0, 0, 0}, s[3] = {0, 0, 0}, g = 0, eta = 1;
    obs_json_get_vec3(p, v, "sigma_a", 1, 0, 1e30, a);
    obs_json_get_vec3(p, v, "sigma_s", 1, 0, 1e30, s);
    obs_json_get_number(p, v, "g", 0, -0.99, 0.99, 0, 0, &g);
    obs_json_get_number(p, v, "eta", 0, 1, 3, 0, 0, &eta);
    for (int k = 0; k < 3 && (p->err ? p->err->count : 0) == before; k++)
      if (!(a[k] + s[k] > 0)) {
        obs_jpath_fail(p, "must have sigma_a + sigma_s > 0 in every channel (channel %d is 0)", k);
        break;
      }
    if ((p->err ? p->err->count : 0) == before) {
      set_vec(&ob->medium.sigma_a, a);
      set_vec(&ob->medium.sigma_s, s);
      ob->medium.g = g;
      ob->medium.eta = eta;
      ob->has_medium = 1;
    }
  } else {
    obs_jpath_fail(p, "must be a preset name (\"marble\") or an object {sigma_a, sigma_s, g, "
                   "eta} (got %s)", obs_json_brief(v));
  }
  obs_jpath_pop(p, mk);
}

static void load_objects(obs_jpath *p, const json_t *doc, const char *base_dir, obs_scene *sc,
                         int camera_ok) {
  json_t *arr = obs_json_get_array(p, doc, "objects", 1, NULL);
  if (!arr) return;
  size_t m = obs_jpath_push_key(p, "objects");
  size_t n = json_array_size(arr);
  if (n > 100000) {
    obs_jpath_fail(p, "must have at most 100000 objects (got %zu)", n);
    obs_jpath_pop(p, m);
    return;
  }
  sc->objects = calloc(n ? n : 1, sizeof *sc->objects);
  if (!sc->objects) {
    obs_err_set(p->err, OBS_ENOMEM, "%s: out of memory", p->doc);
    obs_jpath_pop(p, m);
    return;
  }
  sc->nobjects = n;
  for (size_t i = 0; i < n; i++) {
    json_t *o = json_array_get(arr, i);
    obs_object *ob = &sc->objects[i];
    size_t mi = obs_jpath_push_index(p, i);
    if (!json_is_object(o)) {
      obs_jpath_fail(p, "must be an object (got %s)", obs_json_brief(o));
      obs_jpath_pop(p, mi);
      continue;
    }
    static const char *const k[] = {"name", "shape", "material", "transform", "motion", NULL};
    obs_json_check_keys(p, o, k);
    const char *name = NULL;
    char defname[32];
    if (obs_json_get_string(p, o, "name", 0, NULL, &name) == 0 && name) {
      size_t len = 0; /* code points, as JSON Schema counts them */
      for (const unsigned char *c = (const unsigned char *)name; *c; c++)
        len += (*c & 0xC0) != 0x80;
      if (len < 1 || len > 128) {
        size_t mk = obs_jpath_push_key(p, "name");
        obs_jpath_fail(p, "must be 1 to 128 characters long (got %zu)", len);
        obs_jpath_pop(p, mk);
      }
    } else {
      snprintf(defname, sizeof defname, "object%zu", i);
      name = defname;
    }
    ob->name = xstrdup(name);
    int before = p->err ? p->err->count : 0;
    load_shape(p, o, base_dir, ob);
    load_transform(p, o, ob);
    load_motion(p, o, ob);
    if (camera_ok && (p->err ? p->err->count : 0) == before) check_reach(p, sc, i);
    int absent = 0;
    json_t *mat = obs_json_get_object(p, o, "material", 0, &absent);
    if (mat) {
      size_t mk = obs_jpath_push_key(p, "material");
      static const char *const km[] = {"reflectivity", "emission", "medium", NULL};
      obs_json_check_keys(p, mat, km);
      double r[3] = {0, 0, 0}, e[3] = {0, 0, 0};
      if (obs_json_get_vec3(p, mat, "reflectivity", 1, 0, 1, r) == 0) ob->has_material = 1;
      set_vec(&ob->reflectivity, r);
      obs_json_get_vec3(p, mat, "emission", 0, 0, COORD_MAX, e);
      set_vec(&ob->emission, e);
      load_medium(p, mat, ob);
      obs_jpath_pop(p, mk);
    }
    obs_jpath_pop(p, mi);
  }
  obs_jpath_pop(p, m);
}

/* One light's kind and placement (its emission is read by the caller). */
static void load_light(obs_jpath *p, const json_t *l, obs_light *out) {
  static const char *const types[] = {"quad", "point", "directional", NULL}; /* obs_light_type */
  static const char *const keys[][4] = {{"type", "vertices", "emission", NULL},
                                        {"type", "position", "emission", NULL},
                                        {"type", "direction", "emission", NULL}};
  const char *t = NULL;
  obs_json_get_string(p, l, "type", 1, types, &t);
  for (int i = 0; t && types[i]; i++)
    if (!strcmp(t, types[i])) out->type = (obs_light_type)i;
  obs_json_check_keys(p, l, keys[out->type]);
  if (out->type == OBS_LIGHT_QUAD) {
    /* A quad light's vertices read as a quad shape's. */
    obs_shape tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.type = OBS_SHAPE_QUAD;
    obs_shape_kind_of(OBS_SHAPE_QUAD)->parse(p, l, NULL, &tmp);
    memcpy(out->v, tmp.v, sizeof tmp.v);
  } else if (out->type == OBS_LIGHT_POINT) {
    double x[3] = {0, 0, 0};
    obs_json_get_vec3(p, l, "position", 1, -COORD_MAX, COORD_MAX, x);
    set_vec(&out->position, x);
  } else {
    double d[3] = {0, 0, -1};
    if (obs_json_get_vec3(p, l, "direction", 1, -COORD_MAX, COORD_MAX, d) == 0) {
      double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (!(n > 1e-150) || !isfinite(n)) {
        size_t m = obs_jpath_push_key(p, "direction");
        obs_jpath_fail(p, "must be a non-zero direction (got %s)",
                       obs_json_brief(json_object_get(l, "direction")));
        obs_jpath_pop(p, m);
      } else {
        for (int k = 0; k < 3; k++) d[k] /= n;
      }
    }
    set_vec(&out->direction, d);
  }
}

static void load_probes(obs_jpath *p, const json_t *doc, obs_scene *sc) {
  int absent = 0;
  json_t *arr = obs_json_get_array(p, doc, "probes", 0, &absent);
  if (!arr) return;
  size_t m = obs_jpath_push_key(p, "probes");
  size_t n = json_array_size(arr);
  sc->probes = calloc(n ? n : 1, sizeof *sc->probes);
  sc->nprobes = sc->probes ? n : 0;
  for (size_t i = 0; i < sc->nprobes; i++) {
    json_t *o = json_array_get(arr, i);
    size_t mi = obs_jpath_push_index(p, i);
    if (!json_is_object(o)) {
      obs_jpath_fail(p, "must be an object (got %s)", obs_json_brief(o));
    } else {
      static const char *const keys[] = {"position", "radius", NULL};
      obs_json_check_keys(p, o, keys);
      double x[3] = {0, 0, 0}, r = 1;
      obs_json_get_vec3(p, o, "position", 1, -COORD_MAX, COORD_MAX, x);
      obs_json_get_number(p, o, "radius", 1, 0, COORD_MAX, 1, 0, &r);
      set_vec(&sc->probes[i].position, x);
      sc->probes[i].radius = r;
    }
    obs_jpath_pop(p, mi);
  }
  obs_jpath_pop(p, m);
}

static void load_lights(obs_jpath *p, const json_t *doc, obs_scene *sc) {
  int absent = 0;
  json_t *arr = obs_json_get_array(p, doc, "lights", 0, &absent);
  if (!arr) return;
  size_t m = obs_jpath_push_key(p, "lights");
  size_t n = json_array_size(arr);
  sc->lights = calloc(n ? n : 1, sizeof *sc->lights);
  sc->nlights = sc->lights ? n : 0;
  for (size_t i = 0; i < sc->nlights; i++) {
    json_t *l = json_array_get(arr, i);
    size_t mi = obs_jpath_push_index(p, i);
    if (!json_is_object(l)) {
      obs_jpath_fail(p, "must be an object (got %s)", obs_json_brief(l));
    } else {
      load_light(p, l, &sc->lights[i]);
      double e[3] = {0, 0, 0};
      obs_json_get_vec3(p, l, "emission", 1, 0, COORD_MAX, e);
      set_vec(&sc->lights[i].emission, e);
    }
    obs_jpath_pop(p, mi);
  }
  obs_jpath_pop(p, m);
}

/* A map environment's files, resolved inside the scene's tree into sc->env.files. */
static void env_files(obs_jpath *p, const json_t *env, const char *base_dir, obs_scene *sc) {
  static const char *const exts[] = {".exr", NULL};
  char real_file[PATH_MAX], real_base[PATH_MAX];
  if (sc->env.kind == OBS_ENV_LATLONG) {
    if (obs_shape_resolve_file(p, env, "file", base_dir, exts, "an .exr", real_file, real_base))
      sc->env.files[0] = strdup(real_file);
    return;
  }
  json_t *arr = obs_json_get_array(p, env, "files", 1, NULL);
  if (!arr) return;
  size_t m = obs_jpath_push_key(p, "files");
  if (json_array_size(arr) != 6) {
    obs_jpath_fail(p, "must list the six cube faces +X, -X, +Y, -Y, +Z, -Z (got %zu files)",
                   json_array_size(arr));
  } else {
    for (size_t i = 0; i < 6; i++) {
      char key[4];
      snprintf(key, sizeof key, "%zu", i);
      json_t *wrap = json_object(); /* so the resolver's pointer ends in /files/<i> */
      json_object_set(wrap, key, json_array_get(arr, i));
      if (obs_shape_resolve_file(p, wrap, key, base_dir, exts, "an .exr", real_file, real_base))
        sc->env.files[i] = strdup(real_file);
      json_decref(wrap);
    }
  }
  obs_jpath_pop(p, m);
}

static void env_sky(obs_jpath *p, const json_t *env, obs_scene *sc) {
  /* Defaults: a blue zenith over a pale horizon and brown ground, a sun up to the side. */
  double z[3] = {0.25, 0.45, 0.9}, h[3] = {0.9, 0.9, 0.85}, g[3] = {0.25, 0.2, 0.15};
  double sd[3] = {0.5, 1, 0.3}, su[3] = {20, 18, 15}, r = 2;
  obs_json_get_vec3(p, env, "zenith", 0, 0, COORD_MAX, z);
  obs_json_get_vec3(p, env, "horizon", 0, 0, COORD_MAX, h);
  obs_json_get_vec3(p, env, "ground", 0, 0, COORD_MAX, g);
  obs_json_get_vec3(p, env, "sun", 0, 0, COORD_MAX, su);
  obs_json_get_number(p, env, "sun_radius", 0, 0, 45, 0, 0, &r);
  if (obs_json_get_vec3(p, env, "sun_direction", 0, -COORD_MAX, COORD_MAX, sd) == 0) {
    double n = sqrt(sd[0] * sd[0] + sd[1] * sd[1] + sd[2] * sd[2]);
    if (!(n > 1e-150) || !isfinite(n)) {
      size_t m = obs_jpath_push_key(p, "sun_direction");
      obs_jpath_fail(p, "must be a non-zero direction (got %s)",
                     obs_json_brief(json_object_get(env, "sun_direction")));
      obs_jpath_pop(p, m);
    }
  }
  double n = sqrt(sd[0] * sd[0] + sd[1] * sd[1] + sd[2] * sd[2]);
  for (int k = 0; k < 3 && n > 0 && isfinite(n); k++) sd[k] /= n;
  set_vec(&sc->env.zenith, z);
  set_vec(&sc->env.horizon, h);
  set_vec(&sc->env.ground, g);
  set_vec(&sc->env.sun_direction, sd);
  set_vec(&sc->env.sun, su);
  sc->env.sun_radius = r;
}

/* environment: {"color": [r, g, b]}, or a map: {"map": "latlong", "file"}, {"map": "faces",
 * "files"} or {"map": "sky", ...}, with "resolution" and "intensity". */
static void load_environment(obs_jpath *p, const json_t *doc, const char *base_dir,
                             obs_scene *sc) {
  int absent = 0;
  json_t *env = obs_json_get_object(p, doc, "environment", 0, &absent);
  if (!env) return;
  size_t m = obs_jpath_push_key(p, "environment");
  static const char *const maps[] = {"latlong", "faces", "sky", NULL}; /* obs_env_kind - 1 */
  static const char *const keys[][12] = {
      {"color", NULL},
      {"map", "file", "resolution", "intensity", NULL},
      {"map", "files", "intensity", NULL},
      {"map", "zenith", "horizon", "ground", "sun_direction", "sun", "sun_radius", "resolution",
       "intensity", NULL}};
  const char *map = NULL;
  if (json_object_get(env, "map")) obs_json_get_string(p, env, "map", 1, maps, &map);
  sc->env.kind = OBS_ENV_COLOR;
  for (int i = 0; map && maps[i]; i++)
    if (!strcmp(map, maps[i])) sc->env.kind = (obs_env_kind)(i + 1);
  obs_json_check_keys(p, env, keys[sc->env.kind]);
  sc->env.resolution = 128;
  sc->env.intensity = 1;
  long long res = 128;
  obs_json_get_int(p, env, "resolution", 0, 1, 2048, &res);
  sc->env.resolution = (int)res;
  obs_json_get_number(p, env, "intensity", 0, 0, COORD_MAX, 0, 0, &sc->env.intensity);
  sc->has_environment = 1;
  if (sc->env.kind == OBS_ENV_COLOR) {
    double c[3] = {0, 0, 0};
    if (obs_json_get_vec3(p, env, "color", 1, 0, COORD_MAX, c)) sc->has_environment = 0;
    set_vec(&sc->environment, c);
  } else if (sc->env.kind == OBS_ENV_SKY) {
    env_sky(p, env, sc);
  } else {
    env_files(p, env, base_dir, sc);
  }
  obs_jpath_pop(p, m);
}

static int validate_doc(obs_scene *sc, const json_t *doc, const char *name,
                        const char *base_dir, obs_scene_technique_fn tech, obs_err *err) {
  obs_jpath p;
  obs_jpath_init(&p, name, err);
  int before = err ? err->count : 0;
  if (!json_is_object(doc)) {
    obs_jpath_fail(&p, "the document must be a JSON object (got %s)", obs_json_brief(doc));
    return OBS_EINVAL;
  }
  static const char *const k[] = {"camera",      "image",     "objects", "lights",
                                  "probes",      "environment", "technique", NULL};
  obs_json_check_keys(&p, doc, k);
  int camera_before = err ? err->count : 0;
  load_camera(&p, doc, &sc->camera);
  int camera_ok = (err ? err->count : 0) == camera_before;
  json_t *img = obs_json_get_object(&p, doc, "image", 1, NULL);
  sc->spp = 1;
  if (img) {
    size_t m = obs_jpath_push_key(&p, "image");
    static const char *const ki[] = {"width", "height", "spp", NULL};
    obs_json_check_keys(&p, img, ki);
    long long w = 1, h = 1, spp = 1;
    obs_json_get_int(&p, img, "width", 1, 1, 16384, &w);
    obs_json_get_int(&p, img, "height", 1, 1, 16384, &h);
    obs_json_get_int(&p, img, "spp", 0, 1, 1024, &spp);
    sc->width = (int)w;
    sc->height = (int)h;
    sc->spp = (int)spp;
    obs_jpath_pop(&p, m);
  }
  load_objects(&p, doc, base_dir, sc, camera_ok);
  check_frames(&p, sc);
  load_lights(&p, doc, sc);
  load_probes(&p, doc, sc);
  load_environment(&p, doc, base_dir, sc);
  /* The technique block last: its rules run even after other problems so the list is complete;
   * they only read what loaded (objects/lights arrays may be partial). */
  tech(&p, doc, sc);
  if (err && err->count != before) return OBS_EINVAL;
  if (!sc->technique || !sc->params) return OBS_EINVAL;
  return 0;
}

/* Validation whose messages name the scene's files as the scene does (relative to its
 * directory), never by where they were found. */
static int validate(obs_scene *sc, const json_t *doc, const char *name, const char *base_dir,
                    obs_scene_technique_fn tech, obs_err *err) {
  int rc = validate_doc(sc, doc, name, base_dir, tech, err);
  if (rc) obs_path_err_relative(err, base_dir);
  return rc;
}

void obs_scene_free(obs_scene *sc) {
  if (!sc) return;
  for (size_t i = 0; i < sc->nobjects; i++) {
    free(sc->objects[i].name);
    free(sc->objects[i].motion);
    obs_shape_free(&sc->objects[i].shape);
  }
  free(sc->objects);
  free(sc->lights);
  free(sc->probes);
  for (int i = 0; i < 6; i++) free(sc->env.files[i]);
  free(sc->name);
  free(sc->base_dir);
  json_decref(sc->params);
  json_decref(sc->doc);
  memset(sc, 0, sizeof *sc);
}

int obs_scene_check_json(const json_t *doc, const char *name, const char *base_dir,
                         obs_scene_technique_fn tech, obs_err *err) {
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
  obs_err local = OBS_ERR_INIT;
  obs_jpath p;
  obs_jpath_init(&p, name, err ? err : &local);
  int rc = obs_json_check_depth(&p, doc, OBS_JSON_MAX_DEPTH);
  if (!rc) rc = validate(&sc, doc, name, base_dir, tech, err ? err : &local);
  obs_scene_free(&sc);
  obs_err_free(&local);
  return rc;
}

/* Files are the user's own but may come from anywhere: the same depth bound as requests, and no
 * bound on the number of values (the file size is bounded). */
static int parse_doc(const char *text, const char *name, json_t **out, obs_err *err) {
  static const obs_json_limits lim = {OBS_JSON_MAX_DEPTH, 0, 0};
  *out = NULL;
  if (obs_json_prescan_exact(text, strlen(text), &lim, name, err, NULL)) return OBS_EINVAL;
  json_error_t je;
  *out = json_loads(text, JSON_REJECT_DUPLICATES, &je);
  if (!*out)
    return obs_err_set(err, OBS_EINVAL, "%s: line %d, column %d: invalid JSON: %s", name, je.line,
                       je.column, je.text);
  return 0;
}

/* The overrides, each refused whole (the document keeps the ones that applied). */
static int apply_overrides(json_t *doc, const char *name, const obs_override *ov, size_t nov,
                           obs_err *err) {
  int bad = 0;
  for (size_t i = 0; i < nov; i++) {
    obs_err tmp = OBS_ERR_INIT;
    if (obs_json_pointer_set(doc, ov[i].pointer, ov[i].value, &tmp)) {
      char clip[160];
      obs_err_set(err, OBS_EINVAL, "%s: --set %s: %s", name,
                  obs_json_clip(ov[i].pointer ? ov[i].pointer : "", clip, sizeof clip),
                  obs_err_message(&tmp));
      bad = 1;
    }
    obs_err_free(&tmp);
  }
  return bad ? OBS_EINVAL : 0;
}

int obs_scene_read_json(obs_scene *sc, json_t *doc, const char *name, const char *base_dir,
                        const obs_override *ov, size_t nov, obs_scene_technique_fn tech,
                        obs_err *err) {
  memset(sc, 0, sizeof *sc);
  if (!name) name = "scene";
  if (!doc) return obs_err_set(err, OBS_EINVAL, "%s: no document", name);
  if (apply_overrides(doc, name, ov, nov, err)) return OBS_EINVAL;
  obs_jpath p;
  obs_jpath_init(&p, name, err);
  /* Validation briefs values by dumping them, which recurses: bounded first. */
  if (obs_json_check_depth(&p, doc, OBS_JSON_MAX_DEPTH)) return OBS_EINVAL;
  int rc = validate(sc, doc, name, base_dir, tech, err);
  if (rc) {
    obs_scene_free(sc);
    return rc;
  }
  sc->doc = json_incref(doc);
  sc->name = xstrdup(name);
  /* Resolved now: a later change of working directory must not move the scene's tree. */
  char real[PATH_MAX];
  sc->base_dir = base_dir ? xstrdup(realpath(base_dir, real) ? real : base_dir) : NULL;
  return 0;
}

int obs_scene_read_string(obs_scene *sc, const char *text, const char *name,
                          const char *base_dir, const obs_override *ov, size_t nov,
                          obs_scene_technique_fn tech, obs_err *err) {
  memset(sc, 0, sizeof *sc);
  if (!name) name = "scene";
  json_t *doc = NULL;
  int rc = parse_doc(text ? text : "", name, &doc, err);
  if (rc) return rc;
  rc = obs_scene_read_json(sc, doc, name, base_dir, ov, nov, tech, err);
  json_decref(doc);
  return rc;
}

int obs_scene_read_file(obs_scene *sc, const char *path, const obs_override *ov, size_t nov,
                        obs_scene_technique_fn tech, obs_err *err) {
  memset(sc, 0, sizeof *sc);
  char *buf = NULL;
  size_t len = 0;
  int rc = obs_json_read_file(path, (size_t)256 << 20, &buf, &len, err);
  if (rc) return rc;
  const char *slash = strrchr(path, '/');
  const char *base = slash ? slash + 1 : path;
  char dir[PATH_MAX];
  if (slash) {
    size_t dl = (size_t)(slash - path);
    if (dl == 0) dl = 1;
    if (dl >= sizeof dir) dl = sizeof dir - 1;
    memcpy(dir, path, dl);
    dir[dl] = '\0';
  } else {
    strcpy(dir, ".");
  }
  rc = obs_scene_read_string(sc, buf, base, dir, ov, nov, tech, err);
  free(buf);
  return rc;
}
