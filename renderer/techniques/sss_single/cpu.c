/* sss_single on the CPU: single scattering inside media (ShaderX7 6.5) by the article's light-view
 * maps (method shadow_maps, cpu_maps.c) or by ray tracing, the reference (method trace,
 * cpu_trace.c). This file sets up the job (the media per scene unit, the punctual lights in the ray
 * tracer's frame) and shades a pixel: its camera rays, each hit on a medium object estimated by the
 * chosen method; objects without a medium are opaque and black. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "obscura/render.h"
#include "sss_job.h"
#include "techniques.h"

enum { CH_R, CH_G, CH_B, CH_SR, CH_SG, CH_SB, CH_ALPHA, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {
    "radiance.R", "radiance.G", "radiance.B", "radiance_stderr.R", "radiance_stderr.G",
    "radiance_stderr.B", "alpha"};

typedef struct pixel_job {
  sss_job jb;
  obs_camera_rig cam;
  atomic_ullong entry_count[3]; /* trace: entry-point searches, unconverged, without a path */
} pixel_job;

static uint64_t shade_pixel(const void *user, int thread, int x, int y, float *d) {
  (void)thread;
  const pixel_job *pj = user;
  const sss_job *jb = &pj->jb;
  uint64_t rays = 0;
  double rad[3] = {0, 0, 0}, var[3] = {0, 0, 0};
  int hits = 0;
  for (int s = 0; s < jb->spp; s++) {
    double org[3], dir[3];
    obs_sss_sample_ray(&pj->cam, jb->p.seed, jb->spp, x, y, s, org, dir);
    obs_hit hit;
    rays++;
    if (!obs_rt_intersect(jb->rt, org, dir, INFINITY, &hit)) continue;
    hits++;
    size_t obj = obs_rt_hit_object(jb->rt, hit.geom, hit.prim);
    if (!jb->has_medium[obj]) continue;
    if (jb->p.method == OBS_SSS_TRACE) {
      double sum[3], sum2[3], n = jb->p.samples;
      rays += obs_sss_trace_shade(jb, &hit, obj, dir, (uint32_t)x, (uint32_t)y, (uint32_t)s, sum,
                                  sum2);
      for (int k = 0; k < 3; k++) {
        double mean = sum[k] / n;
        rad[k] += mean;
        /* the variance of the mean of n independent path values */
        var[k] += n > 1 ? fmax(0.0, sum2[k] - n * mean * mean) / (n * (n - 1)) : 0.0;
      }
    } else {
      double v[3];
      int refined;
      obs_sss_maps_shade(jb, &hit, obj, dir, (uint32_t)x, (uint32_t)y, (uint32_t)s, v, &refined);
      for (int k = 0; k < 3; k++) rad[k] += v[k];
    }
  }
  for (int k = 0; k < 3; k++) {
    d[CH_R + k] = (float)(rad[k] / jb->spp);
    d[CH_SR + k] = (float)(sqrt(var[k]) / jb->spp);
  }
  d[CH_ALPHA] = (float)hits / (float)jb->spp;
  return rays;
}

int obs_sss_single_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: sss_single: no BVH was built for it", sc->name);
  pixel_job pj;
  memset(&pj, 0, sizeof pj);
  pj.jb.p = *(const obs_sss_single_params *)ctx->bound;
  pj.jb.rt = ctx->rt;
  pj.jb.spp = sc->spp;
  atomic_init(&pj.entry_count[0], 0);
  atomic_init(&pj.entry_count[1], 0);
  atomic_init(&pj.entry_count[2], 0);
  pj.jb.entry_count = pj.entry_count;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &pj.cam);
  int rc = obs_sss_job_setup(ctx, &pj.jb, err);
  double maps_ms = 0;
  if (!rc && pj.jb.p.method == OBS_SSS_SHADOW_MAPS) {
    double t0 = obs_now_ms();
    rc = obs_sss_maps_build(&pj.jb, ctx->threads, err);
    if (!rc) {
      maps_ms = obs_now_ms() - t0;
      obs_driver_stage_add(ctx, "light_maps", maps_ms);
      /* The maps' rays are set-up, like ibl_shadows' maps and the BVH build: `rays` counts the
       * per-pixel work, which a render split across processes shares out (each part builds the
       * maps again, and the parts' counts must add up to one process's). */
    }
  }
  if (!rc) {
    static const obs_pixel_ops ops = {CH_COUNT, channel_names, .shade = shade_pixel};
    rc = obs_driver_pixels(ctx, &ops, &pj, out, err);
    ctx->render_ms += maps_ms; /* the maps are the technique's work too (the driver's is shade) */
  }
  unsigned long long searches = atomic_load(&pj.entry_count[0]);
  unsigned long long stuck = atomic_load(&pj.entry_count[1]);
  if (!rc && stuck)
    obs_render_ctx_warn(ctx, "sss_single trace: %llu of %llu entry-point searches stopped "
                        "unconverged after %d steps (their best iterate is used)", stuck, searches,
                        OBS_SSS_ENTRY_STEPS);
  obs_sss_job_free(&pj.jb);
  return rc;
}
