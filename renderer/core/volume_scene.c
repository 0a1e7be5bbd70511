/* Reading a scene's volume objects for the volume techniques (volume_scene.h). */
#include "volume_scene.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "volume_io.h"

/* Inverts the linear part a (3x3); 0 when it is singular or not finite. */
static int invert3(const double a[3][3], double inv[3][3]) {
  double c[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      c[j][i] = a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]; /* adjugate (transposed) */
    }
  double det = a[0][0] * c[0][0] + a[0][1] * c[1][0] + a[0][2] * c[2][0];
  if (!(fabs(det) > 0) || !isfinite(det)) return 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      inv[i][j] = c[i][j] / det;
      if (!isfinite(inv[i][j])) return 0;
    }
  return 1;
}

/* to_world = object transform x (data - extent / 2), and its inverse. */
static int set_maps(const obs_object *o, obs_scene_volume *sv) {
  double m[3][4], lin[3][3], inv[3][3];
  obs_geometry_transform_matrix(&o->transform, m);
  for (int i = 0; i < 3; i++) {
    double shift = 0;
    for (int j = 0; j < 3; j++) {
      lin[i][j] = m[i][j];
      shift += m[i][j] * 0.5 * o->shape.volume.extent[j];
    }
    memcpy(sv->to_world[i], m[i], sizeof m[i]);
    sv->to_world[i][3] = m[i][3] - shift;
  }
  if (!invert3(lin, inv)) return 0;
  for (int i = 0; i < 3; i++) {
    double t = 0;
    for (int j = 0; j < 3; j++) {
      sv->to_data[i][j] = inv[i][j];
      sv->normal[i][j] = inv[j][i];
      t += inv[i][j] * sv->to_world[j][3];
    }
    sv->to_data[i][3] = -t;
  }
  return 1;
}

static int read_one(const obs_object *o, obs_volume *v, obs_err *err) {
  const obs_shape *s = &o->shape;
  if (s->volume.procedural >= 0)
    return obs_volume_procedural_fill((obs_volume_procedural)s->volume.procedural, s->volume.seed,
                                      s->volume.dims, v, err);
  obs_volume_source src = {.format = (obs_volume_file)s->volume.format,
                           .path = s->volume.path,
                           .type = (obs_volume_type)s->volume.data_type};
  memcpy(src.dims, s->volume.dims, sizeof src.dims);
  memcpy(src.spacing, s->volume.spacing, sizeof src.spacing);
  memcpy(src.range, s->volume.range, sizeof src.range);
  return obs_volume_read(&src, v, err);
}

static int load_one(const obs_scene *sc, size_t oi, obs_scene_volume *sv, obs_err *err) {
  const obs_object *o = &sc->objects[oi];
  sv->object = oi;
  sv->iso = (float)o->shape.volume.isovalue;
  sv->colormap = o->shape.volume.colormap;
  sv->ncolormap = o->shape.volume.ncolormap;
  if (!set_maps(o, sv))
    return obs_err_set(err, OBS_EINVAL,
                       "%s: /objects/%zu/transform: volume \"%s\" needs an invertible transform "
                       "(no zero scale)",
                       sc->name, oi, o->name);
  obs_err e = OBS_ERR_INIT;
  int rc = read_one(o, &sv->v, &e);
  if (!rc && o->shape.volume.procedural >= 0) {
    /* A procedural fill samples [-1, 1]^3 at spacing 2 / n; a given spacing sets the aspect, as
     * the loader's extent says. */
    for (int a = 0; a < 3; a++)
      if (o->shape.volume.spacing[a] > 0) sv->v.spacing[a] = o->shape.volume.spacing[a];
  }
  if (!rc) {
    /* The box is [0, extent]: the same scale on every axis keeps the voxels' aspect. */
    double longest = 0;
    for (int a = 0; a < 3; a++) longest = fmax(longest, sv->v.n[a] * sv->v.spacing[a]);
    for (int a = 0; a < 3; a++) sv->v.spacing[a] /= longest;
    rc = obs_volume_cells_build(&sv->v, OBS_VOLUME_CELL, &sv->cells, &e);
  }
  if (rc)
    obs_err_set(err, rc, "%s: /objects/%zu/shape: volume \"%s\": %s", sc->name, oi, o->name,
                obs_err_message(&e));
  obs_err_free(&e);
  return rc;
}

int obs_scene_volumes_load(const obs_scene *sc, obs_scene_volumes *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  size_t n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) n += sc->objects[i].shape.type == OBS_SHAPE_VOLUME;
  if (!n) return 0;
  if (!(out->v = calloc(n, sizeof *out->v)))
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for %zu volumes", sc->name, n);
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (sc->objects[i].shape.type != OBS_SHAPE_VOLUME) continue;
    int rc = load_one(sc, i, &out->v[out->n], err);
    out->n++;
    if (rc) {
      obs_scene_volumes_free(out);
      return rc;
    }
  }
  return 0;
}

void obs_scene_volumes_free(obs_scene_volumes *vs) {
  for (size_t i = 0; i < vs->n; i++) {
    obs_volume_free(&vs->v[i].v);
    obs_volume_cells_free(&vs->v[i].cells);
  }
  free(vs->v);
  memset(vs, 0, sizeof *vs);
}

void obs_scene_volume_color(const obs_scene_volume *v, double value, double rgb[3]) {
  const double *c = v->colormap;
  size_t n = v->ncolormap;
  if (!n) {
    rgb[0] = rgb[1] = rgb[2] = 1;
    return;
  }
  size_t i = 0;
  while (i < n && c[4 * i] < value) i++;
  if (i == 0 || i == n) {
    const double *e = c + 4 * (i == 0 ? 0 : n - 1);
    for (int k = 0; k < 3; k++) rgb[k] = e[1 + k];
    return;
  }
  const double *a = c + 4 * (i - 1), *b = c + 4 * i;
  double t = (value - a[0]) / (b[0] - a[0]);
  for (int k = 0; k < 3; k++) rgb[k] = a[1 + k] + t * (b[1 + k] - a[1 + k]);
}
