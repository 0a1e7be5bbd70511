/* Proximity fields (renderer/core/proximity.h): the grids' layout per object, the build that
 * voxelises and floods them, the world-to-grid maps and the reconstruction of occlusion. */
#include "proximity.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "sampling.h"
#include "shapes.h"

#define PI 3.14159265358979323846

/* What one object contributes before its grid is laid out. */
typedef struct prox_src {
  size_t object;
  int sphere;           /* analytic sphere: centre and radius, no mesh */
  double centre[3], radius;
  obs_mesh mesh;        /* object space */
  double box[2][3];     /* object-space box of the surface */
  double scale[3];      /* |transform scale| per axis: object lengths to world */
} prox_src;

static void src_free(prox_src *s, size_t n) {
  for (size_t i = 0; i < n; i++) obs_geometry_mesh_free(&s[i].mesh);
  free(s);
}

static int has_surface(const obs_object *o) {
  const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
  return k->vertices || k->mesh || k->sphere;
}

/* The world box of object `o` in frame 0, from the points its shape kind declares. */
static void world_box(const obs_object *o, double w[2][3]) {
  memset(w, 0, sizeof(double[2][3]));
  double pts[8][3], r;
  int n = obs_geometry_object_points(o, 0, NULL, pts, &r);
  for (int c = 0; c < n; c++)
    for (int i = 0; i < 3; i++) {
      if (c == 0 || pts[c][i] - r < w[0][i]) w[0][i] = pts[c][i] - r;
      if (c == 0 || pts[c][i] + r > w[1][i]) w[1][i] = pts[c][i] + r;
    }
}

static double diag(const double b[2][3]) {
  double d[3] = {b[1][0] - b[0][0], b[1][1] - b[0][1], b[1][2] - b[0][2]};
  return sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

static int src_read(const obs_scene *sc, size_t oi, prox_src *s, obs_err *err) {
  const obs_object *o = &sc->objects[oi];
  s->object = oi;
  s->scale[0] = fabs(o->transform.scale.x);
  s->scale[1] = fabs(o->transform.scale.y);
  s->scale[2] = fabs(o->transform.scale.z);
  if (obs_shape_is_analytic(&o->shape)) {
    s->sphere = 1;
    obs_shape_kind_of(o->shape.type)->sphere(&o->shape, s->centre, &s->radius);
    for (int k = 0; k < 3; k++) {
      s->box[0][k] = s->centre[k] - s->radius;
      s->box[1][k] = s->centre[k] + s->radius;
    }
  } else {
    int rc = obs_geometry_object_mesh(sc, oi, &s->mesh, err);
    if (rc) return rc;
    obs_geometry_mesh_bounds(&s->mesh, s->box);
  }
  return 0;
}

double obs_prox_radius(const obs_scene *sc, const obs_prox_layout *lay) {
  double ref = 0, ubox[2][3] = {{0}}, w[2][3] = {{0}};
  int first = 1;
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (!has_surface(&sc->objects[i])) continue;
    world_box(&sc->objects[i], w);
    ref = fmax(ref, diag(w));
    for (int k = 0; k < 3; k++) {
      if (first || w[0][k] < ubox[0][k]) ubox[0][k] = w[0][k];
      if (first || w[1][k] > ubox[1][k]) ubox[1][k] = w[1][k];
    }
    first = 0;
  }
  if (lay->union_box && !first) ref = diag(ubox);
  return lay->fraction * ref;
}

/* The power of two nearest to x (in the log), clamped to [lo, hi]. */
static int pow2_near(double x, int lo, int hi) {
  double e = x > 0 ? round(log2(x)) : -1e9;
  double v = e < 0 ? 1 : e > 30 ? 1e9 : ldexp(1.0, (int)e);
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return (int)v;
}

/* Lays out s's grid: the box grown by r_p (world) in object units per axis, voxels per axis the
 * nearest power of two to res x (the side / the longest side of every grid). */
static void layout_grid(const prox_src *s, double rp, double longest, const obs_prox_layout *lay,
                        obs_prox_field *f) {
  int lo = lay->min_res < lay->res ? lay->min_res : lay->res;
  double d2 = 0;
  f->count = 1;
  for (int k = 0; k < 3; k++) {
    double grow = s->scale[k] > 0 ? rp / s->scale[k] : 0;
    double side = (s->box[1][k] - s->box[0][k]) + 2 * grow;
    if (!(side > 0)) side = s->scale[k] > 0 ? longest / s->scale[k] : 1; /* a flat box, r_p 0 */
    if (!(side > 0) || !isfinite(side)) side = 1;
    double centre = 0.5 * (s->box[0][k] + s->box[1][k]);
    double wside = side * s->scale[k];
    f->dims[k] = pow2_near(longest > 0 ? lay->res * wside / longest : 1, lo, lay->res);
    f->lo[k] = centre - 0.5 * side;
    f->voxel[k] = side / f->dims[k];
    double wv = f->voxel[k] * s->scale[k];
    d2 += wv * wv;
    f->count *= (size_t)f->dims[k];
  }
  double dv = sqrt(d2);
  double it = dv > 0 ? ceil(rp / dv) : 0;
  f->iterations = it > 1e6 ? 1000000 : (int)it;
  f->object = s->object;
}

void obs_prox_fields_free(obs_prox_fields *fs) {
  for (size_t i = 0; i < fs->n; i++) {
    free(fs->f[i].occupied);
    free(fs->f[i].value);
  }
  free(fs->f);
  memset(fs, 0, sizeof *fs);
}

/* Every field together must stay within this many bytes (values and occupancy, plus the flood's
 * two working copies of the largest). */
#define PROX_MAX_BYTES ((double)(6ull << 30))

int obs_prox_build(const obs_scene *sc, const obs_prox_layout *lay, int threads,
                   obs_prox_flood_fn flood, void *flood_user, obs_prox_fields *out,
                   obs_err *err) {
  memset(out, 0, sizeof *out);
  size_t n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) n += has_surface(&sc->objects[i]);
  prox_src *src = calloc(n ? n : 1, sizeof *src);
  out->f = calloc(n ? n : 1, sizeof *out->f);
  if (!src || !out->f) {
    free(src);
    obs_prox_fields_free(out);
    return obs_err_set(err, OBS_ENOMEM, "%s: proximity fields: out of memory", sc->name);
  }
  double t0 = obs_now_ms();
  int rc = 0;
  size_t m = 0;
  for (size_t i = 0; i < sc->nobjects && !rc; i++)
    if (has_surface(&sc->objects[i])) rc = src_read(sc, i, &src[m++], err);
  out->rp = obs_prox_radius(sc, lay);
  double longest = 0;
  for (size_t i = 0; i < m; i++)
    for (int k = 0; k < 3; k++)
      longest = fmax(longest, (src[i].box[1][k] - src[i].box[0][k]) * src[i].scale[k] + 2 * out->rp);
  double bytes = 0, biggest = 0;
  for (size_t i = 0; i < m && !rc; i++) {
    layout_grid(&src[i], out->rp, longest, lay, &out->f[i]);
    bytes += 5.0 * (double)out->f[i].count;
    biggest = fmax(biggest, 8.0 * (double)out->f[i].count);
  }
  if (!rc && bytes + biggest > PROX_MAX_BYTES)
    rc = obs_err_set(err, OBS_EINVAL, "%s: /technique/params/volume_res: the proximity fields "
                     "would take %.1f GiB, more than %.0f GiB; lower volume_res",
                     sc->name, (bytes + biggest) / (1 << 30), PROX_MAX_BYTES / (1 << 30));
  for (size_t i = 0; i < m && !rc; i++) {
    obs_prox_field *f = &out->f[i];
    f->occupied = calloc(f->count, 1);
    f->value = malloc(f->count * sizeof *f->value);
    out->n++;
    if (!f->occupied || !f->value) {
      rc = obs_err_set(err, OBS_ENOMEM, "%s: /objects/%zu: out of memory for its proximity field "
                       "(%zu voxels)", sc->name, f->object, f->count);
      break;
    }
    if (src[i].sphere) obs_prox_voxelise_sphere(f, src[i].centre, src[i].radius, threads);
    else obs_prox_voxelise_mesh(f, &src[i].mesh, threads);
    for (size_t v = 0; v < f->count; v++) {
      f->value[v] = f->occupied[v] ? 1.0f : 0.0f;
      f->occupied_count += f->occupied[v];
    }
    out->bytes += 5 * f->count;
  }
  src_free(src, n);
  double t1 = obs_now_ms();
  out->voxelise_ms = t1 - t0;
  for (size_t i = 0; i < out->n && !rc; i++)
    rc = (flood ? flood : obs_prox_flood_cpu)(flood_user, &out->f[i], threads, err);
  out->flood_ms = obs_now_ms() - t1;
  if (rc) obs_prox_fields_free(out);
  return rc;
}

void obs_prox_world_to_grid(const obs_prox_field *f, const obs_object *o, int frame,
                            double g[3][4]) {
  double m[3][4];
  obs_geometry_transform_matrix(obs_object_transform_at(o, frame), m);
  /* The inverse of the linear part by cofactors; a singular transform maps every point to the
   * grid's far outside, where nothing is read. */
  double a[3][3], det;
  a[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
  a[0][1] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
  a[0][2] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
  a[1][0] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
  a[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
  a[1][2] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
  a[2][0] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
  a[2][1] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
  a[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  det = m[0][0] * a[0][0] + m[0][1] * a[1][0] + m[0][2] * a[2][0];
  if (det == 0 || !isfinite(det)) {
    memset(g, 0, sizeof(double[3][4]));
    for (int i = 0; i < 3; i++) g[i][3] = -1e30;
    return;
  }
  for (int i = 0; i < 3; i++) {
    double inv[3], t = 0;
    for (int j = 0; j < 3; j++) {
      inv[j] = a[i][j] / det;
      t -= inv[j] * m[j][3];
    }
    /* object = inv (w) + t; grid = (object - lo) / voxel */
    for (int j = 0; j < 3; j++) g[i][j] = inv[j] / f->voxel[i];
    g[i][3] = (t - f->lo[i]) / f->voxel[i];
  }
}

float obs_prox_sample(const obs_prox_field *f, const float g[3]) {
  int i0[3], i1[3];
  float w[3];
  for (int k = 0; k < 3; k++) {
    float u = g[k] - 0.5f, hi = (float)(f->dims[k] - 1);
    if (!(u > 0.0f)) u = 0.0f;
    if (u > hi) u = hi;
    int i = (int)u;
    i0[k] = i;
    i1[k] = i + 1 < f->dims[k] ? i + 1 : i;
    w[k] = u - (float)i;
  }
  size_t sx = (size_t)f->dims[0], sxy = sx * (size_t)f->dims[1];
  const float *v = f->value;
  float c[2][2];
  for (int dz = 0; dz < 2; dz++)
    for (int dy = 0; dy < 2; dy++) {
      size_t r = (size_t)(dz ? i1[2] : i0[2]) * sxy + (size_t)(dy ? i1[1] : i0[1]) * sx;
      float a = v[r + (size_t)i0[0]], b = v[r + (size_t)i1[0]];
      c[dz][dy] = a + (b - a) * w[0];
    }
  float y0 = c[0][0] + (c[0][1] - c[0][0]) * w[1];
  float y1 = c[1][0] + (c[1][1] - c[1][0]) * w[1];
  return y0 + (y1 - y0) * w[2];
}

void obs_prox_recon_init(obs_prox_recon *r, int steps, int mode, float stop_value,
                         float scale_before, float scale_after, uint32_t seed) {
  memset(r, 0, sizeof *r);
  if (steps > OBS_PROX_MAX_STEPS) steps = OBS_PROX_MAX_STEPS;
  r->steps = steps;
  r->mode = mode;
  r->stop_value = stop_value;
  r->scale_before = scale_before;
  r->scale_after = scale_after;
  int at = 0;
  for (int i = 0; i < steps; i++) {
    r->first[i] = at;
    int m = i / 2;
    for (int k = 0; k < m; k++, at++) {
      uint32_t h = obs_hash_combine(obs_hash_combine(seed, (uint32_t)i), (uint32_t)k);
      double u = obs_u32_to_unit(obs_hash_combine(h, 0)), v = obs_u32_to_unit(obs_hash_combine(h, 1));
      double phi = 2 * PI * (k + u) / m, rad = sqrt(v);
      r->disc[at][0] = (float)(rad * cos(phi));
      r->disc[at][1] = (float)(rad * sin(phi));
    }
  }
  r->first[steps] = at;
}

void obs_prox_disc_axes(const float n[3], float t[3], float b[3]) {
  float m[3] = {n[0], n[1], fabsf(n[2]) < OBS_PROX_FLAT_Z ? 0.0f : n[2]};
  obs_onb(m, t, b);
}

static int inside(const obs_prox_field *f, const float q[3]) {
  return q[0] >= 0.0f && q[0] <= (float)f->dims[0] && q[1] >= 0.0f &&
         q[1] <= (float)f->dims[1] && q[2] >= 0.0f && q[2] <= (float)f->dims[2];
}

float obs_prox_occlusion(const obs_prox_field *f, const obs_prox_recon *r, const float gp[3],
                         const float gs[3], const float gt[3], const float gb[3]) {
  const int n = r->steps, code = r->mode == OBS_PROX_THESIS_CODE;
  /* The thesis's code advances one step before its loop and again at the top of each: step i
   * samples at p + (i + 2) step. The corrected walk samples at p + i step. */
  float base = code ? 2.0f : 0.0f, ao = 0.0f, prev = 0.0f;
  for (int i = 0; i < n; i++) {
    float d = base + (float)i, rad = (float)i; /* the disc's radius: R i / N */
    float c[3];
    for (int k = 0; k < 3; k++) c[k] = gp[k] + d * gs[k];
    float sum = 0.0f;
    int read = 0;
    for (int j = r->first[i]; j < r->first[i + 1]; j++) {
      float q[3];
      float dx = r->disc[j][0] * rad, dy = r->disc[j][1] * rad;
      for (int k = 0; k < 3; k++) q[k] = c[k] + dx * gt[k] + dy * gb[k];
      if (!inside(f, q)) continue;
      sum += obs_prox_sample(f, q);
      read++;
    }
    float value = code ? sum : read ? sum / (float)read : 0.0f;
    if (value < prev) continue; /* moving away from what occludes: dropped, prev kept */
    /* The listing's (1 - i / N) is integer division: 1 for every i < N. */
    float weight = code ? 1.0f : 1.0f - (float)i / (float)n;
    ao += value * weight;
    if (value > r->stop_value) break;
    prev = value;
  }
  ao *= r->scale_before;
  ao /= (float)n;
  if (!(ao > 0.0f)) ao = 0.0f;
  if (ao > 1.0f) ao = 1.0f;
  return ao * r->scale_after;
}
