/* Reading a scene's volume objects for the volume techniques, whole or one brick of each for a
 * data-parallel render (volume_scene.h). */
#include "volume_scene.h"

#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include "geometry.h"
#include "volume_io.h"

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
  if (!obs_geometry_invert3(lin, inv)) return 0;
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

/* The part of a volume of full_n voxels that a brick keeps: the owned voxels [lo, hi) and the
 * kept ones [k0, k1) (with the ghost zone) along `axis`. */
typedef struct keep {
  int axis, lo, hi, k0, k1;
} keep;

/* The kept part of a volume of full_n voxels: its first voxel `o` and its size `n`. */
static void kept_part(const int full_n[3], const keep *kp, int n[3], int o[3]) {
  for (int a = 0; a < 3; a++) n[a] = full_n[a], o[a] = 0;
  n[kp->axis] = kp->k1 - kp->k0;
  o[kp->axis] = kp->k0;
}

/* A volume of the kept voxels of `full`, voxel for voxel (the data array is copied). */
static int crop(const obs_volume *full, const keep *kp, obs_volume *v, obs_err *err) {
  int n[3], o[3];
  kept_part(full->n, kp, n, o);
  int rc = obs_volume_init(v, n, full->spacing, err);
  if (rc) return rc;
  for (int k = 0; k < n[2]; k++)
    for (int j = 0; j < n[1]; j++)
      memcpy(v->data + ((size_t)k * (size_t)n[1] + (size_t)j) * (size_t)n[0],
             &full->data[((size_t)(k + o[2]) * (size_t)full->n[1] + (size_t)(j + o[1])) *
                             (size_t)full->n[0] +
                         (size_t)o[0]],
             (size_t)n[0] * sizeof *v->data);
  return 0;
}

/* The kept voxels of a procedural volume of full_n voxels, each computed exactly as the whole
 * volume's fill computes it, so a brick's samples are its bits. */
static int procedural_brick(const obs_shape *s, const keep *kp, obs_volume *v, obs_err *err) {
  int n[3], o[3];
  kept_part(s->volume.dims, kp, n, o);
  return obs_volume_procedural_fill_part((obs_volume_procedural)s->volume.procedural,
                                         s->volume.seed, s->volume.dims, o, n, v, err);
}

/* The largest singular value of a (power iteration on a^T a from each axis; a bound on how much
 * a stretches any direction). */
static double norm2(const double a[3][3]) {
  double best = 0;
  for (int s = 0; s < 3; s++) {
    double x[3] = {s == 0, s == 1, s == 2}, l = 0;
    for (int it = 0; it < 40; it++) {
      double y[3], z[3];
      for (int i = 0; i < 3; i++) y[i] = a[i][0] * x[0] + a[i][1] * x[1] + a[i][2] * x[2];
      for (int i = 0; i < 3; i++) z[i] = a[0][i] * y[0] + a[1][i] * y[1] + a[2][i] * y[2];
      l = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
      if (!(l > 0)) break;
      for (int i = 0; i < 3; i++) x[i] = z[i] / l;
    }
    best = fmax(best, sqrt(l));
  }
  return best;
}

/* The AO reach in volume k's data units: a march of `reach` in any volume's data space (the
 * marcher carries it through world space into the others) goes at most this far in k's. */
static double reach_in(const obs_scene_volumes *vs, size_t k, double reach) {
  double lk[3][3], best = 1;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) lk[i][j] = vs->v[k].to_data[i][j];
  double to_k = norm2(lk);
  for (size_t a = 0; a < vs->n; a++) {
    if (a == k) continue;
    double la[3][3];
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) la[i][j] = vs->v[a].to_world[i][j];
    best = fmax(best, norm2(la) * to_k);
  }
  return reach * best;
}

/* The brick's slab of a volume of full_n voxels whose spacing (scaled, data space) is sp; 0 when
 * the volume has fewer voxels along its axis than there are bricks. */
static int brick_keep(const obs_brick *b, const int full_n[3], const double sp[3], double reach,
                      keep *kp) {
  int ax = 0;
  for (int a = 1; a < 3; a++)
    if (full_n[a] > full_n[ax]) ax = a;
  int n = full_n[ax];
  kp->axis = ax;
  if (b->count > n) return 0;
  kp->lo = (int)((int64_t)b->index * n / b->count);
  kp->hi = (int)((int64_t)(b->index + 1) * n / b->count);
  /* The trilinear field and the half-voxel gradient read one voxel past a point, so a march that
   * ends `reach` past the slab's face needs its voxels and one more on each side of them. */
  double g = b->no_ghost ? 0 : ceil(reach / sp[ax]) + 2;
  if (!(g < n)) g = n;
  kp->k0 = kp->lo - (int)g < 0 ? 0 : kp->lo - (int)g;
  kp->k1 = kp->hi + (int)g > n ? n : kp->hi + (int)g;
  return 1;
}

/* Records the brick in sv and moves its maps to the brick's own data space (voxel origin). */
static void set_brick(obs_scene_volume *sv, const keep *kp) {
  sv->brick = 1;
  sv->axis = kp->axis;
  sv->origin[kp->axis] = kp->k0;
  double sp = sv->v.spacing[kp->axis], off = kp->k0 * sp;
  sv->own[0] = (kp->lo - kp->k0) * sp;
  sv->own[1] = (kp->hi - kp->k0) * sp;
  sv->open[0] = kp->lo > 0;
  sv->open[1] = kp->hi < sv->full_n[kp->axis];
  for (int i = 0; i < 3; i++) sv->to_world[i][3] += sv->to_world[i][kp->axis] * off;
  sv->to_data[kp->axis][3] -= off;
}

/* What the loader recorded of a volume file, as obs_volume_read takes it. */
static void file_source(const obs_shape *s, obs_volume_source *src) {
  *src = (obs_volume_source){.format = (obs_volume_file)s->volume.format,
                             .path = s->volume.path,
                             .type = (obs_volume_type)s->volume.data_type};
  memcpy(src->dims, s->volume.dims, sizeof src->dims);
  memcpy(src->spacing, s->volume.spacing, sizeof src->spacing);
  memcpy(src->range, s->volume.range, sizeof src->range);
}

int obs_scene_volume_read_shape(const obs_shape *s, obs_volume *v, obs_err *err) {
  memset(v, 0, sizeof *v);
  int rc;
  double sp[3], longest = 0;
  if (s->volume.procedural < 0) {
    obs_volume_source src;
    file_source(s, &src);
    rc = obs_volume_read(&src, v, err);
    if (!rc) memcpy(sp, v->spacing, sizeof sp);
  } else {
    rc = obs_volume_procedural_fill((obs_volume_procedural)s->volume.procedural, s->volume.seed,
                                    s->volume.dims, v, err);
    /* A procedural fill samples [-1, 1]^3 at spacing 2 / n; a given spacing sets the aspect. */
    for (int a = 0; !rc && a < 3; a++)
      sp[a] = s->volume.spacing[a] > 0 ? s->volume.spacing[a] : 2.0 / v->n[a];
  }
  if (rc) return rc;
  for (int a = 0; a < 3; a++) longest = fmax(longest, v->n[a] * sp[a]);
  for (int a = 0; a < 3; a++) v->spacing[a] = sp[a] / longest;
  return 0;
}

/* The volume's samples into sv->v: the file's or the procedural kind's, the brick's voxels only
 * when b is set. The spacing is scaled so that the full volume's longest side is 1. */
static int read_samples(const obs_object *o, obs_scene_volume *sv, const obs_brick *b,
                        double reach, obs_err *err) {
  const obs_shape *s = &o->shape;
  if (!b) {
    int rc = obs_scene_volume_read_shape(s, &sv->v, err);
    if (rc) return rc;
    memcpy(sv->full_n, sv->v.n, sizeof sv->full_n);
    sv->own[0] = 0;
    sv->own[1] = sv->v.n[0] * sv->v.spacing[0];
    return 0;
  }
  obs_volume full = {0};
  double sp[3], longest = 0;
  int rc = 0, file = s->volume.procedural < 0;
  if (file) {
    obs_volume_source src;
    file_source(s, &src);
    /* Read whole even for a brick: the formats are not read a slab at a time here. */
    if ((rc = obs_volume_read(&src, &full, err))) return rc;
  }
  for (int a = 0; a < 3; a++) {
    sv->full_n[a] = file ? full.n[a] : s->volume.dims[a];
    /* A procedural fill samples [-1, 1]^3 at spacing 2 / n; a given spacing sets the aspect, as
     * the loader's extent says. */
    sp[a] = file ? full.spacing[a]
                 : s->volume.spacing[a] > 0 ? s->volume.spacing[a] : 2.0 / sv->full_n[a];
    longest = fmax(longest, sv->full_n[a] * sp[a]);
  }
  /* The box is [0, extent]: the same scale on every axis keeps the voxels' aspect. */
  for (int a = 0; a < 3; a++) sp[a] /= longest;
  keep kp = {0, 0, 0, 0, 0};
  if (b && !brick_keep(b, sv->full_n, sp, reach, &kp)) {
    obs_volume_free(&full);
    return obs_err_set(err, OBS_EINVAL,
                       "%d voxels along its longest axis are too few for %d bricks",
                       sv->full_n[kp.axis], b->count);
  }
  if (!file)
    rc = b ? procedural_brick(s, &kp, &sv->v, err)
           : obs_volume_procedural_fill((obs_volume_procedural)s->volume.procedural,
                                        s->volume.seed, s->volume.dims, &sv->v, err);
  else if (b)
    rc = crop(&full, &kp, &sv->v, err);
  else
    sv->v = full, full.data = NULL;
  obs_volume_free(&full);
  if (rc) return rc;
  memcpy(sv->v.spacing, sp, sizeof sp);
  sv->own[0] = 0;
  sv->own[1] = sv->v.n[0] * sp[0];
  if (b) set_brick(sv, &kp);
  return 0;
}

/* Reads volume sv (its maps and isovalue set): whole, or the brick's part of it, its macrocells
 * and (sides) its cells' sides of the isovalue. */
static int read_volume(const obs_scene *sc, obs_scene_volume *sv, const obs_brick *b,
                       double reach, int sides, obs_err *err) {
  const obs_object *o = &sc->objects[sv->object];
  obs_err e = OBS_ERR_INIT;
  int rc = read_samples(o, sv, b, reach, &e);
  if (!rc) rc = obs_volume_cells_build(&sv->v, OBS_VOLUME_CELL, &sv->cells, &e);
  if (!rc && sides) rc = obs_volume_sides_build(&sv->v, sv->iso, &sv->sides, &e);
  if (rc)
    obs_err_set(err, rc, "%s: /objects/%zu/shape: volume \"%s\": %s", sc->name, sv->object,
                o->name, obs_err_message(&e));
  obs_err_free(&e);
  return rc;
}

static int start_one(const obs_scene *sc, size_t oi, obs_scene_volume *sv, obs_err *err) {
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
  return 0;
}

int obs_scene_volumes_load_brick(const obs_scene *sc, const obs_brick *brick, double reach,
                                 int sides, obs_scene_volumes *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  const obs_brick *b = brick && brick->count > 0 ? brick : NULL;
  if (b && (b->index < 0 || b->index >= b->count))
    return obs_err_set(err, OBS_EINVAL, "%s: brick %d of %d does not exist", sc->name, b->index,
                       b->count);
  size_t n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) n += sc->objects[i].shape.type == OBS_SHAPE_VOLUME;
  if (!n) return 0;
  if (!(out->v = calloc(n, sizeof *out->v)))
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for %zu volumes", sc->name, n);
  int rc = 0;
  for (size_t i = 0; i < sc->nobjects && !rc; i++)
    if (sc->objects[i].shape.type == OBS_SHAPE_VOLUME)
      rc = start_one(sc, i, &out->v[out->n++], err);
  /* Every map is known before any volume is read: a brick's ghost zone depends on them all. */
  for (size_t k = 0; k < out->n && !rc; k++) {
    rc = read_volume(sc, &out->v[k], b, b ? reach_in(out, k, reach) : 0, sides, err);
  }
  if (rc) obs_scene_volumes_free(out);
  return rc;
}

int obs_scene_volumes_load(const obs_scene *sc, obs_scene_volumes *out, obs_err *err) {
  return obs_scene_volumes_load_brick(sc, NULL, 0, 1, out, err);
}

void obs_scene_volumes_free(obs_scene_volumes *vs) {
  for (size_t i = 0; i < vs->n; i++) {
    obs_volume_free(&vs->v[i].v);
    obs_volume_cells_free(&vs->v[i].cells);
    obs_volume_sides_free(&vs->v[i].sides);
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
