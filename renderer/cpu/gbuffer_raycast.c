/* The CPU backend's G-buffer: one Embree ray through each pixel centre, traced in small packets,
 * producing exactly the buffers the Vulkan rasteriser produces (see renderer/core/gbuffer.h for
 * the definitions). */
#include "gbuffer_cpu.h"

#include <math.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"

/* Pixel block traced as one packet: 4 wide and as tall as the packet allows, so neighbouring
 * rays share BVH traversal. Tiles are multiples of it except at the image's right and bottom. */
enum { GB_BLOCK_W = 4, GB_BLOCK_H = OBS_RT_PACKET / GB_BLOCK_W };

typedef struct gb_job {
  const obs_scene *scene;
  const obs_rt *rt;
  obs_camera_rig cam;
  obs_rt_view view;
  obs_gbuffer *g;
} gb_job;

static const obs_object *hit_object(const gb_job *j, const obs_rt_primary *h) {
  return &j->scene->objects[obs_rt_hit_object(j->rt, h->geom, h->prim)];
}

static int gb_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  gb_job *j = user;
  const obs_camera_rig *cam = &j->cam;
  obs_gbuffer *g = j->g;
  /* obs_camera_ray's image-plane offsets, per column and per row of the tile. */
  double sxs[OBS_TILE], sys[OBS_TILE];
  for (int x = x0; x < x1; x++) sxs[x - x0] = obs_rt_view_sx(cam, x + 0.5);
  for (int y = y0; y < y1; y++) sys[y - y0] = obs_rt_view_sy(cam, y + 0.5);
  /* Runs of pixels see the same face: its view-space normal and albedo are reused while the hit's
   * primitive and world normal stay the same. */
  unsigned last_geom = RTC_INVALID_GEOMETRY_ID, last_prim = 0;
  double last_ng[3] = {0, 0, 0};
  float view_n[3] = {0, 0, 0}, albedo[3] = {0, 0, 0};
  for (int by = y0; by < y1; by += GB_BLOCK_H)
    for (int bx = x0; bx < x1; bx += GB_BLOCK_W) {
      double sx[OBS_RT_PACKET], sy[OBS_RT_PACKET];
      size_t pix[OBS_RT_PACKET];
      int n = 0;
      for (int y = by; y < by + GB_BLOCK_H && y < y1; y++)
        for (int x = bx; x < bx + GB_BLOCK_W && x < x1; x++, n++) {
          sx[n] = sxs[x - x0];
          sy[n] = sys[y - y0];
          pix[n] = (size_t)y * (size_t)g->width + (size_t)x;
        }
      obs_rt_primary hits[OBS_RT_PACKET];
      obs_rt_intersect_primary(j->rt, &j->view, n, sx, sy, hits);
      for (int l = 0; l < n; l++) {
        const obs_rt_primary *h = &hits[l];
        if (h->geom == RTC_INVALID_GEOMETRY_ID) continue;
        if (h->geom != last_geom || h->prim != last_prim || h->ng[0] != last_ng[0] ||
            h->ng[1] != last_ng[1] || h->ng[2] != last_ng[2]) {
          /* Face normal (not the shading normal), as the rasteriser derives it from positions. */
          obs_gbuffer_view_normal(cam, h->ng, view_n);
          obs_gbuffer_albedo(hit_object(j, h), albedo);
          last_geom = h->geom;
          last_prim = h->prim;
          last_ng[0] = h->ng[0], last_ng[1] = h->ng[1], last_ng[2] = h->ng[2];
        }
        size_t i = pix[l];
        g->depth[i] = (float)h->t;
        g->coverage[i] = 1.0f;
        memcpy(g->normal + 3 * i, view_n, sizeof view_n);
        memcpy(g->albedo + 3 * i, albedo, sizeof albedo);
      }
    }
  return 0;
}

int obs_gbuffer_raycast_geo(const obs_scene *sc, obs_geometry *geo, obs_gbuffer *g, int threads,
                            double *bvh_ms, double *render_ms, obs_err *err) {
  gb_job j;
  memset(&j, 0, sizeof j);
  j.scene = sc;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &j.cam);
  int rc = obs_gbuffer_alloc(g, sc->width, sc->height, &j.cam, err);
  if (rc) {
    obs_geometry_free(geo);
    return rc;
  }
  double t0 = obs_now_ms();
  obs_rt rt;
  if ((rc = obs_rt_build_geo(geo, &rt, threads, err))) {
    obs_gbuffer_free(g);
    return rc;
  }
  double t1 = obs_now_ms();
  j.rt = &rt;
  /* obs_camera_ray's rays, but with the perspective direction left unnormalised: its projection
   * on forward is 1, so a hit's ray parameter is its view depth. */
  obs_rt_view_init(&j.cam, rt.geo.origin, &j.view);
  j.g = g;
  rc = obs_parallel_tiles(sc->width, sc->height, threads, gb_tile, &j, NULL, NULL, NULL);
  if (bvh_ms) *bvh_ms = t1 - t0;
  if (render_ms) *render_ms = obs_now_ms() - t1;
  obs_rt_free(&rt);
  if (rc) {
    obs_gbuffer_free(g);
    return obs_err_set(err, rc, "%s: G-buffer ray cast failed", sc->name);
  }
  return 0;
}
