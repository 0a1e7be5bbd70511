/* Host-side clipping of camera-relative triangles for the G-buffer rasteriser. A rasteriser snaps
 * vertices to a fixed-point grid of limited range (lavapipe: 8 sub-pixel bits in a guard band of a
 * few viewports) and clips what lies beyond in float clip space, so a triangle reaching far past
 * the view or behind the camera loses precision or vanishes there. Clipped here in double to a
 * guard band twice the view, every vertex the device sees lies within a few viewports of it. */
#include "gbuffer_clip.h"

#include <math.h>
#include <string.h>

/* Triangles within 4x the view's half-extents pass unchanged (ordinary scenes keep their bits);
 * others are cut at 2x, well inside any guard band a Vulkan device must have (the viewport
 * bounds range is at least twice the largest viewport). */
#define KEEP_BAND 4.0
#define CUT_BAND 2.0
#define NPLANES 5

void obs_vk_clip_init(obs_vk_clip *c, const obs_camera_rig *rig, double znear) {
  memset(c, 0, sizeof *c);
  memcpy(c->right, rig->right, sizeof c->right);
  memcpy(c->up, rig->up, sizeof c->up);
  memcpy(c->forward, rig->forward, sizeof c->forward);
  c->ortho = rig->ortho;
  c->keep_x = KEEP_BAND * rig->half_w;
  c->keep_y = KEEP_BAND * rig->half_h;
  c->cut_x = CUT_BAND * rig->half_w;
  c->cut_y = CUT_BAND * rig->half_h;
  c->znear = znear;
  c->zmin = INFINITY;
  c->zmax = -INFINITY;
}

typedef struct cvert {
  double p[3]; /* camera-relative position */
  double v[3]; /* view coordinates (right, up, forward) */
} cvert;

static void view_of(const obs_vk_clip *c, cvert *q) {
  const double *p = q->p;
  q->v[0] = p[0] * c->right[0] + p[1] * c->right[1] + p[2] * c->right[2];
  q->v[1] = p[0] * c->up[0] + p[1] * c->up[1] + p[2] * c->up[2];
  q->v[2] = p[0] * c->forward[0] + p[1] * c->forward[1] + p[2] * c->forward[2];
}

/* Signed distance-like value of plane k (>= 0 inside) for half-extents (hx, hy). */
static double plane(const obs_vk_clip *c, int k, double hx, double hy, const double v[3]) {
  double sx = c->ortho ? hx : hx * v[2], sy = c->ortho ? hy : hy * v[2];
  switch (k) {
  case 0: return v[2] - c->znear;
  case 1: return sx - v[0];
  case 2: return sx + v[0];
  case 3: return sy - v[1];
  default: return sy + v[1];
  }
}

static int inside_all(const obs_vk_clip *c, double hx, double hy, const double v[3]) {
  for (int k = 0; k < NPLANES; k++)
    if (!(plane(c, k, hx, hy, v) >= 0.0)) return 0;
  return 1;
}

static void track(obs_vk_clip *c, double z) {
  if (z < c->zmin) c->zmin = z;
  if (z > c->zmax) c->zmax = z;
}

/* One Sutherland-Hodgman stage. The crossing point is always computed from the inside end toward
 * the outside end, so the two triangles sharing an edge get the same point (no cracks). */
static int clip_plane(const obs_vk_clip *c, int k, const cvert *in, int n, cvert *out) {
  int m = 0;
  for (int i = 0; i < n; i++) {
    const cvert *a = &in[i], *b = &in[(i + 1) % n];
    double da = plane(c, k, c->cut_x, c->cut_y, a->v), db = plane(c, k, c->cut_x, c->cut_y, b->v);
    int ia = da >= 0.0, ib = db >= 0.0;
    if (ia) out[m++] = *a;
    if (ia != ib) {
      const cvert *s = ia ? a : b, *o = ia ? b : a;
      double ds = ia ? da : db, dout = ia ? db : da;
      double t = ds / (ds - dout);
      cvert *q = &out[m++];
      for (int j = 0; j < 3; j++) q->p[j] = s->p[j] + t * (o->p[j] - s->p[j]);
      view_of(c, q);
    }
  }
  return m;
}

size_t obs_vk_clip_triangle(obs_vk_clip *c, const float tri[9], float *out) {
  cvert poly[2][NPLANES + 3];
  int keep = 1;
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) poly[0][i].p[j] = tri[3 * i + j];
    view_of(c, &poly[0][i]);
    keep = keep && inside_all(c, c->keep_x, c->keep_y, poly[0][i].v);
  }
  if (keep) {
    for (int i = 0; i < 3; i++) track(c, poly[0][i].v[2]);
    if (out) memcpy(out, tri, 9 * sizeof(float));
    return 3;
  }
  int n = 3, cur = 0;
  for (int k = 0; k < NPLANES && n > 0; k++) {
    n = clip_plane(c, k, poly[cur], n, poly[cur ^ 1]);
    cur ^= 1;
  }
  if (n < 3) return 0;
  for (int i = 0; i < n; i++) track(c, poly[cur][i].v[2]);
  if (out) {
    /* A fan: the polygon is convex. */
    for (int i = 1; i + 1 < n; i++) {
      const cvert *f[3] = {&poly[cur][0], &poly[cur][i], &poly[cur][i + 1]};
      for (int a = 0; a < 3; a++)
        for (int j = 0; j < 3; j++) *out++ = (float)f[a]->p[j];
    }
  }
  return 3 * (size_t)(n - 2);
}
