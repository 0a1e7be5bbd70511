/* analytic_ao on the CPU: per tile, the occluders whose bounding cubes reach the tile's receivers,
 * then per pixel the product of (1 - occlusion) over those whose cube holds the pixel's point.
 * No BVH: the occluders are the scene's analytic shapes, read in closed form (occluders.c). The
 * Vulkan twin is vulkan.c with analytic_ao.comp.glsl. */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"

/* Which pixels a pass evaluates: every one (full resolution), pixel (2X, 2Y) of each cell of the
 * half-resolution grid, or the pixels the upsampling could not fill (mask set). */
enum { AAO_PASS_FULL, AAO_PASS_LOW, AAO_PASS_EDGES };

typedef struct aao_job {
  const obs_gbuffer *g;
  const obs_aao_occluder *occ;
  size_t nocc;
  int *lists; /* per thread: nocc indices of the tile's occluders */
  int mode;   /* AAO_PASS_* */
  int gw;     /* the grid's width: the image's, or the half-resolution grid's */
  float *out; /* gw x rows: the AO of each cell */
  const unsigned char *mask; /* AAO_PASS_EDGES: 1 where the pixel is evaluated */
  const float *low;          /* the upsampling's input */
  unsigned char *wmask;      /* the upsampling's output mask */
  int lw, lh;
} aao_job;

/* The G-buffer pixel a grid cell evaluates, or -1 where the cell is not evaluated. */
static ptrdiff_t aao_cell(const aao_job *j, int cx, int cy, int *x, int *y) {
  const obs_gbuffer *g = j->g;
  *x = j->mode == AAO_PASS_LOW ? 2 * cx : cx;
  *y = j->mode == AAO_PASS_LOW ? 2 * cy : cy;
  size_t k = (size_t)*y * (size_t)g->width + (size_t)*x;
  if (!(g->depth[k] > 0.0f)) return -1;
  if (j->mode == AAO_PASS_EDGES && !j->mask[k]) return -1;
  return (ptrdiff_t)k;
}

/* The AO at G-buffer pixel k = (x, y) over the candidate occluders `list`. */
static float aao_pixel(const aao_job *j, const int *list, size_t n, int x, int y, size_t k) {
  const obs_gbuffer *g = j->g;
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
  for (int cy = y0; cy < y1; cy++)
    for (int cx = x0; cx < x1; cx++) {
      int x, y;
      ptrdiff_t k = aao_cell(j, cx, cy, &x, &y);
      if (j->mode != AAO_PASS_EDGES) j->out[(size_t)cy * (size_t)j->gw + (size_t)cx] = 1.0f;
      if (k < 0) continue;
      float p[3];
      obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, g->depth[k], p);
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
  for (int cy = y0; cy < y1; cy++)
    for (int cx = x0; cx < x1; cx++) {
      int x, y;
      ptrdiff_t k = aao_cell(j, cx, cy, &x, &y);
      if (k >= 0)
        j->out[(size_t)cy * (size_t)j->gw + (size_t)cx] = aao_pixel(j, list, n, x, y, (size_t)k);
    }
  return 0;
}

/* Bilateral upsampling of the half-resolution AO (the twin of analytic_ao_up.comp.glsl): each
 * pixel averages the up to four cells around it, weighted bilinearly, by the agreement of
 * normals (cos^8) and of depths (relative difference tapering to 0 at OBS_AAO_UP_DEPTH); a pixel
 * no cell agrees with is marked for evaluation at full resolution. */
static int aao_up_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  aao_job *j = user;
  const obs_gbuffer *g = j->g;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      size_t k = (size_t)y * (size_t)g->width + (size_t)x;
      float zp = g->depth[k];
      j->wmask[k] = 0;
      j->out[k] = 1.0f;
      if (!(zp > 0.0f)) continue;
      const float *np = g->normal + 3 * k;
      float acc = 0.0f, sum = 0.0f;
      for (int s = 0; s < 4; s++) {
        int cx = (x >> 1) + (s & 1), cy = (y >> 1) + (s >> 1);
        if (((s & 1) && !(x & 1)) || ((s >> 1) && !(y & 1)) || cx >= j->lw || cy >= j->lh)
          continue;
        float b = ((x & 1) ? 0.5f : 1.0f) * ((y & 1) ? 0.5f : 1.0f);
        size_t ks = (size_t)(2 * cy) * (size_t)g->width + (size_t)(2 * cx);
        float zs = g->depth[ks];
        if (!(zs > 0.0f)) continue;
        const float *ns = g->normal + 3 * ks;
        float dn = ns[0] * np[0] + ns[1] * np[1] + ns[2] * np[2];
        if (!(dn > 0.0f)) continue;
        float dn2 = dn * dn, dn4 = dn2 * dn2;
        float dz = fabsf(zs - zp) / zp;
        if (!(dz < OBS_AAO_UP_DEPTH)) continue;
        float w = b * (dn4 * dn4) * (1.0f - dz / OBS_AAO_UP_DEPTH);
        acc += w * j->low[(size_t)cy * (size_t)j->lw + (size_t)cx];
        sum += w;
      }
      if (sum > 0.0f)
        j->out[k] = acc / sum;
      else
        j->wmask[k] = 1;
    }
  return 0;
}

/* Push-pull upsampling (the twin of analytic_ao_pp.comp.glsl, operation for operation): level 0
 * at pixel k is (AO, 1) where evaluated (the pixels the edge pass marked, then the half grid's),
 * else (0, 0). */
static void aao_pp_sample0(const obs_gbuffer *g, const float *low, int lw, const unsigned char *mask,
                           const float *ao, int x, int y, float *v, float *w) {
  size_t k = (size_t)y * (size_t)g->width + (size_t)x;
  *v = 0.0f, *w = 0.0f;
  if (!(g->depth[k] > 0.0f)) return;
  if (mask[k])
    *v = ao[k], *w = 1.0f;
  else if (!(x & 1) && !(y & 1))
    *v = low[(size_t)(y >> 1) * (size_t)lw + (size_t)(x >> 1)], *w = 1.0f;
}

/* The parents' value at child (x, y) from the level at column px, pw x ph, of the atlas of width
 * as: bilinear over the 2x2 parents around it (weights 3/4 and 1/4 on each axis, clamped at the
 * level's edges). */
static float aao_pp_parent(const float *av, size_t as, int px, int pw, int ph, int x, int y) {
  int x1 = x >> 1, y1 = y >> 1;
  int x2 = (x & 1) ? x1 + 1 : x1 - 1, y2 = (y & 1) ? y1 + 1 : y1 - 1;
  x2 = x2 < 0 ? 0 : x2 > pw - 1 ? pw - 1 : x2;
  y2 = y2 < 0 ? 0 : y2 > ph - 1 ? ph - 1 : y2;
  const float *r1 = av + (size_t)y1 * as + (size_t)px, *r2 = av + (size_t)y2 * as + (size_t)px;
  float a = 0.75f * r1[x1] + 0.25f * r1[x2];
  float b = 0.75f * r2[x1] + 0.25f * r2[x2];
  return 0.75f * a + 0.25f * b;
}

/* Push (each level's texel the weighted mean of its 2x2 children, weight min(1, sum)) then pull
 * (each texel w own + (1 - w) the bilinear of its parents, from the coarsest level to the frame) over
 * the atlas of obs_aao_pyramid: av values, aw weights. Serial: a few operations per pixel beside
 * the closed forms. */
static void aao_push_pull(const obs_gbuffer *g, const float *low, int lw, const unsigned char *mask,
                          float *ao, float *av, float *aw) {
  obs_aao_pyramid py;
  obs_aao_pyramid_make(g->width, g->height, &py);
  const size_t as = (size_t)py.aw;
  for (int l = 1; l <= py.n; l++)
    for (int y = 0; y < py.h[l]; y++)
      for (int x = 0; x < py.w[l]; x++) {
        float acc = 0.0f, sum = 0.0f;
        for (int s = 0; s < 4; s++) {
          int cx = 2 * x + (s & 1), cy = 2 * y + (s >> 1);
          if (cx >= py.w[l - 1] || cy >= py.h[l - 1]) continue;
          float tv, tw;
          if (l == 1) {
            aao_pp_sample0(g, low, lw, mask, ao, cx, cy, &tv, &tw);
          } else {
            size_t c = (size_t)cy * as + (size_t)(py.x[l - 1] + cx);
            tv = av[c], tw = aw[c];
          }
          acc += tw * tv;
          sum += tw;
        }
        size_t d = (size_t)y * as + (size_t)(py.x[l] + x);
        av[d] = sum > 0.0f ? acc / sum : 1.0f;
        aw[d] = sum < 1.0f ? sum : 1.0f;
      }
  for (int l = py.n - 1; l >= 1; l--)
    for (int y = 0; y < py.h[l]; y++)
      for (int x = 0; x < py.w[l]; x++) {
        size_t d = (size_t)y * as + (size_t)(py.x[l] + x);
        float par = aao_pp_parent(av, as, py.x[l + 1], py.w[l + 1], py.h[l + 1], x, y);
        av[d] = aw[d] * av[d] + (1.0f - aw[d]) * par;
        aw[d] = 1.0f;
      }
  for (int y = 0; y < g->height; y++)
    for (int x = 0; x < g->width; x++) {
      size_t k = (size_t)y * (size_t)g->width + (size_t)x;
      if (!(g->depth[k] > 0.0f)) {
        ao[k] = 1.0f;
        continue;
      }
      float v, w;
      aao_pp_sample0(g, low, lw, mask, ao, x, y, &v, &w);
      float par = aao_pp_parent(av, as, py.x[1], py.w[1], py.h[1], x, y);
      ao[k] = w * v + (1.0f - w) * par;
    }
}

/* The passes within a render (r) or outside one: full resolution, or half resolution, the
 * bilateral upsampling and the pixels it left at full resolution, then under upsample push_pull
 * the push-pull over those samples in place of the bilateral result. stage_ms (may be NULL)
 * receives OBS_AAO_STAGES entries. */
static int aao_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_aao_occluder *occ,
                      size_t nocc, const obs_analytic_ao_params *p, float *ao, double *stage_ms,
                      obs_err *err) {
  if (!g || !ao || !p || g->width < 1 || g->height < 1 || (nocc && !occ))
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: missing G-buffer, occluders or output");
  int threads = r->threads > 0 ? r->threads : 1;
  const int w = g->width, h = g->height, lw = (w + 1) / 2, lh = (h + 1) / 2;
  const int half = p->resolution == OBS_AAO_HALF;
  size_t n = (size_t)w * (size_t)h;
  aao_job j = {.g = g, .occ = occ, .nocc = nocc, .mode = AAO_PASS_FULL, .gw = w, .out = ao,
               .lw = lw, .lh = lh};
  j.lists = malloc((size_t)threads * (nocc ? nocc : 1) * sizeof *j.lists);
  float *low = half ? malloc((size_t)lw * (size_t)lh * sizeof *low) : NULL;
  unsigned char *mask = half ? malloc(n) : NULL;
  if (!j.lists || (half && (!low || !mask))) {
    free(j.lists), free(low), free(mask);
    return obs_err_set(err, OBS_ENOMEM, "analytic_ao: %zu occluders, %dx%d: out of memory", nocc,
                       w, h);
  }
  double t[4];
  t[0] = obs_now_ms();
  r->passes = half ? 3 : 1;
  int rc;
  if (!half) {
    rc = obs_screen_cpu_tiles(r, w, h, aao_tile, &j);
    t[1] = t[2] = t[3] = obs_now_ms();
  } else {
    j.mode = AAO_PASS_LOW, j.gw = lw, j.out = low;
    rc = obs_screen_cpu_tiles(r, lw, lh, aao_tile, &j);
    t[1] = obs_now_ms();
    j.low = low, j.wmask = mask, j.out = ao;
    if (!rc) rc = obs_screen_cpu_tiles(r, w, h, aao_up_tile, &j);
    t[2] = obs_now_ms();
    j.mode = AAO_PASS_EDGES, j.gw = w, j.mask = mask;
    if (!rc) rc = obs_screen_cpu_tiles(r, w, h, aao_tile, &j);
    t[3] = obs_now_ms();
    if (!rc && p->upsample == OBS_AAO_PUSH_PULL) {
      obs_aao_pyramid py;
      obs_aao_pyramid_make(w, h, &py);
      size_t na = (size_t)py.aw * (size_t)py.ah;
      float *av = malloc(na * sizeof *av), *aw = malloc(na * sizeof *aw);
      if (!av || !aw)
        rc = OBS_ENOMEM;
      else
        aao_push_pull(g, low, lw, mask, ao, av, aw);
      free(av), free(aw);
      /* The push-pull counts as the upsampling's time. */
      double t4 = obs_now_ms();
      t[2] += t4 - t[3], t[3] = t4;
    }
  }
  if (stage_ms)
    for (int k = 0; k < OBS_AAO_STAGES; k++) stage_ms[k] = t[k + 1] - t[k];
  free(j.lists), free(low), free(mask);
  if (rc && rc != OBS_ECANCELED) return obs_err_set(err, rc, "analytic_ao: CPU pass failed");
  return rc;
}

int obs_analytic_ao_cpu_apply(const obs_gbuffer *g, const obs_aao_occluder *occ, size_t nocc,
                              const obs_analytic_ao_params *p, int threads, float *ao,
                              double *stage_ms, obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return aao_passes(&r, g, occ, nocc, p, ao, stage_ms, err);
}

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const obs_analytic_ao_params *p = params;
  obs_aao_occluder *occ;
  size_t nocc;
  int rc = obs_aao_render_occluders(r->ctx, g->width, g->height, p, &occ, &nocc, err);
  if (rc) return rc;
  double st[OBS_AAO_STAGES];
  rc = aao_passes(r, g, occ, nocc, p, ao, st, err);
  free(occ);
  if (rc) return rc;
  for (int k = 0; k < OBS_AAO_STAGES; k++)
    if (k == 0 || p->resolution == OBS_AAO_HALF) obs_screen_cpu_stage(r, obs_aao_stage_names[k], st[k]);
  memcpy(ao_raw, ao, (size_t)g->width * (size_t)g->height * sizeof *ao);
  return 0;
}

int obs_analytic_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_cpu_run(ctx, passes, ctx->bound, out, err);
}
