/* Host-side preparation of the G-buffer rasteriser's triangles, in double (long double where a
 * huge triangle is cut). A rasteriser snaps vertices to a fixed-point grid of limited range
 * (lavapipe: 8 sub-pixel bits in a guard band of a few viewports) and clips what lies beyond in
 * float clip space, so a triangle reaching far past the view or behind the camera loses precision
 * or vanishes there; it also interpolates 1/w linearly in screen space in float, whose absolute
 * error is relative to the triangle's nearest point, so depth at its far end errs by float epsilon
 * times its depth ratio. Here every triangle is rotated into view space, clipped to a guard band
 * twice the view and to the near plane, and, in perspective, cut into slabs whose far depth is at
 * most DEPTH_RATIO times their near depth. The rotation is done here rather than on the device
 * because in float it errs by ~1e-7 of the distance from the camera, a whole pixel at a field of
 * view of ~1e-5 radians; the face normal is computed here too, from the double vertices, because
 * screen-space derivatives of float positions lose it at tiny fields of view. */
#include "gbuffer_clip.h"

#include <math.h>
#include <string.h>

/* Triangles within 4x the view's half-extents (and within the depth ratio) pass uncut; others are
 * cut at 2x, well inside any guard band a Vulkan device must have (its viewport bounds range is
 * at least twice the largest viewport). */
#define KEEP_BAND 4.0
#define CUT_BAND 2.0
#define DEPTH_RATIO 4.0
#define NPLANES 5
/* A triangle cut by five planes has at most 8 corners; a slab of it adds 2. */
#define MAX_POLY 12

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

/* New vertices are interpolated in camera-relative world coordinates, not view coordinates: a
 * triangle far larger than the view then keeps its plane to the rounding of its own coordinates
 * (exactly when it is axis-aligned, as the ray caster's double re-intersection does), where a
 * rotation first would mix ~1e-16 of its far vertices' size into the plane near the camera. */
typedef obs_vk_clip_vertex cvert;

/* The cutting path works in long double (a 64-bit significand on x86-64): a crossing point near
 * the camera is interpolated between vertices that may be ~1e18 away, and double would place it
 * only to ~1e-16 of that (~200 units), more than the guard band's margin. */
typedef long double wide;
typedef struct wvert {
  wide p[3]; /* camera-relative world position */
  wide v[3]; /* view coordinates */
} wvert;

static void view_of(const obs_vk_clip *c, cvert *q) {
  const double *p = q->p;
  q->v[0] = p[0] * c->right[0] + p[1] * c->right[1] + p[2] * c->right[2];
  q->v[1] = p[0] * c->up[0] + p[1] * c->up[1] + p[2] * c->up[2];
  q->v[2] = p[0] * c->forward[0] + p[1] * c->forward[1] + p[2] * c->forward[2];
}

static void wview_of(const obs_vk_clip *c, wvert *q) {
  const wide *p = q->p;
  q->v[0] = p[0] * c->right[0] + p[1] * c->right[1] + p[2] * c->right[2];
  q->v[1] = p[0] * c->up[0] + p[1] * c->up[1] + p[2] * c->up[2];
  q->v[2] = p[0] * c->forward[0] + p[1] * c->forward[1] + p[2] * c->forward[2];
}

static void between(const obs_vk_clip *c, const wvert *s, const wvert *o, wide t, wvert *q) {
  for (int j = 0; j < 3; j++) q->p[j] = s->p[j] + t * (o->p[j] - s->p[j]);
  wview_of(c, q);
}

/* >= 0 inside plane k of the band with half-extents (hx, hy) (slopes when perspective). */
static wide plane(const obs_vk_clip *c, int k, double hx, double hy, const wide v[3]) {
  wide sx = c->ortho ? hx : hx * v[2], sy = c->ortho ? hy : hy * v[2];
  switch (k) {
  case 0: return v[2] - c->znear;
  case 1: return sx - v[0];
  case 2: return sx + v[0];
  case 3: return sy - v[1];
  default: return sy + v[1];
  }
}

void obs_vk_clip_vertex_init(const obs_vk_clip *c, const double p[3], obs_vk_clip_vertex *out) {
  memcpy(out->p, p, sizeof out->p);
  view_of(c, out);
  double sx = c->ortho ? c->keep_x : c->keep_x * out->v[2];
  double sy = c->ortho ? c->keep_y : c->keep_y * out->v[2];
  out->band = sx - out->v[0] >= 0.0 && sx + out->v[0] >= 0.0 && sy - out->v[1] >= 0.0 &&
              sy + out->v[1] >= 0.0;
}

/* One Sutherland-Hodgman stage against plane k of the cut band. The crossing point is computed
 * from the end nearer to the plane, a choice made from the edge's two ends alone, so the two
 * triangles sharing an edge get the same point (no cracks). From the far end the fraction would
 * round to 1 when one end lies far inside and the other just outside (geometry through the eye,
 * against the near plane), and the crossing would fall onto the outside end. */
static int clip_plane(const obs_vk_clip *c, int k, const wvert *in, int n, wvert *out) {
  int m = 0;
  for (int i = 0; i < n; i++) {
    const wvert *a = &in[i], *b = &in[(i + 1) % n];
    wide da = plane(c, k, c->cut_x, c->cut_y, a->v), db = plane(c, k, c->cut_x, c->cut_y, b->v);
    int ia = da >= 0, ib = db >= 0;
    if (ia) out[m++] = *a;
    if (ia != ib) {
      const wvert *s = ia ? a : b, *o = ia ? b : a;
      wide ds = ia ? da : db, dout = ia ? db : da;
      if (ds <= -dout)
        between(c, s, o, ds / (ds - dout), &out[m++]);
      else
        between(c, o, s, dout / (dout - ds), &out[m++]);
    }
  }
  return m;
}

/* Keeps the part of the polygon with z >= zc (upper) or z <= zc. The crossing is computed from the
 * nearer end whichever side is kept, so both slabs, and the neighbouring triangle, share it. */
static int clip_depth(const obs_vk_clip *c, const wvert *in, int n, wide zc, int upper,
                      wvert *out) {
  int m = 0;
  for (int i = 0; i < n; i++) {
    const wvert *a = &in[i], *b = &in[(i + 1) % n];
    int ia = upper ? a->v[2] >= zc : a->v[2] <= zc, ib = upper ? b->v[2] >= zc : b->v[2] <= zc;
    if (ia) out[m++] = *a;
    if (ia != ib) {
      const wvert *s = a->v[2] < b->v[2] ? a : b, *o = s == a ? b : a;
      between(c, s, o, (zc - s->v[2]) / (o->v[2] - s->v[2]), &out[m++]);
    }
  }
  return m;
}

typedef struct emitter {
  obs_vk_clip *c;
  float *out;
  float nrm[3];
  size_t n;
} emitter;

static void emit_vertex(emitter *e, const double v[3]) {
  if (v[2] < e->c->zmin) e->c->zmin = v[2];
  if (v[2] > e->c->zmax) e->c->zmax = v[2];
  if (e->out) {
    float *o = e->out + OBS_VK_CLIP_FLOATS * e->n;
    for (int j = 0; j < 3; j++) o[j] = (float)v[j];
    memcpy(o + 3, e->nrm, sizeof e->nrm);
  }
  e->n++;
}

static void emit_wvertex(emitter *e, const wvert *q) {
  double v[3] = {(double)q->v[0], (double)q->v[1], (double)q->v[2]};
  emit_vertex(e, v);
}

/* A fan: the polygon is convex. */
static void emit_polygon(emitter *e, const wvert *p, int n) {
  for (int i = 1; i + 1 < n; i++) {
    emit_wvertex(e, &p[0]);
    emit_wvertex(e, &p[i]);
    emit_wvertex(e, &p[i + 1]);
  }
}

/* Cuts the polygon into slabs between depths znear * DEPTH_RATIO^k, so slabs of neighbouring
 * triangles meet at the same depths. */
static void emit_slabs(emitter *e, const wvert *p, int n) {
  wide lo = INFINITY, hi = -INFINITY;
  for (int i = 0; i < n; i++) {
    lo = p[i].v[2] < lo ? p[i].v[2] : lo;
    hi = p[i].v[2] > hi ? p[i].v[2] : hi;
  }
  const obs_vk_clip *c = e->c;
  /* The near-plane cut leaves lo within rounding of znear; below it (or a non-finite depth) the
   * slab walk below would have no start or no end. */
  if (!(lo >= c->znear)) lo = c->znear;
  if (c->ortho || !(c->znear > 0.0) || !isfinite((double)hi) || !(hi > DEPTH_RATIO * lo)) {
    emit_polygon(e, p, n);
    return;
  }
  wide z = c->znear * pow(DEPTH_RATIO, floor(log((double)lo / c->znear) / log(DEPTH_RATIO)));
  while (z > lo) z /= DEPTH_RATIO; /* log's rounding, either way */
  while (!(z * DEPTH_RATIO > lo)) z *= DEPTH_RATIO;
  wvert a[MAX_POLY], b[MAX_POLY];
  for (; z < hi; z *= DEPTH_RATIO) {
    int m = clip_depth(c, p, n, z, 1, a);
    m = m >= 3 ? clip_depth(c, a, m, z * DEPTH_RATIO, 0, b) : 0;
    if (m >= 3) emit_polygon(e, b, m);
  }
}

/* The unit face normal of the triangle in view space, from double vertices, each edge and the
 * product scaled by its largest component first so nothing over- or underflows. */
static void face_normal(const cvert *a, const cvert *b, const cvert *d, float out[3]) {
  double e[2][3];
  const cvert *to[2] = {b, d};
  for (int k = 0; k < 2; k++) {
    double m = 0;
    for (int j = 0; j < 3; j++) {
      e[k][j] = to[k]->v[j] - a->v[j];
      m = fmax(m, fabs(e[k][j]));
    }
    double s = m > 0 ? 1.0 / m : 0.0;
    for (int j = 0; j < 3; j++) e[k][j] *= s;
  }
  double n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                 e[0][0] * e[1][1] - e[0][1] * e[1][0]};
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  double s = l > 0 ? 1.0 / l : 0.0;
  for (int j = 0; j < 3; j++) out[j] = (float)(n[j] * s);
}

size_t obs_vk_clip_triangle(obs_vk_clip *c, const obs_vk_clip_vertex *a,
                            const obs_vk_clip_vertex *b, const obs_vk_clip_vertex *d, float *out) {
  emitter e = {c, out, {0, 0, 0}, 0};
  double lo = fmin(fmin(a->v[2], b->v[2]), d->v[2]), hi = fmax(fmax(a->v[2], b->v[2]), d->v[2]);
  if (out) face_normal(a, b, d, e.nrm);
  if (a->band && b->band && d->band && lo >= c->znear &&
      (c->ortho || !(c->znear > 0.0) || hi <= DEPTH_RATIO * lo)) {
    emit_vertex(&e, a->v);
    emit_vertex(&e, b->v);
    emit_vertex(&e, d->v);
    return e.n;
  }
  wvert poly[2][MAX_POLY];
  const cvert *in[3] = {a, b, d};
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) poly[0][i].p[j] = in[i]->p[j];
    wview_of(c, &poly[0][i]); /* the double rotation errs by ~1e-16 of the vertex's size */
  }
  /* The side planes first: they pass through the eye, so the corners they make on a huge
   * triangle lie where the view's edges meet it, well away from the eye; the near plane, last,
   * then rarely cuts anything. Cut first, it would make a line a hair's breadth from the eye out
   * of vertices ~1e18 away, and the side planes' corners on it would carry that rounding. */
  int n = 3, cur = 0;
  for (int i = 0; i < NPLANES && n > 0; i++) {
    n = clip_plane(c, (i + 1) % NPLANES, poly[cur], n, poly[cur ^ 1]);
    cur ^= 1;
  }
  if (n >= 3) emit_slabs(&e, poly[cur], n);
  return e.n;
}
