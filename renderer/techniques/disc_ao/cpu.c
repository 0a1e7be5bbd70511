/* disc_ao on the CPU: the twin of the device's proxies (vulkan.c). Each disc is listed in every
 * cell of a uniform grid over the receivers that its influence sphere's box touches, so a
 * receiver visits only the discs of its own cell, in the discs' order (the order in which the
 * device blends them), and sums the same terms. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "disc_ao.h"
#include "obscura/render.h"
#include "parallel.h"
#include "screen.h"

/* Cells per axis (about), and the cell entries one grid may hold. */
#define GRID_SIDE_MAX 128
#define GRID_ENTRIES_MAX ((size_t)1 << 28)

typedef struct grid {
  float lo[3], inv_h;
  int dim[3];
  uint32_t *start; /* dim[0] dim[1] dim[2] + 1 offsets into idx */
  uint32_t *idx;   /* disc indices, ascending within a cell */
} grid;

static int cmp_float(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

/* The cells [c0, c1] that disc d's box covers, clipped to the grid; 0 when it misses it. The box
 * is grown by 10^-5 so that a receiver the reach test admits at its very edge is never in a cell
 * the rounding of c +- r left out. */
static int disc_cells(const grid *gr, const obs_disc *d, int c0[3], int c1[3]) {
  const float r = sqrtf(d->r2) * 1.00001f;
  for (int k = 0; k < 3; k++) {
    float a = (d->c[k] - r - gr->lo[k]) * gr->inv_h, b = (d->c[k] + r - gr->lo[k]) * gr->inv_h;
    if (!(b >= 0.0f) || !(a < (float)gr->dim[k])) return 0;
    c0[k] = a <= 0.0f ? 0 : (int)a;
    c1[k] = b >= (float)(gr->dim[k] - 1) ? gr->dim[k] - 1 : (int)b;
  }
  return 1;
}

/* The grid over the box of the covered receivers (lo, hi), with cells of the median influence
 * diameter (at least 1/GRID_SIDE_MAX of the box's longest side), filled in two passes. */
static int grid_build(grid *gr, const obs_disc_set *s, const float lo[3], const float hi[3],
                      obs_err *err) {
  memset(gr, 0, sizeof *gr);
  float ext = 0.0f;
  for (int k = 0; k < 3; k++) ext = fmaxf(ext, hi[k] - lo[k]);
  float h = ext / GRID_SIDE_MAX;
  if (s->n) {
    size_t step = s->n / 4096 + 1, m = 0;
    float *r = malloc((s->n / step + 1) * sizeof *r);
    if (!r) return obs_err_set(err, OBS_ENOMEM, "disc_ao: out of memory for the grid");
    for (size_t i = 0; i < s->n; i += step) r[m++] = 2.0f * sqrtf(s->d[i].r2);
    qsort(r, m, sizeof *r, cmp_float);
    h = fmaxf(h, r[m / 2]);
    free(r);
  }
  if (!(h > 0.0f) || !isfinite(h)) h = fmaxf(ext, 1.0f);
  gr->inv_h = 1.0f / h;
  size_t cells = 1;
  for (int k = 0; k < 3; k++) {
    gr->lo[k] = lo[k];
    /* At most GRID_SIDE_MAX + 1 (a few more after rounding): h >= ext / GRID_SIDE_MAX. The grid
     * covers every receiver, so a disc within reach of one is listed in its cell. */
    float n = floorf((hi[k] - lo[k]) * gr->inv_h) + 1.0f;
    gr->dim[k] = n < GRID_SIDE_MAX + 4 ? (int)n : GRID_SIDE_MAX + 4;
    cells *= (size_t)gr->dim[k];
  }
  gr->start = calloc(cells + 1, sizeof *gr->start);
  uint32_t *fill = malloc(cells * sizeof *fill);
  if (!gr->start || !fill) {
    free(fill);
    return obs_err_set(err, OBS_ENOMEM, "disc_ao: out of memory for the grid");
  }
  size_t total = 0;
  for (int pass = 0; pass < 2; pass++) {
    for (size_t i = 0; i < s->n; i++) {
      int c0[3], c1[3];
      if (!disc_cells(gr, &s->d[i], c0, c1)) continue;
      for (int z = c0[2]; z <= c1[2]; z++)
        for (int y = c0[1]; y <= c1[1]; y++)
          for (int x = c0[0]; x <= c1[0]; x++) {
            size_t c = ((size_t)z * (size_t)gr->dim[1] + (size_t)y) * (size_t)gr->dim[0] +
                       (size_t)x;
            if (pass)
              gr->idx[fill[c]++] = (uint32_t)i;
            else
              gr->start[c + 1]++, total++;
          }
    }
    if (pass) break;
    /* The counts into offsets: cell c holds idx[start[c], start[c + 1]). */
    if (total > GRID_ENTRIES_MAX) {
      free(fill);
      return obs_err_set(err, OBS_EINVAL,
                         "/technique/params/influence_scale: disc_ao: the discs' influence "
                         "spheres fill %zu grid cells, more than %zu; lower influence_scale",
                         total, GRID_ENTRIES_MAX);
    }
    for (size_t c = 0; c < cells; c++) gr->start[c + 1] += gr->start[c];
    memcpy(fill, gr->start, cells * sizeof *fill);
    gr->idx = malloc((total ? total : 1) * sizeof *gr->idx);
    if (!gr->idx) {
      free(fill);
      return obs_err_set(err, OBS_ENOMEM, "disc_ao: out of memory for the grid");
    }
  }
  free(fill);
  return 0;
}

static void grid_free(grid *gr) {
  free(gr->start);
  free(gr->idx);
  memset(gr, 0, sizeof *gr);
}

typedef struct disc_job {
  const obs_gbuffer *g;
  const obs_disc_set *s;
  const grid *gr;
  int side;
  float *ao, *raw;
  uint64_t *pairs;   /* per thread */
  uint32_t *most;    /* per thread */
  uint64_t *clamped; /* per thread */
} disc_job;

static int disc_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  const disc_job *j = user;
  const obs_gbuffer *g = j->g;
  const grid *gr = j->gr;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      const size_t i = (size_t)y * (size_t)g->width + (size_t)x;
      const float z = g->depth[i];
      if (!(z > 0.0f)) {
        j->ao[i] = 1.0f;
        if (j->raw) j->raw[i] = 1.0f;
        continue;
      }
      float p[3];
      obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, z, p);
      const float *nr = g->normal + 3 * i;
      size_t cell = 0;
      for (int k = 2; k >= 0; k--) {
        float f = (p[k] - gr->lo[k]) * gr->inv_h;
        int c = f <= 0.0f ? 0 : f >= (float)(gr->dim[k] - 1) ? gr->dim[k] - 1 : (int)f;
        cell = cell * (size_t)gr->dim[k] + (size_t)c;
      }
      float sum = 0.0f;
      uint32_t n = 0;
      for (uint32_t e = gr->start[cell]; e < gr->start[cell + 1]; e++) {
        float o = obs_disc_occlusion(&j->s->d[gr->idx[e]], p, nr, j->side);
        n += o > 0.0f;
        sum += o;
      }
      j->pairs[thread] += n;
      if (n > j->most[thread]) j->most[thread] = n;
      j->clamped[thread] += sum > 1.0f;
      obs_disc_ao_finish(sum, &j->ao[i], j->raw ? &j->raw[i] : NULL);
    }
  return 0;
}

/* The receivers' box: every covered pixel's view-space position. 0 when none is covered. */
static int receiver_box(const obs_gbuffer *g, float lo[3], float hi[3]) {
  int any = 0;
  for (int y = 0; y < g->height; y++)
    for (int x = 0; x < g->width; x++) {
      float z = g->depth[(size_t)y * (size_t)g->width + (size_t)x], p[3];
      if (!(z > 0.0f)) continue;
      obs_gbuffer_position(g, (float)x + 0.5f, (float)y + 0.5f, z, p);
      for (int k = 0; k < 3; k++) {
        lo[k] = any ? fminf(lo[k], p[k]) : p[k];
        hi[k] = any ? fmaxf(hi[k], p[k]) : p[k];
      }
      any = 1;
    }
  return any;
}

static int disc_passes(obs_screen_cpu *r, const obs_gbuffer *g, const obs_disc_set *s,
                       const obs_disc_ao_params *p, float *ao, float *ao_raw,
                       obs_disc_ao_stats *stats, obs_err *err) {
  if (!g || !s || !p || !ao || g->width < 1 || g->height < 1)
    return obs_err_set(err, OBS_EINVAL, "disc_ao: missing G-buffer, discs, parameters or output");
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  receiver_box(g, lo, hi);
  grid gr;
  int rc = grid_build(&gr, s, lo, hi, err);
  int threads = r->threads > 0 ? r->threads : 1;
  uint64_t *pairs = calloc((size_t)threads, sizeof *pairs);
  uint64_t *clamped = calloc((size_t)threads, sizeof *clamped);
  uint32_t *most = calloc((size_t)threads, sizeof *most);
  if (!rc && (!pairs || !clamped || !most))
    rc = obs_err_set(err, OBS_ENOMEM, "disc_ao: out of memory");
  if (!rc) {
    disc_job j = {.g = g, .s = s, .gr = &gr, .side = p->side, .ao = ao, .raw = ao_raw,
                  .pairs = pairs, .most = most, .clamped = clamped};
    r->passes = 1;
    rc = obs_screen_cpu_tiles(r, g->width, g->height, disc_tile, &j);
    if (rc && rc != OBS_ECANCELED) rc = obs_err_set(err, rc, "disc_ao: CPU pass failed");
  }
  if (!rc && stats) {
    memset(stats, 0, sizeof *stats);
    for (int t = 0; t < threads; t++) {
      stats->fragments += pairs[t];
      stats->clamped += clamped[t];
      if (most[t] > stats->max_overdraw) stats->max_overdraw = most[t];
    }
  }
  free(pairs);
  free(clamped);
  free(most);
  grid_free(&gr);
  return rc;
}

int obs_disc_ao_cpu_apply(const obs_gbuffer *g, const obs_disc_set *s, const obs_disc_ao_params *p,
                          int threads, float *ao, float *ao_raw, obs_disc_ao_stats *stats,
                          obs_err *err) {
  obs_screen_cpu r = {.threads = threads};
  return disc_passes(&r, g, s, p, ao, ao_raw, stats, err);
}

/* What the CPU passes get as their params: the bound ones and the scene the discs come from. */
typedef struct disc_run {
  const obs_disc_ao_params *p;
  const obs_scene *scene;
} disc_run;

static int passes(obs_screen_cpu *r, const obs_gbuffer *g, const void *params, float *ao,
                  float *ao_raw, obs_err *err) {
  const disc_run *run = params;
  obs_camera_rig rig;
  obs_camera_setup(&run->scene->camera, g->width, g->height, &rig);
  obs_disc_set s;
  double t0 = obs_now_ms();
  int rc = obs_disc_set_build(run->scene, &rig, run->p, &s, err);
  if (rc) return rc;
  double t1 = obs_now_ms();
  rc = disc_passes(r, g, &s, run->p, ao, ao_raw, NULL, err);
  obs_disc_set_free(&s);
  if (rc) return rc;
  obs_screen_cpu_stage(r, "discs", t1 - t0);
  obs_screen_cpu_stage(r, "ao", obs_now_ms() - t1);
  return 0;
}

int obs_disc_ao_cpu(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  disc_run run = {.p = ctx->bound, .scene = ctx->scene};
  return obs_screen_cpu_run(ctx, passes, &run, out, err);
}
