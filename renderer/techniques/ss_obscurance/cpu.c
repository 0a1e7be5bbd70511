/* ss_obscurance on the CPU: the twin of ss_obscurance*.comp.glsl, operation for operation.
 *
 * Both sides must give the same bits on the same G-buffer, so this file keeps to float32, performs
 * each expression in the shader's order (ISO C: nothing is contracted to FMA; the shaders mark
 * the same expressions `precise`) and divides only where the shader divides. The definition is in
 * docs/techniques/ss_obscurance.md. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "sampling.h"
#include "screen.h"
#include "simd.h"
#include "ss_obscurance.h"
#include "sso_pixel.h"
#include "techniques.h"

typedef struct sso_job {
  const obs_gbuffer *g;
  const obs_sso_params *p;
  const obs_sso_tables *t;
  obs_sso_push pc;
  const float *raw; /* the average's input */
  float *out;
} sso_job;

OBS_HOT_INLINE int ao_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  sso_job *j = user;
  const size_t w = (size_t)j->g->width;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++)
      j->out[(size_t)y * w + (size_t)x] =
          obs_sso_pixel(&j->pc, j->g->depth, j->g->normal, &j->t->offsets[0][0][0], x, y);
  return 0;
}
OBS_TILE_KERNELS(ao_tile)

/* The 4x4 average of the interleaved pattern over neighbours within R in depth, as the mean of
 * the closed shares 1 - W, so that an open neighbourhood reads exactly 1. */
OBS_HOT_INLINE float avg_pixel(const sso_job *j, int x, int y) {
  const obs_gbuffer *g = j->g;
  const int w = g->width, h = g->height;
  const float zc = g->depth[(size_t)y * (size_t)w + (size_t)x];
  if (!(zc > 0.0f)) return 1.0f;
  const float lim = j->pc.radius;
  float sum = 0.0f;
  int cnt = 0;
  for (int dy = OBS_SSO_AVG_LO; dy <= OBS_SSO_AVG_HI; dy++)
    for (int dx = OBS_SSO_AVG_LO; dx <= OBS_SSO_AVG_HI; dx++) {
      int xx = x + dx, yy = y + dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      size_t k = (size_t)yy * (size_t)w + (size_t)xx;
      float zn = g->depth[k];
      if (zn > 0.0f && fabsf(zn - zc) <= lim) {
        sum += 1.0f - j->raw[k];
        cnt++;
      }
    }
  /* cnt >= 1: the centre always passes. */
  float r = 1.0f - sum * j->t->inv_count[cnt];
  return r < 0.0f ? 0.0f : r;
}

OBS_HOT_INLINE int avg_tile_body(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  sso_job *j = user;
  const size_t w = (size_t)j->g->width;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) j->out[(size_t)y * w + (size_t)x] = avg_pixel(j, x, y);
  return 0;
}
OBS_TILE_KERNELS(avg_tile)

/* The two passes: obs_sso_cpu_apply within a render (r) or outside one. */
static int sso_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_sso_params *p, float *ao,
                      float *ao_raw, double *stage_ms, obs_err *err) {
  if (stage_ms)
    for (int k = 0; k < OBS_SSO_CPU_STAGES; k++) stage_ms[k] = 0.0;
  int rc = obs_sso_params_valid(p, err);
  if (rc) return rc;
  if (!g || !ao || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "ss_obscurance: missing G-buffer or output");
  obs_sso_tables *t = malloc(sizeof *t);
  size_t n = (size_t)g->width * (size_t)g->height;
  float *raw = p->interleave ? ao_raw : ao;
  if (t && !raw) raw = malloc(n * sizeof *raw);
  if (!t || !raw) {
    free(t);
    return obs_err_set(err, OBS_ENOMEM, "ss_obscurance: %dx%d: out of memory", g->width,
                       g->height);
  }
  obs_sso_tables_make(p, t);
  sso_job j = {.g = g, .p = p, .t = t, .raw = raw, .out = raw};
  obs_sso_push_make(p, g->width, g->height, g->ortho, g->half_w, g->half_h, &j.pc);
  const int isa = obs_simd_isa();
  r->passes = p->interleave ? 2 : 1;
  double t0 = obs_now_ms();
  rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(ao_tile, isa), &j);
  double t1 = obs_now_ms();
  if (!rc && p->interleave) {
    j.out = ao;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, obs_simd_tile_pick(avg_tile, isa), &j);
  } else if (!rc && ao_raw) {
    memcpy(ao_raw, ao, n * sizeof *ao);
  }
  double t2 = obs_now_ms();
  if (stage_ms) {
    stage_ms[0] = t1 - t0;
    stage_ms[1] = p->interleave ? t2 - t1 : 0.0;
  }
  if (raw != ao_raw && raw != ao) free(raw);
  free(t);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "ss_obscurance: CPU passes failed");
  return rc;
}

int obs_sso_cpu_apply(const obs_gbuffer *g, const obs_sso_params *p, int threads, float *ao,
                      float *ao_raw, double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return sso_passes(&r, g, p, ao, ao_raw, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const obs_sso_params *p = params;
  double st[OBS_SSO_CPU_STAGES];
  int rc = sso_passes(r, g, p, ao, ao_raw, st, err);
  if (rc) return rc;
  obs_screen_cpu_stage(r, "ao", st[0]);
  if (p->interleave) obs_screen_cpu_stage(r, "blur", st[1]);
  return 0;
}

int obs_ss_obscurance_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
