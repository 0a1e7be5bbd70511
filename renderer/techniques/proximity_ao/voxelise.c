/* Voxelisation and flooding of proximity fields (proximity.h): which voxels a
 * surface touches, by exact overlap tests, and the flood that spreads proximity outward. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "proximity.h"

/* ---- triangle-box overlap (separating axes) ------------------------------------------------ */

static void sub3(const double a[3], const double b[3], double o[3]) {
  for (int k = 0; k < 3; k++) o[k] = a[k] - b[k];
}

static void cross3(const double a[3], const double b[3], double o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1];
  o[1] = a[2] * b[0] - a[0] * b[2];
  o[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Whether axis `ax` separates the triangle (v, relative to the box centre) from the box. */
static int separates(const double ax[3], const double v[3][3], const double half[3]) {
  double p0 = dot3(ax, v[0]), p1 = dot3(ax, v[1]), p2 = dot3(ax, v[2]);
  double lo = fmin(p0, fmin(p1, p2)), hi = fmax(p0, fmax(p1, p2));
  double r = half[0] * fabs(ax[0]) + half[1] * fabs(ax[1]) + half[2] * fabs(ax[2]);
  return lo > r || hi < -r;
}

int obs_prox_tri_box(const double centre[3], const double half[3], const double a[3],
                     const double b[3], const double c[3]) {
  double v[3][3], e[3][3];
  sub3(a, centre, v[0]);
  sub3(b, centre, v[1]);
  sub3(c, centre, v[2]);
  /* The box's own axes: the triangle's extent against the box's. */
  for (int k = 0; k < 3; k++) {
    double lo = fmin(v[0][k], fmin(v[1][k], v[2][k])), hi = fmax(v[0][k], fmax(v[1][k], v[2][k]));
    if (lo > half[k] || hi < -half[k]) return 0;
  }
  sub3(v[1], v[0], e[0]);
  sub3(v[2], v[1], e[1]);
  sub3(v[0], v[2], e[2]);
  /* The triangle's plane. */
  double n[3];
  cross3(e[0], e[1], n);
  if (separates(n, v, half)) return 0;
  /* The nine cross products of the edges with the box's axes. */
  for (int i = 0; i < 3; i++)
    for (int k = 0; k < 3; k++) {
      double unit[3] = {0, 0, 0}, ax[3];
      unit[k] = 1;
      cross3(e[i], unit, ax);
      if ((ax[0] != 0 || ax[1] != 0 || ax[2] != 0) && separates(ax, v, half)) return 0;
    }
  return 1;
}

/* ---- voxelisation -------------------------------------------------------------------------- */

typedef struct vox_job {
  obs_prox_field *f;
  const obs_mesh *m;
  const double *g;  /* grid coordinates of m's vertices */
  double centre[3], radius; /* a sphere's, in grid coordinates scaled per axis: see sphere_tile */
} vox_job;

static int clampi(double x, int lo, int hi) {
  if (!(x > lo)) return lo;
  if (x > hi) return hi;
  return (int)x;
}

/* Slices [z0, z1) of the grid against every triangle whose box reaches them. */
static int mesh_tile(void *user, int thread, int z0, int y0, int z1, int y1) {
  (void)thread, (void)y0, (void)y1;
  vox_job *j = user;
  obs_prox_field *f = j->f;
  const double h = 0.5 + OBS_PROX_VOXEL_MARGIN, half[3] = {h, h, h};
  size_t sx = (size_t)f->dims[0], sxy = sx * (size_t)f->dims[1];
  for (size_t t = 0; t < j->m->ntris; t++) {
    const double *v[3];
    double lo[3], hi[3];
    for (int c = 0; c < 3; c++) v[c] = j->g + 3 * (size_t)j->m->idx[3 * t + c];
    for (int k = 0; k < 3; k++) {
      lo[k] = fmin(v[0][k], fmin(v[1][k], v[2][k]));
      hi[k] = fmax(v[0][k], fmax(v[1][k], v[2][k]));
    }
    /* Voxels grown by the margin: a vertex on or near a face touches both neighbours. */
    int i0[3], i1[3];
    for (int k = 0; k < 3; k++) {
      i0[k] = clampi(ceil(lo[k] - OBS_PROX_VOXEL_MARGIN) - 1, 0, f->dims[k] - 1);
      i1[k] = clampi(floor(hi[k] + OBS_PROX_VOXEL_MARGIN), 0, f->dims[k] - 1);
      if (hi[k] < -OBS_PROX_VOXEL_MARGIN || lo[k] > f->dims[k] + OBS_PROX_VOXEL_MARGIN) i1[k] = -1;
    }
    if (i0[2] < z0) i0[2] = z0;
    if (i1[2] > z1 - 1) i1[2] = z1 - 1;
    for (int z = i0[2]; z <= i1[2]; z++)
      for (int y = i0[1]; y <= i1[1]; y++)
        for (int x = i0[0]; x <= i1[0]; x++) {
          size_t i = (size_t)z * sxy + (size_t)y * sx + (size_t)x;
          if (f->occupied[i]) continue;
          double c[3] = {x + 0.5, y + 0.5, z + 0.5};
          if (obs_prox_tri_box(c, half, v[0], v[1], v[2])) f->occupied[i] = 1;
        }
  }
  return 0;
}

void obs_prox_voxelise_mesh(obs_prox_field *f, const obs_mesh *m, int threads) {
  double *g = malloc((m->nverts ? m->nverts : 1) * 3 * sizeof *g);
  if (!g) return;
  for (size_t i = 0; i < m->nverts; i++)
    for (int k = 0; k < 3; k++) g[3 * i + k] = ((double)m->pos[3 * i + k] - f->lo[k]) / f->voxel[k];
  vox_job j = {.f = f, .m = m, .g = g};
  obs_parallel_tiles(f->dims[2], 1, threads, mesh_tile, &j, NULL, NULL, NULL);
  free(g);
}

/* A voxel touches the sphere's surface when the surface passes between the voxel's nearest and
 * farthest points from the centre (object space, where the sphere is round). */
static int sphere_tile(void *user, int thread, int z0, int y0, int z1, int y1) {
  (void)thread, (void)y0, (void)y1;
  vox_job *j = user;
  obs_prox_field *f = j->f;
  double r2 = j->radius * j->radius;
  size_t sx = (size_t)f->dims[0], sxy = sx * (size_t)f->dims[1];
  for (int z = z0; z < z1; z++)
    for (int y = 0; y < f->dims[1]; y++)
      for (int x = 0; x < f->dims[0]; x++) {
        int idx[3] = {x, y, z};
        double near2 = 0, far2 = 0;
        for (int k = 0; k < 3; k++) {
          double m = OBS_PROX_VOXEL_MARGIN * f->voxel[k];
          double a = f->lo[k] + idx[k] * f->voxel[k] - j->centre[k] - m;
          double b = a + f->voxel[k] + 2 * m;
          double nd = a > 0 ? a : b < 0 ? -b : 0, fd = fmax(fabs(a), fabs(b));
          near2 += nd * nd;
          far2 += fd * fd;
        }
        if (near2 <= r2 && r2 <= far2) f->occupied[(size_t)z * sxy + (size_t)y * sx + x] = 1;
      }
  return 0;
}

void obs_prox_voxelise_sphere(obs_prox_field *f, const double c[3], double r, int threads) {
  vox_job j = {.f = f, .radius = r};
  memcpy(j.centre, c, sizeof j.centre);
  obs_parallel_tiles(f->dims[2], 1, threads, sphere_tile, &j, NULL, NULL, NULL);
}

/* ---- flood --------------------------------------------------------------------------------- */

typedef struct flood_job {
  obs_prox_field *f;
  const float *cur;
  float *sxy;  /* per voxel: its 3x3 block sum in x and y */
  float *next;
} flood_job;

/* Sums along x, then along y, of slices [z0, z1). */
static int flood_xy(void *user, int thread, int z0, int y0, int z1, int y1) {
  (void)thread, (void)y0, (void)y1;
  flood_job *j = user;
  int nx = j->f->dims[0], ny = j->f->dims[1];
  size_t sxy = (size_t)nx * (size_t)ny;
  float *row = malloc(sxy * sizeof *row);
  if (!row) return OBS_ENOMEM;
  for (int z = z0; z < z1; z++) {
    const float *c = j->cur + (size_t)z * sxy;
    for (int y = 0; y < ny; y++) {
      const float *r = c + (size_t)y * nx;
      float *o = row + (size_t)y * nx;
      for (int x = 0; x < nx; x++) {
        float l = x > 0 ? r[x - 1] : 0.0f, h = x + 1 < nx ? r[x + 1] : 0.0f;
        o[x] = (l + r[x]) + h;
      }
    }
    float *out = j->sxy + (size_t)z * sxy;
    for (int y = 0; y < ny; y++)
      for (int x = 0; x < nx; x++) {
        float l = y > 0 ? row[(size_t)(y - 1) * nx + x] : 0.0f;
        float h = y + 1 < ny ? row[(size_t)(y + 1) * nx + x] : 0.0f;
        out[(size_t)y * nx + x] = (l + row[(size_t)y * nx + x]) + h;
      }
  }
  free(row);
  return 0;
}

/* Sums along z and the update of slices [z0, z1). */
static int flood_z(void *user, int thread, int z0, int y0, int z1, int y1) {
  (void)thread, (void)y0, (void)y1;
  flood_job *j = user;
  int nz = j->f->dims[2];
  size_t sxy = (size_t)j->f->dims[0] * (size_t)j->f->dims[1];
  for (int z = z0; z < z1; z++) {
    const float *m = j->sxy + (size_t)z * sxy;
    const float *lo = z > 0 ? m - sxy : NULL, *hi = z + 1 < nz ? m + sxy : NULL;
    const float *c = j->cur + (size_t)z * sxy;
    const uint8_t *occ = j->f->occupied + (size_t)z * sxy;
    float *o = j->next + (size_t)z * sxy;
    for (size_t i = 0; i < sxy; i++) {
      float s = ((lo ? lo[i] : 0.0f) + m[i]) + (hi ? hi[i] : 0.0f);
      o[i] = occ[i] ? 1.0f : 0.5f * (c[i] + (s - c[i]) * OBS_PROX_INV26);
    }
  }
  return 0;
}

int obs_prox_flood_cpu(void *user, obs_prox_field *f, int threads, obs_err *err) {
  (void)user;
  if (f->iterations <= 0) return 0;
  float *sxy = malloc(f->count * sizeof *sxy), *next = malloc(f->count * sizeof *next);
  if (!sxy || !next) {
    free(sxy);
    free(next);
    return obs_err_set(err, OBS_ENOMEM, "proximity field of object %zu: out of memory for the "
                       "flood (%zu voxels)", f->object, f->count);
  }
  flood_job j = {.f = f, .sxy = sxy};
  float *cur = f->value;
  int rc = 0;
  for (int it = 0; it < f->iterations && !rc; it++) {
    j.cur = cur;
    j.next = next;
    rc = obs_parallel_tiles(f->dims[2], 1, threads, flood_xy, &j, NULL, NULL, NULL);
    if (!rc) rc = obs_parallel_tiles(f->dims[2], 1, threads, flood_z, &j, NULL, NULL, NULL);
    float *t = cur;
    cur = next;
    next = t;
  }
  if (cur != f->value) {
    memcpy(f->value, cur, f->count * sizeof *cur);
    next = cur;
  }
  free(next);
  free(sxy);
  if (rc == OBS_ENOMEM)
    return obs_err_set(err, rc, "proximity field of object %zu: out of memory", f->object);
  return rc;
}
