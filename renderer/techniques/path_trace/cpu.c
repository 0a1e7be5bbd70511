/* path_trace on the CPU: a diffuse global-illumination reference with Embree.
 *
 * Lambertian surfaces (material.reflectivity), emitters: quad lights, emissive objects
 * (material.emission) and a constant sky (environment.color) or an environment map (latlong, faces,
 * sky; sampled by luminance x sin theta, obs_env_dist). Unidirectional path tracing with
 * next-event estimation: at every diffuse vertex one emitter point is sampled (power-proportional
 * emitter choice, then uniform in area) and one cosine-distributed direction continues the path;
 * the two estimates of light reaching the vertex are combined by multiple importance sampling with
 * the power heuristic (Veach 1997; pbrt-v4's PathIntegrator); an environment map is one more
 * such pair (a map direction and its shadow ray against the BSDF direction that escapes).
 * Russian roulette after rr_depth
 * bounces keeps long paths unbiased and cheap. docs/techniques/path_trace.md states the model. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "obscura/render.h"
#include "driver.h"
#include "emitters.h"
#include "environment.h"
#include "mcerr.h"
#include "path_trace.h"
#include "raytrace.h"
#include "sampling.h"
#include "techniques.h"

#define INV_PI 0.31830988618379067154

/* clang-format off */
enum {
  CH_R, CH_G, CH_B, CH_SR, CH_SG, CH_SB, CH_AR, CH_AG, CH_AB, CH_NX, CH_NY, CH_NZ, CH_DEPTH,
  CH_ALPHA, CH_COUNT
};
static const char *const channel_names[CH_COUNT] = {
    "radiance.R", "radiance.G", "radiance.B", "radiance_stderr.R", "radiance_stderr.G",
    "radiance_stderr.B", "albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z",
    "depth.Z", "alpha"};
/* clang-format on */

typedef struct pt_job {
  const obs_rt *rt;
  const obs_scene *sc;
  obs_camera_rig cam;
  obs_path_trace_params p;
  obs_sampler_kind sampler;
  int spp, paths; /* pixel samples; paths = spp * samples */
  obs_emitters em;
  double env[3];
  const obs_env *map; /* an environment map (NULL: the constant env above) */
  obs_env_dist dist;  /* its sampling distribution */
} pt_job;

#define mean3 obs_emitters_mean3
static void vec3(const obs_vec3 *v, double o[3]) { o[0] = v->x, o[1] = v->y, o[2] = v->z; }
static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The streams of one replicate's dimension pairs (see pt_shade), seeded once per replicate (the
 * seeding hashes cost as much as a point): the first PT_CACHED_DIMS pairs are kept, deeper ones
 * seeded on each use. */
#define PT_CACHED_DIMS 64
typedef struct pt_dims {
  const pt_job *jb;
  int x, y;
  uint32_t rep;  /* the replicate whose streams are cached (0 for random streams) */
  uint64_t have; /* bit d: s[d] is seeded */
  obs_sampler2d s[PT_CACHED_DIMS];
} pt_dims;

/* The 2D point of dimension pair `dim` for the path at index j of replicate `rep`: each pair of a
 * replicate is its own scrambled sequence over the replicate's paths, so every pair is stratified
 * across them, read at a shuffled index so that pairs are independent of one another (measured:
 * without the shuffle the white furnace converges 1.3 % low in its rho = 0.8 channel with Sobol).
 * Replicates have independent scrambles (their own pixel-sample seed). The shuffle maps the first
 * 2^k indices onto an aligned block of 2^k; keeping its low 16 bits keeps that (for up to 2^16
 * paths) and keeps Sobol's generator loop short. */
static void pt_sample(pt_dims *dc, uint32_t rep, uint32_t j, uint32_t dim, double *u, double *v) {
  if (rep != dc->rep) dc->rep = rep, dc->have = 0;
  obs_sampler2d local, *smp = dim < PT_CACHED_DIMS ? &dc->s[dim] : &local;
  if (dim >= PT_CACHED_DIMS || !(dc->have >> dim & 1)) {
    obs_sampler2d_init(smp, dc->jb->sampler, (uint32_t)dc->x, (uint32_t)dc->y, rep, dim,
                       dc->jb->p.seed);
    if (dim < PT_CACHED_DIMS) dc->have |= (uint64_t)1 << dim;
  }
  float fu, fv;
  uint32_t i = obs_sample_shuffle(j, smp->scramble0 ^ 0x5bd1e995U) & 0xffffu;
  obs_sampler2d_get(smp, i, &fu, &fv);
  *u = fu, *v = fv;
}

/* The power heuristic's weight of a strategy of density a against one of density b. */
static double power_weight(double a, double b) { return a * a / (a * a + b * b); }

/* Adds what the quad lights crossed by (o, d) before distance tmax emit toward o. Quad lights
 * are emitters only, not surfaces: they neither stop paths nor shadow. `pdf_bsdf` is the
 * direction's density (0: weight 1, the direction was not chosen by the BSDF). */
static void add_quad_lights(const pt_job *jb, const double o[3], const double d[3], double tmax,
                            double pdf_bsdf, const double beta[3], double L[3]) {
  for (size_t i = 0; i < jb->em.nquad; i++) {
    const obs_emitter *e = &jb->em.em[i];
    double cosl = -dot3(e->n, d);
    if (!(cosl > 0)) continue;
    double t = obs_emitter_tri_hit(e, o, d);
    if (!(t < tmax)) continue;
    double w = 1;
    if (pdf_bsdf > 0) w = power_weight(pdf_bsdf, mean3(e->le) / jb->em.total * t * t / cosl);
    for (int k = 0; k < 3; k++) L[k] += beta[k] * w * e->le[k];
  }
}

/* Next-event estimation at `hit`: one emitter point, its shadow ray, its MIS-weighted share. */
static uint64_t sample_light(const pt_job *jb, const obs_hit *hit, obs_rt_ctx *ctx,
                             const float org[3], const double rho[3], const double u[3],
                             const double beta[3], double L[3]) {
  obs_emitter_sample es;
  if (!obs_emitters_sample(&jb->em, hit, u, &es)) return 0;
  const double *wi = es.wi, *le = es.e->le;
  double dist = es.dist, coss = es.coss, pdf_l = es.pdf;
  float w[3] = {(float)wi[0], (float)wi[1], (float)wi[2]};
  /* The shadow ray stops short of the emitter's own surface (in the BVH for emissive objects). */
  if (obs_rt_occluded(jb->rt, ctx, org, w, (float)(dist * (1 - 1e-4)))) return 1;
  double mis = power_weight(pdf_l, coss * INV_PI);
  for (int k = 0; k < 3; k++) L[k] += beta[k] * rho[k] * INV_PI * le[k] * coss / pdf_l * mis;
  return 1;
}

/* The dimension pair of depth d's environment-map sample: apart from the 3 pairs per depth, so a
 * scene without a map reads the same streams as before maps existed. */
#define PT_ENV_DIM(d) (0x10000u + (uint32_t)(d))

/* The map's radiance along d and the MIS weight of a BSDF direction of density pdf_bsdf that
 * escapes along it (0: weight 1, no map sampling competed). */
static void add_map(const pt_job *jb, const double d[3], double pdf_bsdf, const double beta[3],
                    double L[3]) {
  float fd[3] = {(float)d[0], (float)d[1], (float)d[2]}, le[3];
  obs_env_lookup(jb->map, fd, le);
  double w = 1;
  if (pdf_bsdf > 0) w = power_weight(pdf_bsdf, obs_env_dist_pdf(&jb->dist, d));
  for (int k = 0; k < 3; k++) L[k] += beta[k] * w * le[k];
}

/* Next-event estimation of the map at `hit`: one direction by luminance x sin theta, its shadow
 * ray to infinity, its MIS-weighted share against the cosine density. */
static uint64_t sample_map(const pt_job *jb, const obs_hit *hit, obs_rt_ctx *ctx,
                           const float org[3], const double rho[3], double u0, double u1,
                           const double beta[3], double L[3]) {
  double wi[3];
  double pdf_l = obs_env_dist_sample(&jb->dist, u0, u1, wi);
  if (!(pdf_l > 0)) return 0;
  double cosn = hit->ns[0] * wi[0] + hit->ns[1] * wi[1] + hit->ns[2] * wi[2];
  double cosg = hit->ng[0] * wi[0] + hit->ng[1] * wi[1] + hit->ng[2] * wi[2];
  if (!(cosn > 0) || !(cosg > 0)) return 0;
  float w[3] = {(float)wi[0], (float)wi[1], (float)wi[2]}, le[3];
  if (obs_rt_occluded(jb->rt, ctx, org, w, INFINITY)) return 1;
  obs_env_lookup(jb->map, w, le);
  double mis = power_weight(pdf_l, cosn * INV_PI);
  for (int k = 0; k < 3; k++) L[k] += beta[k] * rho[k] * INV_PI * le[k] * cosn / pdf_l * mis;
  return 1;
}

/* First-hit facts of one pixel sample, for the auxiliary channels. */
typedef struct pt_first {
  int hit;
  double albedo[3], normal[3], depth;
} pt_first;

/* The radiance one camera path carries back, starting from the primary hit or miss. */
static uint64_t trace_path(const pt_job *jb, pt_dims *dc, uint32_t rep, uint32_t j,
                           const double org[3], const double dir[3], double L[3],
                           pt_first *first) {
  const obs_rt *rt = jb->rt;
  const obs_path_trace_params *p = &jb->p;
  double beta[3] = {1, 1, 1}, o[3], d[3] = {dir[0], dir[1], dir[2]}, pdf_bsdf = 0;
  for (int k = 0; k < 3; k++) o[k] = org[k] - rt->geo.origin[k], L[k] = 0;
  obs_hit hit;
  uint64_t rays = 1;
  int found = obs_rt_intersect(rt, org, dir, INFINITY, &hit);
  memset(first, 0, sizeof *first);
  for (int depth = 0;; depth++) {
    add_quad_lights(jb, o, d, found ? hit.t : INFINITY, pdf_bsdf, beta, L);
    if (!found) {
      if (jb->map)
        add_map(jb, d, p->bsdf_only ? 0 : pdf_bsdf, beta, L);
      else
        for (int k = 0; k < 3; k++) L[k] += beta[k] * jb->env[k];
      break;
    }
    const obs_object *ob = &jb->sc->objects[obs_rt_hit_object(rt, hit.geom, hit.prim)];
    double le[3], rho[3];
    vec3(&ob->emission, le);
    vec3(&ob->reflectivity, rho);
    if (mean3(le) > 0) {
      double w = 1, cosl = fabs(hit.ng[0] * d[0] + hit.ng[1] * d[1] + hit.ng[2] * d[2]);
      if (pdf_bsdf > 0 && cosl > 0)
        w = power_weight(pdf_bsdf, mean3(le) / jb->em.total * (double)hit.t * hit.t / cosl);
      for (int k = 0; k < 3; k++) L[k] += beta[k] * w * le[k];
    }
    if (depth == 0) {
      first->hit = 1;
      for (int k = 0; k < 3; k++) first->albedo[k] = rho[k], first->normal[k] = hit.ns[k];
      first->depth = hit.t * (dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] +
                              dir[2] * jb->cam.forward[2]);
    }
    if (depth >= p->max_bounces || !(mean3(rho) > 0)) break;
    float from[3];
    obs_rt_offset(rt, &hit, from);
    obs_rt_ctx ctx;
    obs_rt_ctx_init(&ctx, rt, &hit);
    double u[6];
    pt_sample(dc, rep, j, 1 + 3 * (uint32_t)depth, &u[0], &u[1]);
    pt_sample(dc, rep, j, 2 + 3 * (uint32_t)depth, &u[2], &u[3]);
    pt_sample(dc, rep, j, 3 + 3 * (uint32_t)depth, &u[4], &u[5]);
    if (!p->bsdf_only && jb->em.n) {
      const double ul[3] = {u[2], u[3], u[4]};
      rays += sample_light(jb, &hit, &ctx, from, rho, ul, beta, L);
    }
    if (!p->bsdf_only && jb->map) {
      double m0, m1;
      pt_sample(dc, rep, j, PT_ENV_DIM(depth), &m0, &m1);
      rays += sample_map(jb, &hit, &ctx, from, rho, m0, m1, beta, L);
    }
    float l[3], tb[3], bb[3], w[3];
    obs_sample_cosine((float)u[0], (float)u[1], l);
    obs_onb(hit.ns, tb, bb);
    for (int k = 0; k < 3; k++) w[k] = l[0] * tb[k] + l[1] * bb[k] + l[2] * hit.ns[k];
    /* Shading normals may tilt the hemisphere below the surface: such a direction is absorbed. */
    if (!(w[0] * hit.ng[0] + w[1] * hit.ng[1] + w[2] * hit.ng[2] > 0.0f)) break;
    pdf_bsdf = p->bsdf_only ? 0 : (double)l[2] * INV_PI;
    double bmax = 0;
    for (int k = 0; k < 3; k++) bmax = fmax(bmax, beta[k] *= rho[k]);
    if (depth + 1 > p->rr_depth && bmax < 1) {
      if (u[5] >= bmax) break;
      for (int k = 0; k < 3; k++) beta[k] /= bmax;
    }
    for (int k = 0; k < 3; k++) o[k] = from[k], d[k] = w[k];
    rays++;
    found = obs_rt_intersect_from(rt, &ctx, from, w, INFINITY, &hit);
  }
  return rays;
}

/* One pixel: the mean of its n = spp x samples paths, its standard error and the first hits'
 * facts. The paths form replicates (sampling.h, obs_rqmc: with `random` every path is one; with
 * `sobol` 8 of consecutive paths, each with its own scrambles), whose means' spread is the
 * standard error (mcerr.h), pooled with the neighbourhood's by the driver (pt_prior). With
 * several pixel samples every path looks through its own point of the pixel (dimension pair 0,
 * used for nothing else); one pixel sample looks through the pixel's centre. */
static uint64_t pt_shade(const void *job, int thread, int x, int y, float *v) {
  (void)thread;
  const pt_job *jb = job;
  double part[3] = {0, 0, 0}, alb[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
  double depth = 0;
  int hits = 0;
  uint64_t rays = 0;
  obs_mcerr e[3];
  memset(e, 0, sizeof e);
  obs_rqmc reps;
  obs_rqmc_init(&reps, jb->sampler, (uint32_t)x, (uint32_t)y, 0, 0, jb->p.seed,
                (uint32_t)jb->paths);
  pt_dims dc;
  dc.jb = jb, dc.x = x, dc.y = y, dc.rep = 0, dc.have = 0;
  uint32_t first = 0;
  for (uint32_t s = 0; s < (uint32_t)jb->paths; s++) {
    uint32_t j, rep = obs_rqmc_locate(&reps, s, &j);
    double jx = 0.5, jy = 0.5;
    if (jb->spp > 1) pt_sample(&dc, rep, j, 0, &jx, &jy);
    double org[3], dir[3], L[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    pt_first f;
    rays += trace_path(jb, &dc, rep, j, org, dir, L, &f);
    for (int k = 0; k < 3; k++) part[k] += L[k];
    if (jb->sampler == OBS_SAMPLER_RANDOM || s + 1 == obs_rqmc_first(&reps, rep + 1)) {
      for (int k = 0; k < 3; k++) obs_mcerr_add(&e[k], part[k] / (double)(s + 1 - first));
      memset(part, 0, sizeof part);
      first = s + 1;
    }
    if (!f.hit) continue;
    hits++;
    depth += f.depth;
    for (int k = 0; k < 3; k++) alb[k] += f.albedo[k], nrm[k] += f.normal[k];
  }
  double nl = sqrt(dot3(nrm, nrm));
  for (int k = 0; k < 3; k++) {
    v[CH_R + k] = (float)e[k].mean;
    /* Radiance has no bound: replicates that all agree (every path 0, say) leave the error to
     * the prior (a floor of 0, negated). */
    v[CH_SR + k] = (float)obs_mcerr_stderr(&e[k], (uint32_t)jb->paths, 0.0, 1);
    v[CH_AR + k] = hits ? (float)(alb[k] / hits) : 0.0f;
    v[CH_NX + k] = nl > 0 ? (float)(nrm[k] / nl) : 0.0f;
  }
  v[CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  v[CH_ALPHA] = (float)hits / (float)jb->paths;
  return rays;
}

static double pt_df(const void *job, int c) {
  (void)c;
  const pt_job *jb = job;
  return obs_rqmc_replicates(jb->sampler, (uint32_t)jb->paths) - 1.0;
}

static const int pt_se[3] = {CH_SR, CH_SG, CH_SB}, pt_values[3] = {CH_R, CH_G, CH_B};
static const obs_pixel_prior pt_prior = {
    3, pt_se, pt_values, CH_ALPHA, sizeof(pt_job),
    offsetof(pt_job, p) + offsetof(obs_path_trace_params, seed), pt_df};

int obs_path_trace_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: path_trace: no BVH was built for it", sc->name);
  pt_job jb;
  memset(&jb, 0, sizeof jb);
  jb.p = *(const obs_path_trace_params *)ctx->bound;
  jb.sampler = jb.p.random ? OBS_SAMPLER_RANDOM : OBS_SAMPLER_SOBOL;
  jb.sc = sc;
  jb.rt = ctx->rt;
  jb.spp = sc->spp;
  jb.paths = sc->spp * jb.p.samples;
  if (sc->has_environment) vec3(&sc->environment, jb.env);
  if (sc->has_environment && sc->env.kind != OBS_ENV_COLOR) {
    if (!ctx->environment)
      return obs_err_set(err, OBS_EINTERNAL, "%s: path_trace: no environment map was built",
                         sc->name);
    jb.map = ctx->environment;
  }
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  /* The emitter table is part of what is built for the render. */
  double t0 = obs_now_ms();
  int rc = obs_emitters_build(sc, jb.rt, &jb.em, err);
  if (!rc && jb.map) {
    int w, h;
    obs_env_dist_grid(jb.map->res, &w, &h);
    rc = obs_env_dist_build(&jb.dist, jb.map, w, h, err);
  }
  ctx->build_ms += obs_now_ms() - t0;
  if (!rc) {
    static const obs_pixel_ops ops = {CH_COUNT, channel_names, .shade = pt_shade,
                                        .prior = &pt_prior};
    rc = obs_driver_pixels(ctx, &ops, &jb, out, err);
  }
  obs_emitters_free(&jb.em);
  obs_env_dist_free(&jb.dist);
  return rc;
}
