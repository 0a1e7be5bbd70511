/* The G-buffer shared by screen-space techniques on every backend: the one definition of each
 * buffer, which the Vulkan rasteriser and the CPU ray caster both produce.
 *
 * View space: x right, y up, z forward (into the screen), origin at the camera. For pixel centre
 * (fx, fy) in pixels (0,0 = top-left corner) with ndc_x = 2 fx / W - 1 and ndc_y = 1 - 2 fy / H:
 *   perspective:  P = (ndc_x * tan_half_w * z, ndc_y * tan_half_h * z, z)
 *   orthographic: P = (ndc_x * half_w, ndc_y * half_h, z)
 * where z = depth[pixel]. */
#ifndef OBS_GBUFFER_H
#define OBS_GBUFFER_H

#include <stddef.h>

#include "camera.h"
#include "geometry.h"
#include "obscura/error.h"
#include "obscura/image.h"
#include "obscura/scene.h"
#include "obscura/backend.h"
#include "obscura/technique.h"

/* Owns its planes (one allocation); release with obs_gbuffer_free. */
typedef struct obs_gbuffer {
  int width, height;
  int ortho;
  float half_w, half_h; /* perspective: tan of the half field of view; orthographic: half extents */
  float *depth;    /* linear view depth z (> 0) where covered; 0 where not */
  float *normal;   /* 3 per pixel: unit face normal in view space, facing the camera; 0 where not */
  float *albedo;   /* 3 per pixel: the object's reflectivity ((1,1,1) without material); 0 if not */
  float *coverage; /* 1 where a surface covers the pixel centre, else 0 */
} obs_gbuffer;

int obs_gbuffer_alloc(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig,
                      obs_err *err);
/* The same with the buffers' contents unset, for a writer of every pixel (the CPU raster): spares
 * zeroing 32 bytes a pixel that are written again at once. */
int obs_gbuffer_alloc_unset(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig,
                            obs_err *err);
void obs_gbuffer_free(obs_gbuffer *g);

/* The albedo the G-buffer stores for an object: its reflectivity, (1, 1, 1) without a material. */
static inline void obs_gbuffer_albedo(const obs_object *o, float out[3]) {
  out[0] = o->has_material ? (float)o->reflectivity.x : 1.0f;
  out[1] = o->has_material ? (float)o->reflectivity.y : 1.0f;
  out[2] = o->has_material ? (float)o->reflectivity.z : 1.0f;
}

/* A world-space unit normal in the camera's view frame (right, up, forward), rounded to float:
 * what the CPU G-buffers store, whichever way they find the surface. */
static inline void obs_gbuffer_view_normal(const obs_camera_rig *rig, const double n[3],
                                           float out[3]) {
  const double *axes[3] = {rig->right, rig->up, rig->forward};
  for (int k = 0; k < 3; k++)
    out[k] = (float)(n[0] * axes[k][0] + n[1] * axes[k][1] + n[2] * axes[k][2]);
}

static inline void obs_gbuffer_position(const obs_gbuffer *g, float fx, float fy, float z,
                                        float out[3]) {
  float nx = 2.0f * fx / (float)g->width - 1.0f, ny = 1.0f - 2.0f * fy / (float)g->height;
  if (g->ortho) {
    out[0] = nx * g->half_w;
    out[1] = ny * g->half_h;
  } else {
    out[0] = nx * g->half_w * z;
    out[1] = ny * g->half_h * z;
  }
  out[2] = z;
}

/* Median linear view depth of the covered pixels, from a host G-buffer of the scene's camera
 * made by `gbuffer` (the CPU backend's, obs_gbuffer_cpu: what the CPU twins render from) at most
 * `max_side` pixels on its longer side (the aspect ratio kept; <= 0: full size). OBS_EINVAL
 * when nothing covers the image. Used by reference hooks that scale screen-space radii. */
int obs_gbuffer_median_depth(const obs_scene *scene, obs_backend_gbuffer_fn gbuffer, int max_side,
                             int threads, double *out, obs_err *err);

/* The screen-space rule (obs_range.screen of the scene's technique on `backend`) held against the
 * covered pixels of `g`, the G-buffer the technique ran on: one warning added to `ctx` per limit
 * (a pixel, a depth step) the radius falls short of somewhere (renderer/core/screen_rule.c).
 * Nothing when the technique declares no rule. */
void obs_screen_rule_check(obs_render_ctx *ctx, obs_backend backend, const obs_gbuffer *g);

/* The output channels of every screen-space technique, in this order: AO after and before its
 * blur, then the G-buffer's depth, world-space normal and coverage. */
enum { OBS_SCREEN_AO, OBS_SCREEN_AO_RAW, OBS_SCREEN_DEPTH, OBS_SCREEN_NX, OBS_SCREEN_NY,
       OBS_SCREEN_NZ, OBS_SCREEN_ALPHA, OBS_SCREEN_CHANNELS };
extern const char *const obs_screen_channel_names[OBS_SCREEN_CHANNELS];
/* The declared outputs those channels make: what a screen-space technique's descriptor names. */
extern const obs_output obs_screen_outputs[];
/* Channels a screen-space technique writes besides those (RGB outputs, say): `n` names, appended
 * to the image after the fixed set by both screen-space drivers, which hand the passes one plane
 * of w x h per name, in this order. */
#define OBS_SCREEN_EXTRA_MAX 16
typedef struct obs_screen_extra {
  int n;
  const char *const *names;
} obs_screen_extra;

/* Output channels every screen-space technique writes besides its own: "depth.Z", "normal.X/Y/Z"
 * (world space) and "alpha", taken from the G-buffer. `img` must already have those channels. */
void obs_gbuffer_export(const obs_gbuffer *g, const obs_camera_rig *rig, obs_image *img);

#endif
