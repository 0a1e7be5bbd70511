/* sss_single's light-view maps (ShaderX7 6.5, "subsurface-scatter maps") and the job both backends
 * share: each punctual light sees the scene through one map holding, per texel, the first
 * surface's position and object id, its normal, and the irradiance it transmits into a medium
 * (Eq. 6.5.4). The maps are filled by casting one ray per texel centre with Embree, which is what
 * a rasteriser of the same projection writes at its sample points; the CPU reads them in
 * cpu_maps.c, the Vulkan backend uploads them for sss_single.comp.glsl. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "obscura/render.h"
#include "parallel.h"
#include "sss_job.h"

/* The scene's media per scene unit and its punctual lights in the ray tracer's frame; quad lights
 * are ignored with a warning. */
int obs_sss_job_setup(obs_render_ctx *ctx, sss_job *jb, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  jb->media = calloc(sc->nobjects ? sc->nobjects : 1, sizeof *jb->media);
  jb->has_medium = calloc(sc->nobjects ? sc->nobjects : 1, sizeof *jb->has_medium);
  jb->lights = calloc(sc->nlights ? sc->nlights : 1, sizeof *jb->lights);
  if (!jb->media || !jb->has_medium || !jb->lights)
    return obs_err_set(err, OBS_ENOMEM, "%s: sss_single: out of memory", sc->name);
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_object *o = &sc->objects[i];
    if (!o->has_medium) continue;
    sss_medium *m = &jb->media[i];
    const obs_vec3 *av = &o->medium.sigma_a, *sv = &o->medium.sigma_s;
    const double a[3] = {av->x, av->y, av->z}, s[3] = {sv->x, sv->y, sv->z};
    m->sigma_min = INFINITY;
    for (int k = 0; k < 3; k++) {
      m->sigma_s[k] = s[k] / jb->p.unit_length;
      m->sigma_t[k] = (a[k] + s[k]) / jb->p.unit_length;
      m->sigma_min = fmin(m->sigma_min, m->sigma_t[k]);
    }
    m->g = o->medium.g;
    m->eta = o->medium.eta;
    jb->has_medium[i] = 1;
  }
  int quads = 0;
  for (size_t i = 0; i < sc->nlights; i++) {
    const obs_light *sl = &sc->lights[i];
    if (sl->type == OBS_LIGHT_QUAD) {
      quads++;
      continue;
    }
    sss_light *l = &jb->lights[jb->nlights++];
    l->point = sl->type == OBS_LIGHT_POINT;
    const double p[3] = {sl->position.x, sl->position.y, sl->position.z};
    const double dd[3] = {sl->direction.x, sl->direction.y, sl->direction.z};
    const double e[3] = {sl->emission.x, sl->emission.y, sl->emission.z};
    for (int k = 0; k < 3; k++) {
      l->pos[k] = p[k] - jb->rt->geo.origin[k];
      l->dir[k] = dd[k];
      l->power[k] = e[k];
    }
  }
  if (quads)
    obs_render_ctx_warn(ctx, "sss_single lights with point and directional lights only: %d quad "
                        "light%s ignored", quads, quads > 1 ? "s" : "");
  return 0;
}

void obs_sss_job_free(sss_job *jb) {
  for (int i = 0; i < jb->nlights; i++) {
    free(jb->lights[i].pos_map);
    free(jb->lights[i].nrm_map);
    free(jb->lights[i].irr_map);
    free(jb->lights[i].id_map);
  }
  free(jb->lights);
  free(jb->media);
  free(jb->has_medium);
}

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


void obs_sss_sample_ray(const obs_camera_rig *cam, uint32_t seed, int spp, int x, int y, int s,
                        double org[3], double dir[3]) {
  double jx = 0.5, jy = 0.5;
  if (spp > 1) {
    int g = (int)ceil(sqrt((double)spp));
    jx = (s % g + obs_sss_rand(obs_sss_key(seed, (uint32_t)x, (uint32_t)y, (uint32_t)s, ~0u))) / g;
    jy = (s / g + obs_sss_rand(obs_sss_key(seed, (uint32_t)x, (uint32_t)y, (uint32_t)s, ~1u))) / g;
  }
  obs_camera_ray(cam, x + jx, y + jy, org, dir);
  double dl = sqrt(obs_sss_dot(dir, dir));
  for (int k = 0; k < 3; k++) dir[k] /= dl;
}
