/* sss_single's light-view maps on the CPU (ShaderX7 6.5, "subsurface-scatter maps"): each punctual
 * light sees the scene through one map holding, per texel, the first surface's position and object
 * id, its normal, and the irradiance it transmits into a medium (Eq. 6.5.4). A pixel then walks M
 * path lengths along its refracted view ray and reads the light's entry point for each from the
 * maps (Listing 6.5.1). The maps are filled by casting one ray per texel centre, which is what a
 * rasteriser of the same projection writes. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "sss_cpu.h"

typedef struct map_job {
  sss_job *jb;
  sss_light *l;
} map_job;

static int fill_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const map_job *mj = user;
  const sss_job *jb = mj->jb;
  sss_light *l = mj->l;
  const double *o = jb->rt->geo.origin;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      double u = ((x + 0.5) / l->size * 2.0 - 1.0) * l->half;
      double v = ((y + 0.5) / l->size * 2.0 - 1.0) * l->half;
      double org[3], dir[3];
      for (int k = 0; k < 3; k++) {
        if (l->point) {
          org[k] = l->pos[k] + o[k];
          dir[k] = l->fwd[k] + u * l->right[k] + v * l->up[k];
        } else {
          org[k] = l->centre[k] - l->back * l->fwd[k] + u * l->right[k] + v * l->up[k] + o[k];
          dir[k] = l->fwd[k];
        }
      }
      double dl = sqrt(obs_sss_dot(dir, dir));
      for (int k = 0; k < 3; k++) dir[k] /= dl;
      size_t t = (size_t)y * (size_t)l->size + (size_t)x;
      obs_hit h;
      l->id_map[t] = -1;
      memset(l->irr_map + 3 * t, 0, 3 * sizeof(float));
      if (!obs_rt_intersect(jb->rt, org, dir, INFINITY, &h)) continue;
      size_t obj = obs_rt_hit_object(jb->rt, h.geom, h.prim);
      l->id_map[t] = (int32_t)obj;
      for (int k = 0; k < 3; k++) {
        l->pos_map[3 * t + k] = h.p[k];
        l->nrm_map[3 * t + k] = h.ns[k];
      }
      if (!jb->has_medium[obj]) continue;
      double n[3] = {h.ns[0], h.ns[1], h.ns[2]}, e = 1.0;
      if (l->point) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (h.p[k] - l->pos[k]) * (h.p[k] - l->pos[k]);
        e = 1.0 / d2;
      }
      double c = -obs_sss_dot(dir, n);
      if (!(c > 0)) continue;
      double ft = obs_sss_schlick_t(c, jb->media[obj].eta);
      for (int k = 0; k < 3; k++) l->irr_map[3 * t + k] = (float)(l->power[k] * e * ft * c);
    }
  return 0;
}

/* The box of the medium objects in the ray tracer's frame. */
static int media_box(const sss_job *jb, double lo[3], double hi[3]) {
  const obs_geometry *g = &jb->rt->geo;
  int any = 0;
  for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
  for (size_t m = 0; m < g->nmeshes; m++) {
    if (!jb->has_medium[g->meshes[m].object]) continue;
    for (size_t i = 0; i < g->meshes[m].nverts; i++)
      for (int k = 0; k < 3; k++) {
        double p = g->meshes[m].pos[3 * i + k];
        lo[k] = fmin(lo[k], p), hi[k] = fmax(hi[k], p);
      }
    any = 1;
  }
  for (size_t s = 0; s < g->nspheres; s++) {
    if (!jb->has_medium[g->spheres[s].object]) continue;
    for (int k = 0; k < 3; k++) {
      lo[k] = fmin(lo[k], g->spheres[s].center[k] - g->spheres[s].radius);
      hi[k] = fmax(hi[k], g->spheres[s].center[k] + g->spheres[s].radius);
    }
    any = 1;
  }
  return any;
}

static void basis(const double f[3], double r[3], double u[3]) {
  double a[3] = {0, 0, 0};
  a[fabs(f[0]) < 0.5 ? 0 : (fabs(f[1]) < 0.5 ? 1 : 2)] = 1;
  r[0] = f[1] * a[2] - f[2] * a[1], r[1] = f[2] * a[0] - f[0] * a[2],
  r[2] = f[0] * a[1] - f[1] * a[0];
  double l = sqrt(obs_sss_dot(r, r));
  for (int k = 0; k < 3; k++) r[k] /= l;
  u[0] = f[1] * r[2] - f[2] * r[1], u[1] = f[2] * r[0] - f[0] * r[2],
  u[2] = f[0] * r[1] - f[1] * r[0];
}

int obs_sss_maps_build(sss_job *jb, int threads, obs_err *err) {
  double lo[3], hi[3];
  if (!media_box(jb, lo, hi))
    return obs_err_set(err, OBS_EINVAL, "sss_single: no medium object has geometry");
  const double *sb0 = jb->rt->geo.bounds[0], *sb1 = jb->rt->geo.bounds[1];
  double centre[3], r2 = 0, far2 = 0;
  for (int k = 0; k < 3; k++) {
    centre[k] = 0.5 * (lo[k] + hi[k]);
    r2 += 0.25 * (hi[k] - lo[k]) * (hi[k] - lo[k]);
    double e = fmax(fabs(sb0[k] - centre[k]), fabs(sb1[k] - centre[k]));
    far2 += e * e;
  }
  double r = sqrt(r2) * (1 + 1e-3);
  for (int i = 0; i < jb->nlights; i++) {
    sss_light *l = &jb->lights[i];
    l->size = (int)jb->p.map_size;
    memcpy(l->centre, centre, sizeof centre);
    if (l->point) {
      double d[3], dist;
      for (int k = 0; k < 3; k++) d[k] = centre[k] - l->pos[k];
      dist = sqrt(obs_sss_dot(d, d));
      if (!(dist > r))
        return obs_err_set(err, OBS_EINVAL,
                           "sss_single: a point light lies within the bounding sphere of the "
                           "medium objects, which one light-view map cannot cover (method "
                           "\"trace\" renders it)");
      for (int k = 0; k < 3; k++) l->fwd[k] = d[k] / dist;
      l->half = tan(asin(r / dist)) * (1 + 1e-3);
    } else {
      memcpy(l->fwd, l->dir, sizeof l->fwd);
      l->half = r;
      l->back = sqrt(far2) * 2 + r;
    }
    basis(l->fwd, l->right, l->up);
    size_t n = (size_t)l->size * (size_t)l->size;
    l->pos_map = malloc(3 * n * sizeof(float));
    l->nrm_map = malloc(3 * n * sizeof(float));
    l->irr_map = malloc(3 * n * sizeof(float));
    l->id_map = malloc(n * sizeof(int32_t));
    if (!l->pos_map || !l->nrm_map || !l->irr_map || !l->id_map)
      return obs_err_set(err, OBS_ENOMEM, "sss_single: out of memory for %d x %d light-view maps",
                         l->size, l->size);
    map_job mj = {jb, l};
    int rc = obs_parallel_tiles(l->size, l->size, threads, fill_tile, &mj, NULL, NULL, NULL);
    if (rc) return obs_err_set(err, rc, "sss_single: light-view map failed");
  }
  return 0;
}

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
                const float p[3], const double t[3], uint32_t m, uint64_t key, double acc[3]) {
  int dim = 0;
  for (uint32_t k = 0; k < m; k++) {
    /* Deterministic sampling: xi_k at the midpoints of M strata (the article prints
     * xi_k = k 0.5 / M, which covers only xi <= 0.5), s_o' = -ln(xi_k) / sigma. */
    double xi = (k + 0.5) / m, so = -log(xi) / md->sigma_min, xs[3];
    for (int c = 0; c < 3; c++) xs[c] = p[c] + t[c] * so;
    double ju = 0, jv = 0;
    if (jb->p.jitter > 0) {
      ju = (2 * obs_sss_rand(key + 2 * k) - 1) * jb->p.jitter;
      jv = (2 * obs_sss_rand(key + 2 * k + 1) - 1) * jb->p.jitter;
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
    uint64_t key = obs_sss_key(jb->p.seed, px, py, s, (uint32_t)i) * 0x2545F4914F6CDD1Dull;
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
