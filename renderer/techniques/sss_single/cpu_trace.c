/* sss_single's reference on the CPU (method "trace"): the same single-scattering integral as the
 * light-view maps (Eq. 6.5.3 with E_t of Eq. 6.5.4, the same Schlick Fresnel, Henyey-Greenstein
 * phase and eta), estimated with Embree and none of the maps' approximations: path lengths are
 * random and end where the refracted view ray leaves the object, the light's entry point is found
 * by ray tracing along the refracted light direction (so the in-medium light path is measured, not
 * Eq. 6.5.6's flat-surface estimate) and the entry point's visibility by a shadow ray. */
#include <math.h>
#include <string.h>

#include "sss_job.h"

/* A context for rays leaving `h` into the medium (inward) or out of it: the analytic sphere must
 * know which of its roots the ray may still meet. */
static void ctx_leaving(obs_rt_ctx *c, const obs_rt *rt, const obs_hit *h, int inward) {
  obs_rt_ctx_init(c, rt, h);
  if (h->geom == rt->sphere_geom) c->skip_mode = inward ? 2 : 1;
}

/* The origin of a ray leaving h's surface on the side of unit `side` (+1 along ng, -1 against). */
static void offset_side(const obs_rt *rt, const obs_hit *h, float side, float out[3]) {
  obs_hit f = *h;
  for (int k = 0; k < 3; k++) f.ng[k] = side * h->ng[k];
  obs_rt_offset(rt, &f, out);
}

/* The light reaching frame point xs inside object obj from light l, through the refracted entry
 * point; *rays counts the rays. Fills light[] (E_t exp(-sigma_t s_i')) and returns the phase
 * function's value for the exit direction -t, 0 when no light arrives. */
static double connect(const sss_job *jb, const sss_light *l, const sss_medium *md, size_t obj,
                      const float xs[3], const double t[3], double light[3], uint64_t *rays) {
  const obs_rt *rt = jb->rt;
  obs_rt_ctx c;
  obs_rt_ctx_init(&c, rt, NULL);
  /* 1. The surface between xs and the light along the straight line: its normal refracts the
   *    light, whose refracted direction then leads back from xs to the true entry point. */
  float to[3];
  double d0 = 0;
  for (int k = 0; k < 3; k++) {
    to[k] = (float)(l->point ? l->pos[k] - xs[k] : -l->dir[k]);
    d0 += (double)to[k] * to[k];
  }
  d0 = sqrt(d0);
  for (int k = 0; k < 3; k++) to[k] = (float)(to[k] / d0);
  obs_hit h1;
  (*rays)++;
  if (!obs_rt_intersect_from(rt, &c, xs, to, INFINITY, &h1)) return 0;
  if (obs_rt_hit_object(rt, h1.geom, h1.prim) != obj) return 0;
  double n1[3] = {-h1.ns[0], -h1.ns[1], -h1.ns[2]}, wl[3], wi[3]; /* outward */
  for (int k = 0; k < 3; k++) wl[k] = l->point ? h1.p[k] - l->pos[k] : l->dir[k];
  double wll = sqrt(obs_sss_dot(wl, wl));
  for (int k = 0; k < 3; k++) wl[k] /= wll;
  if (!(obs_sss_dot(wl, n1) < 0)) return 0; /* the light is behind that face */
  obs_sss_refract(wl, n1, md->eta, wi);
  /* 2. Back along the refracted light direction to where that light entered. */
  float back[3] = {(float)-wi[0], (float)-wi[1], (float)-wi[2]};
  obs_hit h2;
  obs_rt_ctx_init(&c, rt, NULL);
  (*rays)++;
  if (!obs_rt_intersect_from(rt, &c, xs, back, INFINITY, &h2)) return 0;
  if (obs_rt_hit_object(rt, h2.geom, h2.prim) != obj) return 0;
  double n2[3] = {-h2.ns[0], -h2.ns[1], -h2.ns[2]}, w2[3], e = 1.0, dist = INFINITY;
  for (int k = 0; k < 3; k++) w2[k] = l->point ? h2.p[k] - l->pos[k] : l->dir[k];
  if (l->point) {
    dist = sqrt(obs_sss_dot(w2, w2));
    for (int k = 0; k < 3; k++) w2[k] /= dist;
    e = 1.0 / (dist * dist);
  }
  double ci = -obs_sss_dot(w2, n2);
  if (!(ci > 0)) return 0;
  /* 3. The entry point's own visibility of the light. */
  float org[3], tl[3] = {(float)-w2[0], (float)-w2[1], (float)-w2[2]};
  offset_side(rt, &h2, -1.0f, org);
  ctx_leaving(&c, rt, &h2, 0);
  (*rays)++;
  if (obs_rt_occluded(rt, &c, org, tl, l->point ? (float)dist : INFINITY)) return 0;
  double ft = obs_sss_schlick_t(ci, md->eta), si = h2.t;
  for (int k = 0; k < 3; k++)
    light[k] = l->power[k] * e * ft * ci * exp(-md->sigma_t[k] * si);
  return obs_sss_hg(-obs_sss_dot(wi, t), md->g);
}

uint64_t obs_sss_trace_shade(const sss_job *jb, const obs_hit *hit, size_t obj,
                             const double dir[3], uint32_t px, uint32_t py, uint32_t s,
                             double sum[3], double sum2[3]) {
  const obs_rt *rt = jb->rt;
  const sss_medium *md = &jb->media[obj];
  double n[3] = {hit->ns[0], hit->ns[1], hit->ns[2]}, t[3];
  double fto = obs_sss_schlick_t(obs_sss_dot(dir, n), md->eta);
  obs_sss_refract(dir, n, md->eta, t);
  uint64_t rays = 1;
  /* Where the refracted view ray leaves the object: no path sample lies beyond. */
  float org[3], tf[3] = {(float)t[0], (float)t[1], (float)t[2]};
  offset_side(rt, hit, -1.0f, org);
  obs_rt_ctx c;
  ctx_leaving(&c, rt, hit, 1);
  float smax = obs_rt_distance(rt, &c, org, tf, INFINITY);
  for (int k = 0; k < 3; k++) sum[k] = sum2[k] = 0;
  for (uint32_t i = 0; i < jb->p.samples; i++) {
    double xi = obs_sss_rand(obs_sss_key(jb->p.seed, px, py, s, i));
    double so = -log1p(-xi) / md->sigma_min, v[3] = {0, 0, 0};
    if (so < smax) {
      float xs[3];
      for (int k = 0; k < 3; k++) xs[k] = (float)(org[k] + t[k] * so);
      for (int j = 0; j < jb->nlights; j++) {
        double light[3];
        double ph = connect(jb, &jb->lights[j], md, obj, xs, t, light, &rays);
        if (ph > 0)
          for (int k = 0; k < 3; k++)
            v[k] += ph * light[k] * exp(-(md->sigma_t[k] - md->sigma_min) * so) / md->sigma_min;
      }
    }
    for (int k = 0; k < 3; k++) {
      v[k] *= md->sigma_s[k] * fto;
      sum[k] += v[k];
      sum2[k] += v[k] * v[k];
    }
  }
  return rays;
}
