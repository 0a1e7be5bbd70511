/* ibl_shadows on the CPU: orthographic shadow maps ray cast with Embree along the
 * importance-sampled directions, the per-pixel least-squares SH fit of visibility x cosine over
 * the G-buffer's texels, the article's 9 x 9 normal-weighted blur in screen space, and the
 * diffuse shading SH visibility . environment SH (docs/techniques/ibl_shadows.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "ibl_shadows.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"
#include "screen.h"
#include "techniques.h"

typedef struct ibl_job {
  const obs_rt *rt;
  const obs_gbuffer *g;
  const obs_env *env;
  const obs_ibl_setup *s;
  obs_camera_rig rig;
  double centre[3];             /* world centre of the scene's bounding sphere */
  double eye[3];                /* the camera's origin relative to the centre */
  double radius, start;         /* the sphere's radius; the maps' plane sits at start along dir */
  double axis[OBS_IBL_MAX_MAPS][2][3]; /* each map's texel axes, orthogonal to its direction */
  int size;
  double bias;                  /* in texels */
  float *maps;                  /* m size x size: distance from the plane to the first hit */
  float *raw, *tmp, *res;       /* n coefficients per pixel */
  const float *src;
  float *dst;
  int horizontal;
  float *ao, *ao_raw, *extra;
} ibl_job;

static double dot3(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Two unit axes orthogonal to unit d (Duff et al. 2017, branch-free and continuous but at one
 * sign flip). */
static void frame_of(const double d[3], double t[3], double b[3]) {
  double s = d[2] >= 0 ? 1.0 : -1.0, a = -1.0 / (s + d[2]), c = d[0] * d[1] * a;
  t[0] = 1 + s * d[0] * d[0] * a, t[1] = s * c, t[2] = -s * d[0];
  b[0] = c, b[1] = s + d[1] * d[1] * a, b[2] = -d[1];
}

/* One shadow-map row per image row: the image is size wide and m size high. */
static int map_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const ibl_job *j = user;
  const int S = j->size;
  for (int y = y0; y < y1; y++) {
    int m = y / S, row = y % S;
    const double *d = j->s->dir[m], *t = j->axis[m][0], *b = j->axis[m][1];
    double ty = ((row + 0.5) / S * 2 - 1) * j->radius;
    const double dir[3] = {-d[0], -d[1], -d[2]};
    for (int x = x0; x < x1; x++) {
      double tx = ((x + 0.5) / S * 2 - 1) * j->radius, org[3];
      for (int k = 0; k < 3; k++) org[k] = j->centre[k] + d[k] * j->start + tx * t[k] + ty * b[k];
      obs_hit hit;
      float depth = INFINITY;
      if (obs_rt_intersect(j->rt, org, dir, INFINITY, &hit)) depth = hit.t;
      j->maps[((size_t)m * (size_t)S + (size_t)row) * (size_t)S + (size_t)x] = depth;
    }
  }
  return 0;
}

/* World position (relative to the centre) and world normal of G-buffer pixel i at (x, y). */
static void pixel_world(const ibl_job *j, int x, int y, size_t i, double q[3], double nw[3]) {
  const obs_gbuffer *g = j->g;
  float pv[3];
  obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, g->depth[i], pv);
  const float *nv = g->normal + 3 * i;
  for (int k = 0; k < 3; k++) {
    q[k] = j->eye[k] + pv[0] * j->rig.right[k] + pv[1] * j->rig.up[k] + pv[2] * j->rig.forward[k];
    nw[k] = nv[0] * j->rig.right[k] + nv[1] * j->rig.up[k] + nv[2] * j->rig.forward[k];
  }
}

/* The shadow test of receiver q (relative to the centre) with cosine c to map m: 1 lit, 0 not.
 * The depth bias grows with the slope (tan of the angle to the direction, at most 10). */
static int lit(const ibl_job *j, int m, const double q[3], double c) {
  const int S = j->size;
  double u = (dot3(q, j->axis[m][0]) / j->radius + 1) * 0.5 * S;
  double v = (dot3(q, j->axis[m][1]) / j->radius + 1) * 0.5 * S;
  if (!(u >= 0 && u < S && v >= 0 && v < S)) return 1;
  float occ = j->maps[((size_t)m * (size_t)S + (size_t)v) * (size_t)S + (size_t)u];
  double z = j->start - dot3(q, j->s->dir[m]);
  double slope = c < 0.0995 ? 10.0 : sqrt(1 - c * c) / c;
  return z <= occ + j->bias * (2 * j->radius / S) * (1 + slope);
}

static int fit_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const ibl_job *j = user;
  const obs_ibl_setup *s = j->s;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)j->g->width + (size_t)x;
      float *w = j->raw + i * (size_t)s->n;
      for (int k = 0; k < s->n; k++) w[k] = 0.0f;
      if (!(j->g->depth[i] > 0.0f)) continue;
      double q[3], nw[3];
      pixel_world(j, x, y, i, q, nw);
      float b[OBS_IBL_MAX_MAPS];
      for (int m = 0; m < s->m; m++) {
        double c = dot3(nw, s->dir[m]);
        b[m] = c > 0 && lit(j, m, q, c) ? (float)c : 0.0f;
      }
      for (int k = 0; k < s->n; k++) {
        float acc = 0.0f;
        for (int m = 0; m < s->m; m++) acc += s->yplus[k][m] * b[m];
        w[k] = acc;
      }
    }
  return 0;
}

/* The article's 1D window exp(-i^2 / 10), i = -4..4, times max(0, n_i . n_centre), normalised;
 * one axis per pass. Uncovered pixels neither give nor take. */
static int blur_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const ibl_job *j = user;
  const obs_gbuffer *g = j->g;
  const int n = j->s->n, W = g->width, H = g->height;
  float gw[9];
  for (int i = -4; i <= 4; i++) gw[i + 4] = expf(-(float)(i * i) / 10.0f);
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t c = (size_t)y * (size_t)W + (size_t)x;
      float *o = j->dst + c * (size_t)n;
      for (int k = 0; k < n; k++) o[k] = 0.0f;
      if (!(g->depth[c] > 0.0f)) continue;
      const float *nc = g->normal + 3 * c;
      float acc[OBS_SH_MAX_COEFFS] = {0}, total = 0.0f;
      for (int t = -4; t <= 4; t++) {
        int xx = j->horizontal ? x + t : x, yy = j->horizontal ? y : y + t;
        if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
        size_t q = (size_t)yy * (size_t)W + (size_t)xx;
        if (!(g->depth[q] > 0.0f)) continue;
        const float *nq = g->normal + 3 * q;
        float a = nq[0] * nc[0] + nq[1] * nc[1] + nq[2] * nc[2];
        float wt = gw[t + 4] * (a > 0.0f ? a : 0.0f);
        if (!(wt > 0.0f)) continue;
        const float *v = j->src + q * (size_t)n;
        for (int k = 0; k < n; k++) acc[k] += wt * v[k];
        total += wt;
      }
      for (int k = 0; k < n; k++) o[k] = total > 0.0f ? acc[k] / total : 0.0f;
    }
  return 0;
}

static int shade_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const ibl_job *j = user;
  const obs_gbuffer *g = j->g;
  const size_t N = (size_t)g->width * (size_t)g->height;
  const int n = j->s->n;
  float *ex[OBS_IBL_EXTRA];
  for (int k = 0; k < OBS_IBL_EXTRA; k++) ex[k] = j->extra + (size_t)k * N;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      float rgb[3], ao, aor, bent[3], bent_raw[3];
      if (!(g->depth[i] > 0.0f)) {
        /* The background shows the environment, as path_trace's misses do. */
        double org[3], dir[3];
        obs_camera_ray(&j->rig, x + 0.5, y + 0.5, org, dir);
        float fd[3] = {(float)dir[0], (float)dir[1], (float)dir[2]};
        obs_env_lookup(j->env, fd, rgb);
        ao = aor = 1.0f;
        bent[0] = bent[1] = bent[2] = 0.0f;
      } else {
        double q[3], nw[3];
        pixel_world(j, x, y, i, q, nw);
        float nf[3] = {(float)nw[0], (float)nw[1], (float)nw[2]}, rgb_raw[3];
        obs_ibl_shade(j->s, j->res + i * (size_t)n, g->albedo + 3 * i, nf, rgb, &ao, bent);
        obs_ibl_shade(j->s, j->raw + i * (size_t)n, g->albedo + 3 * i, nf, rgb_raw, &aor,
                      bent_raw);
      }
      j->ao[i] = ao;
      j->ao_raw[i] = aor;
      for (int k = 0; k < 3; k++) {
        ex[OBS_IBL_RADIANCE + k][i] = rgb[k];
        ex[OBS_IBL_BENT + k][i] = bent[k];
      }
    }
  return 0;
}

/* Where the maps look from: the bounding sphere of the geometry (world), the plane 1.5 radii out. */
static void place_maps(ibl_job *j, const obs_scene *sc) {
  const obs_geometry *geo = &j->rt->geo;
  double r2 = 0;
  for (int k = 0; k < 3; k++) {
    double h = 0.5 * (geo->bounds[1][k] - geo->bounds[0][k]);
    j->centre[k] = geo->origin[k] + 0.5 * (geo->bounds[0][k] + geo->bounds[1][k]);
    r2 += h * h;
  }
  j->radius = sqrt(r2) > 0 ? sqrt(r2) : 1e-30;
  j->start = 1.5 * j->radius;
  obs_camera_setup(&sc->camera, j->g->width, j->g->height, &j->rig);
  for (int k = 0; k < 3; k++) j->eye[k] = j->rig.origin[k] - j->centre[k];
  for (int m = 0; m < j->s->m; m++) frame_of(j->s->dir[m], j->axis[m][0], j->axis[m][1]);
}

static int ibl_passes(obs_screen_cpu *r, const obs_scene *sc, const obs_rt *rt,
                      const obs_env *env, const obs_gbuffer *g, const obs_ibl_shadows_params *p,
                      float *ao, float *ao_raw, float *extra, double *stage_ms, obs_err *err) {
  double st[OBS_IBL_CPU_STAGES] = {0, 0, 0, 0};
  if (!sc || !rt || !g || !p || !ao || !ao_raw || !extra)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: missing scene, BVH, G-buffer or output");
  if (p->map_size < 1 || p->sh_order < 1 || p->sh_order > OBS_SH_MAX_BANDS)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: map_size %d or sh_order %d out of range",
                       p->map_size, p->sh_order);
  obs_ibl_setup *s = malloc(sizeof *s);
  if (!s) return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: out of memory");
  double t0 = obs_now_ms();
  int rc = obs_ibl_setup_make(env, p, s, err);
  if (rc) {
    free(s);
    return rc;
  }
  const size_t N = (size_t)g->width * (size_t)g->height, S = (size_t)p->map_size;
  ibl_job j = {.rt = rt, .g = g, .env = env, .s = s, .size = p->map_size, .bias = p->bias,
               .ao = ao, .ao_raw = ao_raw, .extra = extra};
  j.maps = malloc(S * S * (size_t)s->m * sizeof *j.maps);
  j.raw = malloc(N * (size_t)s->n * 3 * sizeof *j.raw);
  if (!j.maps || !j.raw) {
    free(j.maps), free(j.raw), free(s);
    return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: %d maps of %d^2, %dx%d: out of memory",
                       p->shadow_maps, p->map_size, g->width, g->height);
  }
  j.tmp = j.raw + N * (size_t)s->n;
  j.res = j.tmp + N * (size_t)s->n;
  place_maps(&j, sc);
  r->passes = p->blur ? 5 : 3;
  rc = obs_screen_cpu_tiles(r, p->map_size, p->map_size * s->m, map_tile, &j);
  double t1 = obs_now_ms();
  if (!rc) rc = obs_screen_cpu_tiles(r, g->width, g->height, fit_tile, &j);
  double t2 = obs_now_ms();
  if (!rc && p->blur) {
    j.src = j.raw, j.dst = j.tmp, j.horizontal = 1;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, blur_tile, &j);
    j.src = j.tmp, j.dst = j.res, j.horizontal = 0;
    if (!rc) rc = obs_screen_cpu_tiles(r, g->width, g->height, blur_tile, &j);
  } else if (!rc) {
    memcpy(j.res, j.raw, N * (size_t)s->n * sizeof *j.raw);
  }
  double t3 = obs_now_ms();
  if (!rc) rc = obs_screen_cpu_tiles(r, g->width, g->height, shade_tile, &j);
  st[0] = t1 - t0, st[1] = t2 - t1, st[2] = t3 - t2, st[3] = obs_now_ms() - t3;
  if (stage_ms) memcpy(stage_ms, st, sizeof st);
  free(j.maps), free(j.raw), free(s);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ibl_shadows: CPU passes failed");
  return rc;
}

int obs_ibl_shadows_cpu_apply(const obs_scene *sc, const obs_rt *rt, const obs_env *env,
                              const obs_gbuffer *g, const obs_ibl_shadows_params *p, int threads,
                              float *ao, float *ao_raw, float *extra, double *stage_ms,
                              obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return ibl_passes(&r, sc, rt, env, g, p, ao, ao_raw, extra, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, float *extra, obs_err *err) {
  obs_render_ctx *ctx = r->ctx;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: ibl_shadows: no BVH was built", ctx->scene->name);
  /* A scene without an environment is lit by a black one: radiance 0, and the ao and bent normal
   * still come, from directions uniform over the sphere (obs_ibl_setup_make). */
  obs_env dark;
  memset(&dark, 0, sizeof dark);
  const obs_env *env = ctx->environment;
  if (!env) {
    const double zero[3] = {0, 0, 0};
    int rc = obs_env_constant(&dark, zero, err);
    if (rc) return rc;
    env = &dark;
  }
  double st[OBS_IBL_CPU_STAGES];
  int rc = ibl_passes(r, ctx->scene, ctx->rt, env, g, params, ao, ao_raw, extra, st, err);
  obs_env_free(&dark);
  if (!rc) {
    obs_screen_cpu_stage(r, "shadow_maps", st[0]);
    obs_screen_cpu_stage(r, "fit", st[1]);
    if (((const obs_ibl_shadows_params *)params)->blur) obs_screen_cpu_stage(r, "blur", st[2]);
    obs_screen_cpu_stage(r, "shade", st[3]);
  }
  return rc;
}

static const obs_screen_extra ibl_extra = {OBS_IBL_EXTRA, obs_ibl_shadows_extra_names};

int obs_ibl_shadows_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run_ex(ctx, passes, &ibl_extra, ctx->bound, out, err);
}
