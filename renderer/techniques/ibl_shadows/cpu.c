/* ibl_shadows on the CPU: the fit and blur passes, the twins of ibl_shadows_fit.comp.glsl and
 * ibl_shadows_blur.comp.glsl operation for operation (float32, the shaders' order, nothing
 * contracted: the build has -ffp-contract=off and the shaders mark the same expressions
 * `precise`), over the host's shadow maps and shading (ibl_maps.c), on the CPU screen-space
 * driver (docs/techniques/ibl_shadows.md). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ibl_shadows.h"
#include "obscura/render.h"
#include "parallel.h"
#include "raytrace.h"
#include "screen.h"
#include "simd.h"
#include "techniques.h"

typedef struct ibl_job {
  const obs_gbuffer *g;
  const obs_ibl_frame *f;
  float *raw, *tmp, *res; /* OBS_IBL_GROUPS planes of w h 4 floats each */
  const float *src;       /* blur: one plane in, one out */
  float *dst;
  int horizontal;
  float weights[9];
} ibl_job;

OBS_HOT_INLINE void fit_pixel(const ibl_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const obs_ibl_fit_push *pc = &j->f->fit;
  const obs_ibl_table *tb = &j->f->table;
  const size_t N = (size_t)g->width * (size_t)g->height;
  const size_t i = (size_t)y * (size_t)g->width + (size_t)x;
  float w[OBS_SH_MAX_COEFFS];
  for (int k = 0; k < OBS_SH_MAX_COEFFS; k++) w[k] = 0.0f;
  const float z = g->depth[i];
  if (z > 0.0f) {
    const int ortho = (pc->flags & OBS_IBL_ORTHO) != 0;
    const float fx = (float)x + 0.5f, fy = (float)y + 0.5f;
    const float nx = 2.0f * fx / (float)pc->width - 1.0f;
    const float ny = 1.0f - 2.0f * fy / (float)pc->height;
    const float pv0 = ortho ? nx * pc->half_w : nx * pc->half_w * z;
    const float pv1 = ortho ? ny * pc->half_h : ny * pc->half_h * z;
    const float *nv = g->normal + 3 * i;
    float q[3], nw[3];
    for (int k = 0; k < 3; k++) {
      q[k] = pc->eye[k] + pv0 * pc->right[k] + pv1 * pc->up[k] + z * pc->fwd[k];
      nw[k] = nv[0] * pc->right[k] + nv[1] * pc->up[k] + nv[2] * pc->fwd[k];
    }
    float b[OBS_IBL_MAX_MAPS];
    const float S = (float)pc->size;
    for (int m = 0; m < pc->maps; m++) {
      const float *d = tb->dir[m], *t = tb->tax[m], *bb = tb->bax[m];
      const float c = nw[0] * d[0] + nw[1] * d[1] + nw[2] * d[2];
      b[m] = 0.0f;
      if (!(c > 0.0f)) continue;
      const float du = q[0] * t[0] + q[1] * t[1] + q[2] * t[2];
      const float dv = q[0] * bb[0] + q[1] * bb[1] + q[2] * bb[2];
      const float u = (du / pc->radius + 1.0f) * 0.5f * S;
      const float v = (dv / pc->radius + 1.0f) * 0.5f * S;
      int lit = 1;
      if (u >= 0.0f && u < S && v >= 0.0f && v < S) {
        const size_t at = ((size_t)m * (size_t)pc->size + (size_t)(int)v) * (size_t)pc->size +
                          (size_t)(int)u;
        const float occ = j->f->maps[at] * pc->depth_scale;
        const float zz = pc->start - (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]);
        const float slope = c < (float)OBS_IBL_MIN_COS ? (float)OBS_IBL_MAX_SLOPE
                                                       : sqrtf(1.0f - c * c) / c;
        const float thr = occ + pc->texel_bias * (1.0f + slope);
        lit = zz <= thr;
      }
      b[m] = lit ? c : 0.0f;
    }
    for (int k = 0; k < pc->coeffs; k++) {
      float acc = 0.0f;
      for (int m = 0; m < pc->maps; m++) acc += tb->yplus[k * OBS_IBL_MAX_MAPS + m] * b[m];
      w[k] = acc;
    }
  }
  for (int k = 0; k < OBS_SH_MAX_COEFFS; k++) j->raw[obs_ibl_coef_at(N, i, k)] = w[k];
}

OBS_HOT_INLINE void blur_pixel(const ibl_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const int W = g->width, H = g->height;
  const size_t c = (size_t)y * (size_t)W + (size_t)x;
  float *o = j->dst + 4 * c;
  o[0] = o[1] = o[2] = o[3] = 0.0f;
  if (!(g->depth[c] > 0.0f)) return;
  const float *nc = g->normal + 3 * c;
  float acc[4] = {0.0f, 0.0f, 0.0f, 0.0f}, total = 0.0f;
  for (int t = -4; t <= 4; t++) {
    int xx = j->horizontal ? x + t : x, yy = j->horizontal ? y : y + t;
    if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
    size_t q = (size_t)yy * (size_t)W + (size_t)xx;
    if (!(g->depth[q] > 0.0f)) continue;
    const float *nq = g->normal + 3 * q;
    const float a = nq[0] * nc[0] + nq[1] * nc[1] + nq[2] * nc[2];
    const float wt = j->weights[t + 4] * (a > 0.0f ? a : 0.0f);
    if (!(wt > 0.0f)) continue;
    const float *v = j->src + 4 * q;
    for (int k = 0; k < 4; k++) acc[k] += wt * v[k];
    total += wt;
  }
  if (total > 0.0f)
    for (int k = 0; k < 4; k++) o[k] = acc[k] / total;
}

/* The tile loops twice (simd.h): baseline and x86-64-v3, the same scalar operations either way
 * (no contraction), so the same bits at every level. */
OBS_HOT_INLINE int fit_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) fit_pixel(user, x, y);
  return 0;
}
OBS_TILE_KERNELS(fit_tile)

OBS_HOT_INLINE int blur_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) blur_pixel(user, x, y);
  return 0;
}
OBS_TILE_KERNELS(blur_tile)

/* Fit and blur over the frame's maps; j->res ends holding the result (raw without the blur). */
static int fit_blur(obs_screen_cpu *r, ibl_job *j, int blur, double st[2]) {
  const obs_gbuffer *g = j->g;
  const size_t N = (size_t)g->width * (size_t)g->height;
  const int isa = obs_simd_isa(), groups = (j->f->s.n + 3) / 4;
  double t0 = obs_now_ms();
  int rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(fit_tile, isa), j);
  double t1 = obs_now_ms();
  for (int k = 0; !rc && blur && k < groups; k++) {
    j->src = j->raw + 4 * N * (size_t)k, j->dst = j->tmp + 4 * N * (size_t)k, j->horizontal = 1;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(blur_tile, isa), j);
    j->src = j->dst, j->dst = j->res + 4 * N * (size_t)k, j->horizontal = 0;
    if (!rc) rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(blur_tile, isa), j);
  }
  if (!blur) j->res = j->raw;
  st[0] = t1 - t0, st[1] = blur ? obs_now_ms() - t1 : 0.0;
  return rc;
}

static int ibl_passes(obs_screen_cpu *r, const obs_scene *sc, const obs_rt *rt,
                      const obs_env *env, const obs_gbuffer *g, const obs_ibl_shadows_params *p,
                      float *ao, float *ao_raw, float *extra, double *stage_ms, obs_err *err) {
  double st[OBS_IBL_CPU_STAGES] = {0, 0, 0, 0, 0};
  if (stage_ms) memcpy(stage_ms, st, sizeof st);
  if (!g || !ao || !ao_raw || !extra)
    return obs_err_set(err, OBS_EINVAL, "ibl_shadows: missing G-buffer or output");
  obs_ibl_frame *f = malloc(sizeof *f);
  if (!f) return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: out of memory");
  double t0 = obs_now_ms();
  int rc = obs_ibl_frame_make(sc, &rt->geo, env, g, p, f, err);
  double t1 = obs_now_ms();
  if (!rc) rc = obs_ibl_maps_cast(f, rt, r->threads, r->cancel, err);
  st[0] = t1 - t0, st[1] = obs_now_ms() - t1;
  if (rc) {
    free(f);
    return rc;
  }
  const size_t N = (size_t)g->width * (size_t)g->height, plane = 4 * N * OBS_IBL_GROUPS;
  ibl_job j = {.g = g, .f = f};
  obs_ibl_blur_weights(j.weights);
  j.raw = malloc(3 * plane * sizeof *j.raw);
  if (!j.raw) {
    obs_ibl_frame_free(f), free(f);
    return obs_err_set(err, OBS_ENOMEM, "ibl_shadows: %dx%d: out of memory", g->width, g->height);
  }
  j.tmp = j.raw + plane, j.res = j.tmp + plane;
  memset(j.res, 0, plane * sizeof *j.res);
  const int groups = (f->s.n + 3) / 4;
  r->passes = 1 + (p->blur ? 2 * groups : 0);
  rc = fit_blur(r, &j, p->blur, st + 2);
  if (!rc) {
    double t0 = obs_now_ms();
    obs_ibl_export(f, g, env, j.raw, j.res, r->threads, ao, ao_raw, extra);
    st[4] = obs_now_ms() - t0;
  }
  if (stage_ms) memcpy(stage_ms, st, sizeof st);
  free(j.raw);
  obs_ibl_frame_free(f), free(f);
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

static const char *const stage_names[OBS_IBL_CPU_STAGES] = {"setup", "shadow_maps", "fit", "blur",
                                                            "shade"};

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, float *extra, obs_err *err) {
  obs_render_ctx *ctx = r->ctx;
  if (!ctx->rt)
    return obs_err_set(err, OBS_EINTERNAL, "%s: ibl_shadows: no BVH was built", ctx->scene->name);
  obs_env dark;
  const obs_env *env;
  int rc = obs_ibl_env_of(ctx, &dark, &env, err);
  if (rc) return rc;
  double st[OBS_IBL_CPU_STAGES];
  rc = ibl_passes(r, ctx->scene, ctx->rt, env, g, params, ao, ao_raw, extra, st, err);
  obs_env_free(&dark);
  if (!rc)
    for (int k = 0; k < OBS_IBL_CPU_STAGES; k++)
      if (k != 3 || ((const obs_ibl_shadows_params *)params)->blur)
        obs_screen_cpu_stage(r, stage_names[k], st[k]);
  return rc;
}

static const obs_screen_extra ibl_extra = {OBS_IBL_EXTRA, obs_ibl_shadows_extra_names};

int obs_ibl_shadows_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run_ex(ctx, passes, &ibl_extra, ctx->bound, out, err);
}
