/* disc_ao (Bookout, ShaderX7 6.8, after Bunnell 2005): one disc per scene triangle, its
 * occlusion of the G-buffer's receivers summed without visibility. The disc list and the per-disc
 * occlusion are shared by both backends (discs.c builds the list once on the host), so the CPU
 * twin and the device's proxies see the same discs. */
#ifndef OBS_DISC_AO_H
#define OBS_DISC_AO_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "camera.h"
#include "gbuffer.h"
#include "obscura/error.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

/* The proxy the device rasterises per disc (the CPU visits the same receivers through its grid). */
enum { OBS_DISC_PROXY_QUAD = 0, OBS_DISC_PROXY_PYRAMID = 1 };
/* Which receivers a disc occludes: those in front of it (the article's text) or behind it (its
 * listing, saturate(n_e . v) with v from the receiver to the disc). */
enum { OBS_DISC_SIDE_FRONT = 0, OBS_DISC_SIDE_BACK = 1 };

/* Bound from the descriptor's parameter table. */
typedef struct obs_disc_ao_params {
  int proxy;             /* OBS_DISC_PROXY_* */
  int area_over_pi;      /* the disc's A / pi in the form factor (exact on axis) instead of A */
  float influence_scale; /* a disc reaches influence_scale * sqrt(A): a length, scale-free */
  int side;              /* OBS_DISC_SIDE_* */
  float subdivide;       /* longest triangle edge, as a fraction of the scene's diagonal */
} obs_disc_ao_params;

/* One disc in the camera's view space (gbuffer.h), 32 bytes: also the device's vertex. */
typedef struct obs_disc {
  float c[3]; /* centroid of the triangle */
  float a;    /* the area in the form factor: A, or A / pi with area_over_pi */
  float n[3]; /* unit face normal, from the triangle's winding */
  float r2;   /* squared influence radius, (influence_scale sqrt(A))^2 */
} obs_disc;

typedef struct obs_disc_set {
  obs_disc *d;
  size_t n;
  size_t triangles; /* scene triangles (spheres tessellated) before the subdivision */
} obs_disc_set;

/* Discs at most: the subdivision refuses to make more (OBS_EINVAL naming the count it needed). */
#define OBS_DISC_MAX ((size_t)1 << 24)
/* Spheres become UV spheres of this many longitude segments (half as many latitude bands). */
#define OBS_DISC_SPHERE_LON 32

/* The disc of triangle (a, b, c) given in view space, double: 0 when it has no area. Its normal
 * is the world's for that winding (counter-clockwise seen from the side it faces). */
int obs_disc_make(const double a[3], const double b[3], const double c[3],
                  const obs_disc_ao_params *p, obs_disc *out);
/* Every triangle of the scene (spheres tessellated, each triangle split into m^2 by the
 * subdivision) as discs in the view space of `rig`. */
int obs_disc_set_build(const obs_scene *scene, const obs_camera_rig *rig,
                       const obs_disc_ao_params *p, obs_disc_set *out, obs_err *err);
void obs_disc_set_free(obs_disc_set *s);

/* The occlusion of receiver p (normal nr, view space) by disc d, the article's
 *   (1 - 1/sqrt(a/d^2 + 1)) saturate(+-n_e . v) saturate(4 n_r . v),  v = (c - p)/|c - p|,
 * with the first factor written as x / (s (s + 1)), x = a/d^2, s = sqrt(x + 1), which is the same
 * number without the cancellation of 1 - 1/s; 0 beyond the influence radius or at the centroid.
 * disc_ao.frag.glsl evaluates the same expression in the same order. */
static inline float obs_disc_occlusion(const obs_disc *d, const float p[3], const float nr[3],
                                       int side) {
  const float vx = d->c[0] - p[0], vy = d->c[1] - p[1], vz = d->c[2] - p[2];
  const float d2 = vx * vx + vy * vy + vz * vz;
  if (!(d2 > 0.0f) || d2 > d->r2) return 0.0f;
  const float len = sqrtf(d2);
  float ce = (d->n[0] * vx + d->n[1] * vy + d->n[2] * vz) / len;
  if (side == OBS_DISC_SIDE_FRONT) ce = -ce;
  const float cr = 4.0f * ((nr[0] * vx + nr[1] * vy + nr[2] * vz) / len);
  if (!(ce > 0.0f) || !(cr > 0.0f)) return 0.0f;
  const float x = d->a / d2, s = sqrtf(x + 1.0f);
  return x / (s * (s + 1.0f)) * fminf(ce, 1.0f) * fminf(cr, 1.0f);
}

/* AO from the summed occlusion: 1 - sum clamped into [0, 1] (`ao`), and 1 - sum unclamped
 * (`raw`, negative where the discs over-darken past black). */
static inline void obs_disc_ao_finish(float sum, float *ao, float *raw) {
  const float v = 1.0f - sum;
  if (raw) *raw = v;
  *ao = v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
}

/* What a pass did: receiver-disc pairs evaluated (the device: fragments shaded, a pixel's count of
 * its proxies), the most on one pixel, and the covered pixels whose sum passed 1 (clamped). */
typedef struct obs_disc_ao_stats {
  uint64_t fragments;
  uint32_t max_overdraw;
  uint64_t clamped;
} obs_disc_ao_stats;

/* The occlusion of every covered pixel of `g` by the discs: `ao` (and `ao_raw`, may be NULL) as
 * obs_disc_ao_finish makes them, 1 on uncovered pixels. The CPU loops over the discs of each
 * receiver's cell of a uniform grid; stats (may be NULL) count the pairs within reach. */
int obs_disc_ao_cpu_apply(const obs_gbuffer *g, const obs_disc_set *s, const obs_disc_ao_params *p,
                          int threads, float *ao, float *ao_raw, obs_disc_ao_stats *stats,
                          obs_err *err);
/* The same on the device: one proxy per disc from the geometry shader (p->proxy), rasterised
 * over the device G-buffer `dev` with additive blending; `host` gives the projection (its planes
 * are not read). stats (may be NULL) count the fragments; *ms (may be NULL) the device pass. */
int obs_disc_ao_vk_apply(obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                         const obs_disc_set *s, const obs_disc_ao_params *p, float *ao,
                         float *ao_raw, obs_disc_ao_stats *stats, double *ms, obs_err *err);

/* The run of each backend (cpu.c and vulkan.c), named by the descriptor's `run`. */
int obs_disc_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_disc_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
