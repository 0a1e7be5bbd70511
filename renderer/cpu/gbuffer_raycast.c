/* The CPU backend's G-buffer: one Embree ray through each pixel centre, producing exactly the
 * buffers the Vulkan rasteriser produces (see renderer/core/gbuffer.h for the definitions). */
#include "gbuffer.h"

#include <math.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"

typedef struct gb_job {
  const obs_scene *scene;
  const obs_rt *rt;
  obs_camera_rig cam;
  obs_gbuffer *g;
} gb_job;

static const obs_object *hit_object(const gb_job *j, const obs_hit *h) {
  if (h->geom == j->rt->sphere_geom) return &j->scene->objects[j->rt->geo.spheres[h->prim].object];
  return &j->scene->objects[j->rt->geo.meshes[h->geom].object];
}

static int gb_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  gb_job *j = user;
  obs_gbuffer *g = j->g;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      double org[3], dir[3];
      obs_camera_ray(&j->cam, x + 0.5, y + 0.5, org, dir);
      obs_hit h;
      if (!obs_rt_intersect(j->rt, org, dir, INFINITY, &h)) continue;
      double fwd = dir[0] * j->cam.forward[0] + dir[1] * j->cam.forward[1] +
                   dir[2] * j->cam.forward[2];
      g->depth[i] = (float)(h.t * fwd);
      g->coverage[i] = 1.0f;
      /* Face normal (not the shading normal), as the rasteriser derives it from positions. */
      const double *axes[3] = {j->cam.right, j->cam.up, j->cam.forward};
      for (int k = 0; k < 3; k++)
        g->normal[3 * i + k] =
            (float)(h.ng[0] * axes[k][0] + h.ng[1] * axes[k][1] + h.ng[2] * axes[k][2]);
      const obs_object *o = hit_object(j, &h);
      g->albedo[3 * i] = o->has_material ? (float)o->reflectivity.x : 1.0f;
      g->albedo[3 * i + 1] = o->has_material ? (float)o->reflectivity.y : 1.0f;
      g->albedo[3 * i + 2] = o->has_material ? (float)o->reflectivity.z : 1.0f;
    }
  return 0;
}

int obs_gbuffer_raycast(const obs_scene *sc, obs_gbuffer *g, int threads, double *build_ms,
                        double *render_ms, obs_err *err) {
  gb_job j;
  memset(&j, 0, sizeof j);
  j.scene = sc;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &j.cam);
  int rc = obs_gbuffer_alloc(g, sc->width, sc->height, &j.cam, err);
  if (rc) return rc;
  double t0 = obs_now_ms();
  obs_rt rt;
  if ((rc = obs_rt_build(sc, &rt, threads, err))) {
    obs_gbuffer_free(g);
    return rc;
  }
  double t1 = obs_now_ms();
  j.rt = &rt;
  j.g = g;
  rc = obs_parallel_tiles(sc->width, sc->height, threads, gb_tile, &j, NULL, NULL, NULL);
  if (build_ms) *build_ms = t1 - t0;
  if (render_ms) *render_ms = obs_now_ms() - t1;
  obs_rt_free(&rt);
  if (rc) {
    obs_gbuffer_free(g);
    return obs_err_set(err, rc, "%s: G-buffer ray cast failed", sc->name);
  }
  return 0;
}
