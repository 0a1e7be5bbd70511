/* rt_ao on the CPU: Monte-Carlo ambient occlusion / obscurance with Embree.
 *
 * For each pixel sample a primary ray finds P; `samples` directions over the hemisphere about the
 * shading normal (cosine- or uniform-distributed, so the estimator of W(P) is the plain mean of
 * rho) are traced up to max_distance. The framework builds the BVH (needs) and the per-pixel driver
 * owns the image, tiles, progress and cancellation: this file is the pixel's shading. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "halfball.h"
#include "mcerr.h"
#include "obscurance.h"
#include "obscura/render.h"
#include "raytrace.h"
#include "rt_ao.h"
#include "sampling.h"
#include "techniques.h"

typedef obs_rt_ao_params rt_ao_params;

enum { CH_AO, CH_STDERR, CH_BX, CH_BY, CH_BZ, CH_DEPTH, CH_NX, CH_NY, CH_NZ, CH_ALPHA, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {
    "ao", "ao_stderr", "bent_normal.X", "bent_normal.Y", "bent_normal.Z",
    "depth.Z", "normal.X", "normal.Y", "normal.Z", "alpha"};

typedef struct job {
  const obs_rt *rt;
  obs_camera_rig cam;
  rt_ao_params p;
  obs_falloff falloff; /* rho(d) of p */
  int spp;
} job;

/* One pixel sample's occlusion estimate at `hit`. */
typedef struct ao_accum {
  double mean, se; /* of rho over the rays, and its standard error (mcerr.h) */
  double bent[3];  /* rho-weighted directions */
} ao_accum;

static uint64_t shade(const job *jb, const obs_hit *hit, uint32_t x, uint32_t y, uint32_t s,
                      ao_accum *acc) {
  const rt_ao_params *p = &jb->p;
  float org[3], t[3], b[3];
  obs_rt_offset(jb->rt, hit, org);
  obs_onb(hit->ns, t, b);
  obs_rt_ctx ctx;
  obs_rt_ctx_init(&ctx, jb->rt, hit);
  obs_rqmc smp;
  obs_rqmc_init(&smp, p->sampler, x, y, s, 1, p->seed, p->samples);
  float tfar = isinf(p->max_distance) ? INFINITY : (float)p->max_distance;
  uint64_t rays = 0;
  obs_mcerr e = {0};
  double part = 0;
  uint32_t first = 0, escaped = 0;
  memset(acc, 0, sizeof *acc);
  /* Directions are made in batches before any is traced: the sampler's latency then overlaps
   * instead of sitting between two traversals (measured: ~10 % of rt_ao's time). */
  enum { BATCH = 16 };
  float ws[BATCH][3];
  unsigned char last[BATCH];
  for (uint32_t i0 = 0; i0 < p->samples; i0 += BATCH) {
    uint32_t n = p->samples - i0 < BATCH ? p->samples - i0 : BATCH;
    for (uint32_t j = 0; j < n; j++) {
      float u, v, l[3];
      last[j] = (unsigned char)obs_rqmc_get(&smp, i0 + j, &u, &v);
      if (p->uniform) obs_sample_uniform(u, v, l);
      else obs_sample_cosine(u, v, l);
      for (int k = 0; k < 3; k++) ws[j][k] = l[0] * t[k] + l[1] * b[k] + l[2] * hit->ns[k];
    }
    for (uint32_t j = 0; j < n; j++) {
      const float *w = ws[j];
      double r;
      /* Shading normals may tilt the hemisphere below the true surface; those directions run
       * into the surface itself, so they count as occluded at distance 0 rather than leak. */
      if (w[0] * hit->ng[0] + w[1] * hit->ng[1] + w[2] * hit->ng[2] <= 0.0f) {
        r = obs_falloff_rho(&jb->falloff, 0.0);
      } else if (p->falloff == OBS_FALLOFF_BINARY) {
        r = obs_rt_occluded(jb->rt, &ctx, org, w, tfar) ? 0.0 : 1.0;
        rays++;
      } else {
        r = obs_falloff_rho(&jb->falloff, obs_rt_distance(jb->rt, &ctx, org, w, tfar));
        rays++;
      }
      part += r;
      escaped += r == 1.0;
      for (int k = 0; k < 3; k++) acc->bent[k] += r * w[k];
      if (last[j]) { /* the replicate's mean */
        obs_mcerr_add(&e, part / (double)(i0 + j + 1 - first));
        part = 0;
        first = i0 + j + 1;
      }
    }
  }
  acc->mean = e.mean;
  if (escaped == p->samples) { /* every ray escaped: exact, or bounded by what lies within reach */
    /* 0 where exact; else negated: the rays agreed (driver.h, obs_pixel_prior) */
    acc->se = obs_rt_escape_stderr(jb->rt, hit, org, &jb->falloff, tfar, p->uniform, 0,
                                   p->samples);
    if (acc->se > 0) acc->se = -acc->se;
  } else {
    acc->se = obs_mcerr_stderr(&e, p->samples, 1.0, 1);
  }
  return rays;
}

/* One pixel: its spp camera rays, each hit's occlusion estimate, averaged. Pixel samples are
 * independent estimates, so their errors add in quadrature; one that sees no surface reads 1
 * exactly. */
static uint64_t shade_pixel(const void *user, int thread, int x, int y, float *d) {
  (void)thread;
  const job *jb = user;
  uint64_t rays = 0;
  double ao = 0, depth = 0, bent[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
  obs_mcerr_pixel err = {0};
  int hits = 0;
  obs_sampler2d jit;
  obs_sampler2d_init(&jit, jb->p.sampler, (uint32_t)x, (uint32_t)y, 0, 0, jb->p.seed);
  for (int s = 0; s < jb->spp; s++) {
    float jx, jy;
    obs_sampler2d_pixel(&jit, jb->spp, (uint32_t)s, &jx, &jy);
    double org[3], dir[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    obs_hit hit;
    rays++;
    if (!obs_rt_intersect(jb->rt, org, dir, INFINITY, &hit)) {
      ao += 1.0;
      continue;
    }
    hits++;
    ao_accum acc;
    rays += shade(jb, &hit, (uint32_t)x, (uint32_t)y, (uint32_t)s, &acc);
    ao += acc.mean;
    obs_mcerr_pixel_add(&err, acc.se);
    double bl = sqrt(acc.bent[0] * acc.bent[0] + acc.bent[1] * acc.bent[1] +
                     acc.bent[2] * acc.bent[2]);
    for (int k = 0; k < 3; k++) {
      bent[k] += bl > 0 ? acc.bent[k] / bl : hit.ns[k];
      nrm[k] += hit.ns[k];
    }
    double fwd =
        dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] + dir[2] * jb->cam.forward[2];
    depth += hit.t * fwd;
  }
  d[CH_AO] = (float)(ao / jb->spp);
  d[CH_STDERR] = (float)obs_mcerr_pixel_stderr(&err, jb->spp);
  d[CH_ALPHA] = (float)hits / (float)jb->spp;
  d[CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  double bl = sqrt(bent[0] * bent[0] + bent[1] * bent[1] + bent[2] * bent[2]);
  double nl = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
  for (int k = 0; k < 3; k++) {
    d[CH_BX + k] = bl > 0 ? (float)(bent[k] / bl) : 0.0f;
    d[CH_NX + k] = nl > 0 ? (float)(nrm[k] / nl) : 0.0f;
  }
  return rays;
}

static double shade_df(const void *user, int c) {
  (void)c;
  const job *jb = user;
  return jb->spp * (obs_rqmc_replicates(jb->p.sampler, jb->p.samples) - 1.0);
}

static const int se_channel[1] = {CH_STDERR}, value_channel[1] = {CH_AO};
static const obs_pixel_prior prior = {1,           se_channel,
                                      value_channel, CH_ALPHA,
                                      sizeof(job),  offsetof(job, p) + offsetof(rt_ao_params, seed),
                                      shade_df};

int obs_rt_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: rt_ao: no BVH was built for it", sc->name);
  job jb;
  memset(&jb, 0, sizeof jb);
  jb.p = *(const rt_ao_params *)ctx->bound;
  jb.falloff = (obs_falloff){jb.p.falloff, jb.p.max_distance, jb.p.tau};
  jb.rt = ctx->rt;
  jb.spp = sc->spp;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  static const obs_pixel_ops ops = {CH_COUNT, channel_names, .shade = shade_pixel,
                                        .prior = &prior};
  return obs_driver_pixels(ctx, &ops, &jb, out, err);
}
