/* volume_ao on the CPU: isosurface ray casting of the scene's volumes with the RTPara report's
 * ray-marched ambient occlusion, bent normals and environment lighting.
 *
 * Each pixel sample's camera ray is mapped into every volume's data space (affine, so the ray
 * parameter is shared) and the nearest isosurface crossing wins. At the hit, `samples` cosine-
 * distributed directions about the gradient normal are marched in the data space of the volume
 * hit, and in every other volume along the same parameter, from `start` by `step` to
 * `max_distance`: a direction is occluded where any volume's field crosses its isovalue. The
 * per-pixel driver owns the image, tiles, threads, progress and cancellation. */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "environment.h"
#include "mcerr.h"
#include "obscura/render.h"
#include "sampling.h"
#include "simd.h"
#include "techniques.h"
#include "volume_ao.h"
#include "volume_march.h"
#include "volume_scene.h"

#define PI 3.14159265358979323846


typedef struct job {
  const obs_scene_volumes *vols;
  const obs_scene *scene;
  const obs_env *env; /* NULL: a constant white environment */
  double sh[9][3];    /* the environment's SH9 projection (ibl irradiance) */
  obs_camera_rig cam;
  obs_volume_ao_tparams p;
  obs_volume_ao_params march;
  int spp;
} job;

/* The nearest isosurface hit along org + t dir: the volume, t and the data-space point. */
typedef struct hit {
  size_t vol;
  double t, p[3];
} hit;

static obs_volume_iso iso_of(const obs_scene_volume *sv) {
  return (obs_volume_iso){&sv->v, &sv->cells, sv->iso, sv->sides.bits ? &sv->sides : NULL};
}

/* For a brick of the volume (obs_scene_volume.brick): the ray's parameter range [*t0, *t1] inside
 * the slab the render owns (clipped to the volume's box), 0 when it misses. A ray that enters the
 * slab through a side shared with the neighbouring brick, where the field is already at or above
 * iso, hits nothing here: the whole volume's ray was inside the surface before that side, so its
 * first hit lies in a brick nearer the eye (or at the volume's own face there), which reports it.
 * Counting it here would add a false surface along the seam behind the true one. */
static int owned_range(const obs_scene_volume *sv, const double o[3], const double d[3],
                       double *t0, double *t1) {
  int entered_open = 0;
  for (int a = 0; a < 3; a++) {
    double lo = 0, hi = sv->v.n[a] * sv->v.spacing[a];
    if (a == sv->axis) lo = sv->own[0], hi = sv->own[1];
    if (d[a] == 0) {
      if (o[a] < lo || o[a] > hi) return 0;
      continue;
    }
    double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
    int open_in = a == sv->axis && sv->open[d[a] > 0 ? 0 : 1];
    if (ta > tb) {
      double x = ta;
      ta = tb;
      tb = x;
    }
    if (ta > *t0) *t0 = ta, entered_open = open_in;
    if (tb < *t1) *t1 = tb;
  }
  if (!(*t0 <= *t1)) return 0;
  if (!entered_open) return 1;
  double p[3] = {o[0] + *t0 * d[0], o[1] + *t0 * d[1], o[2] + *t0 * d[2]};
  return obs_volume_sample(&sv->v, p) < sv->iso;
}

static int first_hit(const job *jb, const double org[3], const double dir[3], hit *h) {
  double best = INFINITY;
  int found = 0;
  for (size_t k = 0; k < jb->vols->n; k++) {
    const obs_scene_volume *sv = &jb->vols->v[k];
    double o[3], d[3], t, t0 = 0, t1 = best;
    obs_affine_point(sv->to_data, org, o);
    obs_affine_dir(sv->to_data, dir, d);
    if (sv->brick && !owned_range(sv, o, d, &t0, &t1)) continue;
    obs_volume_iso s = iso_of(sv);
    if (obs_volume_first_hit(&s, o, d, t0, t1, &t) && t < best) {
      best = t;
      found = 1;
      h->vol = k;
      h->t = t;
      for (int a = 0; a < 3; a++) h->p[a] = o[a] + t * d[a];
    }
  }
  return found;
}

static void normalize3(double v[3]) {
  double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 0 && isfinite(l))
    for (int a = 0; a < 3; a++) v[a] /= l;
}

static void env_radiance(const job *jb, const double w[3], double rgb[3]) {
  if (!jb->env) {
    rgb[0] = rgb[1] = rgb[2] = 1;
    return;
  }
  float d[3] = {(float)w[0], (float)w[1], (float)w[2]}, c[3];
  obs_env_lookup(jb->env, d, c);
  for (int k = 0; k < 3; k++) rgb[k] = c[k];
}

/* What the AO directions found at a hit. */
typedef struct ao_result {
  double ao, se;              /* AO and its standard error (replicates: sampling.h, mcerr.h) */
  double bent[3], env[3];     /* env: the mean of environment x visibility (ibl reference) */
} ao_result;

/* Marches the hit's directions (world normal n, data-space point h->p of volume h->vol). */
static void march_ao(const job *jb, const hit *h, const double n[3], uint32_t x, uint32_t y,
                     uint32_t s, ao_result *r) {
  const obs_scene_volume *va = &jb->vols->v[h->vol];
  size_t nv = jb->vols->n;
  double world[3];
  obs_affine_point(va->to_world, h->p, world);
  float nf[3] = {(float)n[0], (float)n[1], (float)n[2]}, t1[3], t2[3];
  obs_onb(nf, t1, t2);
  obs_rqmc smp;
  obs_rqmc_init(&smp, (obs_sampler_kind)jb->p.sampler, x, y, s, 1, jb->p.seed, jb->p.samples);
  double sum[3] = {0, 0, 0};
  memset(r, 0, sizeof *r);
  uint32_t open = 0, part = 0, first = 0, rep = 0;
  obs_mcerr e = {0};
  /* Directions are drawn a batch ahead of their marches: each one's chain (sampler, sincos, the
   * maps, a square root and divisions) is independent of the others and overlaps them. */
  enum { BATCH = 16 };
  double w[BATCH][3], da[BATCH][3];
  for (uint32_t i0 = 0; i0 < jb->p.samples; i0 += BATCH) {
    uint32_t nb = jb->p.samples - i0 < BATCH ? jb->p.samples - i0 : BATCH;
    float us[BATCH], vs[BATCH];
    obs_rqmc_get_n(&smp, i0, nb, us, vs, jb->march.isa);
    for (uint32_t q = 0; q < nb; q++) {
      float l[3];
      obs_sample_cosine(us[q], vs[q], l);
      for (int k = 0; k < 3; k++)
        w[q][k] = l[0] * (double)t1[k] + l[1] * (double)t2[k] + l[2] * n[k];
      obs_affine_dir(va->to_data, w[q], da[q]);
      normalize3(da[q]);
    }
    for (uint32_t q = 0; q < nb; q++) {
      int blocked = 0;
      /* The direction of the march's parameter in world space, for the other volumes. */
      double dw[3] = {0, 0, 0};
      if (nv > 1) obs_affine_dir(va->to_world, da[q], dw);
      for (size_t b = 0; b < nv && !blocked; b++) {
        const obs_scene_volume *vb = &jb->vols->v[b];
        obs_volume_iso is = iso_of(vb);
        if (b == h->vol) {
          blocked = obs_volume_grid_crossing(&is, h->p, da[q], &jb->march);
        } else { /* the same parameter t, carried through world space into b's data space */
          double ob[3], db[3];
          obs_affine_point(vb->to_data, world, ob);
          obs_affine_dir(vb->to_data, dw, db);
          blocked = obs_volume_grid_crossing(&is, ob, db, &jb->march);
        }
      }
      /* The replicate ends with this direction: its mean goes to the estimate. */
      uint32_t end = obs_rqmc_first(&smp, rep + 1);
      if (!blocked) part++;
      if (i0 + q + 1 == end) {
        obs_mcerr_add(&e, (double)part / (double)(i0 + q + 1 - first));
        part = 0, first = i0 + q + 1, rep++;
      }
      if (blocked) continue;
      open++;
      for (int k = 0; k < 3; k++) sum[k] += w[q][k];
      if (jb->p.ibl == OBS_IBL_REFERENCE) {
        double e[3];
        env_radiance(jb, w[q], e);
        for (int k = 0; k < 3; k++) r->env[k] += e[k];
      }
    }
  }
  r->ao = e.mean;
  r->se = obs_mcerr_stderr(&e, jb->p.samples, 1.0, 1);
  for (int k = 0; k < 3; k++) {
    r->env[k] /= jb->p.samples;
    r->bent[k] = sum[k];
  }
  if (open)
    normalize3(r->bent);
  else
    memcpy(r->bent, n, sizeof r->bent);
}

/* Direct light from the scene's point and directional lights at world point x with normal n,
 * seen along view direction v (toward the eye): diffuse irradiance / pi and the highlight. */
static void direct_light(const job *jb, const double x[3], const double n[3], const double v[3],
                         double diffuse[3], double spec[3]) {
  const obs_scene *sc = jb->scene;
  for (size_t i = 0; i < sc->nlights; i++) {
    const obs_light *li = &sc->lights[i];
    double l[3], e = 1;
    if (li->type == OBS_LIGHT_POINT) {
      l[0] = li->position.x - x[0], l[1] = li->position.y - x[1], l[2] = li->position.z - x[2];
      double d2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
      if (!(d2 > 0) || !isfinite(d2)) continue;
      e = 1 / d2;
      normalize3(l);
    } else if (li->type == OBS_LIGHT_DIRECTIONAL) {
      l[0] = -li->direction.x, l[1] = -li->direction.y, l[2] = -li->direction.z;
    } else {
      continue; /* quad lights: the run warns */
    }
    double ndl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
    if (!(ndl > 0)) continue;
    const double em[3] = {li->emission.x, li->emission.y, li->emission.z};
    double hl = 0;
    if (jb->p.blinn_phong) {
      double hv[3] = {l[0] + v[0], l[1] + v[1], l[2] + v[2]};
      normalize3(hv);
      double ndh = fmax(0, n[0] * hv[0] + n[1] * hv[1] + n[2] * hv[2]);
      hl = jb->p.specular * (jb->p.shininess + 8) / (8 * PI) * pow(ndh, jb->p.shininess);
    }
    for (int k = 0; k < 3; k++) {
      diffuse[k] += em[k] * e * ndl / PI;
      spec[k] += hl * em[k] * e * ndl;
    }
  }
}

/* The colour of the material just inside the surface: the colormap at the field one voxel in
 * from the hit, against the gradient (at the hit itself the field is the isovalue everywhere). */
static void albedo_at(const obs_scene_volume *sv, const double p[3], const double n_out[3],
                      double rgb[3]) {
  if (!sv->ncolormap) {
    rgb[0] = rgb[1] = rgb[2] = 1;
    return;
  }
  double h = fmin(sv->v.spacing[0], fmin(sv->v.spacing[1], sv->v.spacing[2]));
  double q[3] = {p[0] - h * n_out[0], p[1] - h * n_out[1], p[2] - h * n_out[2]};
  obs_scene_volume_color(sv, obs_volume_sample(&sv->v, q), rgb);
}

/* One pixel sample at a hit: the final colour and what it adds to the other channels. */
static void shade_hit(const job *jb, const hit *h, const double org[3], const double dir[3],
                      uint32_t x, uint32_t y, uint32_t s, double *acc, obs_mcerr_pixel *err) {
  const obs_scene_volume *sv = &jb->vols->v[h->vol];
  double nd[3], n[3];
  obs_volume_normal(&sv->v, h->p, nd);
  for (int i = 0; i < 3; i++)
    n[i] = sv->normal[i][0] * nd[0] + sv->normal[i][1] * nd[1] + sv->normal[i][2] * nd[2];
  normalize3(n);
  if (n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2] > 0)
    for (int i = 0; i < 3; i++) n[i] = -n[i];
  ao_result r;
  march_ao(jb, h, n, x, y, s, &r);
  double xw[3] = {org[0] + h->t * dir[0], org[1] + h->t * dir[1], org[2] + h->t * dir[2]};
  double v[3] = {-dir[0], -dir[1], -dir[2]}, diffuse[3] = {0, 0, 0}, spec[3] = {0, 0, 0};
  direct_light(jb, xw, n, v, diffuse, spec);
  double ibl[3] = {0, 0, 0};
  if (jb->p.ibl == OBS_IBL_BENT_NORMAL_LOOKUP) {
    env_radiance(jb, r.bent, ibl);
    for (int k = 0; k < 3; k++) ibl[k] *= r.ao;
  } else if (jb->p.ibl == OBS_IBL_IRRADIANCE) {
    float b[3] = {(float)r.bent[0], (float)r.bent[1], (float)r.bent[2]}, e[3] = {1, 1, 1};
    if (jb->env) obs_env_sh_irradiance(jb->sh, b, e);
    for (int k = 0; k < 3; k++) ibl[k] = r.ao * e[k];
  } else if (jb->p.ibl == OBS_IBL_REFERENCE) {
    memcpy(ibl, r.env, sizeof ibl);
  }
  double alb[3];
  albedo_at(sv, h->p, nd, alb);
  for (int k = 0; k < 3; k++) acc[CH_R + k] += alb[k] * (diffuse[k] + ibl[k]) + spec[k];
  acc[CH_AO] += r.ao;
  obs_mcerr_pixel_add(err, r.se);
  for (int k = 0; k < 3; k++) {
    acc[CH_BX + k] += r.bent[k];
    acc[CH_NX + k] += n[k];
  }
  double fwd =
      dir[0] * jb->cam.forward[0] + dir[1] * jb->cam.forward[1] + dir[2] * jb->cam.forward[2];
  acc[CH_DEPTH] += h->t * fwd;
  acc[CH_ALPHA] += 1;
}

static uint64_t shade_pixel(const void *user, int thread, int x, int y, float *d) {
  (void)thread;
  const job *jb = user;
  double acc[CH_COUNT] = {0};
  obs_mcerr_pixel err = {0};
  obs_sampler2d jit;
  obs_sampler2d_init(&jit, (obs_sampler_kind)jb->p.sampler, (uint32_t)x, (uint32_t)y, 0, 0,
                     jb->p.seed);
  for (int s = 0; s < jb->spp; s++) {
    float jx, jy;
    obs_sampler2d_pixel(&jit, jb->spp, (uint32_t)s, &jx, &jy);
    double org[3], dir[3];
    obs_camera_ray(&jb->cam, x + jx, y + jy, org, dir);
    hit h;
    if (!first_hit(jb, org, dir, &h)) {
      acc[CH_AO] += 1;
      continue;
    }
    shade_hit(jb, &h, org, dir, (uint32_t)x, (uint32_t)y, (uint32_t)s, acc, &err);
  }
  double hits = acc[CH_ALPHA];
  for (int k = CH_R; k <= CH_B; k++) d[k] = (float)(acc[k] / jb->spp);
  d[CH_AO] = (float)(acc[CH_AO] / jb->spp);
  d[CH_AOSE] = (float)obs_mcerr_pixel_stderr(&err, jb->spp);
  d[CH_ALPHA] = (float)(hits / jb->spp);
  d[CH_DEPTH] = hits ? (float)(acc[CH_DEPTH] / hits) : 0.0f;
  normalize3(acc + CH_BX);
  normalize3(acc + CH_NX);
  for (int k = 0; k < 3; k++) {
    d[CH_BX + k] = hits ? (float)acc[CH_BX + k] : 0.0f;
    d[CH_NX + k] = hits ? (float)acc[CH_NX + k] : 0.0f;
  }
  return (uint64_t)jb->spp + (uint64_t)hits * jb->p.samples;
}

static double shade_df(const void *user, int c) {
  (void)c;
  const job *jb = user;
  return jb->spp * (obs_rqmc_replicates((obs_sampler_kind)jb->p.sampler, jb->p.samples) - 1.0);
}

int obs_volume_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->volumes)
    return obs_err_set(err, OBS_EINTERNAL, "%s: volume_ao: the volumes were not read", sc->name);
  job jb;
  memset(&jb, 0, sizeof jb);
  jb.vols = ctx->volumes;
  jb.scene = sc;
  jb.env = ctx->environment;
  jb.p = *(const obs_volume_ao_tparams *)ctx->bound;
  jb.march = (obs_volume_ao_params){jb.p.samples,
                                    jb.p.start,
                                    jb.p.step,
                                    jb.p.max_distance,
                                    (obs_volume_crossing)jb.p.crossing,
                                    obs_simd_isa(),
                                    obs_simd_gather_loads()};
  jb.spp = sc->spp;
  if (jb.env && jb.p.ibl == OBS_IBL_IRRADIANCE) obs_env_sh9(jb.env, jb.sh);
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.cam);
  obs_volume_ao_warn(ctx, sc, &jb.p);
  static const obs_pixel_prior prior = {
      1,           obs_volume_ao_se, obs_volume_ao_value, CH_ALPHA,
      sizeof(job), offsetof(job, p) + offsetof(obs_volume_ao_tparams, seed), shade_df};
  static const obs_pixel_ops ops = {CH_COUNT, obs_volume_ao_channels, .shade = shade_pixel,
                                    .prior = &prior};
  return obs_driver_pixels(ctx, &ops, &jb, out, err);
}
