/* sss_single's light-view maps read on the CPU: a pixel walks M path lengths along its refracted
 * view ray and reads the light's entry point for each from the maps (Listing 6.5.1), with the
 * article's jitter and adaptive refinement. The maps themselves are sss_maps.c's. */
#include <math.h>
#include <string.h>

#include "sss_job.h"

/* The texel of frame point x in light l's map, jittered by (ju, jv) texels; -1 outside. */
static long texel(const sss_light *l, const double x[3], double ju, double jv) {
  double q[3], u, v;
  if (l->point) {
    for (int k = 0; k < 3; k++) q[k] = x[k] - l->pos[k];
    double z = obs_sss_dot(q, l->fwd);
    if (!(z > 0)) return -1;
    u = obs_sss_dot(q, l->right) / (z * l->half), v = obs_sss_dot(q, l->up) / (z * l->half);
  } else {
    for (int k = 0; k < 3; k++) q[k] = x[k] - l->centre[k];
    u = obs_sss_dot(q, l->right) / l->half, v = obs_sss_dot(q, l->up) / l->half;
  }
  double fx = (u + 1) * 0.5 * l->size + ju, fy = (v + 1) * 0.5 * l->size + jv;
  if (!(fx >= 0 && fy >= 0 && fx < l->size && fy < l->size)) return -1;
  return (long)fy * l->size + (long)fx;
}

/* Light l's M path samples (Listing 6.5.1) into acc (before the sigma_s F_t(o) / M factor);
 * returns how many were dim. */
static int walk(const sss_job *jb, const sss_light *l, const sss_medium *md, size_t obj,
                const float p[3], const double t[3], uint32_t m, const uint32_t key[4],
                double acc[3]) {
  int dim = 0;
  for (uint32_t k = 0; k < m; k++) {
    /* Deterministic sampling: xi_k at the midpoints of M strata (the article prints
     * xi_k = k 0.5 / M, which covers only xi <= 0.5), s_o' = -ln(xi_k) / sigma. */
    double xi = (k + 0.5) / m, so = -log(xi) / md->sigma_min, xs[3];
    for (int c = 0; c < 3; c++) xs[c] = p[c] + t[c] * so;
    double ju = 0, jv = 0;
    if (jb->p.jitter > 0) {
      ju = (2 * obs_sss_jitter_u(jb->p.seed, key[0], key[1], key[2], key[3], 2 * k) - 1) *
           jb->p.jitter;
      jv = (2 * obs_sss_jitter_u(jb->p.seed, key[0], key[1], key[2], key[3], 2 * k + 1) - 1) *
           jb->p.jitter;
    }
    long tx = texel(l, xs, ju, jv);
    if (tx < 0 || l->id_map[tx] != (int32_t)obj) {
      dim++;
      continue;
    }
    const float *xi_p = l->pos_map + 3 * tx, *ni = l->nrm_map + 3 * tx, *et = l->irr_map + 3 * tx;
    double d[3], wl[3], n[3] = {ni[0], ni[1], ni[2]}, si = 0, e = 1.0;
    for (int c = 0; c < 3; c++) d[c] = xs[c] - xi_p[c], si += d[c] * d[c];
    si = sqrt(si);
    if (l->point) {
      double dl = 0;
      for (int c = 0; c < 3; c++) wl[c] = xi_p[c] - l->pos[c], dl += wl[c] * wl[c];
      dl = sqrt(dl);
      for (int c = 0; c < 3; c++) wl[c] /= dl;
      e = 1.0 / (dl * dl);
    } else {
      memcpy(wl, l->dir, sizeof wl);
    }
    double ci = -obs_sss_dot(wl, n);
    double si_p = obs_sss_refracted_length(si, ci, md->eta), wi[3];
    obs_sss_refract(wl, n, md->eta, wi);
    double ph = obs_sss_hg(-obs_sss_dot(wi, t), md->g), light[3], full[3];
    for (int c = 0; c < 3; c++) {
      light[c] = et[c] * exp(-md->sigma_t[c] * si_p);
      full[c] = l->power[c] * e;
      /* exp(-sigma_t s_o') over the density sigma exp(-sigma s_o') the length was drawn from */
      acc[c] += ph * light[c] * exp(-(md->sigma_t[c] - md->sigma_min) * so) / md->sigma_min;
    }
    dim += obs_sss_lum(light) < OBS_SSS_DIM * obs_sss_lum(full);
  }
  return dim;
}

uint64_t obs_sss_maps_shade(const sss_job *jb, const obs_hit *hit, size_t obj, const double dir[3],
                            uint32_t px, uint32_t py, uint32_t s, double out[3], int *refined) {
  const sss_medium *md = &jb->media[obj];
  double n[3] = {hit->ns[0], hit->ns[1], hit->ns[2]}, t[3];
  double fto = obs_sss_schlick_t(obs_sss_dot(dir, n), md->eta);
  obs_sss_refract(dir, n, md->eta, t);
  uint64_t looks = 0;
  out[0] = out[1] = out[2] = 0;
  *refined = 0;
  for (int i = 0; i < jb->nlights; i++) {
    const sss_light *l = &jb->lights[i];
    uint32_t m = jb->p.samples;
    const uint32_t key[4] = {px, py, s, (uint32_t)i};
    double acc[3] = {0, 0, 0};
    int dim = walk(jb, l, md, obj, hit->p, t, m, key, acc);
    looks += m;
    double share = (double)dim / m;
    if (jb->p.adaptive && share >= OBS_SSS_DIM_LO && share <= OBS_SSS_DIM_HI) {
      /* a shadow boundary: the walk again with twice the samples */
      m *= 2;
      acc[0] = acc[1] = acc[2] = 0;
      walk(jb, l, md, obj, hit->p, t, m, key, acc);
      looks += m;
      *refined = 1;
    }
    for (int c = 0; c < 3; c++) out[c] += md->sigma_s[c] * fto * acc[c] / m;
  }
  return looks;
}
