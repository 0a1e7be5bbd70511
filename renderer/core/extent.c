/* The scene's size and translation (how precision is lost at the extremes), computed in double
 * from the loaded scene, and the one check of a render against its backend's guaranteed range. */
#include "extent.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "geometry.h"

#define PI 3.14159265358979323846

/* The object transform as geometry.c applies it: translate * Rz * Ry * Rx * scale, in double. */
static void transform_point(const obs_transform *t, const double p[3], double o[3]) {
  double q[3] = {p[0] * t->scale.x, p[1] * t->scale.y, p[2] * t->scale.z};
  double a[3] = {t->rotate.x * PI / 180, t->rotate.y * PI / 180, t->rotate.z * PI / 180};
  double c, s, u, v;
  c = cos(a[0]), s = sin(a[0]); /* about X */
  u = c * q[1] - s * q[2], v = s * q[1] + c * q[2];
  q[1] = u, q[2] = v;
  c = cos(a[1]), s = sin(a[1]); /* about Y */
  u = c * q[0] + s * q[2], v = -s * q[0] + c * q[2];
  q[0] = u, q[2] = v;
  c = cos(a[2]), s = sin(a[2]); /* about Z */
  u = c * q[0] - s * q[1], v = s * q[0] + c * q[1];
  q[0] = u, q[1] = v;
  o[0] = q[0] + t->translate.x;
  o[1] = q[1] + t->translate.y;
  o[2] = q[2] + t->translate.z;
}

static void grow(obs_extent *ex, const double p[3]) {
  for (int k = 0; k < 3; k++) {
    if (ex->empty || p[k] < ex->bounds[0][k]) ex->bounds[0][k] = p[k];
    if (ex->empty || p[k] > ex->bounds[1][k]) ex->bounds[1][k] = p[k];
  }
  ex->empty = 0;
}

/* Grows the extent by the 8 transformed corners of the object-space box lo..hi. */
static void grow_box(obs_extent *ex, const obs_transform *t, const double lo[3],
                     const double hi[3]) {
  for (int c = 0; c < 8; c++) {
    double p[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]}, o[3];
    transform_point(t, p, o);
    grow(ex, o);
  }
}

static void grow_object(obs_extent *ex, const obs_scene *sc, size_t oi) {
  const obs_object *o = &sc->objects[oi];
  double p[3], w[3];
  switch (o->shape) {
    case OBS_SHAPE_QUAD:
    case OBS_SHAPE_TRIANGLE:
      for (int i = 0; i < (o->shape == OBS_SHAPE_QUAD ? 4 : 3); i++) {
        p[0] = o->v[i].x, p[1] = o->v[i].y, p[2] = o->v[i].z;
        transform_point(&o->transform, p, w);
        grow(ex, w);
      }
      return;
    case OBS_SHAPE_BOX: {
      double lo[3] = {o->v[0].x, o->v[0].y, o->v[0].z}, hi[3] = {o->v[1].x, o->v[1].y, o->v[1].z};
      grow_box(ex, &o->transform, lo, hi);
      return;
    }
    case OBS_SHAPE_SPHERE: {
      /* Uniform scale only (the loader insists), so the transformed sphere stays a sphere. */
      p[0] = o->v[0].x, p[1] = o->v[0].y, p[2] = o->v[0].z;
      transform_point(&o->transform, p, w);
      double r = o->radius * fabs(o->transform.scale.x);
      for (int k = 0; k < 2; k++) {
        double q[3] = {w[0] + (k ? r : -r), w[1] + (k ? r : -r), w[2] + (k ? r : -r)};
        grow(ex, q);
      }
      return;
    }
    case OBS_SHAPE_DISPLACED_SPHERE: {
      /* Radius 1 + 0.15 + 0.05 at most (obs_geometry_displaced_sphere's displacement). */
      static const double lo[3] = {-1.2, -1.2, -1.2}, hi[3] = {1.2, 1.2, 1.2};
      grow_box(ex, &o->transform, lo, hi);
      return;
    }
    case OBS_SHAPE_MESH: {
      /* The object-space box the loader measured when it imported the file: importing it again
       * here would cost a second import per render. */
      grow_box(ex, &o->transform, o->mesh_bounds[0], o->mesh_bounds[1]);
      return;
    }
  }
}

int obs_scene_extent(const obs_scene *sc, obs_extent *ex, obs_err *err) {
  (void)err; /* no shape can fail today; a shape read from a file later may */
  memset(ex, 0, sizeof *ex);
  ex->empty = 1;
  for (size_t i = 0; i < sc->nobjects; i++) grow_object(ex, sc, i);
  if (ex->empty) return 0;
  double d2 = 0, c2 = 0;
  for (int k = 0; k < 3; k++) {
    /* Halves first: the diagonal of a box near the double range must not overflow. */
    double h = 0.5 * ex->bounds[1][k] - 0.5 * ex->bounds[0][k];
    double c = 0.5 * ex->bounds[1][k] + 0.5 * ex->bounds[0][k];
    d2 += h * h;
    c2 += c * c;
  }
  ex->size = 2 * sqrt(d2);
  const obs_vec3 *cam = &sc->camera.position;
  ex->distance = fmax(sqrt(c2), sqrt(cam->x * cam->x + cam->y * cam->y + cam->z * cam->z));
  ex->translation = ex->size > 0 ? ex->distance / ex->size : ex->distance > 0 ? INFINITY : 0;
  return 0;
}

/* One warning per parameter of `range` that lies outside its subrange. */
static int check_params(const obs_range *range, const char *who, const obs_scene *sc,
                        const obs_extent *ex, obs_render_ctx *ctx) {
  int n = 0;
  for (const obs_param_range *p = range->params; p->name; p++) {
    json_t *v = json_object_get(sc->params, p->name);
    if (!json_is_number(v)) continue; /* absent or null: no bound to check */
    double x = json_number_value(v), rel = x * pow(ex->size, -p->size_power);
    if (rel >= p->min && rel <= p->max) continue;
    const char *unit = obs_param_range_unit(p);
    obs_render_ctx_warn(ctx,
                        "%s = %g is %.3g %s, outside [%g, %g] %s where %s is guaranteed "
                        "(docs/accuracy.md, Guaranteed ranges)",
                        p->name, x, rel, unit, p->min, p->max, unit, who);
    n++;
  }
  return n;
}

int obs_range_check(const obs_range *range, const char *technique, obs_backend backend,
                    const obs_scene *sc, const obs_extent *ex, obs_render_ctx *ctx) {
  char who[96];
  snprintf(who, sizeof who, "%s on %s", technique, obs_backend_name(backend));
  if (!(range->size_max > 0)) {
    obs_render_ctx_warn(ctx, "%s declares no guaranteed range (docs/accuracy.md)", who);
    return 1;
  }
  int n = 0;
  const obs_camera *cam = &sc->camera;
  if (cam->type == OBS_CAMERA_PERSPECTIVE &&
      !(cam->fov_y >= range->fov_min && cam->fov_y <= range->fov_max)) {
    obs_render_ctx_warn(ctx,
                        "camera fov_y %g degrees is outside [%g, %g] degrees where %s is "
                        "guaranteed (docs/accuracy.md, Guaranteed ranges)",
                        cam->fov_y, range->fov_min, range->fov_max, who);
    n++;
  }
  if (cam->type == OBS_CAMERA_ORTHOGRAPHIC && !range->orthographic) {
    obs_render_ctx_warn(ctx, "orthographic camera: %s is guaranteed for perspective cameras only",
                        who);
    n++;
  }
  if (ex->empty) return n; /* nothing to draw: no size to hold */
  if (!(ex->size >= range->size_min && ex->size <= range->size_max)) {
    obs_render_ctx_warn(ctx,
                        "scene size %.3g (diagonal of the geometry's bounding box) is outside "
                        "[%g, %g] where %s is guaranteed (docs/accuracy.md, Guaranteed ranges)",
                        ex->size, range->size_min, range->size_max, who);
    n++;
  }
  if (!(ex->translation <= range->translation_max)) {
    obs_render_ctx_warn(ctx,
                        "scene translation %.3g scene sizes (camera or bounds centre %.3g from "
                        "the world origin) is beyond %g where %s is guaranteed "
                        "(docs/accuracy.md, Guaranteed ranges)",
                        ex->translation, ex->distance, range->translation_max, who);
    n++;
  }
  if (ex->size > 0) n += check_params(range, who, sc, ex, ctx);
  return n;
}
