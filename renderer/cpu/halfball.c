/* What lies in the half-ball above a ray origin (obs_rt_halfball): where nothing does, every ray
 * into that hemisphere escapes within the radius for certain, so an occlusion estimate there is
 * exact and its standard error truly 0; where little does, the share of directions that can meet
 * it bounds the error of an estimate whose every ray escaped (docs/accuracy.md, "Standard
 * errors"). */
#include "halfball.h"

#include <math.h>
#include <string.h>

#include "mcerr.h"

/* Primitives examined at most per query: past this the answer is "unknown" (a surface at
 * distance 0 covering every direction), which costs a conservative error, never a wrong one. */
#define HALFBALL_MAX_PRIMS 32
#define PI 3.14159265358979323846

typedef struct halfball_q {
  const obs_rt *rt;
  const obs_hit *from;
  double o[3], n[3], radius;
  obs_halfball_need need;
  obs_halfball out;
  int prims;
  int capped; /* the cover reached need.cover: only the nearest distance is still measured */
} halfball_q;

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

/* The polygon p (m vertices, at most 10) clipped to dot(q, pn) >= pc, in place; the new count. */
enum { POLY_MAX = 10 };
static int clip(double p[POLY_MAX][3], int m, const double pn[3], double pc) {
  double out[POLY_MAX][3], h[POLY_MAX];
  int k2 = 0;
  for (int k = 0; k < m; k++) h[k] = dot3(p[k], pn) - pc;
  for (int k = 0; k < m && k2 < POLY_MAX - 1; k++) {
    const double *a = p[k], *b = p[(k + 1) % m];
    double ha = h[k], hb = h[(k + 1) % m];
    if (ha >= 0) memcpy(out[k2++], a, sizeof out[0]);
    if ((ha >= 0) != (hb >= 0)) {
      double t = ha / (ha - hb);
      for (int c = 0; c < 3; c++) out[k2][c] = a[c] + t * (b[c] - a[c]);
      k2++;
    }
  }
  memcpy(p, out, (size_t)k2 * sizeof out[0]);
  return k2;
}

/* Distance from the origin to segment [a, b]. */
static double seg_dist(const double a[3], const double b[3]) {
  double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, l2 = dot3(d, d), t = 0;
  if (l2 > 0) t = fmin(1.0, fmax(0.0, -dot3(a, d) / l2));
  double p[3] = {a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]};
  return sqrt(dot3(p, p));
}

/* Distance from the origin to the planar convex polygon p (normal tn). */
static double poly_dist(const double p[POLY_MAX][3], int m, const double tn[3]) {
  double l2 = dot3(tn, tn), best = INFINITY;
  if (l2 > 0 && m >= 3) {
    double s = dot3(p[0], tn) / l2, f[3] = {s * tn[0], s * tn[1], s * tn[2]};
    int inside = 1;
    for (int k = 0; k < m && inside; k++) {
      const double *a = p[k], *b = p[(k + 1) % m];
      double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, af[3] = {f[0] - a[0], f[1] - a[1],
                                                                           f[2] - a[2]}, c[3];
      cross3(ab, af, c);
      inside = dot3(c, tn) >= 0;
    }
    if (inside) best = sqrt(dot3(f, f));
  }
  for (int k = 0; k < m; k++) best = fmin(best, seg_dist(p[k], p[(k + 1) % m]));
  return best;
}

/* The share of cosine-weighted directions about n that polygon p (above the plane, not through
 * the origin) covers: its projected solid angle over pi (Lambert's formula, summed over edges),
 * and of uniform directions: its solid angle over 2 pi (fan of Van Oosterom-Strackee triangles). */
static void poly_cover(const double p[POLY_MAX][3], int m, const double n[3], double *cos_share,
                       double *uni_share) {
  double u[POLY_MAX][3], proj = 0, solid = 0;
  for (int k = 0; k < m; k++) {
    double l = sqrt(dot3(p[k], p[k]));
    for (int c = 0; c < 3; c++) u[k][c] = p[k][c] / l;
  }
  for (int k = 0; k < m; k++) {
    const double *a = u[k], *b = u[(k + 1) % m];
    double g[3];
    cross3(a, b, g);
    double gl = sqrt(dot3(g, g));
    if (gl > 0) proj += atan2(gl, dot3(a, b)) * dot3(g, n) / gl;
  }
  for (int k = 1; k + 1 < m; k++) {
    const double *a = u[0], *b = u[k], *c = u[k + 1];
    double bc[3];
    cross3(b, c, bc);
    double den = 1 + dot3(a, b) + dot3(a, c) + dot3(b, c);
    solid += fabs(2 * atan2(dot3(a, bc), den));
  }
  *cos_share = fmin(1.0, fabs(proj) / (2 * PI));
  *uni_share = fmin(1.0, solid / (2 * PI));
}

static void note_unknown(halfball_q *q) {
  q->out.nearest = 0;
  q->out.cover_cos = q->out.cover_uniform = 1;
}

/* A triangle (vertices relative to the origin): the part above the plane and inside the cube
 * around the ball (a superset of the half-ball, so the shares stay upper bounds). */
static void add_triangle(halfball_q *q, const double v[3][3]) {
  double p[POLY_MAX][3];
  memcpy(p, v, 3 * sizeof p[0]);
  int m = clip(p, 3, q->n, 0.0);
  if (isfinite(q->radius))
    for (int a = 0; a < 3 && m; a++)
      for (int s = -1; s <= 1 && m; s += 2) {
        double pn[3] = {0, 0, 0};
        pn[a] = -s; /* -s q_a >= -radius: q_a within the cube's side */
        m = clip(p, m, pn, -q->radius);
      }
  if (!m) return;
  double e1[3], e2[3], tn[3];
  for (int c = 0; c < 3; c++) e1[c] = v[1][c] - v[0][c], e2[c] = v[2][c] - v[0][c];
  cross3(e1, e2, tn);
  double d = poly_dist(p, m, tn);
  if (!(d < q->radius)) return;
  q->out.nearest = fmin(q->out.nearest, d);
  if (!(d > 0) || m < 3) {
    note_unknown(q);
    return;
  }
  if (q->capped) return;
  double cs, us;
  poly_cover(p, m, q->n, &cs, &us);
  q->out.cover_cos = fmin(1.0, q->out.cover_cos + cs);
  q->out.cover_uniform = fmin(1.0, q->out.cover_uniform + us);
}

/* A sphere of centre c (relative to the origin) and radius r: its cone of directions. */
static void add_sphere(halfball_q *q, const double c[3], double r) {
  if (!(dot3(c, q->n) + r > 0)) return; /* wholly below the plane */
  double l = sqrt(dot3(c, c)), d = fmax(0.0, l - r);
  if (!(d < q->radius)) return;
  q->out.nearest = fmin(q->out.nearest, d);
  if (!(l > r)) {
    note_unknown(q);
    return;
  }
  if (q->capped) return;
  /* The cone of half-angle asin(r / l): solid angle 2 pi (1 - cos), at most twice that share of
   * cosine-weighted directions. */
  double share = 1.0 - sqrt(1.0 - (r / l) * (r / l));
  q->out.cover_uniform = fmin(1.0, q->out.cover_uniform + share);
  q->out.cover_cos = fmin(1.0, q->out.cover_cos + 2 * share);
}

/* After a primitive: once the cover reaches what the caller needs, the cover is reported as 1 (an
 * upper bound still) and no longer measured; the traversal then ends, or, where the nearest
 * distance still matters, goes on only within it (a primitive farther than the nearest so far
 * cannot change it). Returns whether the query's radius changed. */
static bool settle(halfball_q *q, struct RTCPointQueryFunctionArguments *args) {
  if (!(q->out.nearest < INFINITY)) return false;
  if (!q->capped) {
    double c = q->need.uniform ? q->out.cover_uniform : q->out.cover_cos;
    if (!(c >= q->need.cover)) return false;
    q->capped = 1;
    q->out.cover_cos = q->out.cover_uniform = 1;
  }
  float r = q->need.nearest && q->out.nearest > 0 ? nextafterf((float)q->out.nearest, INFINITY) : 0.0f;
  if (!(r < args->query->radius)) return false;
  args->query->radius = r;
  return true;
}

static bool halfball_prim(struct RTCPointQueryFunctionArguments *args) {
  halfball_q *q = args->userPtr;
  const obs_rt *rt = q->rt;
  unsigned g = args->geomID, p = args->primID;
  if (++q->prims > HALFBALL_MAX_PRIMS) note_unknown(q);
  if (q->out.nearest == 0 && q->out.cover_cos >= 1) {
    /* Nothing more to learn: a radius of 0 ends the traversal (a huge mesh under an unbounded
     * radius would otherwise call back once per triangle). */
    args->query->radius = 0.0f;
    return true;
  }
  if (g == rt->sphere_geom) {
    /* The sphere the point lies on, left outward, is below its tangent plane. */
    if (g == q->from->geom && p == q->from->prim && !q->from->sphere_inside) return false;
    const obs_sphere *s = &rt->geo.spheres[p];
    double c[3] = {s->center[0] - q->o[0], s->center[1] - q->o[1], s->center[2] - q->o[2]};
    add_sphere(q, c, s->radius);
  } else {
    const obs_mesh *m = &rt->geo.meshes[g];
    const uint32_t *t = m->idx + 3 * (size_t)p;
    double v[3][3];
    for (int k = 0; k < 3; k++)
      for (int c = 0; c < 3; c++) v[k][c] = (double)m->pos[3 * (size_t)t[k] + (size_t)c] - q->o[c];
    add_triangle(q, v);
  }
  return settle(q, args);
}

void obs_rt_halfball(const obs_rt *rt, const obs_hit *from, const float org[3], float radius,
                     const obs_halfball_need *need, obs_halfball *out) {
  halfball_q q;
  memset(&q, 0, sizeof q);
  q.rt = rt;
  q.from = from;
  q.need = *need;
  for (int c = 0; c < 3; c++) q.o[c] = org[c], q.n[c] = from->ns[c];
  /* A little past the radius: a ray's float hit distance may fall short of the exact one. */
  q.radius = isinf(radius) ? INFINITY : (double)radius * (1 + 1e-4);
  q.out.nearest = INFINITY;
  struct RTCPointQuery pq;
  pq.x = org[0], pq.y = org[1], pq.z = org[2];
  pq.radius = (float)q.radius;
  pq.time = 0.0f;
  struct RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(rt->scene, &pq, &ctx, halfball_prim, &q);
  *out = q.out;
}

double obs_rt_escape_stderr(const obs_rt *rt, const obs_hit *from, const float org[3],
                            const obs_falloff *f, float radius, int uniform, double value_span,
                            uint32_t n) {
  for (int k = 0; k < 3; k++)
    if (from->ns[k] != from->ng[k]) return obs_mcerr_floor(n, 1.0); /* some run into the surface */
  /* Past a cover of 3 floors the bound below is the floor: the cover need not be known better, and
   * under a binary falloff (or a given span) neither does the nearest distance. */
  obs_halfball_need need = {.cover = 3 * obs_mcerr_floor(n, 1.0),
                            .uniform = uniform,
                            .nearest = !(value_span > 0) && f->kind != OBS_FALLOFF_BINARY};
  obs_halfball h;
  obs_rt_halfball(rt, from, org, radius, &need, &h);
  if (isinf(h.nearest)) return 0.0;
  double span = value_span > 0 ? value_span : 1.0 - obs_falloff_rho(f, h.nearest);
  double cover = uniform ? h.cover_uniform : h.cover_cos;
  return fmin(obs_mcerr_floor(n, span), cover * span / 3.0);
}
