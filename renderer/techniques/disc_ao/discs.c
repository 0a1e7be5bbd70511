/* disc_ao's discs: every scene triangle (analytic spheres as UV spheres), split into m^2 smaller
 * ones where its longest edge passes the subdivision length, turned into a disc in the camera's
 * view space. Built once on the host in double and rounded once, for both backends. */
#include "disc_ao.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"

#define PI 3.14159265358979323846

int obs_disc_make(const double a[3], const double b[3], const double c[3],
                  const obs_disc_ao_params *p, obs_disc *out) {
  double e1[3], e2[3], n[3];
  for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  const double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), area = 0.5 * l;
  if (!(l > 0) || !isfinite(l)) return 0;
  /* View space (right, up, forward) is left-handed, a mirror of the world: the winding's world
   * normal, seen in view space, is minus the cross product of the view-space edges. */
  for (int k = 0; k < 3; k++) {
    out->c[k] = (float)((a[k] + b[k] + c[k]) / 3.0);
    out->n[k] = (float)(-n[k] / l);
  }
  out->a = (float)(p->area_over_pi ? area / PI : area);
  const double k = p->influence_scale;
  out->r2 = (float)(k * k * area);
  return out->a > 0.0f && isfinite(out->r2);
}

typedef struct builder {
  const obs_camera_rig *rig;
  const double *shift; /* the geometry's origin minus the camera's */
  const obs_disc_ao_params *p;
  double max_edge;
  obs_disc *d;
  size_t n, cap, triangles;
} builder;

static void to_view(const builder *b, const double w[3], double v[3]) {
  const double q[3] = {w[0] + b->shift[0], w[1] + b->shift[1], w[2] + b->shift[2]};
  const double *ax[3] = {b->rig->right, b->rig->up, b->rig->forward};
  for (int i = 0; i < 3; i++) v[i] = q[0] * ax[i][0] + q[1] * ax[i][1] + q[2] * ax[i][2];
}

static double dist(const double a[3], const double b[3]) {
  return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
              (a[2] - b[2]) * (a[2] - b[2]));
}

/* Splits of each edge so that the longest is at most max_edge (1 without subdivision). */
static size_t splits(const builder *b, const double v[3][3]) {
  double e = fmax(dist(v[0], v[1]), fmax(dist(v[1], v[2]), dist(v[2], v[0])));
  if (!(b->max_edge > 0) || !(e > b->max_edge)) return 1;
  double m = ceil(e / b->max_edge);
  return m < 1e6 ? (size_t)m : (size_t)1e6;
}

static void at(const double v[3][3], double i, double j, double m, double out[3]) {
  for (int k = 0; k < 3; k++)
    out[k] = v[0][k] + (v[1][k] - v[0][k]) * (i / m) + (v[2][k] - v[0][k]) * (j / m);
}

/* Triangle v (world, relative to the geometry's origin) into its m^2 sub-triangles' discs: the
 * regular grid of barycentric steps 1/m, upright and inverted ones, all with v's winding. */
static int add_triangle(builder *b, const double w[3][3], obs_err *err) {
  double v[3][3];
  for (int i = 0; i < 3; i++) to_view(b, w[i], v[i]);
  b->triangles++;
  size_t m = splits(b, v), need = m * m;
  if (need > OBS_DISC_MAX || b->n + need > OBS_DISC_MAX)
    return obs_err_set(err, OBS_EINVAL,
                       "/technique/params/subdivide: disc_ao: splitting the triangles into edges "
                       "of at most %g would make more than %zu discs; raise subdivide (got %g)",
                       b->max_edge, OBS_DISC_MAX, (double)b->p->subdivide);
  if (b->n + need > b->cap) {
    size_t cap = b->cap ? b->cap : 1024;
    while (cap < b->n + need) cap *= 2;
    obs_disc *d = realloc(b->d, cap * sizeof *d);
    if (!d) return obs_err_set(err, OBS_ENOMEM, "disc_ao: out of memory for %zu discs", cap);
    b->d = d, b->cap = cap;
  }
  const double fm = (double)m;
  for (size_t j = 0; j < m; j++)
    for (size_t i = 0; i + j < m; i++) {
      double p00[3], p10[3], p01[3], p11[3];
      at(v, (double)i, (double)j, fm, p00);
      at(v, (double)i + 1, (double)j, fm, p10);
      at(v, (double)i, (double)j + 1, fm, p01);
      b->n += (size_t)obs_disc_make(p00, p10, p01, b->p, b->d + b->n);
      if (i + j + 1 < m) {
        at(v, (double)i + 1, (double)j + 1, fm, p11);
        b->n += (size_t)obs_disc_make(p10, p11, p01, b->p, b->d + b->n);
      }
    }
  return 0;
}

/* A UV sphere: bands of quads split in two, wound outward; the caps' degenerate halves have no
 * area and make no disc. */
static int add_sphere(builder *b, const obs_sphere *s, obs_err *err) {
  const int lon = OBS_DISC_SPHERE_LON, lat = OBS_DISC_SPHERE_LON / 2;
  int rc = 0;
  for (int j = 0; j < lat && !rc; j++)
    for (int i = 0; i < lon && !rc; i++) {
      double c[4][3];
      for (int k = 0; k < 4; k++) {
        double th = PI * (j + (k >> 1)) / lat, ph = 2 * PI * (i + (k & 1)) / lon;
        c[k][0] = s->center[0] + s->radius * sin(th) * cos(ph);
        c[k][1] = s->center[1] + s->radius * cos(th);
        c[k][2] = s->center[2] + s->radius * sin(th) * sin(ph);
      }
      const double t0[3][3] = {{c[0][0], c[0][1], c[0][2]},
                               {c[2][0], c[2][1], c[2][2]},
                               {c[1][0], c[1][1], c[1][2]}};
      const double t1[3][3] = {{c[1][0], c[1][1], c[1][2]},
                               {c[2][0], c[2][1], c[2][2]},
                               {c[3][0], c[3][1], c[3][2]}};
      rc = add_triangle(b, t0, err);
      if (!rc) rc = add_triangle(b, t1, err);
    }
  return rc;
}

int obs_disc_set_build(const obs_scene *scene, const obs_camera_rig *rig,
                       const obs_disc_ao_params *p, obs_disc_set *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  obs_geometry geo;
  int rc = obs_geometry_build_at(scene, rig->origin, &geo, err);
  if (rc) return rc;
  double shift[3], diag2 = 0;
  for (int k = 0; k < 3; k++) {
    shift[k] = geo.origin[k] - rig->origin[k];
    double e = geo.bounds[1][k] - geo.bounds[0][k];
    diag2 += e * e;
  }
  builder b = {.rig = rig, .shift = shift, .p = p, .max_edge = p->subdivide * sqrt(diag2)};
  for (size_t mi = 0; mi < geo.nmeshes && !rc; mi++) {
    const obs_mesh *m = &geo.meshes[mi];
    for (size_t t = 0; t < m->ntris && !rc; t++) {
      double w[3][3];
      for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) w[i][k] = m->pos[3 * (size_t)m->idx[3 * t + (size_t)i] + k];
      rc = add_triangle(&b, w, err);
    }
  }
  for (size_t s = 0; s < geo.nspheres && !rc; s++) rc = add_sphere(&b, &geo.spheres[s], err);
  obs_geometry_free(&geo);
  if (rc) {
    free(b.d);
    return rc;
  }
  out->d = b.d, out->n = b.n, out->triangles = b.triangles;
  return 0;
}

void obs_disc_set_free(obs_disc_set *s) {
  if (!s) return;
  free(s->d);
  memset(s, 0, sizeof *s);
}
