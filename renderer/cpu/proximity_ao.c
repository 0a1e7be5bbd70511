/* proximity_ao on the CPU: a ray through each pixel finds the surface point, its face normal
 * and its object (the ray-cast G-buffer with object ids); every object's proximity field whose
 * box holds the point is read along the normal (core/proximity.c) and the occlusions combined.
 * The framework builds the BVH and the fields (needs); the per-pixel driver owns the image. A
 * scene with moving objects renders every frame from the same fields. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "obscura/render.h"
#include "proximity_ao.h"
#include "raytrace.h"
#include "sampling.h"
#include "techniques.h"

enum { CH_AO, CH_FIELDS, CH_DEPTH, CH_NX, CH_NY, CH_NZ, CH_ALPHA, CH_COUNT };
_Static_assert(CH_COUNT == OBS_PROX_CHANNELS, "the channels of obs_proximity_ao_channels");

typedef struct job {
  const obs_scene *sc;
  const obs_rt *rt;
  const obs_prox_fields *fs;
  obs_camera_rig cam;
  obs_proximity_ao_params p;
  obs_prox_recon recon;
  double step;        /* R / N, world units */
  int spp;
  double (*maps)[3][4]; /* per field: world -> grid in the frame being rendered */
  float **corners;      /* per field: obs_prox_corners, or NULL (read one point at a time) */
} job;

static void map_point(const double m[3][4], const double p[3], float out[3]) {
  for (int i = 0; i < 3; i++)
    out[i] = (float)(m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]);
}

static void map_vector(const double m[3][4], const double v[3], float out[3]) {
  for (int i = 0; i < 3; i++) out[i] = (float)(m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2]);
}

/* Accessibility at world point p with unit normal n on object `self`; *nfields: the fields read. */
static float accessibility(const job *jb, const double p[3], const float n[3], size_t self,
                           int *nfields) {
  float t[3], b[3];
  obs_prox_disc_axes(n, t, b);
  double h = jb->step, s[3], tv[3], bv[3];
  for (int k = 0; k < 3; k++) {
    s[k] = n[k] * h;
    tv[k] = t[k] * h;
    bv[k] = b[k] * h;
  }
  float occl = 0.0f, keep = 1.0f;
  *nfields = 0;
  for (size_t i = 0; i < jb->fs->n; i++) {
    const obs_prox_field *f = &jb->fs->f[i];
    if (!jb->p.self_occlusion && f->object == self) continue;
    float gp[3];
    map_point(jb->maps[i], p, gp);
    if (!obs_prox_inside(f, gp)) continue;
    float gs[3], gt[3], gb[3];
    map_vector(jb->maps[i], s, gs);
    map_vector(jb->maps[i], tv, gt);
    map_vector(jb->maps[i], bv, gb);
    float a = obs_prox_occlusion(f, jb->corners[i], &jb->recon, gp, gs, gt, gb);
    occl += a;
    keep *= 1.0f - a;
    ++*nfields;
  }
  float total = jb->p.combine == OBS_PROX_MULTIPLICATIVE ? 1.0f - keep : occl;
  if (total > 1.0f) total = 1.0f;
  return 1.0f - total;
}

static uint64_t shade_pixel(const void *user, int thread, int x, int y, float *d) {
  (void)thread;
  const job *jb = user;
  double ao = 0, depth = 0, nrm[3] = {0, 0, 0}, fields = 0;
  int hits = 0;
  obs_sampler2d jit;
  obs_sampler2d_init(&jit, OBS_SAMPLER_SOBOL, (uint32_t)x, (uint32_t)y, 0, 0, jb->p.seed);
  for (int s = 0; s < jb->spp; s++) {
    float jx, jy;
    obs_sampler2d_pixel(&jit, jb->spp, (uint32_t)s, &jx, &jy);
    double org[3], dir[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    obs_hit hit;
    if (!obs_rt_intersect(jb->rt, org, dir, INFINITY, &hit)) {
      ao += 1.0;
      continue;
    }
    hits++;
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = (double)hit.p[k] + jb->rt->geo.origin[k];
    int nf;
    ao += accessibility(jb, p, hit.ng, obs_rt_hit_object(jb->rt, hit.geom, hit.prim), &nf);
    fields += nf;
    for (int k = 0; k < 3; k++) nrm[k] += hit.ng[k];
    double fwd =
        dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] + dir[2] * jb->cam.forward[2];
    depth += hit.t * fwd;
  }
  d[CH_AO] = (float)(ao / jb->spp);
  d[CH_FIELDS] = hits ? (float)(fields / hits) : 0.0f;
  d[CH_ALPHA] = (float)hits / (float)jb->spp;
  d[CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  double nl = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
  for (int k = 0; k < 3; k++) d[CH_NX + k] = nl > 0 ? (float)(nrm[k] / nl) : 0.0f;
  return (uint64_t)jb->spp;
}

static void place_fields(job *jb, int frame) {
  for (size_t i = 0; i < jb->fs->n; i++) {
    const obs_prox_field *f = &jb->fs->f[i];
    obs_prox_world_to_grid(f, &jb->sc->objects[f->object], frame, jb->maps[i]);
  }
}

/* Frames after the first: the BVH moved, the fields' maps moved, the pixels again. */
static int render_frames(obs_render_ctx *ctx, job *jb, const obs_pixel_ops *ops, obs_image *out,
                         obs_err *err) {
  const obs_scene *sc = ctx->scene;
  json_t *frames = json_array();
  double shade = 0;
  int rc = 0;
  for (int f = 0; f < sc->frames && !rc; f++) {
    double t0 = obs_now_ms();
    if (f > 0) {
      obs_image_free(out);
      rc = obs_rt_place((obs_rt *)jb->rt, sc, f, err);
    }
    place_fields(jb, f);
    double t1 = obs_now_ms();
    if (!rc) rc = obs_driver_pixels(ctx, ops, jb, out, err);
    if (!rc) {
      shade += ctx->render_ms;
      json_array_append_new(frames, json_pack("{s:i, s:f, s:f}", "frame", f, "place_ms", t1 - t0,
                                              "render_ms", ctx->render_ms));
    }
  }
  if (rc) {
    json_decref(frames);
    return rc;
  }
  ctx->render_ms = shade;
  if (sc->frames > 1) ctx->frames = frames;
  else json_decref(frames);
  return 0;
}

int obs_proximity_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt || !ctx->proximity)
    return obs_err_set(err, OBS_EINTERNAL, "%s: proximity_ao: no BVH or fields were built for it",
                       sc->name);
  job jb;
  memset(&jb, 0, sizeof jb);
  jb.sc = sc;
  jb.rt = ctx->rt;
  jb.fs = ctx->proximity;
  jb.p = *(const obs_proximity_ao_params *)ctx->bound;
  jb.spp = sc->spp;
  jb.step = obs_proximity_ao_step(&jb.p, jb.fs->rp);
  obs_proximity_ao_recon(&jb.p, &jb.recon);
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  size_t n = jb.fs->n ? jb.fs->n : 1;
  jb.maps = malloc(n * sizeof *jb.maps);
  jb.corners = calloc(n, sizeof *jb.corners);
  int rc = 0;
  if (!jb.maps || !jb.corners)
    rc = obs_err_set(err, OBS_ENOMEM, "%s: proximity_ao: out of memory", sc->name);
  /* The eight-lane walk's read copies; a field without one (memory short) reads one point at a
   * time, with the same bits. */
  double t0 = obs_now_ms();
  for (size_t i = 0; !rc && i < jb.fs->n; i++) {
    const obs_prox_field *f = &jb.fs->f[i];
    if (!(jb.corners[i] = obs_prox_corners(f, &jb.recon, ctx->threads))) continue;
    json_array_append_new(ctx->built, json_pack("{s:s, s:I, s:I}", "name", "proximity_corners",
                                                 "object", (json_int_t)f->object, "bytes",
                                                 (json_int_t)(obs_prox_corners_count(f) *
                                                              sizeof(float))));
  }
  double corners_ms = obs_now_ms() - t0;
  if (!rc) obs_driver_stage_add(ctx, "corners", corners_ms);
  static const obs_pixel_ops ops = {CH_COUNT, obs_proximity_ao_channels, shade_pixel, NULL};
  if (!rc) rc = render_frames(ctx, &jb, &ops, out, err);
  /* Built once per render for every frame, as the fields are: part of the build. */
  ctx->build_ms += corners_ms;
  for (size_t i = 0; jb.corners && i < jb.fs->n; i++) free(jb.corners[i]);
  free(jb.corners);
  free(jb.maps);
  return rc;
}
