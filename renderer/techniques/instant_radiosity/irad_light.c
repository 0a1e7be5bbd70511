/* instant_radiosity's light: the photon walk that makes the virtual point lights (Embree), the
 * radiance the camera sees directly, and what both backends share around the passes (the clamped
 * form factor in double, the push blocks, the export). The VPLs and the emission are made once on
 * the host, so the CPU and Vulkan gathers read the same bits. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "emitters.h"
#include "instant_radiosity.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"
#include "sampling.h"

#define IRAD_PI 3.14159265358979323846

const char *const obs_irad_extra_names[OBS_IRAD_EXTRA] = {"radiance.R", "radiance.G",
                                                          "radiance.B"};

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

uint32_t obs_irad_generation(uint32_t path, uint32_t paths, float renew, uint32_t frame) {
  if (paths == 0 || path >= paths) return 0;
  double share = renew < 0.0f ? 0.0 : renew > 1.0f ? 1.0 : (double)renew;
  uint64_t m = (uint64_t)floor(share * paths + 0.5); /* paths renewed per frame */
  /* Frame f >= 1 renews the positions [(f - 1) m, f m) of the cycle 0, 1, ..., paths - 1, 0, ...;
   * path p has been renewed once for each position t < frame m with t = p (mod paths). */
  return (uint32_t)(((uint64_t)frame * m + paths - 1 - path) / paths);
}

double obs_irad_form_factor(const double n[3], const double m[3], const double v[3], int two_sided,
                            double nc2) {
  double d2 = dot3(v, v), nv = dot3(n, v), mv = -dot3(m, v);
  if (two_sided) mv = fabs(mv);
  if (!(nv > 0) || !(mv >= 0)) return 0;
  double n2 = mv * mv; /* d^2 cos^2 psi: the squared distance from the VPL's plane */
  if (n2 < nc2) {
    double dl2 = d2 - n2 + nc2;
    return nv / sqrt(d2) * sqrt(nc2 / dl2) / dl2;
  }
  return (nv / d2) * (mv / d2);
}

/* A uniform number in [0, 1) for (path stream, dimension). */
static double unit(uint32_t stream, uint32_t dim) {
  return (double)obs_u32_to_unit(obs_hash_combine(stream, dim));
}

typedef struct walk_ctx {
  const obs_scene *sc;
  const obs_rt *rt;
  const obs_emitters *em;
  const obs_camera_rig *rig;
  const obs_instant_radiosity_params *p;
  uint32_t paths;
  obs_irad_vpls *out;
} walk_ctx;

/* Appends one VPL: q, unit normal m in the ray tracer's frame; its irradiance coefficient
 * (flux / pi) already scaled by its class's share. */
static void vpl_add(const walk_ctx *w, const double q[3], const double m[3], int two_sided,
                    const double coef[3]) {
  obs_irad_vpls *o = w->out;
  float *r = o->rec + (size_t)o->n * 4 * OBS_IRAD_VPL_VEC4, *wp = o->world + (size_t)o->n * 3;
  const double *axes[3] = {w->rig->right, w->rig->up, w->rig->forward};
  double d[3];
  for (int k = 0; k < 3; k++) d[k] = q[k] + w->rt->geo.origin[k] - w->rig->origin[k];
  for (int k = 0; k < 3; k++) {
    r[k] = (float)dot3(d, axes[k]);
    r[4 + k] = (float)dot3(m, axes[k]);
    r[8 + k] = (float)coef[k];
    wp[k] = (float)q[k];
  }
  r[3] = 0.0f;
  r[7] = two_sided ? 1.0f : 0.0f;
  r[11] = 0.0f;
  o->n++;
}

/* One photon path: the emitter point's VPL, then up to max_bounces - 1 diffuse bounces. */
static void walk_path(const walk_ctx *w, uint32_t path, double scale) {
  const obs_instant_radiosity_params *p = w->p;
  const obs_emitters *em = w->em;
  uint32_t gen = obs_irad_generation(path, w->paths, p->renew, p->frame);
  uint32_t s = obs_hash_combine(obs_hash_combine(obs_hash32(p->seed), path), gen);
  const double u[3] = {unit(s, 0), unit(s, 1), unit(s, 2)};
  double q[3], m[3], beta[3], coef[3];
  const obs_emitter *e = obs_emitters_point(em, u, q, m);
  double pdf = obs_emitters_mean3(e->le) / em->total; /* area density of q */
  for (int k = 0; k < 3; k++) {
    beta[k] = IRAD_PI * e->le[k] / pdf / (double)w->paths; /* flux leaving one side */
    coef[k] = beta[k] * scale / IRAD_PI;
  }
  vpl_add(w, q, m, e->two_sided, coef);
  /* The photon leaves one side: a two-sided emitter's, chosen at random, carries both sides'
   * flux. Emitters in the BVH (emissive objects) start just off their surface. */
  float n[3] = {(float)m[0], (float)m[1], (float)m[2]}, from[3];
  if (e->two_sided) {
    for (int k = 0; k < 3; k++) beta[k] *= 2.0;
    if (unit(s, 3) < 0.5)
      for (int k = 0; k < 3; k++) n[k] = -n[k];
  }
  double mag = fmax(fabs(q[0]), fmax(fabs(q[1]), fabs(q[2])));
  float off = (size_t)(e - em->em) < em->nquad ? 0.0f : (float)(mag * 0x1p-16);
  for (int k = 0; k < 3; k++) from[k] = (float)q[k] + off * n[k];
  obs_rt_ctx ctx;
  obs_rt_ctx_init(&ctx, w->rt, NULL);
  for (int depth = 1; depth < p->max_bounces; depth++) {
    float l[3], t[3], b[3], dir[3];
    obs_sample_cosine((float)unit(s, 2 + 2 * (uint32_t)depth),
                      (float)unit(s, 3 + 2 * (uint32_t)depth), l);
    obs_onb(n, t, b);
    for (int k = 0; k < 3; k++) dir[k] = l[0] * t[k] + l[1] * b[k] + l[2] * n[k];
    obs_hit hit;
    if (!obs_rt_intersect_from(w->rt, &ctx, from, dir, INFINITY, &hit)) break;
    const obs_object *ob = &w->sc->objects[obs_rt_hit_object(w->rt, hit.geom, hit.prim)];
    const double rho[3] = {ob->reflectivity.x, ob->reflectivity.y, ob->reflectivity.z};
    for (int k = 0; k < 3; k++) beta[k] *= rho[k];
    if (!(obs_emitters_mean3(beta) > 0)) break;
    for (int k = 0; k < 3; k++) {
      q[k] = hit.p[k], m[k] = hit.ng[k], n[k] = hit.ng[k];
      coef[k] = beta[k] * scale / IRAD_PI;
    }
    vpl_add(w, q, m, 0, coef);
    obs_rt_offset(w->rt, &hit, from);
    obs_rt_ctx_init(&ctx, w->rt, &hit);
  }
}

int obs_irad_vpls_make(const obs_scene *sc, const obs_rt *rt, const obs_camera_rig *rig,
                       const obs_instant_radiosity_params *p, obs_irad_vpls *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  if (p->max_bounces < 1 || p->vpls < 1) return 0;
  obs_emitters em;
  int rc = obs_emitters_build(sc, rt, &em, err);
  if (rc || !em.n) {
    obs_emitters_free(&em);
    return rc;
  }
  uint32_t paths = (uint32_t)(p->vpls / p->max_bounces);
  if (paths < 1) paths = 1;
  size_t cap = (size_t)paths * (size_t)p->max_bounces;
  out->rec = malloc(cap * 4 * OBS_IRAD_VPL_VEC4 * sizeof(float));
  out->world = malloc(cap * 3 * sizeof(float));
  if (!out->rec || !out->world) {
    obs_emitters_free(&em);
    return obs_err_set(err, OBS_ENOMEM, "%s: instant_radiosity: out of memory for %zu VPLs",
                       sc->name, cap);
  }
  out->paths = (int)paths;
  out->classes = paths < OBS_IRAD_CLASSES ? (int)paths : OBS_IRAD_CLASSES;
  walk_ctx w = {sc, rt, &em, rig, p, paths, out};
  /* Class k walks paths k, k + classes, ...; each class estimates the whole sum, so its VPLs
   * carry paths / (its path count) of their flux. */
  const uint32_t c = (uint32_t)out->classes;
  for (uint32_t k = 0; k < OBS_IRAD_CLASSES; k++) {
    out->start[k] = out->n;
    if (k >= c) continue;
    uint32_t count = (paths - k + c - 1) / c;
    for (uint32_t path = k; path < paths; path += c)
      walk_path(&w, path, (double)paths / (double)count);
  }
  out->start[OBS_IRAD_CLASSES] = out->n;
  obs_emitters_free(&em);
  return 0;
}

void obs_irad_vpls_free(obs_irad_vpls *v) {
  free(v->rec);
  free(v->world);
  memset(v, 0, sizeof *v);
}

typedef struct emission_job {
  const obs_scene *sc;
  const obs_rt *rt;
  const obs_emitters *em;
  const obs_camera_rig *rig;
  float *out;
} emission_job;

/* The radiance the camera ray through the pixel centre brings without a reflection: the surface's
 * emission, quad lights it crosses first, the environment where it hits nothing (path_trace's
 * zero-bounce terms). */
static int emission_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const emission_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      double org[3], dir[3], o[3], L[3] = {0, 0, 0};
      obs_camera_ray(j->rig, x + 0.5, y + 0.5, org, dir);
      for (int k = 0; k < 3; k++) o[k] = org[k] - j->rt->geo.origin[k];
      obs_hit hit;
      int found = obs_rt_intersect(j->rt, org, dir, INFINITY, &hit);
      for (size_t i = 0; i < j->em->nquad; i++) {
        const obs_emitter *e = &j->em->em[i];
        if (!(-dot3(e->n, dir) > 0)) continue;
        if (!(obs_emitter_tri_hit(e, o, dir) < (found ? hit.t : INFINITY))) continue;
        for (int k = 0; k < 3; k++) L[k] += e->le[k];
      }
      if (found) {
        const obs_object *ob = &j->sc->objects[obs_rt_hit_object(j->rt, hit.geom, hit.prim)];
        L[0] += ob->emission.x, L[1] += ob->emission.y, L[2] += ob->emission.z;
      } else if (j->sc->has_environment) {
        L[0] += j->sc->environment.x, L[1] += j->sc->environment.y;
        L[2] += j->sc->environment.z;
      }
      float *v = j->out + 3 * ((size_t)y * (size_t)j->sc->width + (size_t)x);
      for (int k = 0; k < 3; k++) v[k] = (float)L[k];
    }
  return 0;
}

int obs_irad_light_make(const obs_scene *sc, const obs_instant_radiosity_params *p, int threads,
                        const atomic_int *cancel, obs_irad_light *out, double ms[3],
                        obs_err *err) {
  memset(out, 0, sizeof *out);
  if (ms) ms[0] = ms[1] = ms[2] = 0.0;
  out->rt = calloc(1, sizeof *out->rt);
  out->emission = malloc((size_t)sc->width * (size_t)sc->height * 3 * sizeof(float));
  if (!out->rt || !out->emission)
    return obs_err_set(err, OBS_ENOMEM, "%s: instant_radiosity: %dx%d: out of memory", sc->name,
                       sc->width, sc->height);
  obs_camera_setup(&sc->camera, sc->width, sc->height, &out->rig);
  double t0 = obs_now_ms();
  int rc = obs_rt_build(sc, out->rt, threads, err);
  double t1 = obs_now_ms();
  if (rc) {
    free(out->rt);
    out->rt = NULL;
    return rc;
  }
  rc = obs_irad_vpls_make(sc, out->rt, &out->rig, p, &out->vpls, err);
  double t2 = obs_now_ms();
  obs_emitters em;
  if (!rc) rc = obs_emitters_build(sc, out->rt, &em, err);
  if (!rc) {
    emission_job j = {sc, out->rt, &em, &out->rig, out->emission};
    rc = obs_parallel_tiles(sc->width, sc->height, threads < 1 ? 1 : threads, emission_tile, &j,
                            cancel, NULL, NULL);
    obs_emitters_free(&em);
  }
  if (ms) {
    ms[0] = t1 - t0;
    ms[1] = t2 - t1;
    ms[2] = obs_now_ms() - t2;
  }
  return rc;
}

int obs_irad_light_render(obs_render_ctx *ctx, const obs_instant_radiosity_params *p,
                          obs_irad_light *out, obs_err *err) {
  double ms[3];
  int rc = obs_irad_light_make(ctx->scene, p, ctx->threads, ctx->cancel, out, ms, err);
  if (!rc) {
    obs_driver_stage_add(ctx, "bvh", ms[0]);
    obs_driver_stage_add(ctx, "walk", ms[1]);
    obs_driver_stage_add(ctx, "emission", ms[2]);
  }
  return rc;
}

int obs_irad_approx_render(obs_render_ctx *ctx, const obs_gbuffer *g, obs_irad_light *l,
                           obs_err *err) {
  double ms[2];
  int rc = obs_irad_approx_make(g, l, ctx->threads, ctx->cancel, ms, err);
  if (!rc) {
    obs_driver_stage_add(ctx, "pyramid", ms[0]);
    obs_driver_stage_add(ctx, "cube", ms[1]);
  }
  return rc;
}

void obs_irad_light_free(obs_irad_light *l) {
  if (l->rt) obs_rt_free(l->rt);
  free(l->rt);
  obs_irad_vpls_free(&l->vpls);
  free(l->emission);
  free(l->pyramid);
  free(l->cube);
  memset(l, 0, sizeof *l);
}

void obs_irad_gather_push_make(const obs_instant_radiosity_params *p, const obs_irad_light *l,
                               int w, int h, int ortho, float half_w, float half_h,
                               obs_irad_gather_push *out) {
  const obs_irad_vpls *v = &l->vpls;
  memset(out, 0, sizeof *out);
  out->width = w;
  out->height = h;
  out->flags = (ortho ? OBS_IRAD_ORTHO : 0) |
               (p->visibility == OBS_IRAD_VIS_APPROX && l->pyramid ? OBS_IRAD_APPROX : 0);
  out->classes = v->classes;
  out->bias = p->shadow_bias;
  out->thickness = p->shadow_thickness;
  out->cube_x = l->cube_c[0];
  out->cube_y = l->cube_c[1];
  out->cube_z = l->cube_c[2];
  out->half_w = half_w;
  out->half_h = half_h;
  /* N_c^2 in float: kept normal, so the bound 1 / N_c^2 holds at the smallest N_c too. */
  double nc2 = (double)p->clamp_distance * (double)p->clamp_distance;
  out->nc2 = (float)(nc2 < FLT_MIN ? FLT_MIN : nc2 > FLT_MAX ? FLT_MAX : nc2);
  for (int k = 0; k <= OBS_IRAD_CLASSES; k++) out->start[k] = v->start[k];
}

void obs_irad_filter_push_make(const obs_instant_radiosity_params *p, int w, int h, int ortho,
                               float half_w, float half_h, obs_irad_filter_push *out) {
  memset(out, 0, sizeof *out);
  out->width = w;
  out->height = h;
  out->flags = ortho ? OBS_IRAD_ORTHO : 0;
  out->half_w = half_w;
  out->half_h = half_h;
  out->depth_tol = p->filter_depth;
  out->normal_min = p->filter_normal;
  for (int k = 1; k <= OBS_IRAD_CLASSES; k++) out->inv_count[k] = 1.0f / (float)k;
}

void obs_irad_export(const obs_gbuffer *g, const float *emission, const float *raw,
                     const float *res, float *ao, float *ao_raw, float *extra) {
  const size_t n = (size_t)g->width * (size_t)g->height;
  const float inv_pi = (float)(1.0 / IRAD_PI);
  for (size_t i = 0; i < n; i++) {
    const int cov = g->depth[i] > 0.0f;
    ao[i] = cov ? res[4 * i + 3] : 1.0f;
    ao_raw[i] = cov ? raw[4 * i + 3] : 1.0f;
    for (size_t c = 0; c < 3; c++) {
      float b = cov ? g->albedo[3 * i + c] * inv_pi * res[4 * i + c] : 0.0f;
      extra[c * n + i] = emission[3 * i + c] + b;
    }
  }
}
