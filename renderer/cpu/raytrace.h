/* The CPU backend's ray-tracing layer over Embree 3, shared by every CPU technique: scene build,
 * closest hits with world-space surface data, occlusion queries, and robust ray offsets. */
#ifndef OBS_RAYTRACE_H
#define OBS_RAYTRACE_H

#include <embree3/rtcore.h>
#include <stdatomic.h>
#include <math.h>

#include "camera.h"
#include "geometry.h"
#include "obscura/error.h"
#include "obscura/scene.h"

/* Built Embree scene plus the geometry it references. Owns all of it; obs_rt_free releases. */
typedef struct obs_rt {
  RTCDevice device;
  RTCScene scene;
  obs_geometry geo;
  unsigned sphere_geom;  /* geomID of the analytic-sphere user geometry, or RTC_INVALID_GEOMETRY_ID */
  int isa;               /* obs_simd_isa() when built: the level of obs_rt_intersect_primary */
  int native16;          /* Embree runs rtcIntersect16 natively (its AVX-512 kernels) */
  /* Set when the frame sits at the geometry rather than at a far camera (OBS_RT_FRAME_GEOMETRY):
   * obs_rt_intersect then moves each ray's origin up to `box` (the geometry's bounds in the frame,
   * slightly grown) in double before Embree sees it in float. */
  int advance;
  double box[2][3];
  /* Embree's own memory on this device (its memory monitor: BVH, vertex and index copies), now
   * and at its peak, in bytes; written from Embree's build threads. */
  atomic_llong embree_bytes, embree_peak;
} obs_rt;

/* A surface point seen along a ray, with normals faced toward the ray's origin side. */
typedef struct obs_hit {
  float t;
  float p[3];    /* position relative to rt->geo.origin, exactly on the surface (see raytrace.c) */
  float ng[3];   /* unit geometric normal, faced against the incoming ray */
  float ns[3];   /* unit shading normal on the same side as ng (== ng without mesh normals) */
  float perr[3]; /* per-component bound on the rounding error of p */
  unsigned geom, prim;
  int sphere_inside; /* hit a sphere from inside it */
} obs_hit;

/* Intersection context carrying which sphere a ray leaves, so the analytic sphere never reports
 * the surface the ray starts on. Must stay first-member compatible with RTCIntersectContext. */
typedef struct obs_rt_ctx {
  struct RTCIntersectContext ctx;
  unsigned skip_geom;  /* primitive the ray leaves (geomID, primID); ~0u for none */
  unsigned skip_prim;
  int skip_mode;       /* spheres: 0 none, 1 skip that sphere (left outward), 2 far root only */
} obs_rt_ctx;

/* Embree's device configuration string (rtcNewDevice): `threads` (0 = Embree's default) and the
 * instruction-set cap of simd.h (OBSCURA_ISA), so Embree's kernels obey the same switch as ours. */
void obs_rt_device_config(int threads, char *buf, size_t size);
/* The name of the kernels Embree picks under obs_rt_device_config(0, ...) ("AVX512", "AVX2", "AVX",
 * "SSE4.2", "SSE2"), read from its verbose banner; "unknown" if it cannot be read. For reports. */
const char *obs_rt_embree_isa(void);

/* Where the float frame of the geometry sits. At the camera, what the camera sees near it is
 * precise however far from the world origin the scene lies. When the camera is far from all the
 * geometry (a narrow field of view), float coordinates around the camera cannot resolve the
 * geometry and the frame must sit at the geometry instead: OBS_RT_FRAME_GEOMETRY puts it at the
 * point of the geometry's bounds nearest to the camera whenever the camera is more than
 * OBS_RT_FAR_CAMERA box diagonals away, and camera rays then start at the box. */
enum { OBS_RT_FRAME_CAMERA = 0, OBS_RT_FRAME_GEOMETRY = 1 };
#define OBS_RT_FAR_CAMERA 64.0

/* Builds geometry and BVH. `threads` (0 = all cores) also bounds Embree's own build threads.
 * obs_rt_build is obs_rt_build_ex with OBS_RT_FRAME_CAMERA (the G-buffer's primary-ray packets
 * assume their eye at the frame's origin). */
int obs_rt_build(const obs_scene *scene, obs_rt *rt, int threads, obs_err *err);
int obs_rt_build_ex(const obs_scene *scene, obs_rt *rt, int threads, int frame, obs_err *err);
/* obs_rt_build over geometry already built at the camera (obs_geometry_build_at), which `rt` takes
 * over: released by obs_rt_free, and on failure here. */
int obs_rt_build_geo(obs_geometry *geo, obs_rt *rt, int threads, obs_err *err);
void obs_rt_free(obs_rt *rt);
/* Moves the scene's moving meshes (obs_mesh.obj_pos) to where `frame` puts them (sc: the scene
 * rt was built from) and updates the BVH: refits theirs and rebuilds the top level. Not
 * thread-safe with queries on rt. */
int obs_rt_place(obs_rt *rt, const obs_scene *sc, int frame, obs_err *err);

/* Closest hit along (org, dir) within [0, tfar], org in world space. Returns 1 and fills `hit`
 * (p in the ray tracer's frame, world minus rt->geo.origin; t from org), or 0 on a miss. */
int obs_rt_intersect(const obs_rt *rt, const double org[3], const double dir[3], float tfar,
                     obs_hit *hit);
/* Closest hit along (org, dir) within [0, tfar], org in the ray tracer's frame (an obs_rt_offset
 * origin), skipping what `c` says the ray leaves (obs_rt_ctx_init): the secondary-ray twin of
 * obs_rt_intersect for techniques that follow paths. Returns 1 and fills `hit`, or 0. */
int obs_rt_intersect_from(const obs_rt *rt, obs_rt_ctx *c, const float org[3], const float dir[3],
                          float tfar, obs_hit *hit);
/* Rays per obs_rt_intersect_primary call (a 4x4 pixel block), handed to Embree as one stream
 * that it splits into the packets the CPU has. 16 measured ~15% faster than 8 (4x2 blocks) on an
 * AVX-512 machine (G-buffer of the Cornell box). 8 is the other supported value. */
#define OBS_RT_PACKET 16

/* A camera in the ray tracer's frame. The ray through image-plane offset (sx, sy) is
 *   perspective:  org = eye,                     dir = forward + sx right + sy up
 *   orthographic: org = eye + sx right + sy up,  dir = forward
 * With unit, orthogonal axes the ray parameter of a hit is then its view depth. */
typedef struct obs_rt_view {
  int ortho;
  double eye[3]; /* world minus rt->geo.origin */
  double forward[3], right[3], up[3];
} obs_rt_view;

/* The view of camera rig `cam` in a frame whose origin is `origin` (rt->geo.origin). */
static inline void obs_rt_view_init(const obs_camera_rig *cam, const double origin[3],
                                    obs_rt_view *v) {
  v->ortho = cam->ortho;
  for (int k = 0; k < 3; k++) {
    v->eye[k] = cam->origin[k] - origin[k];
    v->forward[k] = cam->forward[k];
    v->right[k] = cam->right[k];
    v->up[k] = cam->up[k];
  }
}

/* The image-plane offsets (sx, sy) of image position (fx, fy) in pixels, as obs_camera_ray takes
 * them. */
static inline double obs_rt_view_sx(const obs_camera_rig *cam, double fx) {
  return (2.0 * fx / cam->width - 1.0) * cam->half_w;
}
static inline double obs_rt_view_sy(const obs_camera_rig *cam, double fy) {
  return (1.0 - 2.0 * fy / cam->height) * cam->half_h;
}

/* The scene object (index into scene->objects) that primitive `prim` of geometry `geom` belongs
 * to: an analytic sphere or a mesh. */
static inline size_t obs_rt_hit_object(const obs_rt *rt, unsigned geom, unsigned prim) {
  return geom == rt->sphere_geom ? rt->geo.spheres[prim].object : rt->geo.meshes[geom].object;
}

/* The ray of `view` through image-plane offset (sx, sy), in double. */
static inline void obs_rt_view_ray(const obs_rt_view *v, double sx, double sy, double o[3],
                                   double d[3]) {
  for (int k = 0; k < 3; k++) {
    double off = sx * v->right[k] + sy * v->up[k];
    o[k] = v->ortho ? v->eye[k] + off : v->eye[k];
    d[k] = v->ortho ? v->forward[k] : v->forward[k] + off;
  }
}

/* The primary hit's refinement, shared by the ray caster and the rasteriser of the CPU G-buffer
 * so both give the same bits: the plane normal of float triangle (a, b, c) in double... */
static inline void obs_rt_plane_normal(const float a[3], const float b[3], const float c[3],
                                       double n[3]) {
  double e1[3], e2[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = (double)b[k] - a[k];
    e2[k] = (double)c[k] - a[k];
  }
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/* ...where the ray (ro, rd) meets that plane (n through a): 1 and *t when the parameter is finite
 * and >= 0, else 0 (the ray parallel to the plane or leaving it behind). Split in two for callers
 * with many rays from one origin: the numerator, then the parameter. */
static inline double obs_rt_plane_num(const double n[3], const float a[3], const double ro[3]) {
  double oa[3] = {a[0] - ro[0], a[1] - ro[1], a[2] - ro[2]};
  return oa[0] * n[0] + oa[1] * n[1] + oa[2] * n[2];
}
static inline int obs_rt_plane_t(double num, const double n[3], const double rd[3], double *t) {
  double dn = n[0] * rd[0] + n[1] * rd[1] + n[2] * rd[2];
  double tp = num / dn;
  *t = tp;
  return dn != 0.0 && isfinite(tp) && tp >= 0.0;
}
static inline int obs_rt_plane_hit(const double n[3], const float a[3], const double ro[3],
                                   const double rd[3], double *t) {
  return obs_rt_plane_t(obs_rt_plane_num(n, a, ro), n, rd, t);
}

/* Ray/sphere roots in double with the numerically careful discriminant of Haines et al.
 * ("Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7). Returns the
 * nearest acceptable root in (tnear, tfar] or -1. `mode`: 0 either root, 1 none (the sphere the
 * ray leaves outward), 2 the far root only (leaving it from inside). */
static inline double obs_rt_sphere_root(const obs_sphere *s, const double o[3], const double d[3],
                                        double tnear, double tfar, int mode) {
  double oc[3] = {o[0] - s->center[0], o[1] - s->center[1], o[2] - s->center[2]};
  double a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (!(a > 0)) return -1;
  double b = -(oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2]) / a; /* closest approach */
  double f[3] = {oc[0] + b * d[0], oc[1] + b * d[1], oc[2] + b * d[2]};
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

/* A primary hit reduced to what a G-buffer needs. */
typedef struct obs_rt_primary {
  double t;     /* ray parameter of the hit, refined in double (see raytrace.c); INFINITY: miss */
  double ng[3]; /* unit geometric normal, faced against the ray */
  unsigned geom, prim; /* geom is RTC_INVALID_GEOMETRY_ID on a miss */
} obs_rt_primary;

/* Closest hits within [0, inf) of n <= OBS_RT_PACKET coherent rays of `view` through the
 * image-plane offsets (sx[i], sy[i]), traced as one Embree packet. The caller owns all arrays;
 * out[i] is written for i < n. */
void obs_rt_intersect_primary(const obs_rt *rt, const obs_rt_view *view, int n, const double sx[],
                              const double sy[], obs_rt_primary *out);
/* Origin for secondary rays leaving `hit` on the side of its faced normal. */
void obs_rt_offset(const obs_rt *rt, const obs_hit *hit, float out[3]);
/* Prepares a context for rays leaving `from`. */
void obs_rt_ctx_init(obs_rt_ctx *c, const obs_rt *rt, const obs_hit *from);
/* Whether anything lies along (org, dir) within [0, tfar). Inline: it is the innermost call of
 * every occlusion technique. */
static inline int obs_rt_occluded(const obs_rt *rt, obs_rt_ctx *c, const float org[3],
                                  const float dir[3], float tfar) {
  struct RTCRay r;
  r.org_x = org[0], r.org_y = org[1], r.org_z = org[2];
  r.dir_x = dir[0], r.dir_y = dir[1], r.dir_z = dir[2];
  r.tnear = 0.0f;
  r.tfar = tfar;
  r.time = 0.0f;
  r.mask = ~0u;
  r.id = 0;
  r.flags = 0;
  rtcOccluded1(rt->scene, &c->ctx, &r);
  return r.tfar < 0.0f;
}
/* Distance to the closest surface along (org, dir) within [0, tfar], or INFINITY. */
float obs_rt_distance(const obs_rt *rt, obs_rt_ctx *c, const float org[3], const float dir[3],
                      float tfar);

#endif
