/* analytic_ao (Shopf, Barczak, Scheuermann, Oat, ShaderX7 6.3, "Deferred Occlusion from Analytic
 * Surfaces"): its parameters, the occluders in view space that both backends read, and the
 * closed-form occlusion of one occluder at one receiver. */
#ifndef OBS_ANALYTIC_AO_H
#define OBS_ANALYTIC_AO_H

#include <stddef.h>

#include "gbuffer.h"
#include "obscura/error.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;

/* Bound from the descriptor's parameter table (obs_params_bind with obs_technique_analytic_ao). */
typedef struct obs_analytic_ao_params {
  double extent;  /* half-size of each occluder's bounding cube in bounding radii; INFINITY: none */
  int resolution; /* OBS_AAO_FULL or OBS_AAO_HALF */
  obs_param_names occluders; /* the objects that occlude (count -1: every one) */
  int method;                /* OBS_AAO_COMPUTE or OBS_AAO_RASTER (Vulkan only) */
  int upsample;              /* OBS_AAO_BILATERAL or OBS_AAO_PUSH_PULL (half resolution only) */
} obs_analytic_ao_params;

enum { OBS_AAO_FULL, OBS_AAO_HALF };
/* How half resolution fills the pixels it did not evaluate. */
enum { OBS_AAO_BILATERAL, OBS_AAO_PUSH_PULL };

/* The push-pull pyramid: its levels 1.. (level 0 is the frame), each half its parent's size
 * rounded up down to 1 x 1, laid side by side in one atlas of width aw and height ah (level 1's):
 * level l at columns [x[l], x[l] + w[l]). */
#define OBS_AAO_PP_LEVELS 40
typedef struct obs_aao_pyramid {
  int n; /* levels 1..n */
  int x[OBS_AAO_PP_LEVELS], w[OBS_AAO_PP_LEVELS], h[OBS_AAO_PP_LEVELS];
  int aw, ah;
} obs_aao_pyramid;

static inline void obs_aao_pyramid_make(int width, int height, obs_aao_pyramid *py) {
  py->w[0] = width, py->h[0] = height, py->x[0] = 0, py->n = 0, py->aw = 0;
  do {
    int l = ++py->n;
    py->w[l] = (py->w[l - 1] + 1) / 2, py->h[l] = (py->h[l - 1] + 1) / 2;
    py->x[l] = py->aw, py->aw += py->w[l];
  } while ((py->w[py->n] > 1 || py->h[py->n] > 1) && py->n + 1 < OBS_AAO_PP_LEVELS);
  py->ah = py->h[1];
}
/* The Vulkan pass: a compute pass with per-tile culling, or the article's rasterised proxies. */
enum { OBS_AAO_COMPUTE, OBS_AAO_RASTER };

/* The upsampling's depth test: a half-resolution cell counts for a pixel while their depths
 * differ by less than this fraction of the pixel's, its weight tapering linearly to 0 there. */
#define OBS_AAO_UP_DEPTH 0.02f

/* The passes' stages, in order: the AO (at half resolution under OBS_AAO_HALF), the
 * upsampling and the pixels it left to full resolution (both 0 at full resolution). */
#define OBS_AAO_STAGES 3
extern const char *const obs_aao_stage_names[OBS_AAO_STAGES];

/* Occluder kinds. A box is its six faces, of which those facing the receiver count. */
enum { OBS_AAO_SPHERE = 0, OBS_AAO_POLYGON = 1, OBS_AAO_BOX = 2 };

/* One occluder in the camera's view space (gbuffer.h), rounded to float once on the host. The
 * layout is what the Vulkan shader reads as ten vec4s, so the host uploads the array as it is. */
typedef struct obs_aao_occluder {
  float center[3]; /* the sphere's centre; a polygon's or box's vertex centroid */
  float bound;     /* half-size of the bounding cube around center: extent x radius, or INFINITY */
  float kind;      /* OBS_AAO_*, as a float (exact) */
  float n;         /* polygon: 3 or 4 vertices; box: 8 corners */
  float radius;    /* sphere: its radius; others: the bounding radius (largest |vertex - centre|) */
  float split;     /* 1: a quad that is not planar, read as its triangles (0, 1, 2) and (0, 2, 3),
                     as the renderers triangulate it; else 0 */
  /* polygon: its vertices in order; box: its corners, corner i at bit 0 = x max, bit 1 = y max,
   * bit 2 = z max of its object-space box, relabelled so the face table winds outward */
  float pts[8][4];
} obs_aao_occluder;

/* A scene's occluders (its spheres, quads, triangles and boxes that `only` names; NULL: every
 * one) in the view space of `rig`, each transform applied in double before the rounding.
 * `*skipped` receives how many of the named objects are receivers only (meshes and other kinds
 * with no closed form). Caller frees *out. */
int obs_aao_occluders(const obs_scene *scene, const obs_camera_rig *rig, double extent,
                      const obs_param_names *only, obs_aao_occluder **out, size_t *count,
                      size_t *skipped, obs_err *err);

/* The occluders of a render's scene for its camera at width x height under the bound params
 * (extent, occluders): obs_aao_occluders, with a warning on ctx naming how many objects only
 * receive, and the time as stage "occluders". */
int obs_aao_render_occluders(obs_render_ctx *ctx, int width, int height,
                             const obs_analytic_ao_params *p, obs_aao_occluder **out,
                             size_t *count, obs_err *err);

/* Occlusion (the form factor from the receiver, in [0, 1]) of one occluder at the receiver p with
 * unit normal nrm, both view space: the sphere's closed form cos a (r/d)^2 saturate((h+r)/2r), a
 * polygon's form factor after clipping to p's tangent plane (two-sided), a box's front faces'
 * sum. The bounding cube is not tested here. */
float obs_aao_occlusion(const obs_aao_occluder *o, const float p[3], const float nrm[3]);

/* The signed contour sum of a polygon (vertices relative to the receiver, already clipped) with
 * the text's convention: sum over edges of theta_i n . unit(v_{i+1} x v_i) / (2 pi), positive for
 * a polygon wound counter-clockwise seen from the receiver (its right-hand normal toward it). */
float obs_aao_polygon_sum(const float (*v)[3], int n, const float nrm[3]);

/* Whether the bounding cube of `o` contains p (the per-pixel test of both backends). */
static inline int obs_aao_in_bound(const obs_aao_occluder *o, const float p[3]) {
  for (int k = 0; k < 3; k++)
    if (!(o->center[k] - o->bound <= p[k] && p[k] <= o->center[k] + o->bound)) return 0;
  return 1;
}

/* The AO of every pixel of a G-buffer: prod over occluders of (1 - occlusion), 1 where
 * uncovered; ao is width*height floats. Multi-threaded; each tile tests the occluders' cubes
 * against its receivers' box before its pixels do. Under p->resolution half: at every second
 * pixel of every second row, then the bilateral upsampling, then the pixels it could not fill.
 * stage_ms (may be NULL) receives OBS_AAO_STAGES entries. */
int obs_analytic_ao_cpu_apply(const obs_gbuffer *g, const obs_aao_occluder *occ, size_t nocc,
                              const obs_analytic_ao_params *p, int threads, float *ao,
                              double *stage_ms, obs_err *err);

/* The same on the device (vulkan.c) over its G-buffer; `host` gives the projection. stage_ms
 * (may be NULL) receives OBS_AAO_STAGES entries. Under p->method raster: the proxies
 * (obs_analytic_ao_vk_raster), at full resolution only. */
int obs_analytic_ao_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *host,
                             const obs_aao_occluder *occ, size_t nocc,
                             const obs_analytic_ao_params *p, float *ao_host, double *stage_ms,
                             obs_err *err);

/* The article's method (raster_vk.c): each occluder's bounding cube (a full-screen triangle
 * when unbounded) rasterised over the G-buffer, its closed form multiplied into a target cleared
 * to 1 by the blend, in occluder order. *ms (may be NULL) receives the pass's time. */
int obs_analytic_ao_vk_raster(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *host,
                              const obs_aao_occluder *occ, size_t nocc, float *ao_host,
                              double *ms, obs_err *err);

int obs_analytic_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_analytic_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
