/* obscurance_map's line estimators on the CPU: every intersection along a line, in order, and the
 * transfers between consecutive ones that face each other; lines from global random pairs of
 * points on the bounding sphere or from bundles of parallel lines (obscurance_lines.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscurance_map_cpu.h"

/* Hits kept per line; a line crossing more surfaces stops transferring there. */
#define LINE_MAX_HITS 1024
/* Primitives skipped at the current tnear (those already reported there). */
#define LINE_SKIP 8

typedef struct line_hit {
  double t;
  int64_t patch;  /* -1: a surface without patches (an analytic sphere) */
  const float *r; /* its reflectivity */
  int face;       /* sign of (front normal . line direction); 0: grazing */
} line_hit;

/* The context of one line's successive queries. The sphere geometry reads the obs_rt_ctx part (a
 * sphere the line has entered reports only its far root next); triangles reported at the current
 * tnear are dropped by the filter, so hits at one parameter on several triangles (a shared edge
 * or vertex) come once each and never again. */
typedef struct line_ctx {
  obs_rt_ctx base; /* first: Embree and the sphere callbacks see it as their context */
  int nskip;
  unsigned skip[LINE_SKIP][2];
} line_ctx;

static void line_filter(const struct RTCFilterFunctionNArguments *a) {
  const line_ctx *c = (const line_ctx *)a->context;
  /* a->hit is RTCHitN, structure of arrays: Ng (3), u, v, primID, geomID, instID. */
  const unsigned *h = (const unsigned *)a->hit;
  const unsigned N = a->N;
  for (unsigned i = 0; i < N; i++) {
    if (a->valid[i] != -1) continue;
    unsigned prim = h[5 * N + i], geom = h[6 * N + i];
    for (int k = 0; k < c->nskip; k++)
      if (c->skip[k][0] == geom && c->skip[k][1] == prim) {
        a->valid[i] = 0;
        break;
      }
  }
}

/* A hit as the collecting filter records it, before sorting. */
typedef struct raw_hit {
  float t, u, v;
  unsigned geom, prim;
} raw_hit;

typedef struct line_state {
  const obs_omap_job *j;
  obs_omap_acc *acc;
  uint64_t rays;
  line_hit hits[LINE_MAX_HITS];
  raw_hit raw[LINE_MAX_HITS];
  int collect;   /* a scene of meshes only: one traversal per line (line_hits_collect) */
  int truncated; /* the last line had more hits than kept: its last kept one is not its last */
} line_state;

/* Every surface along (org, dir) within [0, len], in order, into st->hits; returns how many. */
static int line_hits(line_state *st, const double org[3], const double dir[3], double len) {
  const obs_omap_job *j = st->j;
  const obs_rt *rt = j->rt;
  line_ctx c;
  rtcInitIntersectContext(&c.base.ctx);
  c.base.ctx.filter = line_filter;
  c.base.skip_geom = c.base.skip_prim = ~0u;
  c.base.skip_mode = 0;
  c.nskip = 0;
  /* Two reports closer than this along the line with the same facing are one surface seen
   * twice (the float parameters of neighbouring triangles at their shared edge). */
  const double dup = 1e-6 * len;
  float tnear = 0.0f;
  int n = 0;
  for (int q = 0; n < LINE_MAX_HITS && q < 4 * LINE_MAX_HITS; q++) {
    struct RTCRayHit rh;
    rh.ray.org_x = (float)org[0], rh.ray.org_y = (float)org[1], rh.ray.org_z = (float)org[2];
    rh.ray.dir_x = (float)dir[0], rh.ray.dir_y = (float)dir[1], rh.ray.dir_z = (float)dir[2];
    rh.ray.tnear = tnear;
    rh.ray.tfar = (float)len * 1.0001f;
    rh.ray.time = 0.0f;
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(rt->scene, &c.base.ctx, &rh);
    st->rays++;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
    const unsigned g = rh.hit.geomID, p = rh.hit.primID;
    line_hit h;
    double nf[3];
    h.t = rh.ray.tfar;
    if (g == rt->sphere_geom) {
      nf[0] = rh.hit.Ng_x, nf[1] = rh.hit.Ng_y, nf[2] = rh.hit.Ng_z;
      h.patch = -1;
      h.r = j->sphere_r[p];
    } else {
      obs_omap_tri_normal(rt, g, p, nf);
      h.patch = obs_patch_mesh_find(j->pm, g, p, rh.hit.u, rh.hit.v);
      h.r = j->mesh_r[g];
    }
    double dn = nf[0] * dir[0] + nf[1] * dir[1] + nf[2] * dir[2];
    h.face = dn > 0 ? 1 : dn < 0 ? -1 : 0;
    /* Move on: a sphere entered reports its far root next, one left nothing more; the
     * triangles reported at this parameter are skipped by the filter. */
    if (rh.ray.tfar > tnear) tnear = rh.ray.tfar, c.nskip = 0;
    if (g == rt->sphere_geom) {
      c.base.skip_geom = g, c.base.skip_prim = p;
      c.base.skip_mode = h.face < 0 ? 2 : 1;
    } else {
      if (c.nskip == LINE_SKIP) tnear = nextafterf(tnear, INFINITY), c.nskip = 0;
      c.skip[c.nskip][0] = g, c.skip[c.nskip][1] = p;
      c.nskip++;
    }
    if (n && h.t - st->hits[n - 1].t <= dup && h.face == st->hits[n - 1].face) continue;
    st->hits[n++] = h;
  }
  st->truncated = n == LINE_MAX_HITS;
  return n;
}

/* One traversal reports every triangle the line crosses to this filter, which records each and
 * rejects it so that traversal goes on: the hits arrive in traversal order, not along the line. */
typedef struct collect_ctx {
  struct RTCIntersectContext ctx; /* first: Embree sees it as the context */
  raw_hit *hits;
  int n, max;
} collect_ctx;

static void collect_filter(const struct RTCFilterFunctionNArguments *a) {
  collect_ctx *c = (collect_ctx *)a->context;
  const float *r = (const float *)a->ray, *hf = (const float *)a->hit;
  const unsigned *h = (const unsigned *)a->hit;
  const unsigned N = a->N;
  for (unsigned i = 0; i < N; i++) {
    if (a->valid[i] != -1) continue;
    /* RTCRayN field 8 is tfar, the potential hit's distance; RTCHitN: Ng (3), u, v, prim, geom. */
    if (c->n < c->max)
      c->hits[c->n++] = (raw_hit){r[8 * N + i], hf[3 * N + i], hf[4 * N + i], h[6 * N + i],
                                  h[5 * N + i]};
    a->valid[i] = 0;
  }
}

static int raw_before(const raw_hit *x, const raw_hit *y) {
  if (x->t != y->t) return x->t < y->t;
  return x->geom != y->geom ? x->geom < y->geom : x->prim < y->prim;
}

/* Every surface along (org, dir) within [0, len] of a scene of meshes, in order, in one
 * traversal: the collecting filter's hits sorted by parameter (then primitive, so that equal
 * parameters come in one order), a primitive reported twice (it may sit in several BVH leaves)
 * kept once, and neighbours' reports of one crossing at a shared edge merged as line_hits
 * does. */
static int line_hits_collect(line_state *st, const double org[3], const double dir[3],
                             double len) {
  const obs_omap_job *j = st->j;
  collect_ctx c;
  rtcInitIntersectContext(&c.ctx);
  c.ctx.filter = collect_filter;
  c.hits = st->raw;
  c.n = 0;
  c.max = LINE_MAX_HITS;
  struct RTCRayHit rh;
  rh.ray.org_x = (float)org[0], rh.ray.org_y = (float)org[1], rh.ray.org_z = (float)org[2];
  rh.ray.dir_x = (float)dir[0], rh.ray.dir_y = (float)dir[1], rh.ray.dir_z = (float)dir[2];
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = (float)len * 1.0001f;
  rh.ray.time = 0.0f;
  rh.ray.mask = ~0u;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(j->rt->scene, &c.ctx, &rh);
  st->rays++;
  raw_hit *r = c.hits;
  for (int k = 1; k < c.n; k++) { /* insertion sort: a line crosses few surfaces */
    raw_hit x = r[k];
    int m = k;
    for (; m > 0 && raw_before(&x, &r[m - 1]); m--) r[m] = r[m - 1];
    r[m] = x;
  }
  const double dup = 1e-6 * len;
  int n = 0;
  for (int k = 0; k < c.n; k++) {
    int again = 0;
    for (int m = k - 1; m >= 0 && r[m].t == r[k].t && !again; m--)
      again = r[m].geom == r[k].geom && r[m].prim == r[k].prim;
    if (again) continue;
    line_hit h;
    double nf[3];
    obs_omap_tri_normal(j->rt, r[k].geom, r[k].prim, nf);
    h.t = r[k].t;
    h.patch = obs_patch_mesh_find(j->pm, r[k].geom, r[k].prim, r[k].u, r[k].v);
    h.r = j->mesh_r[r[k].geom];
    double dn = nf[0] * dir[0] + nf[1] * dir[1] + nf[2] * dir[2];
    h.face = dn > 0 ? 1 : dn < 0 ? -1 : 0;
    if (n && h.t - st->hits[n - 1].t <= dup && h.face == st->hits[n - 1].face) continue;
    st->hits[n++] = h;
  }
  /* A line with more crossings than the buffer holds is cut where it filled: its last kept hit
   * is not the line's last, so it gets no "nothing beyond" sample (line_transfer). */
  st->truncated = c.n == LINE_MAX_HITS;
  return n;
}

/* The transfers along one line of n hits: consecutive hits whose fronts face each other see each
 * other at their distance; an outer hit facing out sees nothing within d_max. */
static void line_transfer(line_state *st, int n) {
  const obs_omap_job *j = st->j;
  const line_hit *h = st->hits;
  double v[3];
  if (n && h[0].face < 0 && h[0].patch >= 0) {
    obs_omap_value(j, INFINITY, NULL, v);
    obs_omap_add(&st->acc[h[0].patch], v);
  }
  for (int k = 0; k + 1 < n; k++) {
    const line_hit *a = &h[k], *b = &h[k + 1];
    if (!(a->face > 0 && b->face < 0)) continue;
    double d = b->t - a->t;
    if (a->patch >= 0) {
      obs_omap_value(j, d, b->r, v);
      obs_omap_add(&st->acc[a->patch], v);
    }
    if (b->patch >= 0) {
      obs_omap_value(j, d, a->r, v);
      obs_omap_add(&st->acc[b->patch], v);
    }
  }
  if (n && !st->truncated && h[n - 1].face > 0 && h[n - 1].patch >= 0) {
    obs_omap_value(j, INFINITY, NULL, v);
    obs_omap_add(&st->acc[h[n - 1].patch], v);
  }
}

static line_state *state_new(const obs_omap_job *j, int thread) {
  line_state *st = malloc(sizeof *st);
  if (!st) return NULL;
  st->j = j;
  st->acc = j->acc + (size_t)thread * (size_t)j->pm->count;
  st->rays = 0;
  /* The analytic spheres' intersector reports to no filter: scenes with spheres step from hit
   * to hit. */
  st->collect = j->rt->geo.nspheres == 0;
  return st;
}

int obs_omap_global_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)y0, (void)y1;
  const obs_omap_job *j = user;
  line_state *st = state_new(j, thread);
  if (!st) return OBS_ENOMEM;
  uint64_t total = obs_omap_global_count(&j->p);
  for (uint64_t i = (uint64_t)x0 * OMAP_GLOBAL_CHUNK;
       i < (uint64_t)x1 * OMAP_GLOBAL_CHUNK && i < total; i++) {
    double org[3], dir[3], len;
    obs_global_line(&j->bs, j->p.seed, i, org, dir, &len);
    if (!(len > 0)) continue;
    line_transfer(st, st->collect ? line_hits_collect(st, org, dir, len) : line_hits(st, org, dir, len));
  }
  j->rays[(size_t)thread * 8] += st->rays;
  free(st);
  return 0;
}

int obs_omap_bundle_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)y0, (void)y1;
  const obs_omap_job *j = user;
  line_state *st = state_new(j, thread);
  if (!st) return OBS_ENOMEM;
  const uint32_t res = j->p.bundle_resolution;
  const double r = j->bs.radius, len = 2 * r;
  obs_bundle b;
  uint32_t have = ~0u;
  for (int x = x0; x < x1; x++) {
    uint32_t k = j->dir0 + (uint32_t)x / res, row = (uint32_t)x % res;
    if (k != have) obs_bundle_get(&j->bs, j->p.seed, j->p.directions, k, res, &b), have = k;
    double y = (row + b.offset[1]) * b.cell - r;
    for (uint32_t i = 0; i < res; i++) {
      double xx = (i + b.offset[0]) * b.cell - r;
      if (xx * xx + y * y > r * r) continue; /* outside the sphere's disc: meets nothing */
      double org[3];
      obs_bundle_line(&b, i, row, org);
      line_transfer(st, st->collect ? line_hits_collect(st, org, b.dir, len)
                                 : line_hits(st, org, b.dir, len));
    }
  }
  j->rays[(size_t)thread * 8] += st->rays;
  free(st);
  return 0;
}
