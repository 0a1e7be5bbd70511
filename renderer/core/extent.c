/* The scene's size and translation (how precision is lost at the extremes), computed in double
 * from the loaded scene, and the one check of a render against its backend's guaranteed range. */
#include "extent.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "params.h"

static void grow(obs_extent *ex, const double p[3]) {
  for (int k = 0; k < 3; k++) {
    if (ex->empty || p[k] < ex->bounds[0][k]) ex->bounds[0][k] = p[k];
    if (ex->empty || p[k] > ex->bounds[1][k]) ex->bounds[1][k] = p[k];
  }
  ex->empty = 0;
}

/* Grows the extent by object oi's bounding points (obs_geometry_object_points; a mesh by the box
 * the loader measured when it imported the file, so nothing is imported again). */
static void grow_object(obs_extent *ex, const obs_scene *sc, size_t oi) {
  const obs_object *o = &sc->objects[oi];
  for (size_t f = 0; f <= o->nmotion; f++) { /* a moving object: where it is in every frame */
    double pts[8][3], r;
    int n = obs_geometry_object_points(o, (int)f, NULL, pts, &r);
    for (int i = 0; i < n; i++)
      for (int s = -1; s <= 1; s += 2) {
        double q[3] = {pts[i][0] + s * r, pts[i][1] + s * r, pts[i][2] + s * r};
        grow(ex, q);
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

/* One warning per parameter of `range` that lies outside its subrange, and per length that is
 * implausibly small or large for the scene (OBS_LENGTH_TINY, OBS_LENGTH_HUGE). */
const char *obs_param_range_unit(const obs_param_range *p) {
  return p->size_power > 0 ? "scene sizes" : p->size_power < 0 ? "per scene size" : "";
}

static int check_params(const obs_range *range, const char *who, const obs_scene *sc,
                        const obs_extent *ex, obs_render_ctx *ctx) {
  int n = 0;
  for (const obs_param_range *p = range->params; p->name; p++) {
    json_t *v = json_object_get(sc->params, p->name);
    if (!json_is_number(v)) continue; /* absent or null: no bound to check */
    double x = json_number_value(v), rel = x * pow(ex->size, -p->size_power);
    if (p->size_power == 1 && (rel < OBS_LENGTH_TINY || rel > OBS_LENGTH_HUGE)) {
      obs_render_ctx_warn(ctx,
                          "%s = %g is %.3g scene sizes (scene size %.4g): %s than %g scene sizes, "
                          "so the image is likely %s",
                          p->name, x, rel, ex->size, rel < OBS_LENGTH_TINY ? "less" : "more",
                          rel < OBS_LENGTH_TINY ? OBS_LENGTH_TINY : OBS_LENGTH_HUGE,
                          rel < OBS_LENGTH_TINY ? "unoccluded (white)" : "saturated");
      n++;
    }
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

int obs_range_check(const obs_range *range, const char *technique, const char *backend,
                    const obs_scene *sc, const obs_extent *ex, obs_render_ctx *ctx) {
  char who[96];
  snprintf(who, sizeof who, "%s on %s", technique, backend);
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
