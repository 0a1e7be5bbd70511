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

/* The mesh's frame: world = origin + unit x frame. unit is a power of two near the volumes' size,
 * so the frame's float coordinates are the same bits at any scale of the scene (a power-of-two
 * factor is exact), and rays meet the mesh's edges alike at every scale. */
typedef struct job {
  const obs_rt *rt;
  obs_camera_rig cam;
  int spp;
  double origin[3], unit;
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
    double fo[3];
    for (int k = 0; k < 3; k++) fo[k] = (org[k] - jb->origin[k]) / jb->unit;
    obs_hit h;
    if (!obs_rt_intersect(jb->rt, fo, dir, INFINITY, &h)) continue;
    /* Embree finds the triangle; the hit is refined on its plane in double (as the G-buffer's
     * are), so depth and normal keep their bits' worth at any scale and distance. */
    const obs_mesh *m = &jb->rt->geo.meshes[h.geom];
    const uint32_t *tri = m->idx + 3 * (size_t)h.prim;
    const float *a = m->pos + 3 * (size_t)tri[0];
    double pn[3], t;
    obs_rt_plane_normal(a, m->pos + 3 * (size_t)tri[1], m->pos + 3 * (size_t)tri[2], pn);
    if (!obs_rt_plane_hit(pn, a, fo, dir, &t)) t = h.t;
    t *= jb->unit;
    hits++;
    for (int k = 0; k < 3; k++) n[k] += h.ns[k];
    depth += t * (dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] +
                  dir[2] * jb->cam.forward[2]);
  }
  double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int k = 0; k < 3; k++) d[ISO_CH_NX + k] = hits && len > 0 ? (float)(n[k] / len) : 0.0f;
  d[ISO_CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  d[ISO_CH_ALPHA] = (float)hits / (float)jb->spp;
  return (uint64_t)jb->spp;
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
                       const double origin[3], double unit, obs_geometry *g, obs_err *err) {
  const obs_scene_volumes *vs = ctx->volumes;
  double all_ms = 0;
  memset(g, 0, sizeof *g); /* its origin stays 0: rays come in the frame's own coordinates */
  g->meshes = calloc(vs->n ? vs->n : 1, sizeof *g->meshes);
  g->spheres = calloc(1, sizeof *g->spheres);
  if (!g->meshes || !g->spheres)
    return obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  for (size_t i = 0; i < vs->n; i++) {
    const obs_scene_volume *sv = &vs->v[i];
    if (sv->brick)
      return obs_err_set(err, OBS_EUNSUPPORTED,
                         "%s: /objects/%zu: isosurface_mesh extracts whole volumes, not one brick",
                         ctx->scene->name, sv->object);
    double t0 = obs_now_ms();
    obs_iso_mesh im;
    int rc = obs_iso_extract_threads(&sv->v, sv->iso, p->grid, p->refine, ctx->threads, &im, err);
    if (rc) return rc;
    double ms = obs_now_ms() - t0;
    all_ms += ms;
    rc = obs_iso_mesh_world(sv, &im, origin, unit, 1, &g->meshes[g->nmeshes]);
    if (!rc) {
      obs_iso_mesh_record(ctx, sv, &im, ms);
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

/* Where the mesh's float frame sits: at the camera, unless the camera is more than
 * OBS_RT_FAR_CAMERA box diagonals from the volumes' boxes (a narrow field of view from afar), where
 * float around the camera cannot resolve the mesh; then at the box's point nearest to the camera
 * (raytrace.h's OBS_RT_FRAME_GEOMETRY rule, for a mesh the scene does not hold). */
static int far_frame(const obs_scene_volumes *vs, const double eye[3], double origin[3],
                     double *unit) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < vs->n; i++) {
    const obs_scene_volume *sv = &vs->v[i];
    for (int c = 0; c < 8; c++) {
      double p[3], w[3];
      for (int a = 0; a < 3; a++) p[a] = (c >> a & 1) ? sv->v.n[a] * sv->v.spacing[a] : 0;
      obs_affine_point(sv->to_world, p, w);
      for (int a = 0; a < 3; a++) lo[a] = fmin(lo[a], w[a]), hi[a] = fmax(hi[a], w[a]);
    }
  }
  double gap2 = 0, diag2 = 0;
  for (int a = 0; a < 3; a++) {
    origin[a] = fmin(fmax(eye[a], lo[a]), hi[a]);
    gap2 += (origin[a] - eye[a]) * (origin[a] - eye[a]);
    diag2 += (hi[a] - lo[a]) * (hi[a] - lo[a]);
  }
  *unit = diag2 > 0 && isfinite(diag2) ? exp2(floor(log2(sqrt(diag2)))) : 1.0;
  if (diag2 > 0 && gap2 > OBS_RT_FAR_CAMERA * OBS_RT_FAR_CAMERA * diag2) return 1;
  memcpy(origin, eye, 3 * sizeof *origin);
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
  double origin[3];
  int far = far_frame(ctx->volumes, jb.cam.origin, origin, &jb.unit);
  memcpy(jb.origin, origin, sizeof jb.origin);
  int rc = extract_all(ctx, ctx->bound, origin, jb.unit, &g, err);
  if (rc) {
    obs_geometry_free(&g);
    return rc;
  }
  double t0 = obs_now_ms();
  obs_rt rt;
  if ((rc = obs_rt_build_geo(&g, &rt, ctx->threads, err))) return rc;
  if (far) {
    /* Camera rays start at the mesh's box, grown by far more than double's error on it. */
    double diag2 = 0;
    for (int k = 0; k < 3; k++)
      diag2 +=
          (rt.geo.bounds[1][k] - rt.geo.bounds[0][k]) * (rt.geo.bounds[1][k] - rt.geo.bounds[0][k]);
    for (int k = 0; k < 3; k++) {
      rt.box[0][k] = rt.geo.bounds[0][k] - sqrt(diag2) * 0x1p-20;
      rt.box[1][k] = rt.geo.bounds[1][k] + sqrt(diag2) * 0x1p-20;
    }
    rt.advance = 1;
  }
  /* A marching-tetrahedra mesh is watertight by construction; Embree's default triangle test may
   * still let a ray through a shared edge (rays in a lattice plane meet edges exactly), so this
   * scene asks for its watertight test. */
  rtcSetSceneFlags(rt.scene, rtcGetSceneFlags(rt.scene) | RTC_SCENE_FLAG_ROBUST);
  rtcCommitScene(rt.scene);
  obs_render_ctx_stage(ctx, "bvh", obs_now_ms() - t0);
  jb.rt = &rt;
  static const obs_pixel_ops ops = {ISO_CH_COUNT, obs_isosurface_mesh_channels,
                                    .shade = shade_pixel};
  rc = obs_driver_pixels(ctx, &ops, &jb, out, err);
  obs_rt_free(&rt);
  return rc;
}
