/* obscurance on the CPU: the per-pixel estimator of obscurances with colour bleeding
 * (Mendez-Feliu, Sbert et al., eq. 6) with Embree.
 *
 * For each pixel sample a camera ray finds P. `samples` cosine-distributed directions from P
 * (Halton or Sobol, scrambled per pixel) estimate W(P) = 1/pi int rho(d) cos dw as the plain mean
 * of rho(d) (with colour bleeding: of R(Q) rho(d), and R_ave where no surface lies within d_max).
 * The indirect term is R(P) I_A W(P), I_A the `ambient` parameter, the sky's radiance or the
 * closed environment's ambient intensity of the shared model (obscurance.h). The direct term samples the emitters as
 * path_trace does (emitters.h), without the BSDF strategy: next-event estimation alone is unbiased
 * for direct light from area emitters. docs/techniques/obscurance.md states the model. */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "emitters.h"
#include "halfball.h"
#include "mcerr.h"
#include "obscura/render.h"
#include "obscurance.h"
#include "obscurance_params.h"
#include "raytrace.h"
#include "sampling.h"
#include "techniques.h"

#define INV_PI 0.31830988618379067154

/* clang-format off */
enum {
  CH_F = 0, CH_FS = 3, CH_W = 6, CH_WS = 9, CH_I = 12, CH_D = 15, CH_C = 18, CH_DEPTH = 21,
  CH_NX = 22, CH_ALPHA = 25, CH_COUNT = 26
};
static const char *const channel_names[CH_COUNT] = {
    "final.R", "final.G", "final.B", "final_stderr.R", "final_stderr.G", "final_stderr.B",
    "obscurance.R", "obscurance.G", "obscurance.B", "obscurance_stderr.R", "obscurance_stderr.G",
    "obscurance_stderr.B", "indirect.R", "indirect.G", "indirect.B", "direct.R", "direct.G",
    "direct.B", "constant_ambient.R", "constant_ambient.G", "constant_ambient.B", "depth.Z",
    "normal.X", "normal.Y", "normal.Z", "alpha"};
/* clang-format on */

typedef struct ob_job {
  const obs_rt *rt;
  const obs_scene *sc;
  obs_camera_rig cam;
  obs_obscurance_params p;
  obs_falloff f;
  obs_sampler_kind sampler;
  obs_emitters em;
  double r_ave[3]; /* what a direction without a surface within d_max sees, with bleeding */
  double ia[3];    /* I_A */
  double open[3];  /* W of a point that sees nothing: 1, or R_ave with bleeding */
  int spp;
} ob_job;

/* One pixel sample's estimates at its hit. */
typedef struct ob_point {
  double w[3], w_se[3];      /* W and its standard error */
  double direct[3], d_se[3]; /* direct light (emission seen included) and its standard error */
  double rho[3];             /* R(P) */
} ob_point;

static void vec3(const obs_vec3 *v, double o[3]) { o[0] = v->x, o[1] = v->y, o[2] = v->z; }
static int mean3_pos(const double v[3]) { return v[0] + v[1] + v[2] > 0; }

/* The scene object a hit lies on. */
static const obs_object *hit_object(const ob_job *jb, const obs_hit *h) {
  return &jb->sc->objects[obs_rt_hit_object(jb->rt, h->geom, h->prim)];
}

/* W(P) by eq. (6): the mean over cosine-distributed directions of rho(d), or with colour bleeding
 * of R(Q) rho(d) (R_ave when no surface lies within d_max), with its standard error from the
 * directions' replicates (mcerr.h). */
static uint64_t obscurance_at(const ob_job *jb, const obs_hit *hit, const float org[3],
                              obs_rt_ctx *ctx, uint32_t x, uint32_t y, uint32_t s, ob_point *pt) {
  const obs_obscurance_params *p = &jb->p;
  float t[3], b[3];
  obs_onb(hit->ns, t, b);
  obs_rqmc smp;
  obs_rqmc_init(&smp, jb->sampler, x, y, s, 1, p->seed, p->samples);
  float tfar = (float)p->d_max;
  double part[3] = {0, 0, 0};
  obs_mcerr e[3];
  memset(e, 0, sizeof e);
  uint64_t rays = 0;
  uint32_t first = 0, escaped = 0;
  for (uint32_t i = 0; i < p->samples; i++) {
    float u, v, l[3], w[3];
    int last = obs_rqmc_get(&smp, i, &u, &v);
    obs_sample_cosine(u, v, l);
    for (int k = 0; k < 3; k++) w[k] = l[0] * t[k] + l[1] * b[k] + l[2] * hit->ns[k];
    /* Shading normals may tilt the hemisphere below the true surface; such a direction runs
     * into the surface itself: a surface at distance 0, rho(0) = 0 for every falloff. */
    if (w[0] * hit->ng[0] + w[1] * hit->ng[1] + w[2] * hit->ng[2] > 0.0f) {
      rays++;
      if (p->color_bleeding) {
        obs_hit q;
        if (obs_rt_intersect_from(jb->rt, ctx, org, w, tfar, &q) && (double)q.t < p->d_max) {
          double r = obs_falloff_rho(&jb->f, (double)q.t), rq[3];
          vec3(&hit_object(jb, &q)->reflectivity, rq);
          for (int k = 0; k < 3; k++) part[k] += rq[k] * r;
        } else {
          for (int k = 0; k < 3; k++) part[k] += jb->r_ave[k];
          escaped++;
        }
      } else {
        double r = p->falloff == OBS_FALLOFF_BINARY
                       ? (obs_rt_occluded(jb->rt, ctx, org, w, tfar) ? 0.0 : 1.0)
                       : obs_falloff_rho(&jb->f, obs_rt_distance(jb->rt, ctx, org, w, tfar));
        for (int k = 0; k < 3; k++) part[k] += r;
        escaped += r == 1.0;
      }
    }
    if (last) {
      for (int k = 0; k < 3; k++) obs_mcerr_add(&e[k], part[k] / (double)(i + 1 - first));
      memset(part, 0, sizeof part);
      first = i + 1;
    }
  }
  /* Every direction escaped: exact where nothing lies within d_max above the point, else bounded
   * by what does. With colour bleeding an unseen hit changes R_ave to R(Q) rho, by up to 1. */
  double escaped_se = escaped == p->samples
                          ? obs_rt_escape_stderr(jb->rt, hit, org, &jb->f, tfar, 0,
                                                 p->color_bleeding ? 1.0 : 0.0, p->samples)
                          : -1;
  for (int k = 0; k < 3; k++) {
    pt->w[k] = e[k].mean;
    /* An exact W stays +0; a floor is negated (driver.h, obs_pixel_prior). */
    pt->w_se[k] = escaped_se > 0    ? -escaped_se
                  : escaped_se == 0 ? 0.0
                                    : obs_mcerr_stderr(&e[k], p->samples, 1.0, 1);
  }
  return rays;
}

/* Direct light reflected at the hit: light_samples emitter points, each with its shadow ray
 * (emitters.h; the same choice and densities as path_trace's next-event estimation), in
 * replicates for the standard error. When they all agree (every point shadowed, say) one unseen
 * visible point adds at most its unshadowed value: the largest such value met is the span. */
static uint64_t direct_at(const ob_job *jb, const obs_hit *hit, const float org[3],
                          obs_rt_ctx *ctx, uint32_t x, uint32_t y, uint32_t s, ob_point *pt) {
  const uint32_t n = jb->p.light_samples;
  double part[3] = {0, 0, 0}, span = 0;
  obs_mcerr e[3];
  memset(e, 0, sizeof e);
  uint64_t rays = 0;
  int lit = jb->em.n && mean3_pos(pt->rho);
  obs_rqmc s2, s3;
  obs_rqmc_init(&s2, jb->sampler, x, y, s, 2, jb->p.seed, n);
  obs_rqmc_init(&s3, jb->sampler, x, y, s, 3, jb->p.seed, n);
  uint32_t first = 0;
  for (uint32_t i = 0; i < n; i++) {
    float a, b, c, unused;
    int last = obs_rqmc_get(&s2, i, &a, &b);
    if (lit) {
      /* The third coordinate from another stream at a shuffled index: two streams read at one
       * index are correlated (sampling.h, obs_sample_shuffle). */
      uint32_t j, r = obs_rqmc_locate(&s3, i, &j);
      obs_sampler2d_get(&s3.s[r], obs_sample_shuffle(j, s3.s[r].scramble0 ^ 0x5bd1e995U), &c,
                        &unused);
      const double u[3] = {a, b, c};
      obs_emitter_sample es;
      if (obs_emitters_sample(&jb->em, hit, u, &es)) {
        rays++;
        float w[3] = {(float)es.wi[0], (float)es.wi[1], (float)es.wi[2]};
        int shadowed = obs_rt_occluded(jb->rt, ctx, org, w, (float)(es.dist * (1 - 1e-4)));
        for (int k = 0; k < 3; k++) {
          double v = pt->rho[k] * INV_PI * es.e->le[k] * es.coss / es.pdf;
          span = fmax(span, v);
          if (!shadowed) part[k] += v;
        }
      }
    }
    if (last) {
      for (int k = 0; k < 3; k++) obs_mcerr_add(&e[k], part[k] / (double)(i + 1 - first));
      memset(part, 0, sizeof part);
      first = i + 1;
    }
  }
  for (int k = 0; k < 3; k++) {
    pt->direct[k] += e[k].mean;
    pt->d_se[k] = obs_mcerr_stderr(&e[k], n, span, 1);
  }
  return rays;
}

/* What the quad lights crossed by the camera ray (o, d) in the frame before distance tmax emit
 * toward the camera: they are emitters, not surfaces, so the BVH does not hold them. */
static void quad_lights_seen(const ob_job *jb, const double o[3], const double d[3], double tmax,
                             double L[3]) {
  for (size_t i = 0; i < jb->em.nquad; i++) {
    const obs_emitter *e = &jb->em.em[i];
    if (!(-(e->n[0] * d[0] + e->n[1] * d[1] + e->n[2] * d[2]) > 0)) continue;
    if (!(obs_emitter_tri_hit(e, o, d) < tmax)) continue;
    for (int k = 0; k < 3; k++) L[k] += e->le[k];
  }
}

/* One pixel: its spp camera rays, each hit's W, indirect and direct terms, averaged; background
 * samples add nothing (the model has no sky). */
static uint64_t ob_shade(const void *job, int thread, int x, int y, float *v) {
  (void)thread;
  const ob_job *jb = job;
  double acc[CH_COUNT];
  memset(acc, 0, sizeof acc);
  obs_mcerr_pixel err_w[3], err_f[3];
  memset(err_w, 0, sizeof err_w);
  memset(err_f, 0, sizeof err_f);
  uint64_t rays = 0;
  int hits = 0;
  obs_sampler2d jit;
  obs_sampler2d_init(&jit, jb->sampler, (uint32_t)x, (uint32_t)y, 0, 0, jb->p.seed);
  for (int s = 0; s < jb->spp; s++) {
    float jx, jy;
    obs_sampler2d_pixel(&jit, jb->spp, (uint32_t)s, &jx, &jy);
    double org[3], dir[3], o[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    for (int k = 0; k < 3; k++) o[k] = org[k] - jb->rt->geo.origin[k];
    obs_hit hit;
    rays++;
    int found = obs_rt_intersect(jb->rt, org, dir, INFINITY, &hit);
    ob_point pt;
    memset(&pt, 0, sizeof pt);
    quad_lights_seen(jb, o, dir, found ? hit.t : INFINITY, pt.direct);
    if (found) {
      const obs_object *ob = hit_object(jb, &hit);
      double le[3];
      vec3(&ob->emission, le);
      vec3(&ob->reflectivity, pt.rho);
      for (int k = 0; k < 3; k++) pt.direct[k] += le[k];
      float from[3];
      obs_rt_offset(jb->rt, &hit, from);
      obs_rt_ctx ctx;
      obs_rt_ctx_init(&ctx, jb->rt, &hit);
      rays += obscurance_at(jb, &hit, from, &ctx, (uint32_t)x, (uint32_t)y, (uint32_t)s, &pt);
      rays += direct_at(jb, &hit, from, &ctx, (uint32_t)x, (uint32_t)y, (uint32_t)s, &pt);
      hits++;
      acc[CH_DEPTH] += hit.t * (dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] +
                                dir[2] * jb->cam.forward[2]);
      for (int k = 0; k < 3; k++) acc[CH_NX + k] += hit.ns[k];
    }
    for (int k = 0; k < 3; k++) {
      double a = pt.rho[k] * jb->ia[k]; /* R(P) I_A */
      double ind = a * pt.w[k], ind_se = a * pt.w_se[k];
      acc[CH_W + k] += pt.w[k];
      obs_mcerr_pixel_add(&err_w[k], pt.w_se[k]);
      acc[CH_I + k] += ind;
      acc[CH_D + k] += pt.direct[k];
      acc[CH_F + k] += pt.direct[k] + ind;
      /* Direct and indirect errors are independent; negated (agreed) only when neither has a
       * spread. */
      double fse = sqrt(pt.d_se[k] * pt.d_se[k] + ind_se * ind_se);
      obs_mcerr_pixel_add(&err_f[k], pt.d_se[k] > 0 || ind_se > 0                   ? fse
                                     : signbit(pt.d_se[k]) || signbit(ind_se) ? -fse
                                                                              : 0.0);
      acc[CH_C + k] += pt.direct[k] + (found ? a * jb->open[k] : 0.0);
    }
  }
  const double n = jb->spp;
  for (int k = 0; k < 3; k++) {
    static const int means[] = {CH_F, CH_W, CH_I, CH_D, CH_C};
    for (size_t m = 0; m < sizeof means / sizeof means[0]; m++)
      v[means[m] + k] = (float)(acc[means[m] + k] / n);
    v[CH_FS + k] = (float)obs_mcerr_pixel_stderr(&err_f[k], jb->spp);
    v[CH_WS + k] = (float)obs_mcerr_pixel_stderr(&err_w[k], jb->spp);
  }
  double nl = sqrt(acc[CH_NX] * acc[CH_NX] + acc[CH_NX + 1] * acc[CH_NX + 1] +
                   acc[CH_NX + 2] * acc[CH_NX + 2]);
  for (int k = 0; k < 3; k++) v[CH_NX + k] = nl > 0 ? (float)(acc[CH_NX + k] / nl) : 0.0f;
  v[CH_DEPTH] = hits ? (float)(acc[CH_DEPTH] / hits) : 0.0f;
  v[CH_ALPHA] = (float)hits / (float)jb->spp;
  return rays;
}

/* Channels 0-2 (final) carry W's error and the direct light's: the fewer degrees of freedom. */
static double ob_df(const void *job, int c) {
  const ob_job *jb = job;
  double w = obs_rqmc_replicates(jb->sampler, jb->p.samples) - 1.0;
  double d = obs_rqmc_replicates(jb->sampler, jb->p.light_samples) - 1.0;
  return jb->spp * (c < 3 && d < w ? d : w);
}

static const int ob_se[6] = {CH_FS, CH_FS + 1, CH_FS + 2, CH_WS, CH_WS + 1, CH_WS + 2};
static const int ob_values[6] = {CH_F, CH_F + 1, CH_F + 2, CH_W, CH_W + 1, CH_W + 2};
static const obs_pixel_prior ob_prior = {
    6, ob_se, ob_values, CH_ALPHA, sizeof(ob_job),
    offsetof(ob_job, p) + offsetof(obs_obscurance_params, seed), ob_df};

/* The scene-wide terms: R_ave, W of an open point and I_A, which is, first found: the `ambient`
 * parameter; a sky (environment.color above zero: an open scene, where an open point sees it all
 * around); the closed environment's I_A of the shared model. The first two are the light an open point
 * receives, R(P) I_A with W = 1; with bleeding an open point has W = R_ave, so they are divided
 * by R_ave to give it the same light. */
static int setup_ambient(ob_job *jb, obs_err *err) {
  obs_obscurance_env env;
  int rc = obs_obscurance_env_compute(jb->sc, &jb->rt->geo, &env, err);
  if (rc) return rc;
  obs_obscurance_ambient(&env, jb->p.color_bleeding, jb->ia);
  double given[3] = {jb->p.ambient[0], jb->p.ambient[1], jb->p.ambient[2]};
  int have = jb->p.ambient[0] >= 0;
  if (!have && jb->sc->has_environment) {
    vec3(&jb->sc->environment, given);
    have = mean3_pos(given); /* a black sky lights nothing: the closed environment's I_A then */
  }
  for (int k = 0; k < 3; k++) {
    jb->r_ave[k] = env.r_ave[k];
    jb->open[k] = jb->p.color_bleeding ? env.r_ave[k] : 1.0;
    if (have)
      jb->ia[k] = !jb->p.color_bleeding ? given[k]
                  : env.r_ave[k] > 0    ? given[k] / env.r_ave[k]
                                        : 0.0;
  }
  return 0;
}

int obs_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: obscurance: no BVH was built for it", sc->name);
  ob_job jb;
  memset(&jb, 0, sizeof jb);
  jb.p = *(const obs_obscurance_params *)ctx->bound;
  jb.sc = sc;
  jb.rt = ctx->rt;
  jb.spp = sc->spp;
  jb.sampler = jb.p.sequence == OBS_OBSCURANCE_SOBOL ? OBS_SAMPLER_SOBOL : OBS_SAMPLER_HALTON;
  jb.f = (obs_falloff){.kind = jb.p.falloff, .d_max = jb.p.d_max, .tau = jb.p.tau};
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  double t0 = obs_now_ms();
  int rc = setup_ambient(&jb, err);
  if (!rc) rc = obs_emitters_build(sc, jb.rt, &jb.em, err);
  ctx->build_ms += obs_now_ms() - t0;
  if (!rc) {
    static const obs_pixel_ops ops = {CH_COUNT, channel_names, .shade = ob_shade,
                                        .prior = &ob_prior};
    rc = obs_driver_pixels(ctx, &ops, &jb, out, err);
  }
  obs_emitters_free(&jb.em);
  return rc;
}
