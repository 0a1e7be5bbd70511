/* The emitter table of the CPU techniques' direct light (emitters.h): gathering, choice by power,
 * uniform points in area and their solid-angle densities. */
#include "emitters.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static void vec3(const obs_vec3 *v, double o[3]) { o[0] = v->x, o[1] = v->y, o[2] = v->z; }
static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
#define mean3 obs_emitters_mean3

/* A triangle emitter from world-space corners (moved into the frame at `origin`); 0 when it has
 * no area. */
static int tri_emitter(obs_emitter *e, const double w[3][3], const double origin[3],
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

/* The emissive objects' triangles and spheres, appended at out->em[*n]. */
static void add_objects(const obs_scene *sc, const obs_geometry *g, obs_emitters *out, size_t *n) {
  double le[3];
  for (size_t i = 0; i < g->nmeshes; i++) {
    const obs_mesh *m = &g->meshes[i];
    vec3(&sc->objects[m->object].emission, le);
    if (!(mean3(le) > 0)) continue;
    for (size_t t = 0; t < m->ntris; t++) {
      double w[3][3];
      for (int c = 0; c < 3; c++)
        for (int k = 0; k < 3; k++) w[c][k] = (double)m->pos[3 * m->idx[3 * t + c] + k];
      const double zero[3] = {0, 0, 0};
      *n += tri_emitter(&out->em[*n], w, zero, le, 1);
    }
  }
  for (size_t i = 0; i < g->nspheres; i++) {
    const obs_sphere *s = &g->spheres[i];
    vec3(&sc->objects[s->object].emission, le);
    if (!(mean3(le) > 0)) continue;
    obs_emitter *e = &out->em[*n];
    memset(e, 0, sizeof *e);
    memcpy(e->a, s->center, sizeof e->a);
    memcpy(e->le, le, sizeof e->le);
    e->r = s->radius;
    e->area = 4.0 * M_PI * s->radius * s->radius;
    e->sphere = e->two_sided = 1;
    *n += e->area > 0 && isfinite(e->area);
  }
}

int obs_emitters_build(const obs_scene *sc, const obs_rt *rt, obs_emitters *out, obs_err *err) {
  const obs_geometry *g = &rt->geo;
  memset(out, 0, sizeof *out);
  size_t cap = 2 * sc->nlights + g->nspheres;
  double le[3];
  for (size_t i = 0; i < g->nmeshes; i++) {
    vec3(&sc->objects[g->meshes[i].object].emission, le);
    if (mean3(le) > 0) cap += g->meshes[i].ntris;
  }
  out->em = calloc(cap ? cap : 1, sizeof *out->em);
  out->cdf = calloc(cap ? cap : 1, sizeof *out->cdf);
  if (!out->em || !out->cdf)
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
      n += tri_emitter(&out->em[n], w, g->origin, le, 0);
    }
  }
  out->nquad = n;
  add_objects(sc, g, out, &n);
  out->n = n;
  double sum = 0;
  for (size_t i = 0; i < n; i++) {
    sum += out->em[i].area * mean3(out->em[i].le);
    out->cdf[i] = sum;
  }
  out->total = sum;
  if (n && !(sum > 0 && isfinite(sum)))
    return obs_err_set(err, OBS_EINVAL, "%s: emitted power %g is not finite and positive", sc->name,
                       sum);
  for (size_t i = 0; i < n; i++) out->cdf[i] /= sum;
  return 0;
}

void obs_emitters_free(obs_emitters *em) {
  free(em->em);
  free(em->cdf);
  memset(em, 0, sizeof *em);
}

const obs_emitter *obs_emitters_point(const obs_emitters *em, const double u[3], double q[3],
                                      double nl[3]) {
  size_t lo = 0, hi = em->n - 1;
  while (lo < hi) {
    size_t mid = (lo + hi) / 2;
    if (em->cdf[mid] > u[0])
      hi = mid;
    else
      lo = mid + 1;
  }
  const obs_emitter *e = &em->em[lo];
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
  return e;
}

int obs_emitters_sample(const obs_emitters *em, const obs_hit *hit, const double u[3],
                        obs_emitter_sample *s) {
  double q[3], nl[3];
  const obs_emitter *e = obs_emitters_point(em, u, q, nl);
  double *wi = s->wi;
  for (int k = 0; k < 3; k++) wi[k] = q[k] - hit->p[k];
  double d2 = dot3(wi, wi), dist = sqrt(d2);
  if (!(dist > 0) || !isfinite(d2)) return 0;
  for (int k = 0; k < 3; k++) wi[k] /= dist;
  double ng[3] = {hit->ng[0], hit->ng[1], hit->ng[2]}, ns[3] = {hit->ns[0], hit->ns[1], hit->ns[2]};
  double coss = dot3(ns, wi), cosl = -dot3(nl, wi);
  if (e->two_sided) cosl = fabs(cosl);
  if (!(coss > 0) || !(dot3(ng, wi) > 0) || !(cosl > 0)) return 0;
  double pdf_l = mean3(e->le) / em->total * d2 / cosl;
  if (!(pdf_l > 0) || !isfinite(pdf_l)) return 0;
  s->e = e, s->dist = dist, s->coss = coss, s->pdf = pdf_l;
  return 1;
}

double obs_emitter_tri_hit(const obs_emitter *e, const double o[3], const double d[3]) {
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
