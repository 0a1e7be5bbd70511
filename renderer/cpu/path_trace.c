/* path_trace on the CPU: a diffuse global-illumination reference with Embree.
 *
 * Lambertian surfaces (material.reflectivity), emitters: quad lights, emissive objects
 * (material.emission) and a constant sky (environment.color). Unidirectional path tracing with
 * next-event estimation: at every diffuse vertex one emitter point is sampled (power-proportional
 * emitter choice, then uniform in area) and one cosine-distributed direction continues the path;
 * the two estimates of light reaching the vertex are combined by multiple importance sampling with
 * the power heuristic (Veach 1997; pbrt-v4's PathIntegrator). Russian roulette after rr_depth
 * bounces keeps long paths unbiased and cheap. docs/techniques/path_trace.md states the model. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "obscura/render.h"
#include "driver.h"
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

/* One emitting primitive in the ray tracer's frame: a triangle (a, a + e1, a + e2) or, with
 * `sphere`, the whole sphere of centre a and radius r. */
typedef struct pt_emitter {
  double a[3], e1[3], e2[3], n[3]; /* n: unit normal of a triangle (its emitting side) */
  double r, area;
  double le[3];
  int sphere, two_sided;
} pt_emitter;

typedef struct pt_job {
  const obs_rt *rt;
  const obs_scene *sc;
  obs_camera_rig cam;
  obs_path_trace_params p;
  obs_sampler_kind sampler;
  int spp, paths; /* pixel samples; paths = spp * samples */
  pt_emitter *em; /* quad-light triangles first (nquad of them), then emissive objects */
  size_t nem, nquad;
  double *cdf;  /* emitter choice, by area times mean emission */
  double total; /* sum of area times mean emission: an emitter point's area density is
                   mean(le) / total whichever primitive it lies on */
  double env[3];
} pt_job;

static double mean3(const double v[3]) { return (v[0] + v[1] + v[2]) / 3.0; }
static void vec3(const obs_vec3 *v, double o[3]) { o[0] = v->x, o[1] = v->y, o[2] = v->z; }
static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* A triangle emitter from world-space corners (moved into the frame at `origin`); 0 when it has
 * no area. */
static int tri_emitter(pt_emitter *e, const double w[3][3], const double origin[3],
                       const double le[3], int two_sided) {
  memset(e, 0, sizeof *e);
  for (int k = 0; k < 3; k++) {
    e->a[k] = w[0][k] - origin[k];
    e->e1[k] = w[1][k] - w[0][k];
    e->e2[k] = w[2][k] - w[0][k];
    e->le[k] = le[k];
  }
  double n[3] = {e->e1[1] * e->e2[2] - e->e1[2] * e->e2[1],
                 e->e1[2] * e->e2[0] - e->e1[0] * e->e2[2],
                 e->e1[0] * e->e2[1] - e->e1[1] * e->e2[0]};
  double len = sqrt(dot3(n, n));
  if (!(len > 0) || !isfinite(len)) return 0;
  for (int k = 0; k < 3; k++) e->n[k] = n[k] / len;
  e->area = 0.5 * len;
  e->two_sided = two_sided;
  return 1;
}

/* Gathers every emitter of the scene: quad lights (one-sided, two triangles each) and the
 * triangles and spheres of objects with emission (two-sided). */
static int build_emitters(pt_job *jb, obs_err *err) {
  const obs_scene *sc = jb->sc;
  const obs_geometry *g = &jb->rt->geo;
  size_t cap = 2 * sc->nlights + g->nspheres;
  double le[3];
  for (size_t i = 0; i < g->nmeshes; i++) {
    vec3(&sc->objects[g->meshes[i].object].emission, le);
    if (mean3(le) > 0) cap += g->meshes[i].ntris;
  }
  jb->em = calloc(cap ? cap : 1, sizeof *jb->em);
  jb->cdf = calloc(cap ? cap : 1, sizeof *jb->cdf);
  if (!jb->em || !jb->cdf)
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for %zu emitters", sc->name, cap);
  size_t n = 0;
  for (size_t i = 0; i < sc->nlights; i++) {
    const obs_light *l = &sc->lights[i];
    vec3(&l->emission, le);
    if (!(mean3(le) > 0)) continue;
    static const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
    for (int t = 0; t < 2; t++) {
      double w[3][3];
      for (int c = 0; c < 3; c++) vec3(&l->v[tris[t][c]], w[c]);
      n += tri_emitter(&jb->em[n], w, g->origin, le, 0);
    }
  }
  jb->nquad = n;
  for (size_t i = 0; i < g->nmeshes; i++) {
    const obs_mesh *m = &g->meshes[i];
    vec3(&sc->objects[m->object].emission, le);
    if (!(mean3(le) > 0)) continue;
    for (size_t t = 0; t < m->ntris; t++) {
      double w[3][3];
      for (int c = 0; c < 3; c++)
        for (int k = 0; k < 3; k++) w[c][k] = (double)m->pos[3 * m->idx[3 * t + c] + k];
      const double zero[3] = {0, 0, 0};
      n += tri_emitter(&jb->em[n], w, zero, le, 1);
    }
  }
  for (size_t i = 0; i < g->nspheres; i++) {
    const obs_sphere *s = &g->spheres[i];
    vec3(&sc->objects[s->object].emission, le);
    if (!(mean3(le) > 0)) continue;
    pt_emitter *e = &jb->em[n];
    memset(e, 0, sizeof *e);
    memcpy(e->a, s->center, sizeof e->a);
    memcpy(e->le, le, sizeof e->le);
    e->r = s->radius;
    e->area = 4.0 * M_PI * s->radius * s->radius;
    e->sphere = e->two_sided = 1;
    n += e->area > 0 && isfinite(e->area);
  }
  jb->nem = n;
  double sum = 0;
  for (size_t i = 0; i < n; i++) {
    sum += jb->em[i].area * mean3(jb->em[i].le);
    jb->cdf[i] = sum;
  }
  jb->total = sum;
  if (n && !(sum > 0 && isfinite(sum)))
    return obs_err_set(err, OBS_EINVAL, "%s: emitted power %g is not finite and positive", sc->name,
                       sum);
  for (size_t i = 0; i < n; i++) jb->cdf[i] /= sum;
  return 0;
}

/* The streams of one pixel's dimension pairs, seeded once per pixel (the seeding hashes cost as
 * much as a point): the first PT_CACHED_DIMS pairs are kept, deeper ones seeded on each use. */
#define PT_CACHED_DIMS 64
typedef struct pt_dims {
  const pt_job *jb;
  int x, y;
  uint64_t have; /* bit d: s[d] is seeded */
  obs_sampler2d s[PT_CACHED_DIMS];
} pt_dims;

/* The 2D point of dimension pair `dim` for pixel sample s: each pair is its own scrambled
 * sequence over the pixel's samples, so every pair is stratified across the samples, read at a
 * shuffled index so that pairs are independent of one another (measured: without the shuffle
 * the white furnace converges 1.3 % low in its rho = 0.8 channel with Sobol). The shuffle maps
 * the first 2^k indices onto an aligned block of 2^k; keeping its low 16 bits keeps that (for
 * spp <= 2^16) and keeps Sobol's generator loop short. */
static void pt_sample(pt_dims *dc, int s, uint32_t dim, double *u, double *v) {
  obs_sampler2d local, *smp = dim < PT_CACHED_DIMS ? &dc->s[dim] : &local;
  if (dim >= PT_CACHED_DIMS || !(dc->have >> dim & 1)) {
    obs_sampler2d_init(smp, dc->jb->sampler, (uint32_t)dc->x, (uint32_t)dc->y, 0, dim,
                       dc->jb->p.seed);
    if (dim < PT_CACHED_DIMS) dc->have |= (uint64_t)1 << dim;
  }
  float fu, fv;
  uint32_t i = obs_sample_shuffle((uint32_t)s, smp->scramble0 ^ 0x5bd1e995U) & 0xffffu;
  obs_sampler2d_get(smp, i, &fu, &fv);
  *u = fu, *v = fv;
}

/* Distance along (o, d) to the triangle of `e` (Moeller-Trumbore, double), or INFINITY. */
static double tri_hit(const pt_emitter *e, const double o[3], const double d[3]) {
  double p[3] = {d[1] * e->e2[2] - d[2] * e->e2[1], d[2] * e->e2[0] - d[0] * e->e2[2],
                 d[0] * e->e2[1] - d[1] * e->e2[0]};
  double det = dot3(e->e1, p);
  if (det == 0) return INFINITY;
  double s[3] = {o[0] - e->a[0], o[1] - e->a[1], o[2] - e->a[2]};
  double b1 = dot3(s, p) / det;
  if (!(b1 >= 0 && b1 <= 1)) return INFINITY;
  double q[3] = {s[1] * e->e1[2] - s[2] * e->e1[1], s[2] * e->e1[0] - s[0] * e->e1[2],
                 s[0] * e->e1[1] - s[1] * e->e1[0]};
  double b2 = dot3(d, q) / det;
  if (!(b2 >= 0 && b1 + b2 <= 1)) return INFINITY;
  double t = dot3(e->e2, q) / det;
  return t > 0 ? t : INFINITY;
}

/* The power heuristic's weight of a strategy of density a against one of density b. */
static double power_weight(double a, double b) { return a * a / (a * a + b * b); }

/* Adds what the quad lights crossed by (o, d) before distance tmax emit toward o. Quad lights
 * are emitters only, not surfaces: they neither stop paths nor shadow. `pdf_bsdf` is the
 * direction's density (0: weight 1, the direction was not chosen by the BSDF). */
static void add_quad_lights(const pt_job *jb, const double o[3], const double d[3], double tmax,
                            double pdf_bsdf, const double beta[3], double L[3]) {
  for (size_t i = 0; i < jb->nquad; i++) {
    const pt_emitter *e = &jb->em[i];
    double cosl = -dot3(e->n, d);
    if (!(cosl > 0)) continue;
    double t = tri_hit(e, o, d);
    if (!(t < tmax)) continue;
    double w = 1;
    if (pdf_bsdf > 0) w = power_weight(pdf_bsdf, mean3(e->le) / jb->total * t * t / cosl);
    for (int k = 0; k < 3; k++) L[k] += beta[k] * w * e->le[k];
  }
}

/* Next-event estimation at `hit`: one emitter point, its shadow ray, its MIS-weighted share. */
static uint64_t sample_light(const pt_job *jb, const obs_hit *hit, obs_rt_ctx *ctx,
                             const float org[3], const double rho[3], const double u[3],
                             const double beta[3], double L[3]) {
  size_t lo = 0, hi = jb->nem - 1;
  while (lo < hi) {
    size_t mid = (lo + hi) / 2;
    if (jb->cdf[mid] > u[0])
      hi = mid;
    else
      lo = mid + 1;
  }
  const pt_emitter *e = &jb->em[lo];
  double q[3], nl[3];
  if (e->sphere) {
    double z = 1 - 2 * u[1], r = sqrt(fmax(0.0, 1 - z * z)), phi = 2 * M_PI * u[2];
    nl[0] = r * cos(phi), nl[1] = r * sin(phi), nl[2] = z;
    for (int k = 0; k < 3; k++) q[k] = e->a[k] + e->r * nl[k];
  } else {
    double su = sqrt(u[1]);
    for (int k = 0; k < 3; k++) {
      q[k] = e->a[k] + su * (1 - u[2]) * e->e1[k] + su * u[2] * e->e2[k];
      nl[k] = e->n[k];
    }
  }
  double wi[3] = {q[0] - hit->p[0], q[1] - hit->p[1], q[2] - hit->p[2]};
  double d2 = dot3(wi, wi), dist = sqrt(d2);
  if (!(dist > 0) || !isfinite(d2)) return 0;
  for (int k = 0; k < 3; k++) wi[k] /= dist;
  double ng[3] = {hit->ng[0], hit->ng[1], hit->ng[2]}, ns[3] = {hit->ns[0], hit->ns[1], hit->ns[2]};
  double coss = dot3(ns, wi), cosl = -dot3(nl, wi);
  if (e->two_sided) cosl = fabs(cosl);
  if (!(coss > 0) || !(dot3(ng, wi) > 0) || !(cosl > 0)) return 0;
  double pdf_l = mean3(e->le) / jb->total * d2 / cosl;
  if (!(pdf_l > 0) || !isfinite(pdf_l)) return 0;
  float w[3] = {(float)wi[0], (float)wi[1], (float)wi[2]};
  /* The shadow ray stops short of the emitter's own surface (in the BVH for emissive objects). */
  if (obs_rt_occluded(jb->rt, ctx, org, w, (float)(dist * (1 - 1e-4)))) return 1;
  double mis = power_weight(pdf_l, coss * INV_PI);
  for (int k = 0; k < 3; k++) L[k] += beta[k] * rho[k] * INV_PI * e->le[k] * coss / pdf_l * mis;
  return 1;
}

/* First-hit facts of one pixel sample, for the auxiliary channels. */
typedef struct pt_first {
  int hit;
  double albedo[3], normal[3], depth;
} pt_first;

/* The radiance one camera path carries back, starting from the primary hit or miss. */
static uint64_t trace_path(const pt_job *jb, pt_dims *dc, int s, const double org[3],
                           const double dir[3], double L[3], pt_first *first) {
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
      for (int k = 0; k < 3; k++) L[k] += beta[k] * jb->env[k];
      break;
    }
    const obs_object *ob =
        &jb->sc->objects[hit.geom == rt->sphere_geom ? rt->geo.spheres[hit.prim].object
                                                     : rt->geo.meshes[hit.geom].object];
    double le[3], rho[3];
    vec3(&ob->emission, le);
    vec3(&ob->reflectivity, rho);
    if (mean3(le) > 0) {
      double w = 1, cosl = fabs(hit.ng[0] * d[0] + hit.ng[1] * d[1] + hit.ng[2] * d[2]);
      if (pdf_bsdf > 0 && cosl > 0)
        w = power_weight(pdf_bsdf, mean3(le) / jb->total * (double)hit.t * hit.t / cosl);
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
    pt_sample(dc, s, 1 + 3 * (uint32_t)depth, &u[0], &u[1]);
    pt_sample(dc, s, 2 + 3 * (uint32_t)depth, &u[2], &u[3]);
    pt_sample(dc, s, 3 + 3 * (uint32_t)depth, &u[4], &u[5]);
    if (!p->bsdf_only && jb->nem) {
      const double ul[3] = {u[2], u[3], u[4]};
      rays += sample_light(jb, &hit, &ctx, from, rho, ul, beta, L);
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

/* One pixel: the mean of its paths (p.samples per pixel sample), their standard error, and the
 * first hits' facts. */
static uint64_t pt_shade(const void *job, int thread, int x, int y, float *v) {
  (void)thread;
  const pt_job *jb = job;
  double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0}, alb[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
  double depth = 0;
  int hits = 0;
  uint64_t rays = 0;
  pt_dims dc;
  dc.jb = jb, dc.x = x, dc.y = y, dc.have = 0;
  for (int s = 0; s < jb->paths; s++) {
    double jx = 0.5, jy = 0.5;
    /* One pixel sample looks through the pixel's centre; several are stratified over the pixel
     * (dimension pair 0, indexed by pixel sample, is used for nothing else). */
    if (jb->spp > 1) pt_sample(&dc, s / jb->p.samples, 0, &jx, &jy);
    double org[3], dir[3], L[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    pt_first f;
    rays += trace_path(jb, &dc, s, org, dir, L, &f);
    for (int k = 0; k < 3; k++) {
      sum[k] += L[k];
      sum2[k] += L[k] * L[k];
    }
    if (!f.hit) continue;
    hits++;
    depth += f.depth;
    for (int k = 0; k < 3; k++) alb[k] += f.albedo[k], nrm[k] += f.normal[k];
  }
  double n = jb->paths, nl = sqrt(dot3(nrm, nrm));
  for (int k = 0; k < 3; k++) {
    double mean = sum[k] / n;
    /* Unbiased sample variance of one path's radiance, over n for the mean's; 0 for n = 1. */
    double var = n > 1 ? fmax(0.0, (sum2[k] - n * mean * mean) / (n - 1)) : 0.0;
    v[CH_R + k] = (float)mean;
    v[CH_SR + k] = (float)sqrt(var / n);
    v[CH_AR + k] = hits ? (float)(alb[k] / hits) : 0.0f;
    v[CH_NX + k] = nl > 0 ? (float)(nrm[k] / nl) : 0.0f;
  }
  v[CH_DEPTH] = hits ? (float)(depth / hits) : 0.0f;
  v[CH_ALPHA] = (float)hits / (float)jb->paths;
  return rays;
}

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
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  /* The emitter table is part of what is built for the render. */
  double t0 = obs_now_ms();
  int rc = build_emitters(&jb, err);
  ctx->build_ms += obs_now_ms() - t0;
  if (!rc) {
    static const obs_pixel_ops ops = {CH_COUNT, channel_names, pt_shade};
    rc = obs_driver_pixels(ctx, &ops, &jb, out, err);
  }
  free(jb.em);
  free(jb.cdf);
  return rc;
}
