/* analytic_ao's occluders and their closed forms, shared by the CPU backend, the Vulkan backend's
 * host side and the tests: the scene's analytic shapes in view space, the sphere's occlusion, the
 * polygon's clipped form factor and the box as its receiver-facing faces
 * (docs/techniques/analytic_ao.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "camera.h"
#include "geometry.h"
#include "obscura/render.h"
#include "shapes.h"

const char *const obs_aao_stage_names[OBS_AAO_STAGES] = {"ao", "upsample", "ao_edges"};

#define AAO_TWO_PI 6.28318530717958647692f

/* A world point in the view space of `rig` (gbuffer.h: right, up, forward from the camera), in
 * double: the caller rounds once. */
static void to_view(const obs_camera_rig *rig, const double w[3], double out[3]) {
  double d[3] = {w[0] - rig->origin[0], w[1] - rig->origin[1], w[2] - rig->origin[2]};
  const double *axes[3] = {rig->right, rig->up, rig->forward};
  for (int k = 0; k < 3; k++) out[k] = d[0] * axes[k][0] + d[1] * axes[k][1] + d[2] * axes[k][2];
}

/* Centroid, bounding radius and cube of the points already in o->pts. */
static void bound_points(obs_aao_occluder *o, const double v[8][3], int n, double extent) {
  double c[3] = {0, 0, 0}, r = 0;
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) c[k] += v[i][k] / n;
  for (int i = 0; i < n; i++) {
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (v[i][k] - c[k]) * (v[i][k] - c[k]);
    if (d2 > r * r) r = sqrt(d2);
  }
  for (int k = 0; k < 3; k++) o->center[k] = (float)c[k];
  o->radius = (float)r;
  o->bound = isfinite(extent) ? (float)(extent * r) : INFINITY;
}

/* One object as an occluder; returns 0 for a kind with no closed form (a receiver only). */
static int make_occluder(const obs_object *ob, const obs_camera_rig *rig, double extent,
                         obs_aao_occluder *o) {
  int kind;
  switch (ob->shape.type) {
    case OBS_SHAPE_SPHERE: kind = OBS_AAO_SPHERE; break;
    case OBS_SHAPE_QUAD:
    case OBS_SHAPE_TRIANGLE: kind = OBS_AAO_POLYGON; break;
    case OBS_SHAPE_BOX: kind = OBS_AAO_BOX; break;
    default: return 0;
  }
  double pts[8][3], radius = 0, v[8][3];
  int n = obs_geometry_object_points(ob, 0, NULL, pts, &radius);
  memset(o, 0, sizeof *o);
  o->kind = (float)kind;
  if (kind == OBS_AAO_SPHERE) {
    double cv[3];
    to_view(rig, pts[0], cv);
    for (int k = 0; k < 3; k++) o->center[k] = (float)cv[k];
    o->radius = (float)radius;
    o->bound = isfinite(extent) ? (float)(extent * radius) : INFINITY;
    return 1;
  }
  for (int i = 0; i < n; i++) to_view(rig, pts[i], v[i]);
  if (kind == OBS_AAO_BOX) {
    /* The face table assumes corners whose x, y, z axes are right-handed; a mirroring transform
     * (or the view space's own handedness) reverses them: swapping the x ends restores it. */
    double e[3][3];
    for (int a = 0; a < 3; a++)
      for (int k = 0; k < 3; k++) e[a][k] = v[1 << a][k] - v[0][k];
    double det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                 e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                 e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    if (det < 0)
      for (int i = 0; i < 8; i += 2)
        for (int k = 0; k < 3; k++) {
          double t = v[i][k];
          v[i][k] = v[i + 1][k];
          v[i + 1][k] = t;
        }
  }
  o->n = (float)n;
  if (n == 4) {
    /* v3's distance from the plane of (v0, v1, v2), relative to the quad's size. */
    double a[3], b[3], c[3], nn[3], l2 = 0, d = 0, s2 = 0;
    for (int k = 0; k < 3; k++) {
      a[k] = v[1][k] - v[0][k], b[k] = v[2][k] - v[0][k], c[k] = v[3][k] - v[0][k];
      s2 += b[k] * b[k];
    }
    nn[0] = a[1] * b[2] - a[2] * b[1], nn[1] = a[2] * b[0] - a[0] * b[2];
    nn[2] = a[0] * b[1] - a[1] * b[0];
    for (int k = 0; k < 3; k++) l2 += nn[k] * nn[k], d += nn[k] * c[k];
    o->split = l2 > 0 && fabs(d) > 1e-6 * sqrt(l2) * sqrt(s2) ? 1.0f : 0.0f;
  }
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) o->pts[i][k] = (float)v[i][k];
  bound_points(o, v, n, extent);
  return 1;
}

int obs_aao_occluders(const obs_scene *scene, const obs_camera_rig *rig, double extent,
                      const obs_param_names *only, obs_aao_occluder **out, size_t *count,
                      size_t *skipped, obs_err *err) {
  *out = NULL;
  *count = 0;
  if (skipped) *skipped = 0;
  obs_aao_occluder *a = calloc(scene->nobjects ? scene->nobjects : 1, sizeof *a);
  if (!a) return obs_err_set(err, OBS_ENOMEM, "analytic_ao: %zu occluders: out of memory",
                             scene->nobjects);
  size_t n = 0;
  for (size_t i = 0; i < scene->nobjects; i++) {
    if (only && !obs_param_names_has(only, scene->objects[i].name)) continue;
    if (make_occluder(&scene->objects[i], rig, extent, &a[n]))
      n++;
    else if (skipped)
      (*skipped)++;
  }
  *out = a;
  *count = n;
  return 0;
}

int obs_aao_render_occluders(obs_render_ctx *ctx, int width, int height,
                             const obs_analytic_ao_params *p, obs_aao_occluder **out,
                             size_t *count, obs_err *err) {
  obs_camera_rig rig;
  obs_camera_setup(&ctx->scene->camera, width, height, &rig);
  size_t skipped;
  double t0 = obs_now_ms();
  int rc = obs_aao_occluders(ctx->scene, &rig, p->extent, &p->occluders, out, count, &skipped, err);
  if (rc) return rc;
  if (skipped)
    obs_render_ctx_warn(ctx, "analytic_ao: %zu object(s) with no closed form (meshes) receive "
                        "occlusion but cast none", skipped);
  obs_render_ctx_stage(ctx, "occluders", obs_now_ms() - t0);
  return 0;
}

/* ---- the closed forms (the twin of analytic_ao.comp.glsl) -------------------------------- */

static inline float dot3(const float a[3], const float b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void cross3(const float a[3], const float b[3], float c[3]) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

static inline float saturate(float x) { return x < 0.0f ? 0.0f : x > 1.0f ? 1.0f : x; }

/* The sphere: cos a (r/d)^2, exact while the sphere is wholly above the tangent plane, times the
 * article's horizon factor saturate((h + r) / 2r) that fades it as it sinks below. A receiver on
 * the sphere itself has h = -r: no occlusion. */
static float sphere_occlusion(const obs_aao_occluder *o, const float p[3], const float nrm[3]) {
  float v[3] = {o->center[0] - p[0], o->center[1] - p[1], o->center[2] - p[2]};
  float r = o->radius, d = sqrtf(dot3(v, v));
  if (!(d > 0.0f)) return 0.0f;
  float h = dot3(nrm, v), q = r / d;
  float occ = (h / d) * (q * q) * saturate((h + r) / (2.0f * r));
  return saturate(occ);
}

/* atan of t >= 0 (t may be infinite) in plain float operations (Cephes' atanf: reduction to
 * |x| <= tan(pi/8) and an odd polynomial, about 1e-7 relative), so that every CPU and the shader,
 * which spells out the same operations, round alike; libm's atan2f differs between versions. */
static float atan_pos(float t) {
  float base = 0.0f, x = t;
  if (t > 2.414213562373095f) {
    base = 1.5707963267948966f;
    x = -1.0f / t;
  } else if (t > 0.4142135623730950f) {
    base = 0.7853981633974483f;
    x = (t - 1.0f) / (t + 1.0f);
  }
  float z = x * x;
  float y = (((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
             3.33329491539e-1f) * z * x + x;
  return base + y;
}

/* The angle between unit vectors with |a x b| = s >= 0 and a . b = c, in [0, pi]. */
static float angle_of(float s, float c) {
  if (c > 0.0f) return atan_pos(s / c);
  if (c < 0.0f) return 3.14159265358979323846f - atan_pos(s / -c);
  return 1.5707963267948966f;
}

float obs_aao_polygon_sum(const float (*v)[3], int n, const float nrm[3]) {
  /* Unit vectors first: the cross products of raw ones underflow at 1e-9 scene sizes. */
  float u[8][3];
  for (int i = 0; i < n; i++) {
    float l = sqrtf(dot3(v[i], v[i]));
    for (int k = 0; k < 3; k++) u[i][k] = l > 0.0f ? v[i][k] / l : 0.0f;
  }
  float s = 0.0f;
  for (int i = 0; i < n; i++) {
    const float *a = u[i], *b = u[i + 1 < n ? i + 1 : 0];
    float c[3];
    cross3(b, a, c); /* the text's E_i x V_i = (V_{i+1} - V_i) x V_i = V_{i+1} x V_i */
    float cl = sqrtf(dot3(c, c));
    if (!(cl > 0.0f)) continue;
    float theta = angle_of(cl, dot3(a, b));
    s += theta * (dot3(nrm, c) / cl);
  }
  return s / AAO_TWO_PI;
}

/* Clips the polygon `in` (relative to the receiver) to the receiver's upper half-space
 * nrm . x >= 0 (Sutherland-Hodgman, one plane): at most n + 1 vertices. */
static int clip_horizon(const float (*in)[3], int n, const float nrm[3], float (*out)[3]) {
  int m = 0;
  for (int i = 0; i < n; i++) {
    const float *a = in[i], *b = in[i + 1 < n ? i + 1 : 0];
    float da = dot3(nrm, a), db = dot3(nrm, b);
    if (da >= 0.0f) memcpy(out[m++], a, sizeof out[0]);
    if ((da >= 0.0f) != (db >= 0.0f)) {
      float t = da / (da - db);
      for (int k = 0; k < 3; k++) out[m][k] = a[k] + t * (b[k] - a[k]);
      m++;
    }
  }
  return m;
}

/* Relative distance below which a receiver counts as lying in a polygon's plane: the G-buffer's
 * own rounding of a point on the polygon, which would otherwise see the polygon all round it
 * (form factor 1) whenever the rounding puts it behind. */
#define AAO_COPLANAR 1e-4f

/* A polygon's form factor from p (the contour sum's magnitude); with `front_only`, only a polygon
 * whose right-hand normal faces p counts (a box's face), else both sides do. */
static float polygon_occlusion(const float (*pts)[4], const int *idx, int n, const float p[3],
                               const float nrm[3], int front_only) {
  float v[8][3], c[8][3];
  float reach = sqrtf(dot3(p, p));
  for (int i = 0; i < n; i++) {
    for (int k = 0; k < 3; k++) v[i][k] = pts[idx[i]][k] - p[k];
    float l = sqrtf(dot3(v[i], v[i]));
    if (l > reach) reach = l;
  }
  float e1[3], e2[3], wn[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = v[n > 3 ? 2 : 1][k] - v[0][k];
    e2[k] = v[n > 3 ? 3 : 2][k] - v[n > 3 ? 1 : 0][k];
  }
  cross3(e1, e2, wn); /* the right-hand normal of the winding */
  float wl = sqrtf(dot3(wn, wn));
  if (!(wl > 0.0f)) return 0.0f;
  float side = -dot3(wn, v[0]) / wl; /* signed distance of p from the plane */
  /* p on the polygon itself: in its plane (to the G-buffer's rounding) and facing along its
   * normal. A receiver across a contact line (a floor meeting the wall) faces across it and
   * keeps the wall, however close. */
  if (fabsf(side) <= AAO_COPLANAR * reach && fabsf(dot3(nrm, wn)) > 0.5f * wl) return 0.0f;
  if (front_only && side < 0.0f) return 0.0f;
  int m = clip_horizon((const float (*)[3])v, n, nrm, c);
  if (m < 3) return 0.0f;
  return fabsf(obs_aao_polygon_sum((const float (*)[3])c, m, nrm));
}

/* A box's faces by corner (bit 0 = x max, 1 = y max, 2 = z max), wound with the right-hand normal
 * outward: -x, +x, -y, +y, -z, +z. */
static const int box_faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                    {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};

float obs_aao_occlusion(const obs_aao_occluder *o, const float p[3], const float nrm[3]) {
  if (o->kind == (float)OBS_AAO_SPHERE) return sphere_occlusion(o, p, nrm);
  if (o->kind == (float)OBS_AAO_POLYGON) {
    static const int order[4] = {0, 1, 2, 3}, second[3] = {0, 2, 3};
    if (o->split == 0.0f) return saturate(polygon_occlusion(o->pts, order, (int)o->n, p, nrm, 0));
    /* A non-planar quad's two triangles cover directions side by side: their sum. */
    return saturate(polygon_occlusion(o->pts, order, 3, p, nrm, 0) +
                    polygon_occlusion(o->pts, second, 3, p, nrm, 0));
  }
  /* A box: the faces that face p, summed; those facing away cover the same directions again. */
  float s = 0.0f;
  for (int f = 0; f < 6; f++) s += polygon_occlusion(o->pts, box_faces[f], 4, p, nrm, 1);
  return saturate(s);
}
