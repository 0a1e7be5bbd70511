/* ibl_shadows' host work shared by both backends: where the shadow maps look from, the CPU's
 * maps ray cast with Embree (the Vulkan backend rasterises its own, vulkan.c), the fit's push
 * block and table, and the shading of the fitted coefficients into the outputs
 * (docs/techniques/ibl_shadows.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ibl_shadows.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"

void obs_ibl_blur_weights(float w[9]) {
  for (int i = -4; i <= 4; i++) w[i + 4] = expf(-(float)(i * i) / 10.0f);
}

/* Two unit axes orthogonal to unit d (Duff et al. 2017). */
static void frame_of(const double d[3], double t[3], double b[3]) {
  double s = d[2] >= 0 ? 1.0 : -1.0, a = -1.0 / (s + d[2]), c = d[0] * d[1] * a;
  t[0] = 1 + s * d[0] * d[0] * a, t[1] = s * c, t[2] = -s * d[0];
  b[0] = c, b[1] = s + d[1] * d[1] * a, b[2] = -d[1];
}

typedef struct map_job {
  obs_ibl_frame *f;
  const obs_rt *rt;
} map_job;

/* One shadow-map row per image row of a size x (m size) image: orthographic rays from the maps'
 * plane against the direction. */
static int map_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const map_job *j = user;
  obs_ibl_frame *f = j->f;
  const int S = f->fit.size;
  for (int y = y0; y < y1; y++) {
    int m = y / S, row = y % S;
    const double *d = f->s.dir[m], *t = f->axis[m][0], *b = f->axis[m][1];
    double ty = ((row + 0.5) / S * 2 - 1) * f->radius;
    const double dir[3] = {-d[0], -d[1], -d[2]};
    for (int x = x0; x < x1; x++) {
      double tx = ((x + 0.5) / S * 2 - 1) * f->radius, org[3];
      for (int k = 0; k < 3; k++)
        org[k] = f->centre[k] + d[k] * f->start + tx * t[k] + ty * b[k];
      obs_hit hit;
      float depth = (float)OBS_IBL_FAR;
      if (obs_rt_intersect(j->rt, org, dir, INFINITY, &hit)) depth = hit.t;
      f->maps[((size_t)m * (size_t)S + (size_t)row) * (size_t)S + (size_t)x] = depth;
    }
  }
  return 0;
}

/* The bounding sphere of the geometry (world), the maps' plane 1.5 radii out, each map's axes,
 * the camera relative to the centre, all in the fit's push block and table. */
static void place(obs_ibl_frame *f, const obs_scene *sc, const obs_geometry *geo,
                  const obs_gbuffer *g, const obs_ibl_shadows_params *p) {
  double r2 = 0;
  for (int k = 0; k < 3; k++) {
    double h = 0.5 * (geo->bounds[1][k] - geo->bounds[0][k]);
    f->centre[k] = geo->origin[k] + 0.5 * (geo->bounds[0][k] + geo->bounds[1][k]);
    r2 += h * h;
  }
  /* A point-sized scene still gets maps of some extent. */
  double r = sqrt(r2) > 0 ? sqrt(r2) : fmax(1e-30, 1e-7 * geo->extent);
  f->radius = r, f->start = 1.5 * r;
  obs_camera_setup(&sc->camera, g->width, g->height, &f->rig);
  obs_ibl_fit_push *pc = &f->fit;
  pc->width = g->width, pc->height = g->height, pc->flags = g->ortho ? OBS_IBL_ORTHO : 0;
  pc->maps = f->s.m, pc->coeffs = f->s.n, pc->size = p->map_size;
  pc->half_w = g->half_w, pc->half_h = g->half_h;
  pc->radius = (float)r, pc->start = (float)(1.5 * r);
  pc->texel_bias = (float)(p->bias * (2 * r / p->map_size));
  pc->depth_scale = 1.0f;
  for (int k = 0; k < 3; k++) {
    pc->eye[k] = (float)(f->rig.origin[k] - f->centre[k]);
    pc->right[k] = (float)f->rig.right[k];
    pc->up[k] = (float)f->rig.up[k];
    pc->fwd[k] = (float)f->rig.forward[k];
  }
  for (int m = 0; m < f->s.m; m++) {
    frame_of(f->s.dir[m], f->axis[m][0], f->axis[m][1]);
    for (int k = 0; k < 3; k++) {
      f->table.dir[m][k] = (float)f->s.dir[m][k];
      f->table.tax[m][k] = (float)f->axis[m][0][k];
      f->table.bax[m][k] = (float)f->axis[m][1][k];
    }
  }
  for (int k = 0; k < OBS_SH_MAX_COEFFS; k++)
    for (int m = 0; m < OBS_IBL_MAX_MAPS; m++)
      f->table.yplus[k * OBS_IBL_MAX_MAPS + m] = f->s.yplus[k][m];
}

int obs_ibl_frame_make(const obs_scene *sc, const obs_geometry *geo, const obs_env *env,
                       const obs_gbuffer *g, const obs_ibl_shadows_params *p, obs_ibl_frame *f,
                       obs_err *err) {
  memset(f, 0, sizeof *f);
  if (!sc || !geo || !g || !p)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: missing scene, geometry, G-buffer or params");
  if (p->map_size < 1 || p->map_size > 4096 || p->sh_order < 1 ||
      p->sh_order > OBS_SH_MAX_BANDS)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: map_size %d or sh_order %d out of range",
                       p->map_size, p->sh_order);
  int rc = obs_ibl_setup_make(env, p, &f->s, err);
  if (!rc) place(f, sc, geo, g, p);
  return rc;
}

int obs_ibl_maps_cast(obs_ibl_frame *f, const obs_rt *rt, int threads, const atomic_int *cancel,
                      obs_err *err) {
  const int S = f->fit.size;
  f->maps = malloc((size_t)S * (size_t)S * (size_t)f->s.m * sizeof *f->maps);
  if (!f->maps)
    return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: %d shadow maps of %d^2: out of memory",
                       f->s.m, S);
  map_job j = {.f = f, .rt = rt};
  int rc = obs_parallel_tiles(S, S * f->s.m, threads, map_tile, &j, cancel, NULL, NULL);
  if (rc) {
    obs_ibl_frame_free(f);
    if (rc != OBS_ECANCELED) obs_err_set(err, rc, "ibl_shadows: shadow maps failed");
  }
  return rc;
}

void obs_ibl_frame_free(obs_ibl_frame *f) {
  free(f->maps);
  f->maps = NULL;
}

typedef struct export_job {
  const obs_ibl_frame *f;
  const obs_gbuffer *g;
  const obs_env *env;
  const float *raw, *res;
  float *ao, *ao_raw, *extra;
} export_job;

static void gather(const float *c, size_t npix, size_t i, int n, float w[OBS_SH_MAX_COEFFS]) {
  for (int k = 0; k < n; k++) w[k] = c[obs_ibl_coef_at(npix, i, k)];
}

static int export_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const export_job *j = user;
  const obs_gbuffer *g = j->g;
  const obs_camera_rig *rig = &j->f->rig;
  const size_t N = (size_t)g->width * (size_t)g->height;
  const int n = j->f->s.n;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      float rgb[3], ao, aor, bent[3], unused[3];
      if (!(g->depth[i] > 0.0f)) {
        /* The background shows the environment, as path_trace's misses do. */
        double org[3], dir[3];
        obs_camera_ray(rig, x + 0.5, y + 0.5, org, dir);
        float fd[3] = {(float)dir[0], (float)dir[1], (float)dir[2]};
        obs_env_lookup(j->env, fd, rgb);
        ao = aor = 1.0f;
        bent[0] = bent[1] = bent[2] = 0.0f;
      } else {
        const float *nv = g->normal + 3 * i;
        float nw[3], w[OBS_SH_MAX_COEFFS], rgb_raw[3];
        for (int k = 0; k < 3; k++)
          nw[k] = (float)(nv[0] * rig->right[k] + nv[1] * rig->up[k] + nv[2] * rig->forward[k]);
        gather(j->res, N, i, n, w);
        obs_ibl_shade(&j->f->s, w, g->albedo + 3 * i, nw, rgb, &ao, bent);
        gather(j->raw, N, i, n, w);
        obs_ibl_shade(&j->f->s, w, g->albedo + 3 * i, nw, rgb_raw, &aor, unused);
      }
      j->ao[i] = ao;
      j->ao_raw[i] = aor;
      for (int k = 0; k < 3; k++) {
        j->extra[(size_t)(OBS_IBL_RADIANCE + k) * N + i] = rgb[k];
        j->extra[(size_t)(OBS_IBL_BENT + k) * N + i] = bent[k];
      }
    }
  return 0;
}

void obs_ibl_export(const obs_ibl_frame *f, const obs_gbuffer *g, const obs_env *env,
                    const float *raw, const float *res, int threads, float *ao, float *ao_raw,
                    float *extra) {
  export_job j = {f, g, env, raw, res, ao, ao_raw, extra};
  obs_parallel_tiles(g->width, g->height, threads, export_tile, &j, NULL, NULL, NULL);
}

int obs_ibl_env_of(const obs_render_ctx *ctx, obs_env *dark, const obs_env **env, obs_err *err) {
  memset(dark, 0, sizeof *dark);
  *env = ctx->environment ? ctx->environment : dark;
  if (ctx->environment) return 0;
  const double zero[3] = {0, 0, 0};
  return obs_env_constant(dark, zero, err);
}
