/* instant_radiosity (Szecsi, ShaderX7 6.6, "Instant Radiosity with GPU Photon Tracing and
 * Approximate Indirect Shadows"): parameters, the virtual point lights of the photon walk, the
 * gather and filter passes' entry points for tests and benchmarks. The model is
 * docs/techniques/instant_radiosity.md. */
#ifndef OBS_INSTANT_RADIOSITY_H
#define OBS_INSTANT_RADIOSITY_H

#include <stdatomic.h>
#include <stdint.h>

#include "camera.h"
#include "gbuffer.h"
#include "layout.h"
#include "obscura/error.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_gbuffer obs_vk_gbuffer;
typedef struct obs_rt obs_rt;

enum { OBS_IRAD_VIS_NONE, OBS_IRAD_VIS_APPROX, OBS_IRAD_VIS_EXACT };

/* Bound from the descriptor's parameter table. */
typedef struct obs_instant_radiosity_params {
  int vpls;             /* VPL slots: paths = vpls / max_bounces, each up to max_bounces VPLs */
  int max_bounces;      /* diffuse reflections of the camera path, as path_trace's */
  float renew;          /* share of the paths renewed per frame */
  uint32_t frame;       /* the frame whose VPL set is rendered */
  float clamp_distance; /* N_c */
  int visibility;       /* OBS_IRAD_VIS_* */
  float shadow_bias;    /* approximate visibility's relative depth bias */
  float shadow_thickness; /* and the occluders' assumed relative thickness */
  int filter;           /* geometry-aware 4x4 filter of the interleaved image */
  float filter_depth;   /* relative depth difference a filter sample may have */
  float filter_normal;  /* least cosine between a filter sample's normal and the centre's */
  uint32_t seed;
  double exposure;
} obs_instant_radiosity_params;

/* The virtual point lights of one render. `rec` is what the gather reads (OBS_IRAD_VPL_VEC4 vec4
 * per VPL, view space, grouped by class: class k holds rec entries start[k] .. start[k+1] - 1);
 * `world` holds each VPL's position in the ray tracer's frame (3 floats), for shadow rays. */
typedef struct obs_irad_vpls {
  float *rec;
  float *world;
  int n;       /* VPLs stored (walks that leave the scene or meet black surfaces end early) */
  int paths;   /* photon paths walked */
  int classes; /* min(OBS_IRAD_CLASSES, paths); 0 without VPLs */
  int start[OBS_IRAD_CLASSES + 1];
} obs_irad_vpls;

/* The generation of path `path` (of `paths`) at frame `frame` when a share `renew` of the paths
 * is renewed per frame, round robin: how many times it has been walked anew since frame 0. */
uint32_t obs_irad_generation(uint32_t path, uint32_t paths, float renew, uint32_t frame);

/* The photon walk (Embree, `rt` built from `sc` with obs_rt_build): emitter points chosen by
 * power and uniformly in area, then cosine-distributed (diffuse BSDF-sampled) bounces; every
 * vertex is a VPL, the emitter point's giving direct light. Viewed through `rig`. An empty result
 * (no emitter, max_bounces 0) is no error. obs_irad_vpls_free releases it, also after failure. */
int obs_irad_vpls_make(const obs_scene *sc, const obs_rt *rt, const obs_camera_rig *rig,
                       const obs_instant_radiosity_params *p, obs_irad_vpls *out, obs_err *err);
void obs_irad_vpls_free(obs_irad_vpls *v);

/* The clamped form factor of the article at a receiver of unit normal n, VPL of unit normal m,
 * v from the receiver to the VPL: cos(theta) cos(psi) / d^2, and where the receiver lies closer
 * than N_c to the VPL's plane (d^2 cos^2 psi < nc2) the receiver moved along m onto that distance:
 * cos(theta) (N_c / delta) / delta^2 with delta^2 = d^2 (1 - cos^2 psi) + N_c^2. Zero behind
 * either surface. Double: the tests' closed form; the passes repeat it in float. */
double obs_irad_form_factor(const double n[3], const double m[3], const double v[3], int two_sided,
                            double nc2);

/* What the passes read besides the G-buffer: the VPLs, and per pixel the radiance the camera
 * ray through the pixel centre sees directly (emission of the surface hit, quad lights crossed,
 * the environment on a miss; 3 floats a pixel). `rt` is kept for exact visibility (NULL once
 * released). */
typedef struct obs_irad_light {
  obs_rt *rt;
  obs_camera_rig rig;
  obs_irad_vpls vpls;
  float *emission;
  /* Approximate visibility (obs_irad_approx_make; NULL otherwise): the depth min-pyramid's atlas
   * (pyr_w x its height, layout.h) and the distance cube (6 OBS_IRAD_CUBE x OBS_IRAD_CUBE) about
   * cube_c (view space). */
  float *pyramid, *cube;
  int pyr_w, pyr_h;
  float cube_c[3];
} obs_irad_light;

/* Builds the BVH, walks the photons and renders the emission of `sc` (ms: build, walk and
 * emission times; may be NULL). obs_irad_light_free releases it, also after failure. */
int obs_irad_light_make(const obs_scene *sc, const obs_instant_radiosity_params *p, int threads,
                        const atomic_int *cancel, obs_irad_light *out, double ms[3],
                        obs_err *err);
/* The same for a render: its scene, threads and cancellation, the times recorded as its stages
 * "bvh", "walk" and "emission". */
int obs_irad_light_render(obs_render_ctx *ctx, const obs_instant_radiosity_params *p,
                          obs_irad_light *out, obs_err *err);
void obs_irad_light_free(obs_irad_light *l);

/* Approximate visibility's inputs over the G-buffer `g` (the render's camera): the min-pyramid
 * of its depth and the distance cube of the geometry outside the view (Embree, l->rt), centred
 * on the scene's bounding box. ms (may be NULL): pyramid and cube times. */
int obs_irad_approx_make(const obs_gbuffer *g, obs_irad_light *l, int threads,
                         const atomic_int *cancel, double ms[2], obs_err *err);
/* The pyramid alone (l->pyramid, pyr_w, pyr_h). */
int obs_irad_pyramid_make(const obs_gbuffer *g, obs_irad_light *l, obs_err *err);
/* The same for a render, the times recorded as its stages "pyramid" and "cube". */
int obs_irad_approx_render(obs_render_ctx *ctx, const obs_gbuffer *g, obs_irad_light *l,
                           obs_err *err);
/* The width of the pyramid's atlas for a w x h depth buffer, and level l's x offset in it. */
int obs_irad_pyramid_offset(int w, int l);

/* The gather's push block over a G-buffer of w x h with that projection. */
void obs_irad_gather_push_make(const obs_instant_radiosity_params *p, const obs_irad_light *l,
                               int w, int h, int ortho, float half_w, float half_h,
                               obs_irad_gather_push *out);
void obs_irad_filter_push_make(const obs_instant_radiosity_params *p, int w, int h, int ortho,
                               float half_w, float half_h, obs_irad_filter_push *out);

/* Entries of stage_ms in the apply functions: gather, filter (0 when off); Vulkan adds readback. */
#define OBS_IRAD_CPU_STAGES 2
#define OBS_IRAD_VK_STAGES 3

/* The gather and filter passes on the CPU: `raw` and `out` (w x h x 4: irradiance RGB from the
 * VPLs, the share of it visibility kept) before and after the filter (out unused without it).
 * stage_ms (may be NULL): OBS_IRAD_CPU_STAGES entries. Exact visibility needs l->rt. */
int obs_irad_cpu_apply(const obs_gbuffer *g, const obs_irad_light *l,
                       const obs_instant_radiosity_params *p, int threads, float *raw, float *out,
                       double *stage_ms, obs_err *err);
/* The same on the device (visibility none or approximate), over a device G-buffer with the host G-buffer's
 * projection `proj`. raw_host / out_host as above, downloaded. */
int obs_irad_vk_apply(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *proj,
                      const obs_irad_light *l, const obs_instant_radiosity_params *p,
                      float *raw_host, float *out_host, double *stage_ms, obs_err *err);

/* The technique's extra channels (after the screen drivers' fixed set): radiance RGB. */
#define OBS_IRAD_EXTRA 3
extern const char *const obs_irad_extra_names[OBS_IRAD_EXTRA];
/* Writes the outputs: ao = the visibility share after the filter, ao_raw before it, and radiance
 * = emission + albedo / pi x irradiance. Uncovered pixels get visibility 1 and their emission. */
void obs_irad_export(const obs_gbuffer *g, const float *emission, const float *raw,
                     const float *res, float *ao, float *ao_raw, float *extra);

/* The run functions the descriptor names (obs_technique_run_fn). */
int obs_instant_radiosity_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err);
int obs_instant_radiosity_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err);

#endif
