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

/* The light's unit direction of travel arriving at frame point p, and a point light's distance. */
static void light_dir_at(const sss_light *l, const float p[3], double w[3], double *dist) {
  *dist = INFINITY;
  if (!l->point) {
    for (int k = 0; k < 3; k++) w[k] = l->dir[k];
    return;
  }
  for (int k = 0; k < 3; k++) w[k] = p[k] - l->pos[k];
  *dist = sqrt(obs_sss_dot(w, w));
  for (int k = 0; k < 3; k++) w[k] /= *dist;
}

/* The candidate entry along unit u from xs: the face of obj it meets, the light refracted there and
 * Snell's residual |wi + u| (0 exactly when the refracted light runs straight back to xs). 0 when
 * u leaves through another object or nothing, or the face is turned away from the light. */
static int probe(const sss_job *jb, const sss_light *l, const sss_medium *md, size_t obj,
                 const float xs[3], const double u[3], sss_entry *e, uint64_t *rays) {
  const obs_rt *rt = jb->rt;
  obs_rt_ctx c;
  obs_rt_ctx_init(&c, rt, NULL);
  float uf[3] = {(float)u[0], (float)u[1], (float)u[2]};
  (*rays)++;
  if (!obs_rt_intersect_from(rt, &c, xs, uf, INFINITY, &e->h)) return 0;
  if (obs_rt_hit_object(rt, e->h.geom, e->h.prim) != obj) return 0;
  double n[3] = {-e->h.ns[0], -e->h.ns[1], -e->h.ns[2]}; /* outward: ns faces xs, inside */
  light_dir_at(l, e->h.p, e->w, &e->dist);
  if (!(obs_sss_dot(e->w, n) < 0)) return 0;
  obs_sss_refract(e->w, n, md->eta, e->wi);
  double r2 = 0;
  for (int k = 0; k < 3; k++) r2 += (e->wi[k] + u[k]) * (e->wi[k] + u[k]);
  e->resid = sqrt(r2);
  return 1;
}

/* The search's unknown is the direction u from xs to the entry point, as a point q of the plane
 * one unit along the straight line u0 to the light: u = normalize(u0 + q0 e1 + q1 e2). */
typedef struct entry_frame {
  const sss_job *jb;
  const sss_light *l;
  const sss_medium *md;
  size_t obj;
  const float *xs;
  double u0[3], e1[3], e2[3];
  uint64_t *rays;
} entry_frame;

/* G(q) = P(-wi(hit(xs, u(q)))) - q, P the central projection onto the plane: 0 exactly at the
 * refracted light path. Fills *e; 0 when the candidate has no lit face of obj (see probe). */
static int entry_eval(const entry_frame *f, const double q[2], sss_entry *e, double g[2]) {
  double u[3], ul = 0;
  for (int k = 0; k < 3; k++) {
    u[k] = f->u0[k] + q[0] * f->e1[k] + q[1] * f->e2[k];
    ul += u[k] * u[k];
  }
  ul = sqrt(ul);
  for (int k = 0; k < 3; k++) u[k] /= ul;
  if (!probe(f->jb, f->l, f->md, f->obj, f->xs, u, e, f->rays)) return 0;
  double w[3] = {-e->wi[0], -e->wi[1], -e->wi[2]}, c = obs_sss_dot(w, f->u0);
  if (!(c > 1e-3)) return 0; /* the refracted light points away from the plane's side */
  g[0] = obs_sss_dot(w, f->e1) / c - q[0];
  g[1] = obs_sss_dot(w, f->e2) / c - q[1];
  return 1;
}

/* The refracted light path is the root of G. The search starts on the straight line to the light
 * (exact at normal incidence) and takes plain fixed-point steps q += G(q) while they shrink |G|
 * at least twofold (the first is the one-step estimate, exact on a flat face); then Newton steps
 * with G's Jacobian by finite differences, halved up to 8 times until |G| shrinks. It converges
 * when the entry point would move less than the tolerance, 1e-6 of the scene's diagonal or a few
 * times the hit's own rounding error when that is larger (a frame far from the geometry). No
 * step shrinking |G| means a minimum of |G| above 0: no refracted path reaches xs (the refraction
 * shadow beyond the light's terminator, where even grazing light refracts at the critical angle
 * away from xs). */
int obs_sss_entry_solve(const sss_job *jb, const sss_light *l, size_t obj, const float xs[3],
                        int max_steps, sss_entry *e, uint64_t *rays) {
  entry_frame f = {jb, l, &jb->media[obj], obj, xs, {0}, {0}, {0}, rays};
  const double *b0 = jb->rt->geo.bounds[0], *b1 = jb->rt->geo.bounds[1];
  double diag2 = 0, dist, q[2] = {0, 0}, g[2];
  for (int k = 0; k < 3; k++) diag2 += (b1[k] - b0[k]) * (b1[k] - b0[k]);
  light_dir_at(l, xs, f.u0, &dist);
  for (int k = 0; k < 3; k++) f.u0[k] = -f.u0[k];
  /* e1, e2: an orthonormal basis of the plane normal to u0 */
  double a[3] = {0, 0, 0};
  a[fabs(f.u0[0]) < 0.6 ? 0 : fabs(f.u0[1]) < 0.6 ? 1 : 2] = 1;
  double ad = obs_sss_dot(a, f.u0), el = 0;
  for (int k = 0; k < 3; k++) {
    f.e1[k] = a[k] - ad * f.u0[k];
    el += f.e1[k] * f.e1[k];
  }
  for (int k = 0; k < 3; k++) f.e1[k] /= sqrt(el);
  f.e2[0] = f.u0[1] * f.e1[2] - f.u0[2] * f.e1[1];
  f.e2[1] = f.u0[2] * f.e1[0] - f.u0[0] * f.e1[2];
  f.e2[2] = f.u0[0] * f.e1[1] - f.u0[1] * f.e1[0];
  if (!entry_eval(&f, q, e, g)) return 0;
  e->steps = e->converged = e->stalled = 0;
  int newton = 0;
  sss_entry cand;
  for (;;) {
    double pe = sqrt((double)e->h.perr[0] * e->h.perr[0] + (double)e->h.perr[1] * e->h.perr[1] +
                     (double)e->h.perr[2] * e->h.perr[2]);
    if (e->resid * e->h.t <= fmax(1e-6 * sqrt(diag2), 4.0 * pe)) {
      e->converged = 1;
      break;
    }
    if (e->steps >= max_steps) break;
    e->steps++;
    double gn = hypot(g[0], g[1]), d[2] = {g[0], g[1]}, qn[2], gc[2];
    if (newton) {
      /* G's Jacobian by forward differences of 1e-5 (a tenth of a milliradian) */
      double jac[2][2], h = 1e-5;
      int found = 1;
      for (int i = 0; i < 2 && found; i++) {
        double qh[2] = {q[0], q[1]}, gh[2];
        qh[i] += h;
        if (!entry_eval(&f, qh, &cand, gh)) {
          qh[i] = q[i] - h;
          found = entry_eval(&f, qh, &cand, gh);
        }
        for (int k = 0; k < 2; k++) jac[k][i] = (gh[k] - g[k]) / (qh[i] - q[i]);
      }
      double det = found ? jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0] : 0;
      if (!(fabs(det) > 0)) {
        e->stalled = 1;
        break;
      }
      d[0] = -(jac[1][1] * g[0] - jac[0][1] * g[1]) / det;
      d[1] = -(-jac[1][0] * g[0] + jac[0][0] * g[1]) / det;
    }
    int ok = 0;
    double lam = 1;
    for (int tries = 0; tries < (newton ? 9 : 1) && !ok; tries++, lam *= 0.5) {
      qn[0] = q[0] + lam * d[0];
      qn[1] = q[1] + lam * d[1];
      ok = entry_eval(&f, qn, &cand, gc) && hypot(gc[0], gc[1]) < (newton ? 1.0 : 0.5) * gn;
    }
    if (ok) {
      int steps = e->steps;
      *e = cand;
      e->steps = steps;
      e->converged = e->stalled = 0;
      q[0] = qn[0];
      q[1] = qn[1];
      g[0] = gc[0];
      g[1] = gc[1];
    } else if (newton) {
      e->stalled = 1;
      break;
    } else {
      newton = 1;
    }
  }
  return 1;
}

/* The light reaching frame point xs inside object obj from light l, through the entry point the
 * search converged to; *rays counts the rays. Fills light[] (E_t exp(-sigma_t s_i')) and returns
 * the phase function's value for the exit direction -t, 0 when no light arrives. */
static double connect(const sss_job *jb, const sss_light *l, const sss_medium *md, size_t obj,
                      const float xs[3], const double t[3], double light[3], uint64_t *rays) {
  const obs_rt *rt = jb->rt;
  sss_entry e;
  if (!obs_sss_entry_solve(jb, l, obj, xs, OBS_SSS_ENTRY_STEPS, &e, rays)) return 0;
  if (jb->entry_count) {
    atomic_fetch_add_explicit(&jb->entry_count[0], 1, memory_order_relaxed);
    if (!e.converged)
      atomic_fetch_add_explicit(&jb->entry_count[e.stalled ? 2 : 1], 1, memory_order_relaxed);
  }
  if (e.stalled) return 0; /* no refracted path reaches xs */
  double n[3] = {-e.h.ns[0], -e.h.ns[1], -e.h.ns[2]};
  double ci = -obs_sss_dot(e.w, n), att = l->point ? 1.0 / (e.dist * e.dist) : 1.0;
  /* The entry point's own visibility of the light. */
  obs_rt_ctx c;
  float org[3], tl[3] = {(float)-e.w[0], (float)-e.w[1], (float)-e.w[2]};
  offset_side(rt, &e.h, -1.0f, org);
  ctx_leaving(&c, rt, &e.h, 0);
  (*rays)++;
  if (obs_rt_occluded(rt, &c, org, tl, l->point ? (float)e.dist : INFINITY)) return 0;
  double ft = obs_sss_schlick_t(ci, md->eta), si = e.h.t;
  for (int k = 0; k < 3; k++)
    light[k] = l->power[k] * att * ft * ci * exp(-md->sigma_t[k] * si);
  return obs_sss_hg(-obs_sss_dot(e.wi, t), md->g);
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
