/* Embree scene construction and ray queries for the CPU backend. Triangles go to Embree's
 * triangle geometry; spheres are a user geometry intersected in double precision so they stay
 * exact from 1e-4 to 1e4 scene scales. */
#include "raytrace.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "extent.h"
#include "simd.h"

#include "normalize.h"

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

static int sphere_mode(const obs_rt_ctx *c, unsigned geom, unsigned prim) {
  return c->skip_geom == geom && c->skip_prim == prim ? c->skip_mode : 0;
}

/* RTCRayN and RTCRayHitN are structure-of-arrays, so field k of lane i sits at [k * N + i]: the
 * ray's twelve fields, then the hit's (the C++ accessors of rtcore_ray.h, which C cannot use).
 * N == 1 is the plain RTCRay / RTCRayHit layout. */
enum {
  SOA_ORG = 0,
  SOA_TNEAR = 3,
  SOA_DIR = 4,
  SOA_TFAR = 8,
  SOA_NG = 12,
  SOA_U = 15,
  SOA_V = 16,
  SOA_PRIM = 17,
  SOA_GEOM = 18,
  SOA_INST = 19
};
_Static_assert(offsetof(struct RTCRayHit8, hit.instID) == SOA_INST * 8 * sizeof(float),
               "RTCRayHitN layout");

/* Context filter for rays leaving a triangle: a flat primitive cannot occlude itself, so any hit on
 * it is rounding error and is dropped. This is what lets ray origins sit within a few ulps of the
 * surface instead of being pushed off by an epsilon that would bias contact shadows. */
static void skip_origin_filter(const struct RTCFilterFunctionNArguments *a) {
  const obs_rt_ctx *c = (const obs_rt_ctx *)a->context;
  /* a->hit is the RTCHitN part alone: the hit fields' indices less the ray's SOA_NG. */
  const unsigned *h = (const unsigned *)a->hit;
  const unsigned N = a->N;
  for (unsigned i = 0; i < N; i++) {
    if (a->valid[i] != -1) continue;
    if (h[(SOA_GEOM - SOA_NG) * N + i] == c->skip_geom &&
        h[(SOA_PRIM - SOA_NG) * N + i] == c->skip_prim)
      a->valid[i] = 0;
  }
}

/* Origin and direction of lane i of an N-wide structure-of-arrays ray packet. */
static void lane_ray(const float *r, unsigned N, unsigned i, double o[3], double d[3]) {
  for (int k = 0; k < 3; k++) {
    o[k] = r[(SOA_ORG + k) * N + i];
    d[k] = r[(SOA_DIR + k) * N + i];
  }
}

static void sphere_intersect(const struct RTCIntersectFunctionNArguments *a) {
  const obs_rt *rt = a->geometryUserPtr;
  const obs_sphere *s = &rt->geo.spheres[a->primID];
  const int mode = sphere_mode((const obs_rt_ctx *)a->context, a->geomID, a->primID);
  const unsigned N = a->N;
  float *r = (float *)a->rayhit;
  unsigned *u = (unsigned *)a->rayhit;
  for (unsigned i = 0; i < N; i++) {
    if (a->valid[i] != -1) continue;
    double o[3], d[3];
    lane_ray(r, N, i, o, d);
    double t = obs_rt_sphere_root(s, o, d, r[SOA_TNEAR * N + i], r[SOA_TFAR * N + i], mode);
    if (t < 0) continue;
    r[SOA_TFAR * N + i] = (float)t;
    for (int k = 0; k < 3; k++) r[(SOA_NG + k) * N + i] = (float)(o[k] + t * d[k] - s->center[k]);
    r[SOA_U * N + i] = r[SOA_V * N + i] = 0;
    u[SOA_PRIM * N + i] = a->primID;
    u[SOA_GEOM * N + i] = a->geomID;
    u[SOA_INST * N + i] = a->context->instID[0];
  }
}

static void sphere_occluded(const struct RTCOccludedFunctionNArguments *a) {
  const obs_rt *rt = a->geometryUserPtr;
  const obs_sphere *s = &rt->geo.spheres[a->primID];
  const int mode = sphere_mode((const obs_rt_ctx *)a->context, a->geomID, a->primID);
  const unsigned N = a->N;
  float *r = (float *)a->ray;
  for (unsigned i = 0; i < N; i++) {
    if (a->valid[i] != -1) continue;
    double o[3], d[3];
    lane_ray(r, N, i, o, d);
    /* Embree's occlusion interval is (tnear, tfar]; rays here use tfar = max distance. */
    if (obs_rt_sphere_root(s, o, d, r[SOA_TNEAR * N + i], r[SOA_TFAR * N + i], mode) >= 0)
      r[SOA_TFAR * N + i] = -INFINITY;
  }
}

static void on_embree_error(void *user, enum RTCError code, const char *str) {
  (void)user;
  fprintf(stderr, "obscura: embree error %d: %s\n", (int)code, str ? str : "");
}

static bool on_embree_memory(void *user, ssize_t bytes, bool post) {
  (void)post;
  obs_rt *rt = user;
  long long now = atomic_fetch_add(&rt->embree_bytes, (long long)bytes) + (long long)bytes;
  long long peak = atomic_load(&rt->embree_peak);
  while (now > peak && !atomic_compare_exchange_weak(&rt->embree_peak, &peak, now)) {
  }
  return true; /* counted, never refused */
}

void obs_rt_device_config(int threads, char *buf, size_t size) {
  /* Embree's own names of the levels; native leaves Embree its best. */
  const int cap = obs_simd_isa_cap();
  const char *isa = cap == OBS_ISA_SSE2   ? "max_isa=sse2"
                    : cap == OBS_ISA_AVX2 ? "max_isa=avx2"
                                          : "";
  if (threads > 0)
    snprintf(buf, size, "threads=%d%s%s", threads, *isa ? "," : "", isa);
  else
    snprintf(buf, size, "%s", isa);
}

/* Whether `word` occurs in [from, to) as a whole space-separated word. */
static int has_word(const char *from, const char *to, const char *word) {
  const size_t n = strlen(word);
  for (const char *q = from; q + n <= to; q++)
    if (!strncmp(q, word, n) && (q == from || q[-1] == ' ') &&
        (q + n == to || q[n] == ' ' || q[n] == '\n'))
      return 1;
  return 0;
}

const char *obs_rt_embree_isa(void) {
  /* Embree 3 names the kernels it runs only in its banner (verbose=1, on stdout): read the
   * targets it supports after the cap and the ones this build of it has, best first. */
  static const char *const names[] = {"AVX512", "AVX2", "AVX", "SSE4.2", "SSE2"};
  char config[80], text[4096] = "";
  obs_rt_device_config(0, config, sizeof config);
  snprintf(config + strlen(config), sizeof config - strlen(config), "%sverbose=1",
           config[0] ? "," : "");
  FILE *tmp = tmpfile();
  if (!tmp) return "unknown";
  fflush(stdout);
  int saved = dup(1);
  if (saved < 0 || dup2(fileno(tmp), 1) < 0) {
    if (saved >= 0) close(saved);
    fclose(tmp);
    return "unknown";
  }
  RTCDevice dev = rtcNewDevice(config);
  if (dev) rtcReleaseDevice(dev);
  fflush(stdout);
  dup2(saved, 1);
  close(saved);
  rewind(tmp);
  size_t len = fread(text, 1, sizeof text - 1, tmp);
  text[len] = 0;
  fclose(tmp);
  const char *cfg = strstr(text, "Config");
  const char *sup = cfg ? strstr(cfg, "Targets") : NULL;
  const char *sup_end = sup ? strstr(sup, "(supported)") : NULL;
  const char *built_end = sup_end ? strstr(sup_end, "(compile time enabled)") : NULL;
  if (!built_end) return "unknown";
  for (size_t k = 0; k < sizeof names / sizeof *names; k++)
    if (has_word(sup, sup_end, names[k]) && has_word(sup_end, built_end, names[k])) return names[k];
  return "unknown";
}

/* Where the float frame sits for OBS_RT_FRAME_GEOMETRY: the point of the geometry's bounds
 * (obs_scene_extent, in double, nothing imported) nearest to the eye when the eye is more than
 * OBS_RT_FAR_CAMERA diagonals from them, else the eye itself. Scenes the camera is near or inside
 * keep the camera's frame, and so their exact bits. Returns 1 when the frame moved. */
static int frame_origin(const obs_scene *sc, const double eye[3], double at[3], obs_err *err) {
  memcpy(at, eye, 3 * sizeof *at);
  obs_extent ex;
  if (obs_scene_extent(sc, &ex, err) || ex.empty) return 0;
  double near[3], gap2 = 0, diag2 = ex.size * ex.size;
  for (int k = 0; k < 3; k++) {
    near[k] = fmin(fmax(eye[k], ex.bounds[0][k]), ex.bounds[1][k]);
    gap2 += (near[k] - eye[k]) * (near[k] - eye[k]);
  }
  if (!(gap2 > OBS_RT_FAR_CAMERA * OBS_RT_FAR_CAMERA * diag2) || !(diag2 > 0)) return 0;
  memcpy(at, near, sizeof near);
  return 1;
}

static int build_bvh(obs_rt *rt, int threads, obs_err *err);

int obs_rt_build(const obs_scene *sc, obs_rt *rt, int threads, obs_err *err) {
  return obs_rt_build_ex(sc, rt, threads, OBS_RT_FRAME_CAMERA, err);
}

int obs_rt_build_ex(const obs_scene *sc, obs_rt *rt, int threads, int frame, obs_err *err) {
  memset(rt, 0, sizeof *rt);
  rt->sphere_geom = RTC_INVALID_GEOMETRY_ID;
  /* Camera-relative coordinates: what the camera sees stays precise in float however far from
   * the world origin the scene sits. */
  const double eye[3] = {sc->camera.position.x, sc->camera.position.y, sc->camera.position.z};
  double at[3];
  int moved = frame == OBS_RT_FRAME_GEOMETRY && frame_origin(sc, eye, at, err);
  int rc = obs_geometry_build_at(sc, moved ? at : eye, &rt->geo, err);
  if (rc) return rc;
  if (moved) {
    /* The box must contain every vertex however the slab test rounds: grow it by far more than
     * double's error on coordinates of its own size. */
    const double(*b)[3] = rt->geo.bounds;
    double diag2 = 0;
    for (int k = 0; k < 3; k++) diag2 += (b[1][k] - b[0][k]) * (b[1][k] - b[0][k]);
    double grow = sqrt(diag2) * 0x1p-20;
    for (int k = 0; k < 3; k++) {
      rt->box[0][k] = b[0][k] - grow;
      rt->box[1][k] = b[1][k] + grow;
    }
    rt->advance = 1;
  }
  return build_bvh(rt, threads, err);
}

int obs_rt_build_geo(obs_geometry *geo, obs_rt *rt, int threads, obs_err *err) {
  memset(rt, 0, sizeof *rt);
  rt->sphere_geom = RTC_INVALID_GEOMETRY_ID;
  rt->geo = *geo;
  memset(geo, 0, sizeof *geo);
  return build_bvh(rt, threads, err);
}

/* The Embree device and scene over rt->geo. */
static int build_bvh(obs_rt *rt, int threads, obs_err *err) {
  char config[64];
  obs_rt_device_config(threads, config, sizeof config);
  rt->isa = obs_simd_isa();
  rt->device = rtcNewDevice(config);
  if (!rt->device) {
    obs_geometry_free(&rt->geo);
    return obs_err_set(err, OBS_EINTERNAL, "embree: cannot create device (error %d)",
                       (int)rtcGetDeviceError(NULL));
  }
  /* Follows the device's instruction-set cap (config): 0 under OBSCURA_ISA=avx2. */
  rt->native16 = rtcGetDeviceProperty(rt->device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) > 0;
  rtcSetDeviceErrorFunction(rt->device, on_embree_error, NULL);
  rtcSetDeviceMemoryMonitorFunction(rt->device, on_embree_memory, rt);
  rt->scene = rtcNewScene(rt->device);
  /* Moving meshes are refitted each frame, the rest kept: with a low scene quality Embree builds
   * one BVH per geometry under a top level (each at its geometry's own quality) and rebuilds only
   * what changed. */
  int moves = 0;
  for (size_t i = 0; i < rt->geo.nmeshes; i++) moves |= rt->geo.meshes[i].obj_pos != NULL;
  rtcSetSceneFlags(rt->scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION |
                                  (moves ? RTC_SCENE_FLAG_DYNAMIC : RTC_SCENE_FLAG_NONE));
  if (moves) rtcSetSceneBuildQuality(rt->scene, RTC_BUILD_QUALITY_LOW);
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
    if (m->obj_pos) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
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

int obs_rt_place(obs_rt *rt, const obs_scene *sc, int frame, obs_err *err) {
  for (size_t i = 0; i < rt->geo.nmeshes; i++) {
    obs_mesh *m = &rt->geo.meshes[i];
    if (!m->obj_pos) continue;
    obs_geometry_mesh_place(m, obs_object_transform_at(&sc->objects[m->object], frame),
                            rt->geo.origin);
    RTCGeometry g = rtcGetGeometry(rt->scene, (unsigned)i);
    float *vb = rtcGetGeometryBufferData(g, RTC_BUFFER_TYPE_VERTEX, 0);
    memcpy(vb, m->pos, m->nverts * 3 * sizeof(float));
    rtcUpdateGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(g);
  }
  rtcCommitScene(rt->scene);
  enum RTCError e = rtcGetDeviceError(rt->device);
  if (e != RTC_ERROR_NONE)
    return obs_err_set(err, e == RTC_ERROR_OUT_OF_MEMORY ? OBS_ENOMEM : OBS_EINTERNAL,
                       "%s: embree: update to frame %d failed (error %d)", sc->name, frame,
                       (int)e);
  return 0;
}

void obs_rt_free(obs_rt *rt) {
  if (rt->scene) rtcReleaseScene(rt->scene);
  if (rt->device) rtcReleaseDevice(rt->device);
  obs_geometry_free(&rt->geo);
  memset(rt, 0, sizeof *rt);
}

/* Where the ray (o, d) enters rt->box: 0 when o is inside, -1 when it misses the box within
 * [0, tfar]. In double, so the float ray Embree then sees starts near the geometry. */
static double box_entry(const obs_rt *rt, const double o[3], const double d[3], double tfar) {
  double t0 = 0, t1 = tfar;
  for (int k = 0; k < 3; k++) {
    double lo = rt->box[0][k], hi = rt->box[1][k];
    if (d[k] == 0) {
      if (o[k] < lo || o[k] > hi) return -1;
      continue;
    }
    double a = (lo - o[k]) / d[k], b = (hi - o[k]) / d[k];
    t0 = fmax(t0, fmin(a, b));
    t1 = fmin(t1, fmax(a, b));
  }
  return t0 <= t1 ? t0 : -1;
}

static void fill_hit(const obs_rt *rt, const double org[3], const double dir[3],
                     const struct RTCRayHit *rh, obs_hit *hit);

int obs_rt_intersect(const obs_rt *rt, const double world_org[3], const double dir[3], float tfar,
                     obs_hit *hit) {
  double org[3] = {world_org[0] - rt->geo.origin[0], world_org[1] - rt->geo.origin[1],
                   world_org[2] - rt->geo.origin[2]};
  double tbase = 0;
  if (rt->advance) {
    tbase = box_entry(rt, org, dir, tfar);
    if (tbase < 0) return 0;
    for (int k = 0; k < 3; k++) org[k] += tbase * dir[k];
    tfar = (float)(tfar - tbase);
  }
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
  fill_hit(rt, org, dir, &rh, hit);
  if (tbase > 0) hit->t = (float)(tbase + hit->t);
  return 1;
}

int obs_rt_intersect_from(const obs_rt *rt, obs_rt_ctx *c, const float org[3], const float dir[3],
                          float tfar, obs_hit *hit) {
  struct RTCRayHit rh;
  memset(&rh, 0, sizeof rh);
  rh.ray.org_x = org[0], rh.ray.org_y = org[1], rh.ray.org_z = org[2];
  rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = tfar;
  rh.ray.mask = ~0u;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rt->scene, &c->ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return 0;
  const double o[3] = {org[0], org[1], org[2]}, d[3] = {dir[0], dir[1], dir[2]};
  fill_hit(rt, o, d, &rh, hit);
  return 1;
}

/* The surface data of Embree's hit `rh` of the ray (org, dir) in the ray tracer's frame. */
static void fill_hit(const obs_rt *rt, const double org[3], const double dir[3],
                     const struct RTCRayHit *rhp, obs_hit *hit) {
  const struct RTCRayHit rh = *rhp;
  hit->t = rh.ray.tfar;
  hit->geom = rh.hit.geomID;
  hit->prim = rh.hit.primID;
  hit->sphere_inside = 0;
  float d[3] = {rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
  float ng[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
  int have_ns = 0, unit = 0;
  float ns[3] = {0, 0, 0};
  if (rh.hit.geomID == rt->sphere_geom) {
    const obs_sphere *s = &rt->geo.spheres[rh.hit.primID];
    double q[3] = {org[0] + rh.ray.tfar * dir[0] - s->center[0],
                   org[1] + rh.ray.tfar * dir[1] - s->center[1],
                   org[2] + rh.ray.tfar * dir[2] - s->center[2]};
    /* Project onto the sphere so the point's error is that of the centre and radius only. */
    if (obs_normalize3d(q)) q[0] = 0, q[1] = 0, q[2] = 1;
    for (int k = 0; k < 3; k++) {
      double u = q[k];
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
    double n[3], oa[3];
    obs_rt_plane_normal(a, b, c, n);
    for (int k = 0; k < 3; k++) oa[k] = (double)a[k] - org[k];
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
    /* The face normal is that double cross product of the float vertices, normalised in double
     * and rounded once (obs_rt_intersect_primary's too), not Embree's float Ng: Embree forms its
     * edge products with fused multiply-adds on AVX2 and AVX-512 and plain ones on SSE2, so a
     * component whose products cancel (dx dy - dy dx, two vertices that differ in one coordinate
     * only) came out as +-(the rounding error of dx dy), its sign changing with the scale and the
     * instruction set, where the double one is exactly 0 everywhere; and Embree's runs into the
     * subnormals for edges below ~1e-19. Embree's stands in only for a triangle without area in
     * double. */
    if (!obs_normalize3d(n)) {
      for (int k = 0; k < 3; k++) ng[k] = (float)n[k];
      unit = 1;
    }
    if (m->nrm) {
      const float *na = m->nrm + 3 * tri[0], *nb = m->nrm + 3 * tri[1], *nc = m->nrm + 3 * tri[2];
      for (int k = 0; k < 3; k++) ns[k] = w * na[k] + u * nb[k] + v * nc[k];
      have_ns = ns[0] != 0 || ns[1] != 0 || ns[2] != 0;
    }
  }
  if (!unit && obs_normalize3f(ng)) ng[0] = 0, ng[1] = 0, ng[2] = 1;
  int back = ng[0] * d[0] + ng[1] * d[1] + ng[2] * d[2] > 0;
  if (back) {
    for (int k = 0; k < 3; k++) ng[k] = -ng[k];
    hit->sphere_inside = rh.hit.geomID == rt->sphere_geom;
  }
  memcpy(hit->ng, ng, sizeof ng);
  if (have_ns) {
    if (obs_normalize3f(ns)) memcpy(ns, ng, sizeof ns);
    if (ns[0] * ng[0] + ns[1] * ng[1] + ns[2] * ng[2] < 0)
      for (int k = 0; k < 3; k++) ns[k] = -ns[k];
    memcpy(hit->ns, ns, sizeof ns);
  } else {
    memcpy(hit->ns, ng, sizeof ng);
  }
}

/* Storage for one packet's rays and hits, structure-of-arrays. */
#if OBS_RT_PACKET == 16
typedef struct RTCRayHit16 rt_packet;
#elif OBS_RT_PACKET == 8
typedef struct RTCRayHit8 rt_packet;
#else
#error "OBS_RT_PACKET must be 8 or 16"
#endif

/* The packet's rays go to Embree through rtcIntersect16 where Embree has 16-wide packet kernels
 * (its AVX-512 build on a CPU that has it: obs_rt.native16), else as a structure-of-arrays stream
 * (rtcIntersectNp), which Embree splits into whatever packets the CPU has: rtcIntersect16/8
 * without native kernels fail and leave every ray a miss. The stream costs Embree a copy of the
 * rays into its own packets: on the proximity_ao goal frame (1M-triangle displaced sphere, 1024^2
 * rays in 4x4 packets, one thread of the AVX-512 machine) rtcIntersect16 traced them in 53-55 ms
 * against 66-67 ms as a stream. Under OBSCURA_ISA=avx2 (sse2) the stream is 1.5-2.3x (1.4x) faster
 * than the same rays in two rtcIntersect8 (four rtcIntersect4) packets of 4x2 (4x1) pixels. */
static void trace_packet(const obs_rt *rt, struct RTCIntersectContext *ctx, rt_packet *rh, int n) {
#if OBS_RT_PACKET == 16
  if (rt->native16) {
    _Alignas(64) int valid[16];
    for (int i = 0; i < 16; i++) valid[i] = i < n ? -1 : 0;
    rtcIntersect16(valid, rt->scene, ctx, rh);
    return;
  }
#endif
  struct RTCRayHitNp np;
  np.ray.org_x = rh->ray.org_x, np.ray.org_y = rh->ray.org_y, np.ray.org_z = rh->ray.org_z;
  np.ray.dir_x = rh->ray.dir_x, np.ray.dir_y = rh->ray.dir_y, np.ray.dir_z = rh->ray.dir_z;
  np.ray.tnear = rh->ray.tnear, np.ray.tfar = rh->ray.tfar, np.ray.time = rh->ray.time;
  np.ray.mask = rh->ray.mask, np.ray.id = rh->ray.id, np.ray.flags = rh->ray.flags;
  np.hit.Ng_x = rh->hit.Ng_x, np.hit.Ng_y = rh->hit.Ng_y, np.hit.Ng_z = rh->hit.Ng_z;
  np.hit.u = rh->hit.u, np.hit.v = rh->hit.v;
  np.hit.primID = rh->hit.primID, np.hit.geomID = rh->hit.geomID;
  np.hit.instID[0] = rh->hit.instID[0];
  rtcIntersectNp(rt->scene, ctx, &np, (unsigned)n);
}

static inline __attribute__((always_inline)) void intersect_primary(const obs_rt *rt,
                                                                    const obs_rt_view *view, int n,
                                                                    const double sx[],
                                                                    const double sy[],
                                                                    obs_rt_primary *out) {
  rt_packet rh;
  /* Idle lanes (not traced) repeat lane 0 so every lane holds a well-formed ray. The packet is
   * filled field by field in branch-free loops the compiler vectorises: per-lane setup is a large
   * share of a primary ray's cost once Embree traces 16 at a time. */
  double lx[OBS_RT_PACKET], ly[OBS_RT_PACKET];
  for (int i = 0; i < OBS_RT_PACKET; i++) {
    lx[i] = sx[i < n ? i : 0];
    ly[i] = sy[i < n ? i : 0];
  }
  float *o[3] = {rh.ray.org_x, rh.ray.org_y, rh.ray.org_z};
  float *d[3] = {rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z};
  for (int k = 0; k < 3; k++) {
    const double e = view->eye[k], f = view->forward[k], r = view->right[k], u = view->up[k];
    /* The same expressions as obs_rt_view_ray, so Embree sees the rounding of the refined ray. */
    if (view->ortho) {
      for (int i = 0; i < OBS_RT_PACKET; i++) o[k][i] = (float)(e + (lx[i] * r + ly[i] * u));
      for (int i = 0; i < OBS_RT_PACKET; i++) d[k][i] = (float)f;
    } else {
      for (int i = 0; i < OBS_RT_PACKET; i++) o[k][i] = (float)e;
      for (int i = 0; i < OBS_RT_PACKET; i++) d[k][i] = (float)(f + (lx[i] * r + ly[i] * u));
    }
  }
  for (int i = 0; i < OBS_RT_PACKET; i++) {
    rh.ray.tnear[i] = 0.0f;
    rh.ray.tfar[i] = INFINITY;
    rh.ray.time[i] = 0.0f;
    rh.ray.mask[i] = ~0u;
    rh.ray.id[i] = (unsigned)i;
    rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  obs_rt_ctx c;
  rtcInitIntersectContext(&c.ctx);
  c.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  c.skip_geom = c.skip_prim = ~0u;
  c.skip_mode = 0;
  trace_packet(rt, &c.ctx, &rh, n);
  /* Neighbouring lanes mostly hit the same triangle: its plane is set up once per run of them. */
  unsigned plane_geom = RTC_INVALID_GEOMETRY_ID, plane_prim = 0;
  const float *plane_a = NULL;
  double plane_n[3] = {0, 0, 0}, plane_unit[3] = {0, 0, 0};
  for (int i = 0; i < n; i++) {
    obs_rt_primary *h = &out[i];
    h->geom = rh.hit.geomID[i];
    h->prim = rh.hit.primID[i];
    if (h->geom == RTC_INVALID_GEOMETRY_ID) {
      h->t = INFINITY;
      h->ng[0] = h->ng[1] = h->ng[2] = 0;
      continue;
    }
    double ro[3], rd[3];
    obs_rt_view_ray(view, sx[i], sy[i], ro, rd);
    double t = rh.ray.tfar[i];
    double ng[3] = {rh.hit.Ng_x[i], rh.hit.Ng_y[i], rh.hit.Ng_z[i]};
    int unit = 0;
    if (h->geom == rt->sphere_geom) {
      /* The root again from the double ray, which Embree only saw rounded to float. Grazing rays
       * the double ray misses keep Embree's root. */
      const obs_sphere *s = &rt->geo.spheres[h->prim];
      double td = obs_rt_sphere_root(s, ro, rd, 0.0, INFINITY, 0);
      if (td >= 0 && isfinite(td)) t = td;
      for (int k = 0; k < 3; k++) ng[k] = ro[k] + t * rd[k] - s->center[k];
    } else {
      /* The hit triangle's plane in double, as obs_rt_intersect does: Embree's float t errs in
       * proportion to the vertices' magnitude. The plane's double normal is the face normal. */
      if (h->geom != plane_geom || h->prim != plane_prim) {
        const obs_mesh *m = &rt->geo.meshes[h->geom];
        const uint32_t *tri = m->idx + 3 * (size_t)h->prim;
        const float *a = m->pos + 3 * tri[0], *b = m->pos + 3 * tri[1], *c = m->pos + 3 * tri[2];
        obs_rt_plane_normal(a, b, c, plane_n);
        for (int k = 0; k < 3; k++) plane_unit[k] = plane_n[k];
        if (obs_normalize3d(plane_unit)) plane_unit[0] = plane_unit[1] = plane_unit[2] = 0;
        plane_a = a;
        plane_geom = h->geom;
        plane_prim = h->prim;
      }
      /* The plane's normal is the face normal wherever it has one (fill_hit says why), even
       * where the ray runs along the plane and Embree's t stays. */
      double tp;
      if (obs_rt_plane_hit(plane_n, plane_a, ro, rd, &tp)) t = tp;
      if (plane_unit[0] != 0 || plane_unit[1] != 0 || plane_unit[2] != 0) {
        ng[0] = plane_unit[0], ng[1] = plane_unit[1], ng[2] = plane_unit[2];
        unit = 1;
      }
    }
    if (!unit && obs_normalize3d(ng)) ng[0] = 0, ng[1] = 0, ng[2] = 1;
    /* Element-wise stores: a memcpy of the array here compiled to a vector load of scalar stores,
     * a store-forwarding stall on every lane. */
    double face = ng[0] * rd[0] + ng[1] * rd[1] + ng[2] * rd[2] > 0 ? -1.0 : 1.0;
    h->t = t;
    h->ng[0] = face * ng[0];
    h->ng[1] = face * ng[1];
    h->ng[2] = face * ng[2];
  }
}

/* The lanes' set-up and refinement in double, as baseline and x86-64-v3 code (4 doubles per
 * instruction in the fill loops); the same bits either way. */
static void intersect_primary_base(const obs_rt *rt, const obs_rt_view *view, int n,
                                   const double sx[], const double sy[], obs_rt_primary *out) {
  intersect_primary(rt, view, n, sx, sy, out);
}
OBS_V3_FN static void intersect_primary_v3(const obs_rt *rt, const obs_rt_view *view, int n,
                                           const double sx[], const double sy[],
                                           obs_rt_primary *out) {
  intersect_primary(rt, view, n, sx, sy, out);
}

void obs_rt_intersect_primary(const obs_rt *rt, const obs_rt_view *view, int n, const double sx[],
                              const double sy[], obs_rt_primary *out) {
  if (rt->isa >= OBS_ISA_AVX2)
    intersect_primary_v3(rt, view, n, sx, sy, out);
  else
    intersect_primary_base(rt, view, n, sx, sy, out);
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
