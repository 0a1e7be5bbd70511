/* ss_radiosity's direct pass on the CPU: "the lit colour of the direct pass" of the article, made
 * comparable with path_trace. Per pixel the camera ray through the pixel centre finds the surface
 * (Embree), which reflects light_samples emitter points with shadow rays (emitters.h: the same
 * choice and densities as path_trace's next-event estimation) and adds its own emission; quad
 * lights crossed before it add theirs. Both backends gather from this one buffer, so the Vulkan
 * twin reads the CPU's bits (docs/techniques/ss_radiosity.md, "The direct pass"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "emitters.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"
#include "sampling.h"
#include "ss_radiosity.h"

#define SRAD_INV_PI 0.31830988618379067154

typedef struct direct_job {
  const obs_scene *sc;
  const obs_ss_radiosity_params *p;
  const obs_rt *rt;
  const obs_emitters *em;
  obs_camera_rig rig;
  float *out;
} direct_job;

/* A uniform number in [0, 1) for (pixel, sample, dimension, seed): images depend on nothing else.
 */
static double unit(uint32_t pixel, uint32_t i, uint32_t dim, uint32_t seed) {
  uint32_t h = obs_hash_combine(obs_hash_combine(obs_hash_combine(seed, pixel), i), dim);
  return (double)obs_u32_to_unit(h);
}

static void direct_pixel(const direct_job *j, int x, int y, float *v) {
  const obs_rt *rt = j->rt;
  double org[3], dir[3], o[3], L[3] = {0, 0, 0};
  obs_camera_ray(&j->rig, x + 0.5, y + 0.5, org, dir);
  for (int k = 0; k < 3; k++) o[k] = org[k] - rt->geo.origin[k];
  obs_hit hit;
  int found = obs_rt_intersect(rt, org, dir, INFINITY, &hit);
  for (size_t i = 0; i < j->em->nquad; i++) {
    const obs_emitter *e = &j->em->em[i];
    if (!(-(e->n[0] * dir[0] + e->n[1] * dir[1] + e->n[2] * dir[2]) > 0)) continue;
    if (!(obs_emitter_tri_hit(e, o, dir) < (found ? hit.t : INFINITY))) continue;
    for (int k = 0; k < 3; k++) L[k] += e->le[k];
  }
  float id = 0.0f;
  if (found) {
    size_t oi = obs_rt_hit_object(rt, hit.geom, hit.prim);
    const obs_object *ob = &j->sc->objects[oi];
    id = (float)(oi + 1);
    const double rho[3] = {ob->has_material ? ob->reflectivity.x : 1.0,
                           ob->has_material ? ob->reflectivity.y : 1.0,
                           ob->has_material ? ob->reflectivity.z : 1.0};
    L[0] += ob->emission.x;
    L[1] += ob->emission.y;
    L[2] += ob->emission.z;
    const uint32_t n = j->p->light_samples,
                   pix = (uint32_t)y * (uint32_t)j->sc->width + (uint32_t)x;
    if (j->em->n && (rho[0] > 0 || rho[1] > 0 || rho[2] > 0)) {
      float from[3];
      obs_rt_offset(rt, &hit, from);
      obs_rt_ctx ctx;
      obs_rt_ctx_init(&ctx, rt, &hit);
      double sum[3] = {0, 0, 0};
      for (uint32_t i = 0; i < n; i++) {
        /* The emitter's point stratified over n strata of the first coordinate. */
        const double u[3] = {((double)i + unit(pix, i, 0, j->p->seed)) / (double)n,
                             unit(pix, i, 1, j->p->seed), unit(pix, i, 2, j->p->seed)};
        obs_emitter_sample es;
        if (!obs_emitters_sample(j->em, &hit, u, &es)) continue;
        float w[3] = {(float)es.wi[0], (float)es.wi[1], (float)es.wi[2]};
        if (obs_rt_occluded(rt, &ctx, from, w, (float)(es.dist * (1 - 1e-4)))) continue;
        for (int k = 0; k < 3; k++) sum[k] += rho[k] * SRAD_INV_PI * es.e->le[k] * es.coss / es.pdf;
      }
      for (int k = 0; k < 3; k++) L[k] += sum[k] / (double)n;
    }
  }
  for (int k = 0; k < 3; k++) v[k] = (float)L[k];
  v[3] = id;
}

static int direct_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const direct_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      direct_pixel(j, x, y, j->out + 4 * ((size_t)y * (size_t)j->sc->width + (size_t)x));
  return 0;
}

int obs_ss_radiosity_direct(const obs_scene *sc, const obs_ss_radiosity_params *p, int threads,
                            const atomic_int *cancel, float *direct, double ms[2], obs_err *err) {
  if (ms) ms[0] = ms[1] = 0.0;
  if (!sc || !p || !direct || p->light_samples < 1)
    return obs_err_set(err, OBS_EINVAL, "ss_radiosity: missing scene, parameters or output");
  obs_rt rt;
  obs_emitters em;
  memset(&rt, 0, sizeof rt);
  memset(&em, 0, sizeof em);
  double t0 = obs_now_ms();
  int rc = obs_rt_build(sc, &rt, threads, err);
  if (!rc) rc = obs_emitters_build(sc, &rt, &em, err);
  double t1 = obs_now_ms();
  if (!rc) {
    direct_job j = {.sc = sc, .p = p, .rt = &rt, .em = &em, .out = direct};
    obs_camera_setup(&sc->camera, sc->width, sc->height, &j.rig);
    rc = obs_parallel_tiles(sc->width, sc->height, threads < 1 ? 1 : threads, direct_tile, &j,
                            cancel, NULL, NULL);
  }
  if (ms) {
    ms[0] = t1 - t0;
    ms[1] = obs_now_ms() - t1;
  }
  obs_emitters_free(&em);
  obs_rt_free(&rt);
  return rc;
}
