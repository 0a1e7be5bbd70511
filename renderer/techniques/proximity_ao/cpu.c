/* proximity_ao on the CPU: camera rays, traced a cell of pixels at a time as Embree packets,
 * find each pixel sample's surface point, face normal and object (a ray-cast G-buffer with object
 * ids); every object's proximity field whose box holds the point is read along the normal
 * (core/proximity.c) and the occlusions combined. The framework builds the BVH and the fields
 * (needs); the per-pixel driver owns the image and hands out the cells. A scene with moving
 * objects renders every frame from the same fields. */
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
  obs_rt_view view; /* the camera in the ray tracer's frame */
  obs_proximity_ao_params p;
  obs_prox_recon recon;
  double step;        /* R / N, world units */
  int spp;
  double (*maps)[3][4]; /* per field: world -> grid in the frame being rendered */
  float **corners;      /* per field: obs_prox_corners, or NULL (read one point at a time) */
  double *centre_sx, *centre_sy; /* obs_rt_view_sx / _sy of each column's and row's centre */
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
  obs_onb(n, t, b); /* the disc's axes */
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

/* Rays per cell of the driver's block grid, traced as packets of OBS_RT_PACKET. */
enum { CELL = OBS_PIXEL_BLOCK * OBS_PIXEL_BLOCK };
_Static_assert(CELL % OBS_RT_PACKET == 0, "a cell is whole packets");

/* The pixels [x0, x1) x [y0, y1) of one cell of the driver's grid (obs_shade_block_fn). Each
 * pixel sample is one camera ray; sample s of every pixel of the cell goes to Embree in one
 * packet, the whole cell even where a tile cuts it, so a pixel's hit never depends on the tiles
 * (the packet's lanes are always the same rays). The hit comes refined in double (the triangle's
 * plane, or the analytic sphere's root: obs_rt_intersect_primary), its point taken along the
 * double ray, its depth the ray parameter (the view depth: the rays are not normalised). */
static uint64_t shade_block(const void *user, int thread, int x0, int y0, int x1, int y1,
                            float *values) {
  (void)thread;
  const job *jb = user;
  const int B = OBS_PIXEL_BLOCK, cx = x0 / B * B, cy = y0 / B * B;
  const int cw = jb->cam.width - cx < B ? jb->cam.width - cx : B;
  const int chh = jb->cam.height - cy < B ? jb->cam.height - cy : B;
  const int n = cw * chh, spp = jb->spp;
  double ao[CELL] = {0}, depth[CELL] = {0}, nrm[CELL][3] = {{0}}, fields[CELL] = {0};
  int hits[CELL] = {0}, shade[CELL], px[CELL], py[CELL];
  obs_sampler2d jit[CELL];
  for (int y = cy, i = 0; y < cy + chh; y++)
    for (int x = cx; x < cx + cw; x++, i++) {
      px[i] = x, py[i] = y;
      shade[i] = x >= x0 && x < x1 && y >= y0 && y < y1;
      if (spp > 1)
        obs_sampler2d_init(&jit[i], OBS_SAMPLER_SOBOL, (uint32_t)x, (uint32_t)y, 0, 0, jb->p.seed);
    }
  const double *origin = jb->rt->geo.origin;
  for (int s = 0; s < spp; s++) {
    double sx[CELL], sy[CELL];
    for (int i = 0; i < n; i++) {
      if (spp == 1) {
        sx[i] = jb->centre_sx[px[i]];
        sy[i] = jb->centre_sy[py[i]];
        continue;
      }
      float jx, jy;
      obs_sampler2d_pixel(&jit[i], spp, (uint32_t)s, &jx, &jy);
      sx[i] = obs_rt_view_sx(&jb->cam, px[i] + (double)jx);
      sy[i] = obs_rt_view_sy(&jb->cam, py[i] + (double)jy);
    }
    obs_rt_primary h[CELL];
    for (int i = 0; i < n; i += OBS_RT_PACKET)
      obs_rt_intersect_primary(jb->rt, &jb->view, n - i < OBS_RT_PACKET ? n - i : OBS_RT_PACKET,
                               sx + i, sy + i, h + i);
    for (int i = 0; i < n; i++) {
      if (!shade[i]) continue;
      if (h[i].geom == RTC_INVALID_GEOMETRY_ID) {
        ao[i] += 1.0;
        continue;
      }
      hits[i]++;
      double ro[3], rd[3], p[3];
      obs_rt_view_ray(&jb->view, sx[i], sy[i], ro, rd);
      float ng[3];
      for (int k = 0; k < 3; k++) {
        p[k] = origin[k] + (ro[k] + h[i].t * rd[k]);
        ng[k] = (float)h[i].ng[k];
        nrm[i][k] += ng[k];
      }
      int nf;
      ao[i] += accessibility(jb, p, ng, obs_rt_hit_object(jb->rt, h[i].geom, h[i].prim), &nf);
      fields[i] += nf;
      depth[i] += h[i].t;
    }
  }
  /* Channel after channel (obs_shade_block_fn); one reciprocal per pixel for the averages. */
  const int m = (x1 - x0) * (y1 - y0);
  for (int i = 0, j = 0; i < n; i++) {
    if (!shade[i]) continue;
    double per_hit = hits[i] > 1 ? 1.0 / hits[i] : 1.0;
    double nl = sqrt(nrm[i][0] * nrm[i][0] + nrm[i][1] * nrm[i][1] + nrm[i][2] * nrm[i][2]);
    double per_len = nl > 0 ? 1.0 / nl : 0.0;
    values[CH_AO * m + j] = (float)(spp > 1 ? ao[i] / spp : ao[i]);
    values[CH_FIELDS * m + j] = (float)(fields[i] * per_hit);
    values[CH_ALPHA * m + j] = (float)hits[i] / (float)spp;
    values[CH_DEPTH * m + j] = (float)(depth[i] * per_hit);
    for (int k = 0; k < 3; k++) values[(CH_NX + k) * m + j] = (float)(nrm[i][k] * per_len);
    j++;
  }
  return (uint64_t)spp * (uint64_t)m;
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
  if (!ctx->rt || !ctx->prepared)
    return obs_err_set(err, OBS_EINTERNAL, "%s: proximity_ao: no BVH or fields were built for it",
                       sc->name);
  job jb;
  memset(&jb, 0, sizeof jb);
  jb.sc = sc;
  jb.rt = ctx->rt;
  jb.fs = &ctx->prepared->fields;
  jb.p = *(const obs_proximity_ao_params *)ctx->bound;
  jb.spp = sc->spp;
  jb.step = obs_proximity_ao_step(&jb.p, jb.fs->rp);
  obs_proximity_ao_recon(&jb.p, &jb.recon);
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  obs_rt_view_init(&jb.cam, jb.rt->geo.origin, &jb.view);
  size_t n = jb.fs->n ? jb.fs->n : 1;
  jb.maps = malloc(n * sizeof *jb.maps);
  jb.corners = calloc(n, sizeof *jb.corners);
  jb.centre_sx = malloc((size_t)sc->width * sizeof *jb.centre_sx);
  jb.centre_sy = malloc((size_t)sc->height * sizeof *jb.centre_sy);
  int rc = 0;
  if (!jb.maps || !jb.corners || !jb.centre_sx || !jb.centre_sy)
    rc = obs_err_set(err, OBS_ENOMEM, "%s: proximity_ao: out of memory", sc->name);
  for (int x = 0; !rc && x < sc->width; x++) jb.centre_sx[x] = obs_rt_view_sx(&jb.cam, x + 0.5);
  for (int y = 0; !rc && y < sc->height; y++) jb.centre_sy[y] = obs_rt_view_sy(&jb.cam, y + 0.5);
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
  static const obs_pixel_ops ops = {CH_COUNT, obs_proximity_ao_channels, .block = shade_block};
  if (!rc) rc = render_frames(ctx, &jb, &ops, out, err);
  /* Built once per render for every frame, as the fields are: part of the build. */
  ctx->build_ms += corners_ms;
  for (size_t i = 0; jb.corners && i < jb.fs->n; i++) free(jb.corners[i]);
  free(jb.corners);
  free(jb.maps);
  free(jb.centre_sx);
  free(jb.centre_sy);
  return rc;
}
