/* obscurance_map on the CPU: the patches, the per-patch accumulation shared by the estimators, the
 * `rays` estimator (cosine rays from stratified points of each patch) and the run, which shows the
 * map per pixel. */
#include "obscurance_map_cpu.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "driver.h"
#include "normalize.h"
#include "halfball.h"
#include "mcerr.h"
#include "obscura/render.h"
#include "parallel.h"
#include "patch_ids.h"
#include "sampling.h"
#include "techniques.h"

void obs_omap_free(obs_omap *m) {
  if (!m) return;
  obs_patch_mesh_free(&m->pm);
  free(m->w);
  free(m->se);
  free(m->n);
  memset(m, 0, sizeof *m);
}

uint64_t obs_omap_global_count(const obs_obscurance_map_params *p) {
  if (p->lines) return p->lines;
  return (uint64_t)p->directions * p->bundle_resolution * p->bundle_resolution;
}

/* Halton point i of the patch's stream: the shared table turned by the stream's Cranley-Patterson
 * rotation, as obs_sampler2d_get computes it (the radical inverses are the costly part). */
static inline void halton_get(const obs_omap_job *j, const obs_sampler2d *s, uint32_t i, float *u,
                              float *v) {
  float a = j->halton[i][0] + obs_u32_to_unit(s->scramble0);
  float b = j->halton[i][1] + obs_u32_to_unit(s->scramble1);
  a -= a >= 1.0f ? 1.0f : 0.0f;
  b -= b >= 1.0f ? 1.0f : 0.0f;
  *u = a < 1.0f ? a : 0x1.fffffep-1f;
  *v = b < 1.0f ? b : 0x1.fffffep-1f;
}

/* What every ray of one patch shares, set up once per patch. */
typedef struct patch_frame {
  double c[3][3]; /* corners */
  float tb[2][3]; /* tangents of the unit normal from.ng */
  obs_hit from;   /* ng, perr, geom, prim: what obs_rt_offset and the context read */
  obs_rt_ctx ctx; /* skips the patch's own triangle */
  obs_sampler2d pts, dirs;
  uint32_t shuffle;
  int own_moving;  /* the patch is on a moving mesh */
  int hit_moving;  /* a sample met a moving mesh */
} patch_frame;

/* Records what a sample met for the update of moving objects: whether it was a moving mesh, and
 * which patch of a still mesh a moving patch's sample met. */
static void note_hit(const obs_omap_job *j, patch_frame *f, const struct RTCRayHit *rh) {
  const obs_mesh *m = &j->rt->geo.meshes[rh->hit.geomID];
  if (m->obj_pos) {
    f->hit_moving = 1;
  } else if (f->own_moving && j->seen) {
    int64_t q = obs_patch_mesh_find(j->pm, rh->hit.geomID, rh->hit.primID, rh->hit.u, rh->hit.v);
    atomic_store_explicit(&j->seen[q], 1, memory_order_relaxed);
  }
}

/* Sample i of a patch: a cosine-distributed ray from a stratified point. Returns the rays traced
 * (0 or 1). */
static uint64_t ray_sample(const obs_omap_job *j, obs_omap_acc *acc, patch_frame *f, uint32_t i) {
  float u1, v1, u2, v2;
  halton_get(j, &f->pts, i, &u1, &v1);
  /* The shuffle keeps the direction stream's stratification while decorrelating it from the
   * points' stream at the same index. */
  halton_get(j, &f->dirs, obs_sample_shuffle(i, f->shuffle) & j->halton_mask, &u2, &v2);
  /* Uniform on the triangle: (1 - s, s (1 - v), s v) with s = sqrt(u). */
  double s = sqrt((double)u1), w[3] = {1 - s, s * (1 - v1), s * v1};
  obs_hit from = f->from;
  for (int k = 0; k < 3; k++)
    from.p[k] = (float)(w[0] * f->c[0][k] + w[1] * f->c[1][k] + w[2] * f->c[2][k]);
  float org[3], l[3], dir[3];
  const float *n = f->from.ng;
  obs_rt_offset(j->rt, &from, org);
  obs_sample_cosine(u2, v2, l);
  for (int k = 0; k < 3; k++) dir[k] = l[0] * f->tb[0][k] + l[1] * f->tb[1][k] + l[2] * n[k];
  struct RTCRayHit rh;
  memset(&rh, 0, sizeof rh);
  rh.ray.org_x = org[0], rh.ray.org_y = org[1], rh.ray.org_z = org[2];
  rh.ray.dir_x = dir[0], rh.ray.dir_y = dir[1], rh.ray.dir_z = dir[2];
  rh.ray.tfar = isinf(j->f.d_max) ? INFINITY : (float)j->f.d_max;
  rh.ray.mask = ~0u;
  rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(j->rt->scene, &f->ctx.ctx, &rh);
  double v[3];
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
    obs_omap_value(j, INFINITY, NULL, v);
  } else {
    double nb[3];
    const float *r;
    if (rh.hit.geomID == j->rt->sphere_geom) {
      nb[0] = rh.hit.Ng_x, nb[1] = rh.hit.Ng_y, nb[2] = rh.hit.Ng_z;
      r = j->sphere_r[rh.hit.primID];
    } else {
      obs_omap_tri_normal(j->rt, rh.hit.geomID, rh.hit.primID, nb);
      r = j->mesh_r[rh.hit.geomID];
      if (j->hits_moving) note_hit(j, f, &rh);
    }
    /* Only a surface that faces the patch transfers; a back face eliminates the sample, as a
     * non-facing pair of hits does for the line estimators. */
    if (!(nb[0] * dir[0] + nb[1] * dir[1] + nb[2] * dir[2] < 0)) return 1;
    obs_omap_value(j, rh.ray.tfar, r, v);
  }
  obs_omap_add(acc, v);
  return 1;
}

/* Patch `patch`'s frame: corners, normal, tangents, the hit its rays leave and their context.
 * 0 for a patch without area or normal (no sample). */
static int patch_frame_init(const obs_omap_job *j, int64_t patch, patch_frame *f) {
  const obs_patch_mesh *pm = j->pm;
  int64_t sub;
  size_t t = obs_patch_mesh_owner(pm, patch, &sub);
  if (!(pm->area[patch] > 0)) return 0; /* degenerate: no normal, no sample */
  /* The mesh and primitive of scene triangle t. */
  size_t m = 0;
  while (pm->mesh_tri[m + 1] <= t) m++;
  unsigned prim = (unsigned)(t - pm->mesh_tri[m]);
  const obs_mesh *me = &j->rt->geo.meshes[m];
  const float *v[3];
  for (int k = 0; k < 3; k++) v[k] = me->pos + 3 * (size_t)me->idx[3 * (size_t)prim + (size_t)k];
  memset(f, 0, sizeof *f);
  double uv[3][2];
  obs_patch_sub_corners(pm->split[t], sub, uv);
  float mag = 0;
  for (int q = 0; q < 3; q++)
    for (int k = 0; k < 3; k++) {
      f->c[q][k] = v[0][k] + uv[q][0] * ((double)v[1][k] - v[0][k]) +
                   uv[q][1] * ((double)v[2][k] - v[0][k]);
      mag = fmaxf(mag, fabsf((float)f->c[q][k]));
    }
  double n[3];
  obs_omap_tri_normal(j->rt, (unsigned)m, prim, n);
  if (obs_normalize3d(n)) return 0;
  for (int k = 0; k < 3; k++) f->from.ng[k] = f->from.ns[k] = (float)n[k];
  obs_onb(f->from.ng, f->tb[0], f->tb[1]);
  /* A point is a convex combination of the corners rounded once: a few ulps of the largest
   * coordinate. */
  for (int k = 0; k < 3; k++) f->from.perr[k] = mag * 0x1p-21f;
  f->from.geom = (unsigned)m, f->from.prim = prim;
  f->own_moving = me->obj_pos != NULL;
  obs_rt_ctx_init(&f->ctx, j->rt, &f->from);
  return 1;
}

/* Whether no surface lies within d_max above the patch: then every ray from any of its points
 * escapes, its value is exact. Tested from its centroid over d_max plus its circumradius. */
static int patch_open(const obs_omap_job *j, int64_t patch) {
  patch_frame f;
  if (!patch_frame_init(j, patch, &f)) return 0;
  double r = 0;
  for (int k = 0; k < 3; k++) f.from.p[k] = (float)((f.c[0][k] + f.c[1][k] + f.c[2][k]) / 3);
  for (int q = 0; q < 3; q++) {
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (f.c[q][k] - f.from.p[k]) * (f.c[q][k] - f.from.p[k]);
    r = fmax(r, sqrt(d2));
  }
  float org[3];
  obs_rt_offset(j->rt, &f.from, org);
  obs_halfball h;
  const obs_halfball_need any = {.cover = 0}; /* whether anything is there, nothing more */
  obs_rt_halfball(j->rt, &f.from, org, isinf(j->f.d_max) ? INFINITY : (float)(j->f.d_max + r), &any,
                  &h);
  return isinf(h.nearest);
}

/* Every sample of one patch into acc (zeroed here), in replicates (sampling.h): each with its
 * own rotations of the points' and directions' Halton streams, its sums into the patch's groups
 * (mcerr.h's ratio over groups: the back faces a replicate meets leave it fewer samples). */
static uint64_t rays_patch(const obs_omap_job *j, int64_t patch, obs_omap_acc *acc) {
  memset(acc, 0, sizeof *acc);
  obs_mcerr_ratio *g = j->groups + 3 * (size_t)patch;
  memset(g, 0, 3 * sizeof *g);
  patch_frame f;
  if (!patch_frame_init(j, patch, &f)) return 0;
  uint32_t lo = (uint32_t)patch, hi = (uint32_t)((uint64_t)patch >> 32);
  /* Eight replicates: the pooling over a triangle's patches is coarser than a pixel's, so a
   * patch's own spread must carry more (with four, the two seeds' difference came out 0.75 of
   * the reported error on tests/unit/test_obscurance_agree.c's floor). */
  obs_rqmc pts, dirs;
  obs_rqmc_init_max(&pts, OBS_SAMPLER_HALTON, lo, hi, 0, 0, j->p.seed, j->p.samples, 8);
  obs_rqmc_init_max(&dirs, OBS_SAMPLER_HALTON, lo, hi, 0, 1, j->p.seed, j->p.samples, 8);
  uint64_t rays = 0;
  for (uint32_t r = 0; r < pts.reps; r++) {
    f.pts = pts.s[r], f.dirs = dirs.s[r];
    f.shuffle = obs_hash_combine(obs_hash_combine(j->p.seed + r, lo), hi ^ 0x5bd1e995U);
    obs_omap_acc before = *acc;
    uint32_t m = obs_rqmc_first(&pts, r + 1) - obs_rqmc_first(&pts, r);
    for (uint32_t i = 0; i < m; i++) rays += ray_sample(j, acc, &f, i);
    for (int c = 0; c < 3; c++)
      obs_mcerr_ratio_add(&g[c], (double)(acc->s[c] - before.s[c]) / OMAP_ONE,
                          (double)(acc->n - before.n));
  }
  if (j->hits_moving) j->hits_moving[patch] = (unsigned char)f.hit_moving;
  return rays;
}

int obs_omap_rays_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)y0, (void)y1;
  const obs_omap_job *j = user;
  int64_t n = j->list ? j->nlist : j->pm->count;
  uint64_t rays = 0;
  for (int64_t i = (int64_t)x0 * OMAP_RAYS_CHUNK; i < (int64_t)x1 * OMAP_RAYS_CHUNK && i < n;
       i++) {
    int64_t patch = j->list ? j->list[i] : i;
    rays += rays_patch(j, patch, &j->acc[patch]);
  }
  j->rays[(size_t)thread * 8] += rays;
  return 0;
}

/* Reflectivities per mesh and per sphere, from their objects' materials. */
static int job_reflectivities(obs_omap_job *j, const obs_scene *scene, obs_err *err) {
  const obs_geometry *g = &j->rt->geo;
  j->mesh_r = calloc(g->nmeshes ? g->nmeshes : 1, sizeof *j->mesh_r);
  j->sphere_r = calloc(g->nspheres ? g->nspheres : 1, sizeof *j->sphere_r);
  if (!j->mesh_r || !j->sphere_r)
    return obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory", scene->name);
  for (size_t k = 0; k < g->nmeshes + g->nspheres; k++) {
    int sphere = k >= g->nmeshes;
    size_t oi = sphere ? g->spheres[k - g->nmeshes].object : g->meshes[k].object;
    const obs_object *o = &scene->objects[oi];
    float *r = sphere ? j->sphere_r[k - g->nmeshes] : j->mesh_r[k];
    r[0] = o->has_material ? (float)o->reflectivity.x : 0.0f;
    r[1] = o->has_material ? (float)o->reflectivity.y : 0.0f;
    r[2] = o->has_material ? (float)o->reflectivity.z : 0.0f;
  }
  return 0;
}

/* Patch i's accumulated sums into its value and count in `out`, and what it knows of its error
 * into j->errs (pooled into out->se by obs_patch_mesh_errors). The rays and bundles estimators'
 * samples come in independent groups (replicates, groups of directions): the variance is their
 * spread (mcerr.h's ratio over groups). The global lines' are independent: each sample its own
 * group, from the sums of values and squares. When they all agree the floor is mcerr.h's, or 0
 * where no surface lies within d_max above the patch (its value is then exact). */
static void finish_patch(const obs_omap_job *j, obs_omap *out, int64_t i) {
  const int64_t count = j->pm->count;
  obs_omap_acc a;
  memset(&a, 0, sizeof a);
  for (int t = 0; t < j->acc_sets; t++) {
    const obs_omap_acc *b = &j->acc[(size_t)t * (size_t)count + (size_t)i];
    for (int c = 0; c < 3; c++) a.s[c] += b->s[c], a.q[c] += b->q[c];
    a.n += b->n;
  }
  const obs_mcerr_ratio *g = j->groups ? j->groups + 3 * (size_t)i : NULL;
  double n = g ? g[0].n : (double)a.n;
  obs_patch_err *e = &j->errs[i];
  out->n[i] = (uint64_t)n;
  *e = (obs_patch_err){{0, 0, 0}, n, 0, 0};
  if (!(n > 0)) {
    double v[3];
    obs_omap_value(j, INFINITY, NULL, v);
    for (int c = 0; c < 3; c++) out->w[3 * i + c] = (float)v[c];
    return;
  }
  for (int c = 0; c < 3; c++) {
    double w = g ? g[c].s / n : (double)a.s[c] / OMAP_ONE / n;
    out->w[3 * i + c] = (float)fmin(1.0, fmax(0.0, w));
    double v = g ? obs_mcerr_ratio_var(&g[c])
                 : fmax(0.0, (double)a.q[c] / OMAP_ONE / n - w * w) / (n > 1 ? n - 1 : 1);
    e->var[c] = v;
  }
  e->df = g ? g[0].groups - 1.0 : n - 1;
  /* A channel whose samples all agreed reports the floor, 0 where the patch is open. */
  if (!(e->var[0] > 0 && e->var[1] > 0 && e->var[2] > 0))
    e->floor = patch_open(j, i) ? 0.0f : (float)obs_mcerr_floor((uint32_t)fmin(n, 4e9), 1.0);
}

/* The accumulated sums of the patches sampled into `out`; the unsampled count of the whole map. */
static void finish(const obs_omap_job *j, obs_omap *out) {
  int64_t n = j->list ? j->nlist : j->pm->count;
  for (int64_t i = 0; i < n; i++) finish_patch(j, out, j->list ? j->list[i] : i);
  obs_patch_mesh_errors(j->pm, j->errs, out->se);
  out->unsampled = 0;
  for (int64_t i = 0; i < j->pm->count; i++) out->unsampled += !out->n[i] && j->pm->area[i] > 0;
}

/* The bundles, group by group of directions (obs_bundle_groups), one chunk per grid row of each
 * direction; after each group its per-thread sums are folded into every patch's groups and
 * cleared. */
static int run_bundles(obs_omap_job *j, const atomic_int *cancel, obs_progress_fn progress,
                       void *progress_user) {
  const int64_t count = j->pm->count;
  const uint32_t ng = obs_bundle_groups(j->p.directions);
  memset(j->groups, 0, 3 * (size_t)count * sizeof *j->groups);
  int rc = 0;
  for (uint32_t r = 0; r < ng && !rc; r++) {
    j->dir0 = obs_bundle_group_first(j->p.directions, r);
    uint32_t dirs = obs_bundle_group_first(j->p.directions, r + 1) - j->dir0;
    obs_progress_part pp = {progress, progress_user, (double)j->dir0 / j->p.directions,
                            (double)dirs / j->p.directions};
    rc = obs_parallel_tiles((int)(dirs * j->p.bundle_resolution), 1, j->threads,
                            obs_omap_bundle_tile, j, cancel,
                            progress ? obs_progress_part_report : NULL, &pp);
    for (int64_t i = 0; i < count && !rc; i++) {
      obs_omap_acc a;
      memset(&a, 0, sizeof a);
      for (int t = 0; t < j->acc_sets; t++) {
        obs_omap_acc *b = &j->acc[(size_t)t * (size_t)count + (size_t)i];
        for (int c = 0; c < 3; c++) a.s[c] += b->s[c];
        a.n += b->n;
        memset(b, 0, sizeof *b);
      }
      for (int c = 0; c < 3; c++)
        obs_mcerr_ratio_add(&j->groups[3 * (size_t)i + (size_t)c], (double)a.s[c] / OMAP_ONE,
                            (double)a.n);
    }
  }
  return rc;
}

static int run_estimator(obs_omap_job *j, const atomic_int *cancel, obs_progress_fn progress,
                         void *progress_user) {
  switch (j->p.method) {
    case OBS_OMAP_RAYS: {
      int64_t n = j->list ? j->nlist : j->pm->count;
      int64_t chunks = (n + OMAP_RAYS_CHUNK - 1) / OMAP_RAYS_CHUNK;
      if (!chunks) return 0;
      return obs_parallel_tiles((int)chunks, 1, j->threads, obs_omap_rays_tile, j, cancel, progress,
                                progress_user);
    }
    case OBS_OMAP_GLOBAL_LINES: {
      uint64_t chunks = (obs_omap_global_count(&j->p) + OMAP_GLOBAL_CHUNK - 1) / OMAP_GLOBAL_CHUNK;
      return obs_parallel_tiles((int)chunks, 1, j->threads, obs_omap_global_tile, j, cancel,
                                progress, progress_user);
    }
    default:
      return run_bundles(j, cancel, progress, progress_user);
  }
}

/* The rays estimator's table of Halton points. A stream with no rotation gives the bare radical
 * inverses. The shuffle maps the first 2^k indices onto an aligned block of 2^k: their low k bits
 * are a permutation of them, and the table covers the power of two at or above `samples`. */
static int halton_table(obs_omap_job *j) {
  obs_sampler2d bare = {.kind = OBS_SAMPLER_HALTON, .scramble0 = 0, .scramble1 = 0};
  uint32_t size = 1;
  while (size < j->p.samples) size *= 2;
  j->halton_mask = size - 1;
  if (!(j->halton = malloc((size_t)size * sizeof *j->halton))) return OBS_ENOMEM;
  for (uint32_t i = 0; i < size; i++) obs_sampler2d_get(&bare, i, &j->halton[i][0], &j->halton[i][1]);
  return 0;
}

int obs_omap_job_init(obs_omap_job *j, const obs_rt *rt, const obs_scene *scene,
                      const obs_obscurance_map_params *p, int threads, obs_omap *out,
                      obs_err *err) {
  memset(out, 0, sizeof *out);
  memset(j, 0, sizeof *j);
  j->rt = rt;
  j->p = *p;
  j->p.method = obs_omap_method_on(p->method, 0);
  j->f = (obs_falloff){.kind = p->falloff, .d_max = p->d_max, .tau = p->tau};
  j->threads = threads < 1 ? 1 : threads;
  obs_obscurance_env env;
  int rc = obs_obscurance_env_compute(scene, &rt->geo, &env, err);
  if (!rc)
    rc = obs_patch_mesh_build(&rt->geo, p->patch_size, "/technique/params/patch_size", &out->pm,
                              err);
  if (rc) return rc;
  memcpy(j->r_ave, env.r_ave, sizeof j->r_ave);
  memcpy(out->r_ave, env.r_ave, sizeof out->r_ave);
  j->pm = &out->pm;
  obs_bound_sphere_of(&rt->geo, &j->bs);
  size_t count = (size_t)out->pm.count, n1 = count ? count : 1;
  j->acc_sets = j->p.method == OBS_OMAP_RAYS ? 1 : j->threads;
  j->acc = calloc((size_t)j->acc_sets * n1, sizeof *j->acc);
  if (j->p.method != OBS_OMAP_GLOBAL_LINES) j->groups = calloc(3 * n1, sizeof *j->groups);
  j->rays = calloc((size_t)j->threads * 8, sizeof *j->rays);
  out->w = malloc(3 * n1 * sizeof *out->w);
  out->se = malloc(3 * n1 * sizeof *out->se);
  out->n = malloc(n1 * sizeof *out->n);
  if (!j->acc || !j->rays || !out->w || !out->se || !out->n ||
      (j->p.method != OBS_OMAP_GLOBAL_LINES && !j->groups))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory for %zu patches",
                     scene->name, count);
  if (!rc) rc = job_reflectivities(j, scene, err);
  if (!rc && !(j->errs = calloc(n1, sizeof *j->errs)))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory", scene->name);
  if (!rc && j->p.method == OBS_OMAP_RAYS && halton_table(j))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory", scene->name);
  if (rc) {
    obs_omap_job_free(j);
    obs_omap_free(out);
  }
  return rc;
}

int obs_omap_job_run(obs_omap_job *j, obs_omap *out, const atomic_int *cancel,
                     obs_progress_fn progress, void *progress_user) {
  if (j->p.method != OBS_OMAP_RAYS) { /* the line estimators sum into per-thread sets */
    j->list = NULL;
    memset(j->acc, 0, (size_t)j->acc_sets * (size_t)j->pm->count * sizeof *j->acc);
  }
  int rc = j->pm->count ? run_estimator(j, cancel, progress, progress_user) : 0;
  if (rc) return rc;
  finish(j, out);
  for (int t = 0; t < j->threads; t++) out->rays += j->rays[(size_t)t * 8];
  memset(j->rays, 0, (size_t)j->threads * 8 * sizeof *j->rays);
  return 0;
}

void obs_omap_job_free(obs_omap_job *j) {
  free(j->acc);
  free(j->groups);
  free(j->errs);
  free(j->rays);
  free(j->mesh_r);
  free(j->sphere_r);
  free(j->halton);
  memset(j, 0, sizeof *j);
}

int obs_omap_compute(const obs_rt *rt, const obs_scene *scene, const obs_obscurance_map_params *p,
                     int threads, const atomic_int *cancel, obs_progress_fn progress,
                     void *progress_user, obs_omap *out, obs_err *err) {
  obs_omap_job j;
  int rc = obs_omap_job_init(&j, rt, scene, p, threads, out, err);
  if (rc) return rc;
  rc = obs_omap_job_run(&j, out, cancel, progress, progress_user);
  if (rc == OBS_ECANCELED)
    obs_err_set(err, rc, "%s: render cancelled", scene->name);
  else if (rc)
    obs_err_set(err, rc, "%s: obscurance_map failed", scene->name);
  obs_omap_job_free(&j);
  if (rc) obs_omap_free(out);
  return rc;
}

/* ---- the run: the map, its patches file and its image ---- */

enum { CH_W, CH_SE, CH_R, CH_G, CH_B, CH_ALPHA, CH_COUNT };
static const char *const channel_names[CH_COUNT] = {"obscurance",       "obscurance_stderr",
                                                    "obscurance_rgb.R", "obscurance_rgb.G",
                                                    "obscurance_rgb.B", "alpha"};

/* The patch a primary hit on a mesh sees: its triangle's sub-triangle at the hit. */
static int64_t hit_patch(const void *user, const obs_rt *rt, const obs_hit *hit) {
  const obs_patch_mesh *pm = user;
  const obs_mesh *m = &rt->geo.meshes[hit->geom];
  const uint32_t *t = m->idx + 3 * (size_t)hit->prim;
  double u, v;
  obs_patch_barycentric(m->pos + 3 * t[0], m->pos + 3 * t[1], m->pos + 3 * t[2], hit->p, &u, &v);
  return obs_patch_mesh_find(pm, hit->geom, hit->prim, u, v);
}

static int show(obs_render_ctx *ctx, const obs_omap *m, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  obs_region region;
  int rc = obs_driver_image(ctx, CH_COUNT, channel_names, out, &region, err);
  if (rc) return rc;
  size_t npx = (size_t)sc->width * (size_t)sc->height;
  int32_t *ids = malloc(npx * sizeof *ids);
  if (!ids) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for pixel ids", sc->name);
  obs_patch_ids_map(ctx->rt, sc, hit_patch, &m->pm, ids);
  for (size_t i = 0; i < npx; i++) {
    int32_t id = ids[i];
    int ok = id >= 0 && id < m->pm.count;
    const float *w = ok ? m->w + 3 * (size_t)id : NULL;
    for (int c = 0; c < 3; c++) out->data[(size_t)(CH_R + c) * npx + i] = ok ? w[c] : 0.0f;
    out->data[(size_t)CH_W * npx + i] = ok ? (w[0] + w[1] + w[2]) / 3.0f : 0.0f;
    /* The image's W is the mean of the channels: the mean of their errors bounds its error. */
    const float *se = ok ? m->se + 3 * (size_t)id : NULL;
    out->data[(size_t)CH_SE * npx + i] = ok ? (se[0] + se[1] + se[2]) / 3.0f : 0.0f;
    out->data[(size_t)CH_ALPHA * npx + i] = ok ? 1.0f : 0.0f;
  }
  free(ids);
  obs_driver_clear_outside(out, &region);
  return 0;
}

int obs_obscurance_map_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: obscurance_map: no BVH was built for it", sc->name);
  const obs_obscurance_map_params *p = ctx->bound;
  double t0 = obs_now_ms();
  obs_omap m;
  int rc;
  if (sc->frames > 1) {
    /* The framework's BVH is the technique's to move: the frames place the moving meshes in it,
     * and the image shows the last frame. */
    rc = obs_omap_frames(ctx, (obs_rt *)ctx->rt, p, &m, err);
    if (rc) {
      obs_omap_free(&m);
      return rc;
    }
  } else {
    rc = obs_omap_compute(ctx->rt, sc, p, ctx->threads, ctx->cancel, ctx->progress,
                          ctx->progress_user, &m, err);
    if (rc) return rc;
  }
  double t1 = obs_now_ms();
  obs_driver_stage_add(ctx, sc->frames > 1 ? "frames" : "map", t1 - t0);
  if (sc->frames <= 1) {
    rc = obs_patch_mesh_publish(ctx, "obscurance", &m.pm, 3, m.w, err);
    if (!rc) rc = obs_patch_mesh_publish(ctx, "obscurance_stderr", &m.pm, 3, m.se, err);
  }
  if (!rc) rc = show(ctx, &m, out, err);
  double t2 = obs_now_ms();
  obs_driver_stage_add(ctx, "show", t2 - t1);
  ctx->render_ms += t2 - t0;
  ctx->rays += m.rays + (uint64_t)sc->width * (uint64_t)sc->height;
  if (!rc && m.unsampled)
    obs_render_ctx_warn(ctx,
                        "%lld of %lld patches received no sample and show \"nothing within "
                        "d_max\" (%s)",
                        (long long)m.unsampled, (long long)m.pm.count,
                        obs_omap_method_on(p->method, 0) == OBS_OMAP_RAYS
                            ? "every ray met the back of a surface"
                            : "no line met them, or only backs of surfaces; raise directions, "
                              "lines or bundle_resolution");
  if (!rc) obs_patch_mesh_warn_capped(ctx, &m.pm);
  if (!rc) obs_omap_warn_stderr(ctx, obs_omap_method_on(p->method, 0), p);
  obs_omap_free(&m);
  return rc;
}
