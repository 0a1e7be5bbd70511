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
#include "driver.h"
#include "layout.h"
#include "obscura/render.h"
#include "parallel.h"
#include "sss_host.h"
#include "sss_job.h"

/* The scene's media per scene unit and its punctual lights in the ray tracer's frame; quad lights
 * are ignored with a warning. */
int obs_sss_job_setup(obs_render_ctx *ctx, sss_job *jb, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  jb->media = calloc(sc->nobjects ? sc->nobjects : 1, sizeof *jb->media);
  jb->has_medium = calloc(sc->nobjects ? sc->nobjects : 1, sizeof *jb->has_medium);
  jb->lights = calloc(sc->nlights ? sc->nlights : 1, sizeof *jb->lights);
  jb->nobjects = sc->nobjects;
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
    l->index = (int)i;
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

int obs_sss_maps_setup(sss_job *jb, obs_err *err) {
  double lo[3], hi[3];
  if (!media_box(jb, lo, hi))
    return obs_err_set(err, OBS_EINVAL,
                       "/objects: sss_single: no object with a medium has a surface to scatter "
                       "under (volume shapes are not rendered)");
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
                           "/lights/%d/position: sss_single's shadow_maps needs a point light "
                           "outside the bounding sphere of the medium objects, which one "
                           "light-view map must cover (method \"trace\" renders it)",
                           l->index);
      for (int k = 0; k < 3; k++) l->fwd[k] = d[k] / dist;
      l->half = tan(asin(r / dist)) * (1 + 1e-3);
    } else {
      memcpy(l->fwd, l->dir, sizeof l->fwd);
      l->half = r;
      l->back = sqrt(far2) * 2 + r;
    }
    basis(l->fwd, l->right, l->up);
  }
  return 0;
}

int obs_sss_maps_build(sss_job *jb, int threads, obs_err *err) {
  int rc = obs_sss_maps_setup(jb, err);
  for (int i = 0; i < jb->nlights && !rc; i++) {
    sss_light *l = &jb->lights[i];
    size_t n = (size_t)l->size * (size_t)l->size;
    l->pos_map = malloc(3 * n * sizeof(float));
    l->nrm_map = malloc(3 * n * sizeof(float));
    l->irr_map = malloc(3 * n * sizeof(float));
    l->id_map = malloc(n * sizeof(int32_t));
    if (!l->pos_map || !l->nrm_map || !l->irr_map || !l->id_map)
      return obs_err_set(err, OBS_ENOMEM, "sss_single: out of memory for %d x %d light-view maps",
                         l->size, l->size);
    map_job mj = {jb, l};
    rc = obs_parallel_tiles(l->size, l->size, threads, fill_tile, &mj, NULL, NULL, NULL);
    if (rc) return obs_err_set(err, rc, "sss_single: light-view map failed");
  }
  return rc;
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

/* ---- the host's part of a Vulkan run ------------------------------------------------------ */

struct obs_sss_host {
  obs_rt rt;
  sss_job jb;
  obs_camera_rig cam;
  int w, h;
  float *table;
  size_t rows;
};

static void put4(float *r, double a, double b, double c, double d) {
  r[0] = (float)a, r[1] = (float)b, r[2] = (float)c, r[3] = (float)d;
}

/* The parameter table as layout.h lays it out. */
static int pack(obs_sss_host *h, obs_err *err) {
  const sss_job *jb = &h->jb;
  size_t nobj = h->jb.nobjects;
  h->rows = nobj * OBS_SSS_OBJ_ROWS + (size_t)jb->nlights * OBS_SSS_LIGHT_ROWS;
  h->table = calloc(h->rows ? h->rows : 1, 4 * sizeof(float));
  if (!h->table) return obs_err_set(err, OBS_ENOMEM, "sss_single: out of memory");
  for (int l = 0; l < jb->nlights; l++) {
    const sss_light *L = &jb->lights[l];
    float *r = h->table + 4 * (nobj * OBS_SSS_OBJ_ROWS + (size_t)l * OBS_SSS_LIGHT_ROWS);
    put4(r, L->pos[0], L->pos[1], L->pos[2], L->point);
    put4(r + 4, L->dir[0], L->dir[1], L->dir[2], L->half);
    put4(r + 8, L->power[0], L->power[1], L->power[2], 0);
    put4(r + 12, L->centre[0], L->centre[1], L->centre[2], L->back);
    put4(r + 16, L->right[0], L->right[1], L->right[2], 0);
    put4(r + 20, L->up[0], L->up[1], L->up[2], 0);
    put4(r + 24, L->fwd[0], L->fwd[1], L->fwd[2], 0);
  }
  for (size_t o = 0; o < nobj; o++) {
    const sss_medium *m = &jb->media[o];
    float *r = h->table + 4 * o * OBS_SSS_OBJ_ROWS;
    put4(r, m->sigma_s[0], m->sigma_s[1], m->sigma_s[2], jb->has_medium[o]);
    put4(r + 4, m->sigma_t[0], m->sigma_t[1], m->sigma_t[2], m->sigma_min);
    put4(r + 8, m->g, m->eta, 0, 0);
  }
  return 0;
}

int obs_sss_host_open(obs_render_ctx *ctx, obs_sss_host **out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  obs_sss_host *h = calloc(1, sizeof *h);
  if (!h) return obs_err_set(err, OBS_ENOMEM, "%s: sss_single: out of memory", sc->name);
  *out = h;
  double t0 = obs_now_ms();
  int rc = obs_rt_build_ex(sc, &h->rt, ctx->threads, OBS_RT_FRAME_CAMERA, err);
  if (rc) {
    free(h);
    *out = NULL;
    return rc;
  }
  obs_driver_stage_add(ctx, "bvh", obs_now_ms() - t0);
  h->jb.p = *(const obs_sss_single_params *)ctx->bound;
  h->jb.rt = &h->rt;
  h->jb.spp = sc->spp;
  h->w = sc->width, h->h = sc->height;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &h->cam);
  rc = obs_sss_job_setup(ctx, &h->jb, err);
  if (!rc) rc = obs_sss_maps_setup(&h->jb, err);
  if (!rc) rc = pack(h, err);
  return rc;
}

void obs_sss_host_close(obs_sss_host *h) {
  if (!h) return;
  obs_sss_job_free(&h->jb);
  free(h->table);
  obs_rt_free(&h->rt);
  free(h);
}

int obs_sss_host_nlights(const obs_sss_host *h) { return h->jb.nlights; }
int obs_sss_host_nobjects(const obs_sss_host *h) { return (int)h->jb.nobjects; }
const obs_geometry *obs_sss_host_geometry(const obs_sss_host *h) { return &h->rt.geo; }

void obs_sss_host_light_rig(const obs_sss_host *h, int i, obs_camera_rig *rig) {
  const sss_light *l = &h->jb.lights[i];
  const double *o = h->rt.geo.origin;
  memset(rig, 0, sizeof *rig);
  rig->ortho = !l->point;
  rig->width = rig->height = l->size;
  rig->half_w = rig->half_h = l->half;
  for (int k = 0; k < 3; k++) {
    rig->origin[k] = (l->point ? l->pos[k] : l->centre[k] - l->back * l->fwd[k]) + o[k];
    rig->forward[k] = l->fwd[k];
    rig->right[k] = l->right[k];
    /* the maps' rows run up `up` (fill_tile), an image's rows down its rig's up */
    rig->up[k] = -l->up[k];
  }
}
const float *obs_sss_host_table(const obs_sss_host *h, size_t *rows) {
  *rows = h->rows;
  return h->table;
}

size_t obs_sss_host_hits(const obs_sss_host *h, int s, float *pos, float *nrm, float *dir,
                         float *alpha) {
  size_t rays = 0;
  for (int y = 0; y < h->h; y++)
    for (int x = 0; x < h->w; x++) {
      size_t i = (size_t)y * h->w + x;
      double org[3], d[3];
      obs_sss_sample_ray(&h->cam, h->jb.p.seed, h->jb.spp, x, y, s, org, d);
      obs_hit hit;
      rays++;
      put4(dir + 4 * i, d[0], d[1], d[2], 0);
      put4(pos + 4 * i, 0, 0, 0, -1);
      put4(nrm + 4 * i, 0, 0, 0, 0);
      if (!obs_rt_intersect(&h->rt, org, d, INFINITY, &hit)) continue;
      alpha[i] += 1;
      size_t obj = obs_rt_hit_object(&h->rt, hit.geom, hit.prim);
      if (!h->jb.has_medium[obj]) continue;
      put4(pos + 4 * i, hit.p[0], hit.p[1], hit.p[2], (double)obj);
      put4(nrm + 4 * i, hit.ns[0], hit.ns[1], hit.ns[2], 0);
    }
  return rays;
}
