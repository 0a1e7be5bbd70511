/* analytic_ao on the CPU: per tile, the occluders whose bounding cubes reach the tile's receivers,
 * then per pixel the product of (1 - occlusion) over those whose cube holds the pixel's point.
 * No BVH: the occluders are the scene's analytic shapes, read in closed form (occluders.c). The
 * Vulkan twin is vulkan.c with analytic_ao.comp.glsl. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "camera.h"
#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"

typedef struct aao_job {
  const obs_gbuffer *g;
  const obs_aao_occluder *occ;
  size_t nocc;
  int *lists; /* per thread: nocc indices of the tile's occluders */
  float *ao;
} aao_job;

/* The AO of one covered pixel over the candidate occluders `list`. */
static float aao_pixel(const aao_job *j, const int *list, size_t n, int x, int y) {
  const obs_gbuffer *g = j->g;
  size_t k = (size_t)y * (size_t)g->width + (size_t)x;
  float p[3];
  obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, g->depth[k], p);
  const float *nrm = g->normal + 3 * k;
  float ao = 1.0f;
  for (size_t i = 0; i < n; i++) {
    const obs_aao_occluder *o = &j->occ[list[i]];
    if (obs_aao_in_bound(o, p)) ao *= 1.0f - obs_aao_occlusion(o, p, nrm);
  }
  return ao;
}

static int aao_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  aao_job *j = user;
  const obs_gbuffer *g = j->g;
  /* The box of the tile's receivers: the depth extents the article culls with. */
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  int any = 0;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t k = (size_t)y * (size_t)g->width + (size_t)x;
      float z = g->depth[k];
      j->ao[k] = 1.0f;
      if (!(z > 0.0f)) continue;
      float p[3];
      obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, z, p);
      for (int c = 0; c < 3; c++) {
        lo[c] = p[c] < lo[c] ? p[c] : lo[c];
        hi[c] = p[c] > hi[c] ? p[c] : hi[c];
      }
      any = 1;
    }
  if (!any) return 0;
  int *list = j->lists + (size_t)thread * j->nocc;
  size_t n = 0;
  for (size_t i = 0; i < j->nocc; i++) {
    const obs_aao_occluder *o = &j->occ[i];
    int in = 1;
    for (int c = 0; c < 3; c++)
      if (!(o->center[c] - o->bound <= hi[c] && lo[c] <= o->center[c] + o->bound)) in = 0;
    if (in) list[n++] = (int)i;
  }
  if (!n) return 0;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t k = (size_t)y * (size_t)g->width + (size_t)x;
      if (g->depth[k] > 0.0f) j->ao[k] = aao_pixel(j, list, n, x, y);
    }
  return 0;
}

/* The pass within a render (r) or outside one. */
static int aao_pass(obs_screen_cpu *r, const obs_gbuffer *g, const obs_aao_occluder *occ,
                    size_t nocc, float *ao, obs_err *err) {
  if (!g || !ao || g->width < 1 || g->height < 1 || (nocc && !occ))
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: missing G-buffer, occluders or output");
  int threads = r->threads > 0 ? r->threads : 1;
  aao_job j = {.g = g, .occ = occ, .nocc = nocc, .ao = ao};
  j.lists = malloc((size_t)threads * (nocc ? nocc : 1) * sizeof *j.lists);
  if (!j.lists)
    return obs_err_set(err, OBS_ENOMEM, "analytic_ao: %zu occluders: out of memory", nocc);
  r->passes = 1;
  int rc = obs_screen_cpu_tiles(r, g->width, g->height, aao_tile, &j);
  free(j.lists);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "analytic_ao: CPU pass failed");
  return rc;
}

int obs_analytic_ao_cpu_apply(const obs_gbuffer *g, const obs_aao_occluder *occ, size_t nocc,
                              const obs_analytic_ao_params *p, int threads, float *ao,
                              obs_err *err) {
  (void)p;
  obs_screen_cpu r = {.threads = threads};
  return aao_pass(&r, g, occ, nocc, ao, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const obs_analytic_ao_params *p = params;
  obs_render_ctx *ctx = r->ctx;
  obs_camera_rig rig;
  obs_camera_setup(&ctx->scene->camera, g->width, g->height, &rig);
  obs_aao_occluder *occ;
  size_t nocc, skipped;
  double t0 = obs_now_ms();
  int rc = obs_aao_occluders(ctx->scene, &rig, p->extent, &occ, &nocc, &skipped, err);
  if (rc) return rc;
  if (skipped)
    obs_render_ctx_warn(ctx, "analytic_ao: %zu object(s) with no closed form (meshes) receive "
                        "occlusion but cast none", skipped);
  double t1 = obs_now_ms();
  obs_screen_cpu_stage(r, "occluders", t1 - t0);
  rc = aao_pass(r, g, occ, nocc, ao, err);
  free(occ);
  if (rc) return rc;
  obs_screen_cpu_stage(r, "ao", obs_now_ms() - t1);
  memcpy(ao_raw, ao, (size_t)g->width * (size_t)g->height * sizeof *ao);
  return 0;
}

int obs_analytic_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
