/* isosurface_mesh on the CPU: every volume's isosurface extracted (renderer/core/isosurface.h) in
 * its data space, carried to the camera's frame in double, ray cast with its own Embree scene,
 * one ray per pixel sample on the per-pixel driver. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "isosurface.h"
#include "isosurface_mesh.h"
#include "raytrace.h"
#include "sampling.h"
#include "volume_scene.h"

typedef struct job {
  const obs_rt *rt;
  obs_camera_rig cam;
  int spp;
} job;

/* The camera rays are volume_ao's (its jitter with its default sampler and seed), so the two
 * images sample the same points and differ only by the surface. */
static uint64_t shade_pixel(const void *user, int thread, int x, int y, float *d) {
  (void)thread;
  const job *jb = user;
  double n[3] = {0, 0, 0}, depth = 0;
  int hits = 0;
  obs_sampler2d jit;
  obs_sampler2d_init(&jit, OBS_SAMPLER_SOBOL, (uint32_t)x, (uint32_t)y, 0, 0, 1);
  for (int s = 0; s < jb->spp; s++) {
    float jx, jy;
    obs_sampler2d_pixel(&jit, jb->spp, (uint32_t)s, &jx, &jy);
    double org[3], dir[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    obs_hit h;
    if (!obs_rt_intersect(jb->rt, org, dir, INFINITY, &h)) continue;
    hits++;
    for (int k = 0; k < 3; k++) n[k] += h.ng[k];
    depth += h.t * (dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] +
                    dir[2] * jb->cam.forward[2]);
  }
  double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int k = 0; k < 3; k++) d[ISO_CH_NX + k] = hits && len > 0 ? (float)(n[k] / len) : 0.0f;
  d[ISO_CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  d[ISO_CH_ALPHA] = (float)hits / (float)jb->spp;
  return (uint64_t)jb->spp;
}

/* Volume sv's mesh in the frame at `origin`: data space through to_world in double. */
static int place_mesh(const obs_scene_volume *sv, const obs_iso_mesh *im, const double origin[3],
                      obs_mesh *m) {
  memset(m, 0, sizeof *m);
  m->pos = malloc((im->nverts ? im->nverts : 1) * 3 * sizeof(float));
  m->idx = malloc((im->ntris ? im->ntris : 1) * 3 * sizeof(uint32_t));
  if (!m->pos || !m->idx) return OBS_ENOMEM;
  for (size_t i = 0; i < im->nverts; i++) {
    double w[3];
    obs_affine_point(sv->to_world, im->pos + 3 * i, w);
    for (int k = 0; k < 3; k++) m->pos[3 * i + k] = (float)(w[k] - origin[k]);
  }
  memcpy(m->idx, im->idx, im->ntris * 3 * sizeof(uint32_t));
  m->nverts = im->nverts;
  m->ntris = im->ntris;
  m->object = sv->object;
  return 0;
}

static void geometry_bounds(obs_geometry *g) {
  int first = 1;
  for (size_t i = 0; i < g->nmeshes; i++) {
    double b[2][3];
    if (!g->meshes[i].nverts) continue;
    obs_geometry_mesh_bounds(&g->meshes[i], b);
    for (int k = 0; k < 3; k++) {
      if (first || b[0][k] < g->bounds[0][k]) g->bounds[0][k] = b[0][k];
      if (first || b[1][k] > g->bounds[1][k]) g->bounds[1][k] = b[1][k];
    }
    first = 0;
  }
  for (int k = 0; k < 3; k++)
    g->extent = fmax(g->extent, fmax(fabs(g->bounds[0][k]), fabs(g->bounds[1][k])));
}

/* Extracts every volume into `g` (frame at the camera) and records each mesh in ctx->built. */
static int extract_all(obs_render_ctx *ctx, const obs_isosurface_mesh_params *p,
                       const double origin[3], obs_geometry *g, obs_err *err) {
  const obs_scene_volumes *vs = ctx->volumes;
  double all_ms = 0;
  memset(g, 0, sizeof *g);
  memcpy(g->origin, origin, sizeof g->origin);
  g->meshes = calloc(vs->n ? vs->n : 1, sizeof *g->meshes);
  g->spheres = calloc(1, sizeof *g->spheres);
  if (!g->meshes || !g->spheres) return obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  for (size_t i = 0; i < vs->n; i++) {
    const obs_scene_volume *sv = &vs->v[i];
    if (sv->brick)
      return obs_err_set(err, OBS_EUNSUPPORTED,
                         "%s: /objects/%zu: isosurface_mesh extracts whole volumes, not one brick",
                         ctx->scene->name, sv->object);
    double t0 = obs_now_ms();
    obs_iso_mesh im;
    int rc = obs_iso_extract(&sv->v, sv->iso, p->grid, p->refine, &im, err);
    if (rc) return rc;
    double ms = obs_now_ms() - t0;
    all_ms += ms;
    rc = place_mesh(sv, &im, origin, &g->meshes[g->nmeshes]);
    if (!rc) {
      size_t bytes = im.nverts * 3 * sizeof(float) + im.ntris * 3 * sizeof(uint32_t);
      json_array_append_new(ctx->built,
                            json_pack("{s:s, s:I, s:I, s:I, s:I, s:[i,i,i], s:f}", "name",
                                      "isosurface_mesh", "object", (json_int_t)sv->object,
                                      "bytes", (json_int_t)bytes, "triangles",
                                      (json_int_t)im.ntris, "vertices", (json_int_t)im.nverts,
                                      "cells", im.lat.c[0], im.lat.c[1], im.lat.c[2],
                                      "extract_ms", ms));
      g->ntris += im.ntris;
      g->nmeshes++;
    }
    obs_iso_mesh_free(&im);
    if (rc) return obs_err_set(err, rc, "isosurface_mesh: out of memory");
  }
  obs_render_ctx_stage(ctx, "extract", all_ms);
  geometry_bounds(g);
  return 0;
}

int obs_isosurface_mesh_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->volumes)
    return obs_err_set(err, OBS_EINTERNAL, "%s: isosurface_mesh: the volumes were not read",
                       sc->name);
  job jb;
  memset(&jb, 0, sizeof jb);
  jb.spp = sc->spp;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  obs_geometry g;
  int rc = extract_all(ctx, ctx->bound, jb.cam.origin, &g, err);
  if (rc) {
    obs_geometry_free(&g);
    return rc;
  }
  double t0 = obs_now_ms();
  obs_rt rt;
  if ((rc = obs_rt_build_geo(&g, &rt, ctx->threads, err))) return rc;
  obs_render_ctx_stage(ctx, "bvh", obs_now_ms() - t0);
  jb.rt = &rt;
  static const obs_pixel_ops ops = {ISO_CH_COUNT, obs_isosurface_mesh_channels, .shade = shade_pixel};
  rc = obs_driver_pixels(ctx, &ops, &jb, out, err);
  obs_rt_free(&rt);
  return rc;
}
