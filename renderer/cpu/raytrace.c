/* Embree scene construction and ray queries for the CPU backend. Triangles go to Embree's
 * triangle geometry; spheres are a user geometry intersected in double precision so they stay
 * exact from 1e-4 to 1e4 scene scales. */
#include "raytrace.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static void sphere_bounds(const struct RTCBoundsFunctionArguments *a) {
  const obs_rt *rt = a->geometryUserPtr;
  const obs_sphere *s = &rt->geo.spheres[a->primID];
  /* Widen by float rounding so the box always contains the double-precision sphere. */
  double r = s->radius * (1 + 1e-6);
  a->bounds_o->lower_x = (float)(s->center[0] - r) - 1e-30f;
  a->bounds_o->lower_y = (float)(s->center[1] - r) - 1e-30f;
  a->bounds_o->lower_z = (float)(s->center[2] - r) - 1e-30f;
  a->bounds_o->upper_x = (float)(s->center[0] + r) + 1e-30f;
  a->bounds_o->upper_y = (float)(s->center[1] + r) + 1e-30f;
  a->bounds_o->upper_z = (float)(s->center[2] + r) + 1e-30f;
  a->bounds_o->lower_x = nextafterf(a->bounds_o->lower_x, -INFINITY);
  a->bounds_o->lower_y = nextafterf(a->bounds_o->lower_y, -INFINITY);
  a->bounds_o->lower_z = nextafterf(a->bounds_o->lower_z, -INFINITY);
  a->bounds_o->upper_x = nextafterf(a->bounds_o->upper_x, INFINITY);
  a->bounds_o->upper_y = nextafterf(a->bounds_o->upper_y, INFINITY);
  a->bounds_o->upper_z = nextafterf(a->bounds_o->upper_z, INFINITY);
}

/* Ray/sphere roots in double with the numerically careful discriminant of Haines et al.
 * ("Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7). Returns the
 * nearest acceptable root in (tnear, tfar] or -1. */
static double sphere_root(const obs_sphere *s, const float o[3], const float d[3], float tnear,
                          float tfar, int mode) {
  double oc[3] = {o[0] - s->center[0], o[1] - s->center[1], o[2] - s->center[2]};
  double dd[3] = {d[0], d[1], d[2]};
  double a = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2];
  if (!(a > 0)) return -1;
  double b = -(oc[0] * dd[0] + oc[1] * dd[1] + oc[2] * dd[2]) / a; /* closest approach */
  double f[3] = {oc[0] + b * dd[0], oc[1] + b * dd[1], oc[2] + b * dd[2]};
  double r2 = s->radius * s->radius;
  double disc = r2 - (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (disc < 0) return -1;
  double h = sqrt(disc / a);
  double t0 = b - h, t1 = b + h;
  if (mode == 1) return -1;
  if (mode != 2 && t0 > tnear && t0 <= tfar) return t0;
  if (t1 > tnear && t1 <= tfar) return t1;
  return -1;
}

static int sphere_mode(const obs_rt_ctx *c, unsigned geom, unsigned prim) {
  return c->skip_geom == geom && c->skip_prim == prim ? c->skip_mode : 0;
}

/* Context filter for rays leaving a triangle: a flat primitive cannot occlude itself, so any hit on
 * it is rounding error and is dropped. This is what lets ray origins sit within a few ulps of the
 * surface instead of being pushed off by an epsilon that would bias contact shadows. */
static void skip_origin_filter(const struct RTCFilterFunctionNArguments *a) {
  const obs_rt_ctx *c = (const obs_rt_ctx *)a->context;
  /* RTCHitN is structure-of-arrays: primID at [5N + i], geomID at [6N + i] (the C++ accessors of
   * rtcore_ray.h, which C cannot use). */
  const unsigned *h = (const unsigned *)a->hit;
  for (unsigned i = 0; i < a->N; i++) {
    if (a->valid[i] != -1) continue;
    if (h[6 * a->N + i] == c->skip_geom && h[5 * a->N + i] == c->skip_prim) a->valid[i] = 0;
  }
}

static void sphere_intersect(const struct RTCIntersectFunctionNArguments *a) {
  if (a->N != 1 || !a->valid[0]) return;
  const obs_rt *rt = a->geometryUserPtr;
  const obs_sphere *s = &rt->geo.spheres[a->primID];
  struct RTCRayHit *rh = (struct RTCRayHit *)a->rayhit;
  float o[3] = {rh->ray.org_x, rh->ray.org_y, rh->ray.org_z};
  float d[3] = {rh->ray.dir_x, rh->ray.dir_y, rh->ray.dir_z};
  double t = sphere_root(s, o, d, rh->ray.tnear, rh->ray.tfar,
                         sphere_mode((const obs_rt_ctx *)a->context, a->geomID, a->primID));
  if (t < 0) return;
  rh->ray.tfar = (float)t;
  rh->hit.Ng_x = (float)(o[0] + t * d[0] - s->center[0]);
  rh->hit.Ng_y = (float)(o[1] + t * d[1] - s->center[1]);
  rh->hit.Ng_z = (float)(o[2] + t * d[2] - s->center[2]);
  rh->hit.u = rh->hit.v = 0;
  rh->hit.primID = a->primID;
  rh->hit.geomID = a->geomID;
  rh->hit.instID[0] = a->context->instID[0];
}

static void sphere_occluded(const struct RTCOccludedFunctionNArguments *a) {
  if (a->N != 1 || !a->valid[0]) return;
  const obs_rt *rt = a->geometryUserPtr;
  struct RTCRay *r = (struct RTCRay *)a->ray;
  float o[3] = {r->org_x, r->org_y, r->org_z}, d[3] = {r->dir_x, r->dir_y, r->dir_z};
  /* Embree's occlusion interval is (tnear, tfar]; rays here use tfar = max distance. */
  if (sphere_root(&rt->geo.spheres[a->primID], o, d, r->tnear, r->tfar,
                  sphere_mode((const obs_rt_ctx *)a->context, a->geomID, a->primID)) >= 0)
    r->tfar = -INFINITY;
}

static void on_embree_error(void *user, enum RTCError code, const char *str) {
  (void)user;
  fprintf(stderr, "obscura: embree error %d: %s\n", (int)code, str ? str : "");
}

int obs_rt_build(const obs_scene *sc, obs_rt *rt, int threads, obs_err *err) {
  memset(rt, 0, sizeof *rt);
  rt->sphere_geom = RTC_INVALID_GEOMETRY_ID;
  /* Camera-relative coordinates: what the camera sees stays precise in float however far from
   * the world origin the scene sits. */
  const double eye[3] = {sc->camera.position.x, sc->camera.position.y, sc->camera.position.z};
  int rc = obs_geometry_build_at(sc, eye, &rt->geo, err);
  if (rc) return rc;
  char config[32] = "";
  if (threads > 0) snprintf(config, sizeof config, "threads=%d", threads);
  rt->device = rtcNewDevice(config);
  if (!rt->device) {
    obs_geometry_free(&rt->geo);
    return obs_err_set(err, OBS_EINTERNAL, "embree: cannot create device (error %d)",
                       (int)rtcGetDeviceError(NULL));
  }
  rtcSetDeviceErrorFunction(rt->device, on_embree_error, NULL);
  rt->scene = rtcNewScene(rt->device);
  rtcSetSceneFlags(rt->scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  unsigned id = 0;
  for (size_t i = 0; i < rt->geo.nmeshes; i++) {
    obs_mesh *m = &rt->geo.meshes[i];
    RTCGeometry g = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    /* Embree-allocated buffers carry the tail padding its SIMD vertex loads need, which our
     * tightly packed arrays lack; ours stay for reconstructing hit points. */
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                        3 * sizeof(float), m->nverts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                           3 * sizeof(unsigned), m->ntris);
    if (!vb || !ib) {
      rtcReleaseGeometry(g);
      obs_rt_free(rt);
      return obs_err_set(err, OBS_ENOMEM, "embree: out of memory for %zu triangles", m->ntris);
    }
    memcpy(vb, m->pos, m->nverts * 3 * sizeof(float));
    memcpy(ib, m->idx, m->ntris * 3 * sizeof(unsigned));
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(rt->scene, g, id++);
    rtcReleaseGeometry(g);
  }
  if (rt->geo.nspheres) {
    RTCGeometry g = rtcNewGeometry(rt->device, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, (unsigned)rt->geo.nspheres);
    rtcSetGeometryUserData(g, rt);
    rtcSetGeometryBoundsFunction(g, sphere_bounds, NULL);
    rtcSetGeometryIntersectFunction(g, sphere_intersect);
    rtcSetGeometryOccludedFunction(g, sphere_occluded);
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(rt->scene, g, id);
    rt->sphere_geom = id;
    rtcReleaseGeometry(g);
  }
  rtcCommitScene(rt->scene);
  enum RTCError e = rtcGetDeviceError(rt->device);
  if (e != RTC_ERROR_NONE) {
    obs_rt_free(rt);
    return obs_err_set(err, e == RTC_ERROR_OUT_OF_MEMORY ? OBS_ENOMEM : OBS_EINTERNAL,
                       "embree: scene build failed (error %d)", (int)e);
  }
  return 0;
}

void obs_rt_free(obs_rt *rt) {
  if (rt->scene) rtcReleaseScene(rt->scene);
  if (rt->device) rtcReleaseDevice(rt->device);
  obs_geometry_free(&rt->geo);
  memset(rt, 0, sizeof *rt);
}

static void normalize3(float v[3]) {
  float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 0 && isfinite(l)) {
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
  } else {
    v[0] = 0, v[1] = 0, v[2] = 1;
  }
}

int obs_rt_intersect(const obs_rt *rt, const double world_org[3], const double dir[3], float tfar,
                     obs_hit *hit) {
  const double org[3] = {world_org[0] - rt->geo.origin[0], world_org[1] - rt->geo.origin[1],
                         world_org[2] - rt->geo.origin[2]};
  struct RTCRayHit rh;
  memset(&rh, 0, sizeof rh);
  rh.ray.org_x = (float)org[0];
  rh.ray.org_y = (float)org[1];
  rh.ray.org_z = (float)org[2];
  rh.ray.dir_x = (float)dir[0];
  rh.ray.dir_y = (float)dir[1];
  rh.ray.dir_z = (float)dir[2];
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = tfar;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  obs_rt_ctx c;
  rtcInitIntersectContext(&c.ctx);
  c.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  c.skip_geom = c.skip_prim = ~0u;
  c.skip_mode = 0;
  rtcIntersect1(rt->scene, &c.ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
  hit->t = rh.ray.tfar;
  hit->geom = rh.hit.geomID;
  hit->prim = rh.hit.primID;
  hit->sphere_inside = 0;
  float d[3] = {rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
  float ng[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
  int have_ns = 0;
  float ns[3] = {0, 0, 0};
  if (rh.hit.geomID == rt->sphere_geom) {
    const obs_sphere *s = &rt->geo.spheres[rh.hit.primID];
    double q[3] = {org[0] + rh.ray.tfar * dir[0] - s->center[0],
                   org[1] + rh.ray.tfar * dir[1] - s->center[1],
                   org[2] + rh.ray.tfar * dir[2] - s->center[2]};
    double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    /* Project onto the sphere so the point's error is that of the centre and radius only. */
    for (int k = 0; k < 3; k++) {
      double u = l > 0 ? q[k] / l : (k == 2);
      hit->p[k] = (float)(s->center[k] + s->radius * u);
      ng[k] = (float)u;
      /* The double result is exact to ~1e-16 relative; rounding it to float dominates. */
      hit->perr[k] = fabsf(hit->p[k]) * 0x1p-23f;
    }
  } else {
    const obs_mesh *m = &rt->geo.meshes[rh.hit.geomID];
    const uint32_t *tri = m->idx + 3 * (size_t)rh.hit.primID;
    float u = rh.hit.u, v = rh.hit.v, w = 1.0f - u - v;
    const float *a = m->pos + 3 * tri[0], *b = m->pos + 3 * tri[1], *c = m->pos + 3 * tri[2];
    /* Re-intersect the hit triangle's plane in double: Embree's float t (and barycentrics) err in
     * proportion to the vertices' magnitude, which on a huge triangle is a visible shift of P.
     * In double, P is on the plane and where the ray meets it to ~1e-16; rounding to float is
     * then its only error. Degenerate planes fall back to Embree's t. */
    double e1[3], e2[3], n[3], oa[3];
    for (int k = 0; k < 3; k++) {
      e1[k] = (double)b[k] - a[k];
      e2[k] = (double)c[k] - a[k];
      oa[k] = (double)a[k] - org[k];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double dn = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
    double t = (oa[0] * n[0] + oa[1] * n[1] + oa[2] * n[2]) / dn;
    int exact = dn != 0.0 && isfinite(t) && t >= 0.0;
    for (int k = 0; k < 3; k++) {
      hit->p[k] = exact ? (float)(org[k] + t * dir[k]) : w * a[k] + u * b[k] + v * c[k];
      /* Float rounding of the double point; the fallback's barycentric sum errs like pbrt's
       * gamma(7) * sum |b_i v_i|. */
      hit->perr[k] = exact
                         ? fabsf(hit->p[k]) * 0x1p-24f
                         : 7.0f * 0x1p-24f * (fabsf(w * a[k]) + fabsf(u * b[k]) + fabsf(v * c[k]));
    }
    if (exact) hit->t = (float)t;
    if (m->nrm) {
      const float *na = m->nrm + 3 * tri[0], *nb = m->nrm + 3 * tri[1], *nc = m->nrm + 3 * tri[2];
      for (int k = 0; k < 3; k++) ns[k] = w * na[k] + u * nb[k] + v * nc[k];
      have_ns = ns[0] != 0 || ns[1] != 0 || ns[2] != 0;
    }
  }
  normalize3(ng);
  int back = ng[0] * d[0] + ng[1] * d[1] + ng[2] * d[2] > 0;
  if (back) {
    for (int k = 0; k < 3; k++) ng[k] = -ng[k];
    hit->sphere_inside = rh.hit.geomID == rt->sphere_geom;
  }
  memcpy(hit->ng, ng, sizeof ng);
  if (have_ns) {
    normalize3(ns);
    if (ns[0] * ng[0] + ns[1] * ng[1] + ns[2] * ng[2] < 0)
      for (int k = 0; k < 3; k++) ns[k] = -ns[k];
    memcpy(hit->ns, ns, sizeof ns);
  } else {
    memcpy(hit->ns, ng, sizeof ng);
  }
  return 1;
}

void obs_rt_offset(const obs_rt *rt, const obs_hit *hit, float out[3]) {
  (void)rt;
  /* pbrt's OffsetRayOrigin: move along the geometric normal by the error bound projected on it,
   * then one more float step away, so the origin is provably on the normal's side of the true
   * surface. Scale-invariant and local: it follows p's own error, not the scene's size. The
   * primitive itself is skipped by the context filter, so nothing larger is needed. */
  float d = fabsf(hit->ng[0]) * hit->perr[0] + fabsf(hit->ng[1]) * hit->perr[1] +
            fabsf(hit->ng[2]) * hit->perr[2];
  for (int k = 0; k < 3; k++) {
    float off = d * hit->ng[k];
    float po = hit->p[k] + off;
    if (off > 0.0f || (off == 0.0f && hit->ng[k] > 0.0f))
      po = nextafterf(po, INFINITY);
    else if (off < 0.0f || hit->ng[k] < 0.0f)
      po = nextafterf(po, -INFINITY);
    out[k] = po;
  }
}

void obs_rt_ctx_init(obs_rt_ctx *c, const obs_rt *rt, const obs_hit *from) {
  rtcInitIntersectContext(&c->ctx);
  c->skip_geom = c->skip_prim = ~0u;
  c->skip_mode = 0;
  if (!from) return;
  c->skip_geom = from->geom;
  c->skip_prim = from->prim;
  if (from->geom == rt->sphere_geom)
    c->skip_mode = from->sphere_inside ? 2 : 1;
  else
    c->ctx.filter = skip_origin_filter;
}

float obs_rt_distance(const obs_rt *rt, obs_rt_ctx *c, const float org[3], const float dir[3],
                      float tfar) {
  struct RTCRayHit rh;
  rh.ray.org_x = org[0], rh.ray.org_y = org[1], rh.ray.org_z = org[2];
  rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = tfar;
  rh.ray.time = 0.0f;
  rh.ray.mask = ~0u;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rt->scene, &c->ctx, &rh);
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
}
