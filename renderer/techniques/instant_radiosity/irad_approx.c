/* instant_radiosity's approximate visibility, its host part: the min-pyramid of the depth buffer
 * (the article's "pyramidal occlusion maps") and the distance-impostor cube of the geometry
 * outside the view (the article renders it; here Embree rays from the cube's centre find the
 * nearest off-screen surface per texel). Both are made once on the host and read by both
 * backends' gathers (cpu.c, instant_radiosity_gather.comp.glsl), so the twins see the same bits. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "instant_radiosity.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"

int obs_irad_pyramid_offset(int w, int l) {
  int off = 0;
  for (int k = 0; k < l; k++) off += (w + (1 << k) - 1) >> k;
  return off;
}

static void pyramid_make(const obs_gbuffer *g, float *pyr, int aw) {
  const int w = g->width, h = g->height;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float z = g->depth[(size_t)y * (size_t)w + (size_t)x];
      pyr[(size_t)y * (size_t)aw + (size_t)x] = z > 0.0f ? z : (float)OBS_IRAD_FAR;
    }
  for (int l = 1; l < OBS_IRAD_LEVELS; l++) {
    const int o0 = obs_irad_pyramid_offset(w, l - 1), o1 = obs_irad_pyramid_offset(w, l);
    const int w0 = (w + (1 << (l - 1)) - 1) >> (l - 1), h0 = (h + (1 << (l - 1)) - 1) >> (l - 1);
    const int w1 = (w + (1 << l) - 1) >> l, h1 = (h + (1 << l) - 1) >> l;
    for (int y = 0; y < h1; y++)
      for (int x = 0; x < w1; x++) {
        float m = (float)OBS_IRAD_FAR;
        for (int dy = 0; dy < 2; dy++)
          for (int dx = 0; dx < 2; dx++) {
            int xx = 2 * x + dx, yy = 2 * y + dy;
            if (xx >= w0 || yy >= h0) continue;
            float v = pyr[(size_t)yy * (size_t)aw + (size_t)(o0 + xx)];
            m = v < m ? v : m;
          }
        pyr[(size_t)y * (size_t)aw + (size_t)(o1 + x)] = m;
      }
  }
}

typedef struct cube_job {
  const obs_irad_light *l;
  double c[3];    /* the centre, world */
  double axes[3][3];
  float *out;
} cube_job;

/* Whether world point q (in the ray tracer's frame) lies outside the camera's view. */
static int off_screen(const cube_job *j, const float p[3]) {
  const obs_camera_rig *r = &j->l->rig;
  double d[3], v[3];
  for (int k = 0; k < 3; k++) d[k] = p[k] + j->l->rt->geo.origin[k] - r->origin[k];
  for (int k = 0; k < 3; k++) v[k] = d[0] * j->axes[k][0] + d[1] * j->axes[k][1] + d[2] * j->axes[k][2];
  if (!(v[2] > 0)) return 1;
  if (r->ortho) return fabs(v[0]) > r->half_w || fabs(v[1]) > r->half_h;
  return fabs(v[0]) > r->half_w * v[2] || fabs(v[1]) > r->half_h * v[2];
}

/* Texel (i, j) of face f: the distance from the centre to the nearest surface outside the view
 * along the texel centre's direction (rays continue through what the camera sees). */
static float cube_texel(const cube_job *j, int f, int i, int t) {
  const int axis = f / 2, neg = f & 1, R = OBS_IRAD_CUBE;
  const double a = (i + 0.5) / R * 2 - 1, b = (t + 0.5) / R * 2 - 1;
  double dv[3];
  dv[axis] = neg ? -1.0 : 1.0;
  dv[axis == 0 ? 1 : 0] = a;
  dv[axis == 2 ? 1 : 2] = b;
  double dw[3], len = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
  for (int k = 0; k < 3; k++)
    dw[k] = (dv[0] * j->axes[0][k] + dv[1] * j->axes[1][k] + dv[2] * j->axes[2][k]) / len;
  obs_hit hit;
  if (!obs_rt_intersect(j->l->rt, j->c, dw, INFINITY, &hit)) return (float)OBS_IRAD_FAR;
  for (int n = 0; n < 32; n++) {
    if (off_screen(j, hit.p)) {
      double e[3];
      for (int k = 0; k < 3; k++) e[k] = hit.p[k] + j->l->rt->geo.origin[k] - j->c[k];
      return (float)sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    }
    float from[3], fd[3] = {(float)dw[0], (float)dw[1], (float)dw[2]};
    obs_rt_offset(j->l->rt, &hit, from);
    /* The offset points to the side the ray came from: continue from just behind the surface. */
    for (int k = 0; k < 3; k++) from[k] = 2.0f * hit.p[k] - from[k];
    obs_rt_ctx ctx;
    obs_rt_ctx_init(&ctx, j->l->rt, &hit);
    if (!obs_rt_intersect_from(j->l->rt, &ctx, from, fd, INFINITY, &hit)) break;
  }
  return (float)OBS_IRAD_FAR;
}

static int cube_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  const cube_job *j = user;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      j->out[(size_t)y * 6 * OBS_IRAD_CUBE + (size_t)x] =
          cube_texel(j, x / OBS_IRAD_CUBE, x % OBS_IRAD_CUBE, y);
  return 0;
}

int obs_irad_pyramid_make(const obs_gbuffer *g, obs_irad_light *l, obs_err *err) {
  l->pyr_w = obs_irad_pyramid_offset(g->width, OBS_IRAD_LEVELS);
  l->pyr_h = g->height;
  l->pyramid = malloc((size_t)l->pyr_w * (size_t)l->pyr_h * sizeof(float));
  if (!l->pyramid)
    return obs_err_set(err, OBS_ENOMEM, "instant_radiosity: %dx%d: out of memory", g->width,
                       g->height);
  for (size_t i = 0; i < (size_t)l->pyr_w * (size_t)l->pyr_h; i++)
    l->pyramid[i] = (float)OBS_IRAD_FAR;
  pyramid_make(g, l->pyramid, l->pyr_w);
  return 0;
}

int obs_irad_approx_make(const obs_gbuffer *g, obs_irad_light *l, int threads,
                         const atomic_int *cancel, double ms[2], obs_err *err) {
  if (ms) ms[0] = ms[1] = 0.0;
  if (!g || !l || !l->rt)
    return obs_err_set(err, OBS_EINVAL, "instant_radiosity: approximate visibility needs the "
                                        "G-buffer and the BVH");
  double t0 = obs_now_ms();
  int rc = obs_irad_pyramid_make(g, l, err);
  if (rc) return rc;
  double t1 = obs_now_ms();
  l->cube = malloc((size_t)6 * OBS_IRAD_CUBE * OBS_IRAD_CUBE * sizeof(float));
  if (!l->cube)
    return obs_err_set(err, OBS_ENOMEM, "instant_radiosity: out of memory for the cube");
  cube_job j = {.l = l, .out = l->cube};
  const double *ax[3] = {l->rig.right, l->rig.up, l->rig.forward};
  const double(*b)[3] = l->rt->geo.bounds;
  double d[3];
  for (int k = 0; k < 3; k++) {
    j.c[k] = 0.5 * (b[0][k] + b[1][k]);
    d[k] = j.c[k] - l->rig.origin[k];
    for (int i = 0; i < 3; i++) j.axes[k][i] = ax[k][i];
  }
  for (int k = 0; k < 3; k++) l->cube_c[k] = (float)(d[0] * ax[k][0] + d[1] * ax[k][1] + d[2] * ax[k][2]);
  rc = obs_parallel_tiles(6 * OBS_IRAD_CUBE, OBS_IRAD_CUBE, threads < 1 ? 1 : threads,
                              cube_tile, &j, cancel, NULL, NULL);
  if (ms) {
    ms[0] = t1 - t0;
    ms[1] = obs_now_ms() - t1;
  }
  return rc;
}
