/* The CPU backend's rasterised G-buffer: the same buffers as the ray cast (renderer/core/gbuffer.h)
 * without a BVH. Triangles are bounded on the image, binned to the tiles of obs_parallel_tiles, and
 * each pixel centre a triangle may cover is tested with edge functions in double; a covered
 * pixel's depth is the primary ray's refined hit parameter (raytrace.h's shared expressions), so
 * where the ray cast and the rasteriser see the same surface they write the same bits. Also the
 * choice between the two (obs_gbuffer_cpu). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "normalize.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"
#include "simd.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Pixels [x0, x1) x [y0, y1) that a primitive may cover; empty when x0 >= x1. */
typedef struct rs_box {
  int x0, y0, x1, y1;
} rs_box;

struct rs_tile;

typedef struct rs_job {
  const obs_scene *scene;
  const obs_geometry *geo;
  obs_camera_rig cam;
  obs_rt_view view;
  obs_gbuffer *g;
  size_t ntris, nprims; /* primitive i < ntris: a triangle; else sphere i - ntris */
  size_t *mesh_base;    /* first primitive of each mesh, nmeshes + 1 entries */
  rs_box *box;
  size_t chunk; /* primitives per column of the set-up loop */
  int tiles_x, tiles_y;
  double tests;      /* pixels of all primitives' boxes: the raster's work */
  size_t *bin_start; /* per tile, then the total */
  uint32_t *bin;
  int reference; /* the plain per-pixel loops (obs_gbuffer_raster_reference) */
  void (*row)(struct rs_tile *t, int y, int lo, int hi, const double r[3], const double b[3],
              const double n[3], double num, double zmin, uint32_t id);
} rs_job;

/* View coordinates (right, up, forward) of p relative to the eye. */
static void to_view(const rs_job *j, const double p[3], double v[3]) {
  double q[3] = {p[0] - j->view.eye[0], p[1] - j->view.eye[1], p[2] - j->view.eye[2]};
  const double *axes[3] = {j->view.right, j->view.up, j->view.forward};
  for (int k = 0; k < 3; k++) v[k] = q[0] * axes[k][0] + q[1] * axes[k][1] + q[2] * axes[k][2];
}

/* Bounds on the image-plane offsets (sx, sy) of obs_rt_view that a primitive reaches. */
typedef struct rs_bounds {
  double lo[2], hi[2];
} rs_bounds;

static void bound_offset(rs_bounds *b, double sx, double sy) {
  b->lo[0] = sx < b->lo[0] ? sx : b->lo[0], b->hi[0] = sx > b->hi[0] ? sx : b->hi[0];
  b->lo[1] = sy < b->lo[1] ? sy : b->lo[1], b->hi[1] = sy > b->hi[1] ? sy : b->hi[1];
}

/* A perspective point at or near the camera plane: its projection lies far out in the direction
 * (x, y), or anywhere along an axis where that direction is too small to trust. */
static void bound_direction(rs_bounds *b, double x, double y) {
  double tol = 1e-9 * (fabs(x) + fabs(y));
  if (x >= -tol) b->hi[0] = INFINITY;
  if (x <= tol) b->lo[0] = -INFINITY;
  if (y >= -tol) b->hi[1] = INFINITY;
  if (y <= tol) b->lo[1] = -INFINITY;
}

/* A view-space point of a primitive's outline (z >= 0 for perspective cameras). */
static void bound_point(const rs_job *j, rs_bounds *b, const double v[3]) {
  if (j->cam.ortho)
    bound_offset(b, v[0], v[1]);
  else if (v[2] > 1e-7 * (fabs(v[0]) + fabs(v[1])))
    bound_offset(b, v[0] / v[2], v[1] / v[2]);
  else
    bound_direction(b, v[0], v[1]);
}

/* The pixels whose centres lie within the bounds, grown by RS_MARGIN pixels: the bounds err by
 * double's rounding of on-screen offsets (~1e-12 pixels), far less. */
#define RS_MARGIN 0.01

static rs_box box_of(const rs_job *j, const rs_bounds *b) {
  const double w = j->cam.width, h = j->cam.height;
  /* Centre of pixel x: sx = (2 (x + 0.5) / W - 1) half_w; of row y: sy = (1 - 2 (y + 0.5) / H)
   * half_h. */
  double x0 = (b->lo[0] / j->cam.half_w + 1.0) * 0.5 * w - 0.5;
  double x1 = (b->hi[0] / j->cam.half_w + 1.0) * 0.5 * w - 0.5;
  double y0 = (1.0 - b->hi[1] / j->cam.half_h) * 0.5 * h - 0.5;
  double y1 = (1.0 - b->lo[1] / j->cam.half_h) * 0.5 * h - 0.5;
  rs_box r = {0, 0, 0, 0};
  if (isnan(x0) || isnan(x1) || isnan(y0) || isnan(y1)) {
    r.x1 = j->cam.width, r.y1 = j->cam.height;
    return r;
  }
  x0 = fmax(ceil(x0 - RS_MARGIN), 0.0), y0 = fmax(ceil(y0 - RS_MARGIN), 0.0);
  x1 = fmin(floor(x1 + RS_MARGIN) + 1.0, w), y1 = fmin(floor(y1 + RS_MARGIN) + 1.0, h);
  if (!(x0 < x1 && y0 < y1)) return r;
  r.x0 = (int)x0, r.y0 = (int)y0, r.x1 = (int)x1, r.y1 = (int)y1;
  return r;
}

/* Triangle (view-space vertices v): the part in front of a perspective camera (z >= 0, clipped
 * in double), or the whole of it for an orthographic one; rays there have t >= 0. */
static rs_box triangle_box(const rs_job *j, const double v[3][3]) {
  rs_bounds b = {{INFINITY, INFINITY}, {-INFINITY, -INFINITY}};
  if (!(v[0][2] >= 0 || v[1][2] >= 0 || v[2][2] >= 0)) return (rs_box){0, 0, 0, 0};
  if (j->cam.ortho || (v[0][2] >= 0 && v[1][2] >= 0 && v[2][2] >= 0)) {
    for (int i = 0; i < 3; i++) bound_point(j, &b, v[i]);
  } else {
    for (int i = 0; i < 3; i++) {
      const double *p = v[i], *q = v[(i + 1) % 3];
      if (p[2] >= 0) bound_point(j, &b, p);
      if ((p[2] >= 0) != (q[2] >= 0)) {
        /* Where the edge crosses the camera plane: a point at infinity on the image. */
        double s = p[2] / (p[2] - q[2]);
        bound_direction(&b, p[0] + (q[0] - p[0]) * s, p[1] + (q[1] - p[1]) * s);
      }
    }
  }
  return box_of(j, &b);
}

/* Sphere: the box of its view-space bounding cube; the whole image when the camera plane cuts
 * that cube. */
static rs_box sphere_box(const rs_job *j, const obs_sphere *s) {
  double c[3];
  to_view(j, s->center, c);
  const double r = s->radius * (1 + 1e-9);
  rs_bounds b = {{INFINITY, INFINITY}, {-INFINITY, -INFINITY}};
  if (!(c[2] + r >= 0)) return (rs_box){0, 0, 0, 0};
  if (j->cam.ortho) {
    bound_offset(&b, c[0] - r, c[1] - r);
    bound_offset(&b, c[0] + r, c[1] + r);
  } else if (!(c[2] - r > 0)) {
    return (rs_box){0, 0, j->cam.width, j->cam.height};
  } else {
    for (int k = 0; k < 8; k++) {
      double p[3] = {c[0] + (k & 1 ? r : -r), c[1] + (k & 2 ? r : -r), c[2] + (k & 4 ? r : -r)};
      bound_point(j, &b, p);
    }
  }
  return box_of(j, &b);
}

static size_t mesh_of(const rs_job *j, size_t prim) {
  size_t lo = 0, hi = j->geo->nmeshes; /* mesh_base[lo] <= prim < mesh_base[hi] */
  while (hi - lo > 1) {
    size_t mid = (lo + hi) / 2;
    if (j->mesh_base[mid] <= prim)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

static void tri_verts(const rs_job *j, size_t prim, size_t *mesh, const float *p[3]) {
  size_t mi = mesh_of(j, prim);
  const obs_mesh *m = &j->geo->meshes[mi];
  const uint32_t *t = m->idx + 3 * (prim - j->mesh_base[mi]);
  for (int i = 0; i < 3; i++) p[i] = m->pos + 3 * (size_t)t[i];
  *mesh = mi;
}

/* Set-up loop: column x of the "image" is chunk x of the primitives. */
static int setup_chunk(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread, (void)y0, (void)y1;
  rs_job *j = user;
  size_t end = (size_t)x1 * j->chunk < j->nprims ? (size_t)x1 * j->chunk : j->nprims;
  size_t mi = 0;
  for (size_t i = (size_t)x0 * j->chunk; i < end; i++) {
    if (i >= j->ntris) {
      j->box[i] = sphere_box(j, &j->geo->spheres[i - j->ntris]);
      continue;
    }
    while (j->mesh_base[mi + 1] <= i) mi++;
    const obs_mesh *m = &j->geo->meshes[mi];
    const uint32_t *t = m->idx + 3 * (i - j->mesh_base[mi]);
    double v[3][3];
    for (int k = 0; k < 3; k++) {
      const float *p = m->pos + 3 * (size_t)t[k];
      double w[3] = {p[0], p[1], p[2]};
      to_view(j, w, v[k]);
    }
    j->box[i] = triangle_box(j, v);
  }
  return 0;
}

/* Counting sort of the primitives into per-tile lists: the counts (and the boxes' area)... */
static int count_bins(rs_job *j) {
  const size_t ntiles = (size_t)j->tiles_x * (size_t)j->tiles_y;
  j->bin_start = calloc(ntiles + 1, sizeof *j->bin_start);
  if (!j->bin_start) return OBS_ENOMEM;
  double tests = 0;
  for (size_t i = 0; i < j->nprims; i++) {
    const rs_box *b = &j->box[i];
    if (b->x0 >= b->x1 || b->y0 >= b->y1) continue;
    tests += (double)(b->x1 - b->x0) * (double)(b->y1 - b->y0);
    for (int ty = b->y0 / OBS_TILE; ty <= (b->y1 - 1) / OBS_TILE; ty++)
      for (int tx = b->x0 / OBS_TILE; tx <= (b->x1 - 1) / OBS_TILE; tx++)
        j->bin_start[(size_t)ty * j->tiles_x + tx + 1]++;
  }
  j->tests = tests;
  for (size_t t = 0; t < ntiles; t++) j->bin_start[t + 1] += j->bin_start[t];
  return 0;
}

/* ...then the lists. */
static int fill_bins(rs_job *j) {
  const size_t ntiles = (size_t)j->tiles_x * (size_t)j->tiles_y;
  j->bin = malloc((j->bin_start[ntiles] ? j->bin_start[ntiles] : 1) * sizeof *j->bin);
  size_t *fill = malloc(ntiles * sizeof *fill);
  if (!j->bin || !fill) {
    free(fill);
    return OBS_ENOMEM;
  }
  memcpy(fill, j->bin_start, ntiles * sizeof *fill);
  for (size_t i = 0; i < j->nprims; i++) {
    const rs_box *b = &j->box[i];
    if (b->x0 >= b->x1 || b->y0 >= b->y1) continue;
    for (int ty = b->y0 / OBS_TILE; ty <= (b->y1 - 1) / OBS_TILE; ty++)
      for (int tx = b->x0 / OBS_TILE; tx <= (b->x1 - 1) / OBS_TILE; tx++)
        j->bin[fill[(size_t)ty * j->tiles_x + tx]++] = (uint32_t)i;
  }
  free(fill);
  return 0;
}

/* Per tile: the rays of its pixels (perspective: one origin, a direction per pixel;
 * orthographic: an origin per pixel, one direction), a component per array so that a row's pixels
 * load side by side, and the nearest hit so far of each. */
typedef struct rs_tile {
  int x0, y0, w, h;
  double sx[OBS_TILE], sy[OBS_TILE];
  double ray[3][OBS_TILE * OBS_TILE];
  double t[OBS_TILE * OBS_TILE];
  uint32_t win[OBS_TILE * OBS_TILE];
} rs_tile;

/* Pixel p's ray: its origin and direction. */
static void ray_at(const rs_job *j, const rs_tile *t, int p, double o[3], double d[3]) {
  const double *eye = j->view.eye, *f = j->view.forward;
  for (int k = 0; k < 3; k++) {
    o[k] = j->cam.ortho ? t->ray[k][p] : eye[k];
    d[k] = j->cam.ortho ? f[k] : t->ray[k][p];
  }
}

/* Edge functions of the triangle (vertices relative to the eye, in double):
 * E_i(sx, sy) = a[i] + sx b[i] + sy c[i] for the ray through (sx, sy). Perspective: d . (p_j x p_k)
 * with d = forward + sx right + sy up; orthographic: the same triple product with the ray's origin
 * moved by sx right + sy up. Signed so that all three are >= 0 where the ray meets the triangle
 * (perspective: in front of the eye); returns 0 for a triangle seen edge on. A shared edge gives
 * exactly negated functions to its two triangles, so no pixel centre falls between them. *zmin:
 * the least view depth of the vertices, below every ray parameter of a hit on the triangle (rays
 * have unit depth per unit parameter). */
static int edge_functions(const rs_job *j, const float *v[3], double a[3], double b[3], double c[3],
                          double *zmin) {
  const obs_rt_view *w = &j->view;
  double p[3][3], det = 0;
  for (int i = 0; i < 3; i++)
    for (int k = 0; k < 3; k++) p[i][k] = (double)v[i][k] - w->eye[k];
  *zmin = INFINITY;
  for (int i = 0; i < 3; i++) {
    double z = p[i][0] * w->forward[0] + p[i][1] * w->forward[1] + p[i][2] * w->forward[2];
    *zmin = z < *zmin ? z : *zmin;
  }
  for (int i = 0; i < 3; i++) {
    const double *pj = p[(i + 1) % 3], *pk = p[(i + 2) % 3];
    double x[3] = {pj[1] * pk[2] - pj[2] * pk[1], pj[2] * pk[0] - pj[0] * pk[2],
                   pj[0] * pk[1] - pj[1] * pk[0]};
    if (i == 0) det = p[0][0] * x[0] + p[0][1] * x[1] + p[0][2] * x[2];
    a[i] = w->forward[0] * x[0] + w->forward[1] * x[1] + w->forward[2] * x[2];
    if (j->cam.ortho) {
      double e[3] = {pj[0] - pk[0], pj[1] - pk[1], pj[2] - pk[2]};
      const double *f = w->forward;
      x[0] = e[1] * f[2] - e[2] * f[1];
      x[1] = e[2] * f[0] - e[0] * f[2];
      x[2] = e[0] * f[1] - e[1] * f[0];
    }
    b[i] = w->right[0] * x[0] + w->right[1] * x[1] + w->right[2] * x[2];
    c[i] = w->up[0] * x[0] + w->up[1] * x[1] + w->up[2] * x[2];
  }
  /* The functions sum to det over p's cone (perspective) and to forward . normal (orthographic). */
  const double side = j->cam.ortho ? a[0] + a[1] + a[2] : det;
  if (!(side > 0 || side < 0)) return 0;
  if (side < 0)
    for (int i = 0; i < 3; i++) a[i] = -a[i], b[i] = -b[i], c[i] = -c[i];
  return 1;
}

/* Tile-relative columns [*lo, *hi) of row `r` (the functions' values at sx = 0) that may pass all
 * three edge tests: the crossings in double (inv_b: 1 / b), widened by a pixel. The exact test
 * still decides each pixel. */
static void row_span(const rs_job *j, const rs_tile *t, const double r[3], const double b[3],
                     const double inv_b[3], int *lo, int *hi) {
  double xl = 0, xh = t->w - 1;
  const double scale = 0.5 * j->cam.width / j->cam.half_w, shift = 0.5 * j->cam.width - 0.5 - t->x0;
  for (int i = 0; i < 3; i++) {
    if (b[i] == 0) {
      if (r[i] < 0) xh = -1;
      continue;
    }
    const double x = -r[i] * inv_b[i] * scale + shift; /* the column whose centre is on the edge */
    if (b[i] > 0 && x - 1 > xl) xl = x - 1;            /* NaN leaves the bound */
    if (b[i] < 0 && x + 1 < xh) xh = x + 1;
  }
  if (!(xl <= xh)) { /* also infinities: xl <= xh keeps both inside [0, w - 1] */
    *lo = *hi = 0;
    return;
  }
  *lo = (int)xl; /* floor: xl >= 0 */
  *hi = (int)xh + 1;
  if (*hi < t->w && *hi <= xh) (*hi)++; /* ceil */
}

/* One row's pixels [lo, hi) of a triangle, one pixel and one test after another: the reference
 * of persp_row, and the orthographic camera's loop (a numerator per ray origin). */
static void plain_row(const rs_job *j, rs_tile *t, int y, int lo, int hi, const double r[3],
                      const double b[3], const double n[3], const float *v0, double num,
                      double zmin, uint32_t id) {
  for (int x = lo; x < hi; x++) {
    const double sx = t->sx[x];
    const int p = y * OBS_TILE + x;
    if (!(zmin < t->t[p])) continue;
    if (!(r[0] + sx * b[0] >= 0 && r[1] + sx * b[1] >= 0 && r[2] + sx * b[2] >= 0)) continue;
    double tp, o[3], d[3];
    ray_at(j, t, p, o, d);
    const int hit = j->cam.ortho ? obs_rt_plane_hit(n, v0, o, d, &tp)
                                 : obs_rt_plane_t(num, n, d, &tp);
    if (hit && tp < t->t[p]) {
      t->t[p] = tp;
      t->win[p] = id;
    }
  }
}

/* One row's pixels [lo, hi) of a perspective triangle: plain_row's tests and plane
 * parameter in the same operations, without branches, so that the compiler runs several pixels
 * per instruction (each lane's add, multiply, divide and compare round as the scalar ones do).
 * A pixel whose tests fail keeps its hit; the division on it is wasted but harmless. */
static inline __attribute__((always_inline)) void persp_row_body(
    rs_tile *t, int y, int lo, int hi, const double r[3], const double b[3], const double n[3],
    double num, double zmin, uint32_t id) {
  const double *restrict rx = t->ray[0] + y * OBS_TILE, *restrict ry = t->ray[1] + y * OBS_TILE;
  const double *restrict rz = t->ray[2] + y * OBS_TILE, *restrict sx = t->sx;
  double *restrict tt = t->t + y * OBS_TILE;
  uint32_t *restrict win = t->win + y * OBS_TILE;
  const double r0 = r[0], r1 = r[1], r2 = r[2], b0 = b[0], b1 = b[1], b2 = b[2];
  const double n0 = n[0], n1 = n[1], n2 = n[2];
  for (int x = lo; x < hi; x++) {
    const double e0 = r0 + sx[x] * b0, e1 = r1 + sx[x] * b1, e2 = r2 + sx[x] * b2;
    const double dn = n0 * rx[x] + n1 * ry[x] + n2 * rz[x]; /* obs_rt_plane_t */
    const double tp = num / dn, cur = tt[x];
    const int take = (zmin < cur) & (e0 >= 0) & (e1 >= 0) & (e2 >= 0) & (dn != 0) & (tp >= 0) &
                     (tp <= DBL_MAX) & (tp < cur);
    tt[x] = take ? tp : cur;
    win[x] = take ? id : win[x];
  }
}
static void persp_row_base(rs_tile *t, int y, int lo, int hi, const double r[3],
                           const double b[3], const double n[3], double num, double zmin,
                           uint32_t id) {
  persp_row_body(t, y, lo, hi, r, b, n, num, zmin, id);
}
OBS_V3_FN static void persp_row_v3(rs_tile *t, int y, int lo, int hi, const double r[3],
                                   const double b[3], const double n[3], double num, double zmin,
                                   uint32_t id) {
  persp_row_body(t, y, lo, hi, r, b, n, num, zmin, id);
}

/* A triangle's pixels in the tile: the rows' spans, then the pixels of each span. */
static void draw_triangle(const rs_job *j, rs_tile *t, uint32_t id, const rs_box *bx) {
  size_t mesh;
  const float *v[3];
  tri_verts(j, id, &mesh, v);
  double a[3], b[3], c[3], n[3], zmin;
  if (!edge_functions(j, v, a, b, c, &zmin)) return;
  /* Pixels already nearer than the whole triangle skip the division; shrunk far beyond the
   * rounding of either depth, so that no pixel the triangle would win is skipped. */
  zmin = zmin > 0 ? zmin * (1 - 0x1p-30) : -INFINITY;
  obs_rt_plane_normal(v[0], v[1], v[2], n);
  /* Perspective rays share their origin, and so the plane parameter's numerator. */
  const double num = obs_rt_plane_num(n, v[0], j->view.eye);
  int xa = bx->x0 > t->x0 ? bx->x0 - t->x0 : 0, xb = bx->x1 - t->x0 < t->w ? bx->x1 - t->x0 : t->w;
  int ya = bx->y0 > t->y0 ? bx->y0 - t->y0 : 0, yb = bx->y1 - t->y0 < t->h ? bx->y1 - t->y0 : t->h;
  /* Spans pay off on rows wider than a few pixels. */
  const int spans = xb - xa > 6, plain = j->reference || j->cam.ortho;
  const double inv_b[3] = {1 / b[0], 1 / b[1], 1 / b[2]};
  for (int y = ya; y < yb; y++) {
    const double sy = t->sy[y];
    const double r[3] = {a[0] + sy * c[0], a[1] + sy * c[1], a[2] + sy * c[2]};
    int lo = xa, hi = xb;
    if (spans) {
      row_span(j, t, r, b, inv_b, &lo, &hi);
      if (lo < xa) lo = xa;
      if (hi > xb) hi = xb;
    }
    if (plain)
      plain_row(j, t, y, lo, hi, r, b, n, v[0], num, zmin, id);
    else if (lo < hi)
      j->row(t, y, lo, hi, r, b, n, num, zmin, id);
  }
}

static void draw_sphere(const rs_job *j, rs_tile *t, uint32_t id, const rs_box *bx) {
  const obs_sphere *s = &j->geo->spheres[id - j->ntris];
  int xa = bx->x0 > t->x0 ? bx->x0 - t->x0 : 0, xb = bx->x1 - t->x0 < t->w ? bx->x1 - t->x0 : t->w;
  int ya = bx->y0 > t->y0 ? bx->y0 - t->y0 : 0, yb = bx->y1 - t->y0 < t->h ? bx->y1 - t->y0 : t->h;
  for (int y = ya; y < yb; y++)
    for (int x = xa; x < xb; x++) {
      const int p = y * OBS_TILE + x;
      double o[3], d[3];
      ray_at(j, t, p, o, d);
      const double td = obs_rt_sphere_root(s, o, d, 0.0, INFINITY, 0);
      if (td >= 0 && isfinite(td) && td < t->t[p]) {
        t->t[p] = td;
        t->win[p] = id;
      }
    }
}

/* The winner's unit face normal in the ray tracer's frame, before facing (as the ray cast
 * derives it: the triangle's double plane normal, the sphere's radius direction). */
static void winner_normal(const rs_job *j, uint32_t id, const double ro[3], const double rd[3],
                          double t, double ng[3]) {
  if (id >= j->ntris) {
    const obs_sphere *s = &j->geo->spheres[id - j->ntris];
    for (int k = 0; k < 3; k++) ng[k] = ro[k] + t * rd[k] - s->center[k];
    if (obs_normalize3d(ng)) ng[0] = 0, ng[1] = 0, ng[2] = 1;
    return;
  }
  size_t mesh;
  const float *v[3];
  tri_verts(j, id, &mesh, v);
  obs_rt_plane_normal(v[0], v[1], v[2], ng);
  if (obs_normalize3d(ng)) ng[0] = ng[1] = ng[2] = 0;
}

static const obs_object *winner_object(const rs_job *j, uint32_t id) {
  if (id >= j->ntris) return &j->scene->objects[j->geo->spheres[id - j->ntris].object];
  return &j->scene->objects[j->geo->meshes[mesh_of(j, id)].object];
}

/* The winner's faced normals (both ways, vn[0] along `unit`) and albedo, set up again only when
 * the winner changes from `*last`; a sphere's normal changes with every pixel. Both ways are
 * stored rather than negated afterwards, since the signs of zero sums would differ. */
static void winner_face(const rs_job *j, const rs_tile *t, int p, uint32_t id, uint32_t *last,
                        double unit[3], float vn[2][3], float albedo[3]) {
  if (id < j->ntris && id == *last) return;
  double ro[3], rd[3];
  ray_at(j, t, p, ro, rd);
  winner_normal(j, id, ro, rd, t->t[p], unit);
  const double back[3] = {-unit[0], -unit[1], -unit[2]};
  obs_gbuffer_view_normal(&j->cam, unit, vn[0]);
  obs_gbuffer_view_normal(&j->cam, back, vn[1]);
  if (id != *last) obs_gbuffer_albedo(winner_object(j, id), albedo);
  *last = id;
}

/* Writes the tile's nearest hits into the G-buffer (the reference of resolve_tile); a triangle's
 * normals are set up once per run of its pixels (winner_face). */
static void resolve_tile_ref(const rs_job *j, const rs_tile *t) {
  obs_gbuffer *g = j->g;
  uint32_t last = UINT32_MAX;
  double unit[3] = {0, 0, 0};
  float vn[2][3] = {{0, 0, 0}, {0, 0, 0}}, albedo[3] = {0, 0, 0};
  for (int y = 0; y < t->h; y++)
    for (int x = 0; x < t->w; x++) {
      const int p = y * OBS_TILE + x;
      const uint32_t id = t->win[p];
      if (id == UINT32_MAX) continue;
      double ro[3], rd[3];
      ray_at(j, t, p, ro, rd);
      winner_face(j, t, p, id, &last, unit, vn, albedo);
      const int face = unit[0] * rd[0] + unit[1] * rd[1] + unit[2] * rd[2] > 0;
      const size_t i = (size_t)(t->y0 + y) * (size_t)g->width + (size_t)(t->x0 + x);
      g->depth[i] = (float)t->t[p];
      g->coverage[i] = 1.0f;
      memcpy(g->normal + 3 * i, vn[face], sizeof vn[face]);
      memcpy(g->albedo + 3 * i, albedo, sizeof albedo);
    }
}

/* Copies n floats to the image with stores that bypass the caches: the G-buffer (32 bytes a
 * pixel) is far larger than them, and an ordinary store first reads each line it writes. Whole
 * rows of a tile at a time, so the write-combining buffers fill complete lines. */
static void stream_out(float *dst, const float *src, size_t n) {
  size_t i = 0;
#if defined(__SSE2__)
  for (; i < n && ((uintptr_t)(dst + i) & 15); i++) {
    int bits;
    memcpy(&bits, src + i, sizeof bits);
    _mm_stream_si32((int *)(dst + i), bits);
  }
  for (; i + 4 <= n; i += 4) _mm_stream_ps(dst + i, _mm_loadu_ps(src + i));
  for (; i < n; i++) {
    int bits;
    memcpy(&bits, src + i, sizeof bits);
    _mm_stream_si32((int *)(dst + i), bits);
  }
#endif
  if (i < n) memcpy(dst + i, src + i, (n - i) * sizeof *dst);
}

/* Row n pixels from image pixel i: the four buffers' values. */
static void stream_row(const obs_gbuffer *g, size_t i, size_t n, const float *depth,
                       const float *cover, const float *normal, const float *color) {
  stream_out(g->depth + i, depth, n);
  stream_out(g->coverage + i, cover, n);
  stream_out(g->normal + 3 * i, normal, 3 * n);
  stream_out(g->albedo + 3 * i, color, 3 * n);
}

/* The streaming stores reach memory before the pass reports the tile done. */
static void stream_fence(void) {
#if defined(__SSE2__)
  _mm_sfence();
#endif
}

/* resolve_tile_ref's values, a row of the tile at a time into small buffers (uncovered pixels
 * get the image's zeros again), then streamed out; what the loop reads held in locals. */
static void resolve_tile(const rs_job *j, const rs_tile *t) {
  if (j->reference) {
    resolve_tile_ref(j, t);
    return;
  }
  const obs_gbuffer *g = j->g;
  const size_t width = (size_t)g->width;
  const int ortho = j->cam.ortho;
  const double f0 = j->view.forward[0], f1 = j->view.forward[1], f2 = j->view.forward[2];
  uint32_t last = UINT32_MAX;
  double unit[3] = {0, 0, 0};
  float vn[2][3] = {{0, 0, 0}, {0, 0, 0}}, albedo[3] = {0, 0, 0};
  float depth[OBS_TILE], cover[OBS_TILE], normal[3 * OBS_TILE], color[3 * OBS_TILE];
  for (int y = 0; y < t->h; y++) {
    for (int x = 0; x < t->w; x++) {
      const int p = y * OBS_TILE + x;
      const uint32_t id = t->win[p];
      if (id == UINT32_MAX) {
        depth[x] = cover[x] = 0;
        for (int k = 0; k < 3; k++) normal[3 * x + k] = color[3 * x + k] = 0;
        continue;
      }
      const double dx = ortho ? f0 : t->ray[0][p], dy = ortho ? f1 : t->ray[1][p];
      const double dz = ortho ? f2 : t->ray[2][p];
      winner_face(j, t, p, id, &last, unit, vn, albedo);
      const float *nv = vn[unit[0] * dx + unit[1] * dy + unit[2] * dz > 0];
      depth[x] = (float)t->t[p];
      cover[x] = 1.0f;
      for (int k = 0; k < 3; k++) normal[3 * x + k] = nv[k], color[3 * x + k] = albedo[k];
    }
    stream_row(g, (size_t)(t->y0 + y) * width + (size_t)t->x0, (size_t)t->w, depth, cover, normal,
               color);
  }
  stream_fence();
}

static int raster_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const rs_job *j = user;
  const size_t tile = (size_t)(y0 / OBS_TILE) * j->tiles_x + (size_t)(x0 / OBS_TILE);
  if (j->bin_start[tile] == j->bin_start[tile + 1]) { /* nothing here: zeros */
    static const float zero[3 * OBS_TILE];
    for (int y = y0; y < y1; y++)
      stream_row(j->g, (size_t)y * (size_t)j->g->width + (size_t)x0, (size_t)(x1 - x0), zero, zero,
                 zero, zero);
    stream_fence();
    return 0;
  }
  rs_tile *t = malloc(sizeof *t);
  if (!t) return OBS_ENOMEM;
  t->x0 = x0, t->y0 = y0, t->w = x1 - x0, t->h = y1 - y0;
  const obs_camera_rig *cam = &j->cam;
  /* The ray cast's image-plane offsets and rays (gb_tile, obs_rt_view_ray). */
  for (int x = 0; x < t->w; x++) t->sx[x] = obs_rt_view_sx(cam, x0 + x + 0.5);
  for (int y = 0; y < t->h; y++) t->sy[y] = obs_rt_view_sy(cam, y0 + y + 0.5);
  for (int p = 0; p < OBS_TILE * OBS_TILE; p++) t->t[p] = INFINITY;
  for (int p = 0; p < OBS_TILE * OBS_TILE; p++) t->win[p] = UINT32_MAX;
  /* obs_rt_view_ray's expressions, a row at a time. */
  const obs_rt_view *v = &j->view;
  const double *base = j->cam.ortho ? v->eye : v->forward;
  for (int k = 0; k < 3; k++)
    for (int y = 0; y < t->h; y++) {
      const double sy = t->sy[y], b = base[k], r = v->right[k], u = v->up[k];
      double *row = t->ray[k] + y * OBS_TILE;
      for (int x = 0; x < t->w; x++) row[x] = b + (t->sx[x] * r + sy * u);
    }
  for (size_t e = j->bin_start[tile]; e < j->bin_start[tile + 1]; e++) {
    const uint32_t id = j->bin[e];
    if (id < j->ntris)
      draw_triangle(j, t, id, &j->box[id]);
    else
      draw_sphere(j, t, id, &j->box[id]);
  }
  resolve_tile(j, t);
  free(t);
  return 0;
}

static void rs_free(rs_job *j) {
  free(j->mesh_base);
  free(j->box);
  free(j->bin_start);
  free(j->bin);
}

/* The raster's set-up: every primitive's box on the image, the tiles' counts and j->tests. */
static int rs_prepare(rs_job *j, const obs_scene *sc, const obs_geometry *geo, int threads,
                      obs_err *err) {
  memset(j, 0, sizeof *j);
  j->scene = sc;
  j->geo = geo;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &j->cam);
  obs_rt_view_init(&j->cam, geo->origin, &j->view);
  j->ntris = geo->ntris;
  j->nprims = geo->ntris + geo->nspheres;
  if (j->nprims >= UINT32_MAX)
    return obs_err_set(err, OBS_EINVAL, "%s: %zu primitives are too many to rasterise", sc->name,
                       j->nprims);
  j->tiles_x = (sc->width + OBS_TILE - 1) / OBS_TILE;
  j->tiles_y = (sc->height + OBS_TILE - 1) / OBS_TILE;
  j->mesh_base = malloc((geo->nmeshes + 1) * sizeof *j->mesh_base);
  j->box = malloc((j->nprims ? j->nprims : 1) * sizeof *j->box);
  int rc = j->mesh_base && j->box ? 0 : OBS_ENOMEM;
  if (!rc) {
    j->mesh_base[0] = 0;
    for (size_t m = 0; m < geo->nmeshes; m++)
      j->mesh_base[m + 1] = j->mesh_base[m] + geo->meshes[m].ntris;
    /* Enough columns for every thread to take several tiles of them. */
    const int nt = threads < 1 ? 1 : threads;
    j->chunk = j->nprims / ((size_t)OBS_TILE * (size_t)nt * 4) + 1;
    if (j->chunk < 256) j->chunk = 256;
    const size_t cols = (j->nprims + j->chunk - 1) / j->chunk;
    if (cols) rc = obs_parallel_tiles((int)cols, 1, threads, setup_chunk, j, NULL, NULL, NULL);
  }
  if (!rc) rc = count_bins(j);
  if (rc) return obs_err_set(err, rc, "%s: G-buffer rasterisation failed", sc->name);
  return 0;
}

/* The pass over the tiles, into a new G-buffer `g`. */
static int rs_draw(rs_job *j, obs_gbuffer *g, int threads, double *render_ms, obs_err *err) {
  const obs_scene *sc = j->scene;
  /* resolve_tile writes every pixel; the reference only the covered ones. */
  int rc = j->reference ? obs_gbuffer_alloc(g, sc->width, sc->height, &j->cam, err)
                        : obs_gbuffer_alloc_unset(g, sc->width, sc->height, &j->cam, err);
  if (rc) return rc;
  const double t0 = obs_now_ms();
  j->g = g;
  j->row = obs_simd_isa() >= OBS_ISA_AVX2 ? persp_row_v3 : persp_row_base;
  rc = fill_bins(j);
  if (!rc)
    rc = obs_parallel_tiles(sc->width, sc->height, threads, raster_tile, j, NULL, NULL, NULL);
  if (render_ms) *render_ms += obs_now_ms() - t0;
  if (rc) {
    obs_gbuffer_free(g);
    return obs_err_set(err, rc, "%s: G-buffer rasterisation failed", sc->name);
  }
  return 0;
}

int obs_gbuffer_raster_geo(const obs_scene *sc, const obs_geometry *geo, obs_gbuffer *g,
                           int threads, double *render_ms, obs_err *err) {
  rs_job j;
  const double t0 = obs_now_ms();
  int rc = rs_prepare(&j, sc, geo, threads, err);
  if (render_ms) *render_ms = obs_now_ms() - t0;
  if (!rc) rc = rs_draw(&j, g, threads, render_ms, err);
  rs_free(&j);
  return rc;
}

/* Rasterising costs a set-up per triangle plus a test per pixel of every triangle's box; the ray
 * cast a BVH build per triangle (several times the set-up) plus a traversal per pixel that grows
 * slowly with depth complexity. Measured with bench_gbuffer (docs/architecture.md, "CPU
 * G-buffer"), the raster wins on every bundled scene up to 14 triangles per pixel, and the ray
 * cast only where the boxes overlap each pixel more than OBS_GBUFFER_RAYCAST_TESTS times. */
#define OBS_GBUFFER_RAYCAST_TESTS 10.0

int obs_gbuffer_method(double tests, size_t pixels) {
  const char *force = getenv("OBSCURA_GBUFFER");
  if (force && !strcmp(force, "raster")) return OBS_GBUFFER_RASTER;
  if (force && !strcmp(force, "raycast")) return OBS_GBUFFER_RAYCAST;
  return tests <= OBS_GBUFFER_RAYCAST_TESTS * (double)pixels ? OBS_GBUFFER_RASTER
                                                             : OBS_GBUFFER_RAYCAST;
}

/* method < 0: obs_gbuffer_method's choice, after the raster's set-up (which the ray cast then
 * wastes: a small share of its BVH build). */
static int gbuffer_cpu(const obs_scene *sc, int method, int reference, obs_gbuffer *g,
                       int threads, double *build_ms, double *render_ms, obs_err *err) {
  const double t0 = obs_now_ms();
  const double eye[3] = {sc->camera.position.x, sc->camera.position.y, sc->camera.position.z};
  obs_geometry geo;
  int rc = obs_geometry_build_at(sc, eye, &geo, err);
  if (rc) return rc;
  const double t1 = obs_now_ms();
  if (build_ms) *build_ms = t1 - t0;
  rs_job j;
  memset(&j, 0, sizeof j);
  if (method != OBS_GBUFFER_RAYCAST) {
    rc = rs_prepare(&j, sc, &geo, threads, err);
    if (!rc && method < 0)
      method = obs_gbuffer_method(j.tests, (size_t)sc->width * (size_t)sc->height);
  }
  const double t2 = obs_now_ms();
  if (!rc && method == OBS_GBUFFER_RAYCAST) {
    rs_free(&j);
    double bvh_ms = 0;
    rc = obs_gbuffer_raycast_geo(sc, &geo, g, threads, &bvh_ms, render_ms, err);
    if (build_ms) *build_ms += t2 - t1 + bvh_ms;
    return rc;
  }
  if (render_ms) *render_ms = t2 - t1;
  j.reference = reference;
  if (!rc) rc = rs_draw(&j, g, threads, render_ms, err);
  rs_free(&j);
  obs_geometry_free(&geo);
  return rc;
}

int obs_gbuffer_raster_tests(const obs_scene *sc, int threads, double *tests, obs_err *err) {
  const double eye[3] = {sc->camera.position.x, sc->camera.position.y, sc->camera.position.z};
  obs_geometry geo;
  int rc = obs_geometry_build_at(sc, eye, &geo, err);
  if (rc) return rc;
  rs_job j;
  rc = rs_prepare(&j, sc, &geo, threads, err);
  *tests = j.tests;
  rs_free(&j);
  obs_geometry_free(&geo);
  return rc;
}

int obs_gbuffer_cpu(const obs_scene *sc, obs_gbuffer *g, int threads, double *build_ms,
                    double *render_ms, obs_err *err) {
  return gbuffer_cpu(sc, -1, 0, g, threads, build_ms, render_ms, err);
}

int obs_gbuffer_raycast(const obs_scene *sc, obs_gbuffer *g, int threads, double *build_ms,
                        double *render_ms, obs_err *err) {
  return gbuffer_cpu(sc, OBS_GBUFFER_RAYCAST, 0, g, threads, build_ms, render_ms, err);
}

int obs_gbuffer_raster(const obs_scene *sc, obs_gbuffer *g, int threads, double *build_ms,
                       double *render_ms, obs_err *err) {
  return gbuffer_cpu(sc, OBS_GBUFFER_RASTER, 0, g, threads, build_ms, render_ms, err);
}

int obs_gbuffer_raster_reference(const obs_scene *sc, obs_gbuffer *g, int threads, obs_err *err) {
  return gbuffer_cpu(sc, OBS_GBUFFER_RASTER, 1, g, threads, NULL, NULL, err);
}
