/* volume_ao on Vulkan: the CPU's per-pixel isosurface ray casting with ray-marched AO, bent
 * normals and environment light (cpu.c) as one compute shader
 * (shaders/volume_ao.comp.glsl) over the scene's volumes in 3D textures
 * (volume_textures_vk.h).
 *
 * Precision: the device computes in float, so the host removes what float cannot carry. Every
 * world-space quantity the shader sees is relative to a reference point Q on the view axis at the
 * depth of the volumes' common centre, and each volume's maps between that frame and its data
 * space are composed in double here. Camera rays start at Q's depth plane (the point where the
 * ray crosses it), not at the eye, so a narrow field of view seen from far away (fov_y 1e-3
 * degrees puts the eye ~3e5 sizes off) marches with the precision of the volume's own size.
 * Scale and translation cancel in double before anything is rounded to float.
 *
 * The push block, the image bindings and the parameter buffer's rows are layout.h's, which the
 * shader includes too. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "driver_prior.h"
#include "environment.h"
#include "layout.h"
#include "obscura/render.h"
#include "sampling.h"
#include "session_vk.h"
#include "shaders.h"
#include "techniques.h"
#include "vk.h"
#include "volume_ao.h"
#include "volume_march.h"
#include "volume_scene.h"
#include "volume_textures_vk.h"


/* The codes the push block carries (layout.h) against the C enums they mirror. */
_Static_assert(OBS_VAO_IBL_LOOKUP == OBS_IBL_BENT_NORMAL_LOOKUP &&
                   OBS_VAO_IBL_IRRADIANCE == OBS_IBL_IRRADIANCE &&
                   OBS_VAO_IBL_REFERENCE == OBS_IBL_REFERENCE,
               "layout.h's OBS_VAO_IBL_* against obs_volume_ao_ibl");
_Static_assert(OBS_VAO_SAMPLER_SOBOL == OBS_SAMPLER_SOBOL &&
                   OBS_VAO_SAMPLER_HALTON == OBS_SAMPLER_HALTON &&
                   OBS_VAO_SAMPLER_RANDOM == OBS_SAMPLER_RANDOM,
               "layout.h's OBS_VAO_SAMPLER_* against obs_sampler_kind");
_Static_assert(sizeof(obs_vao_push) <= OBS_VK_PUSH_MAX, "push constants past the device layer's");

/* A band of rows holds about this many AO directions per dispatch, and one obs_vk_run at most
 * GROUP dispatches: progress and cancellation come between runs, and no dispatch runs long. */
#define BAND_WORK ((double)(1 << 22))
#define GROUP 256
/* Loop iterations per invocation and dispatch where the device sets no limit: bounds a dispatch's
 * length on GPUs. */
#define ITERS_UNLIMITED (1 << 20)

static void put4(float *row, double a, double b, double c, double d) {
  row[0] = (float)a, row[1] = (float)b, row[2] = (float)c, row[3] = (float)d;
}

/* The reference point's depth: the centre of the volumes' world-space bounds along the view
 * axis, or the eye when that centre is behind it. */
static double reference_depth(const obs_scene_volumes *vs, const obs_camera_rig *rig) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t k = 0; k < vs->n; k++)
    for (int c = 0; c < 8; c++) {
      double p[3], w[3];
      for (int a = 0; a < 3; a++) p[a] = (c >> a & 1) ? vs->v[k].v.n[a] * vs->v[k].v.spacing[a] : 0;
      obs_affine_point(vs->v[k].to_world, p, w);
      for (int a = 0; a < 3; a++) lo[a] = fmin(lo[a], w[a]), hi[a] = fmax(hi[a], w[a]);
    }
  double t = 0;
  for (int a = 0; a < 3; a++) t += (0.5 * (lo[a] + hi[a]) - rig->origin[a]) * rig->forward[a];
  return t > 0 && isfinite(t) ? t : 0;
}

/* One volume's rows, its maps composed with the shift to Q in double. */
static void put_volume(float *r, const obs_scene_volume *sv, const obs_vk_volume_atlas *at,
                       size_t k, const double q[3], size_t cmap_first) {
  const obs_volume *v = &sv->v;
  for (int i = 0; i < 3; i++) {
    const double *m = sv->to_data[i], *w = sv->to_world[i];
    put4(r + 4 * (OBS_VAO_V_TO_DATA + i), m[0], m[1], m[2],
         m[0] * q[0] + m[1] * q[1] + m[2] * q[2] + m[3]);
    put4(r + 4 * (OBS_VAO_V_TO_WORLD + i), w[0], w[1], w[2], w[3] - q[i]);
    put4(r + 4 * (OBS_VAO_V_NORMAL + i), sv->normal[i][0], sv->normal[i][1], sv->normal[i][2], 0);
  }
  double smin = fmin(v->spacing[0], fmin(v->spacing[1], v->spacing[2]));
  put4(r + 4 * OBS_VAO_V_EXTENT, v->n[0] * v->spacing[0], v->n[1] * v->spacing[1],
       v->n[2] * v->spacing[2],
       sv->iso);
  put4(r + 4 * OBS_VAO_V_SPACING, v->spacing[0], v->spacing[1], v->spacing[2], smin);
  put4(r + 4 * OBS_VAO_V_DIMS, v->n[0], v->n[1], v->n[2], (double)sv->ncolormap);
  put4(r + 4 * OBS_VAO_V_AT, at->at[k][0], at->at[k][1], at->at[k][2], (double)cmap_first);
  put4(r + 4 * OBS_VAO_V_CELLS, sv->cells.n[0], sv->cells.n[1], sv->cells.n[2], sv->cells.cell);
  put4(r + 4 * OBS_VAO_V_CELL_AT, at->cell_at[k][0], at->cell_at[k][1], at->cell_at[k][2], 0);
}

/* The lights the technique shades with (point and directional; quads are ignored). */
static size_t punctual_lights(const obs_scene *sc) {
  size_t n = 0;
  for (size_t i = 0; i < sc->nlights; i++) n += sc->lights[i].type != OBS_LIGHT_QUAD;
  return n;
}

typedef struct job {
  const obs_scene *sc;
  const obs_scene_volumes *vs;
  const obs_env *env;
  obs_volume_ao_tparams p;
  obs_camera_rig rig;
  double t_end;   /* where the AO march's grid ends */
  int32_t last;   /* its last index; -1: no march */
  obs_region rg;  /* the region rendered */
  obs_image *out; /* the render's image */
} job;

/* The whole parameter buffer (malloc'd, *rows rows of 4 floats). */
static float *build_params(const job *jb, const obs_vk_volume_atlas *at, size_t *rows) {
  const obs_scene *sc = jb->sc;
  const obs_scene_volumes *vs = jb->vs;
  size_t ncmap = 0, nl = punctual_lights(sc);
  for (size_t k = 0; k < vs->n; k++) ncmap += vs->v[k].ncolormap;
  *rows = OBS_VAO_H_COUNT + vs->n * OBS_VAO_V_COUNT + nl * OBS_VAO_L_COUNT + ncmap;
  float *b = calloc(*rows * 4, sizeof *b);
  if (!b) return NULL;
  const obs_camera_rig *rig = &jb->rig;
  double tq = reference_depth(vs, rig), q[3];
  for (int a = 0; a < 3; a++) q[a] = rig->origin[a] + tq * rig->forward[a];
  const double *f = rig->forward, *r = rig->right, *u = rig->up;
  put4(b + 4 * OBS_VAO_H_FWD, f[0], f[1], f[2], tq);
  put4(b + 4 * OBS_VAO_H_RIGHT, r[0], r[1], r[2], rig->half_w);
  put4(b + 4 * OBS_VAO_H_UP, u[0], u[1], u[2], rig->half_h);
  put4(b + 4 * OBS_VAO_H_MARCH, jb->p.start, jb->p.step, jb->t_end, jb->p.shininess);
  put4(b + 4 * OBS_VAO_H_ATLAS, 1.0 / at->dims[0], 1.0 / at->dims[1], 1.0 / at->dims[2],
       jb->p.specular);
  double mean[3] = {1, 1, 1}, sh[9][3] = {{0}};
  if (jb->env) obs_env_mean(jb->env, mean);
  if (jb->env && jb->p.ibl == OBS_IBL_IRRADIANCE) obs_env_sh9(jb->env, sh);
  put4(b + 4 * OBS_VAO_H_ENV_MEAN, mean[0], mean[1], mean[2], 0);
  for (int k = 0; k < 9; k++) put4(b + 4 * (OBS_VAO_H_SH + k), sh[k][0], sh[k][1], sh[k][2], 0);
  float *row = b + 4 * OBS_VAO_H_COUNT;
  float *cm = b + 4 * (OBS_VAO_H_COUNT + vs->n * OBS_VAO_V_COUNT + nl * OBS_VAO_L_COUNT);
  size_t first = 0;
  for (size_t k = 0; k < vs->n; k++, row += 4 * OBS_VAO_V_COUNT) {
    const obs_scene_volume *sv = &vs->v[k];
    put_volume(row, sv, at, k, q, first);
    for (size_t i = 0; i < sv->ncolormap; i++, first++)
      put4(cm + 4 * first, sv->colormap[4 * i], sv->colormap[4 * i + 1], sv->colormap[4 * i + 2],
           sv->colormap[4 * i + 3]);
  }
  for (size_t i = 0; i < sc->nlights; i++) {
    const obs_light *li = &sc->lights[i];
    if (li->type == OBS_LIGHT_QUAD) continue;
    if (li->type == OBS_LIGHT_POINT)
      put4(row + 4 * OBS_VAO_L_POS, li->position.x - q[0], li->position.y - q[1],
           li->position.z - q[2], 0);
    else
      put4(row + 4 * OBS_VAO_L_POS, li->direction.x, li->direction.y, li->direction.z, 1);
    put4(row + 4 * OBS_VAO_L_EMISSION, li->emission.x, li->emission.y, li->emission.z, 0);
    row += 4 * OBS_VAO_L_COUNT;
  }
  return b;
}

/* The AO march's grid as the CPU's obs_volume_grid_crossing sets it up, in double. A grid that
 * float cannot step along (the whole march within one float of its start) samples its start
 * alone: every sample would read the same value, and equal values never cross. */
static void march_grid(job *jb) {
  const obs_volume_ao_tparams *p = &jb->p;
  jb->t_end = p->start;
  jb->last = -1;
  if (!(p->step > 0) || !(p->max_distance >= p->start) || !isfinite(p->max_distance)) return;
  double last = floor((p->max_distance - p->start) / p->step + 1e-9);
  if (!(last <= OBS_VOLUME_AO_MAX_STEPS)) last = OBS_VOLUME_AO_MAX_STEPS;
  jb->t_end = p->start + last * p->step;
  jb->last = (int32_t)last;
  if (!((float)p->step > 0) || !((float)jb->t_end > (float)p->start)) {
    jb->t_end = p->start;
    jb->last = 0;
  }
}

/* Whether the ibl method looks the environment up (irradiance reads its SH9 coefficients). */
static int reads_env(const obs_volume_ao_tparams *p) {
  return p->ibl == OBS_IBL_BENT_NORMAL_LOOKUP || p->ibl == OBS_IBL_REFERENCE;
}

/* What the device holds for one render. */
typedef struct dev {
  obs_vk_volume_atlas atlas;
  obs_vk_texture *env;
  obs_vk_data *params;
  /* The shader's acc0..acc2 (the outputs at the end: (R, G, B, ao), (bent normal, depth),
   * (normal, alpha)), st0, st1 (the sample in progress; st1.w the loop-limit flag) and st2 (the
   * replicates of the sample in progress, and in w the pixel's AO variance, at the end its
   * standard error), indexed by their bindings OBS_VAO_B_*. */
  obs_vk_image *img[OBS_VAO_IMAGES];
  obs_vk_image *pilot[OBS_VAO_IMAGES]; /* the same for the prior's pilots, one texel per cell */
  obs_prior_grid grid;       /* the cells of the region's prior */
  int env_linear;
} dev;

static void dev_free(obs_vk *vk, dev *d) {
  obs_vk_volume_atlas_free(vk, &d->atlas);
  obs_vk_texture_free(vk, d->env);
  obs_vk_data_free(vk, d->params);
  for (int i = 0; i < OBS_VAO_IMAGES; i++)
    obs_vk_image_free(vk, d->img[i]), obs_vk_image_free(vk, d->pilot[i]);
  obs_prior_grid_free(&d->grid);
  memset(d, 0, sizeof *d);
}

/* Uploads the volumes, the environment (when an ibl method reads it) and the parameters, and
 * creates the output images (the region's size). */
static int dev_build(obs_vk *vk, const job *jb, const obs_region *rg, dev *d, obs_err *err) {
  int rc = obs_vk_volume_atlas_build(vk, jb->vs, &d->atlas, err);
  if (!rc)
    rc = obs_vk_env_texture(vk, reads_env(&jb->p) ? jb->env : NULL, &d->env, &d->env_linear, err);
  size_t rows = 0;
  float *b = rc ? NULL : build_params(jb, &d->atlas, &rows);
  if (!rc && !b) rc = obs_err_set(err, OBS_ENOMEM, "%s: volume_ao: out of memory", jb->sc->name);
  if (!rc) rc = obs_vk_data_create(vk, b, rows * 4 * sizeof *b, &d->params, err);
  free(b);
  for (int i = 0; i < OBS_VAO_IMAGES && !rc; i++)
    rc = obs_vk_image_create(vk, rg->x1 - rg->x0, rg->y1 - rg->y0, 4, &d->img[i], err);
  if (!rc && obs_prior_grid_init(&d->grid, rg, jb->sc->width, jb->sc->height, 1))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: volume_ao: out of memory", jb->sc->name);
  for (int i = 0; i < OBS_VAO_IMAGES && !rc; i++)
    rc = obs_vk_image_create(vk, d->grid.ncx, d->grid.ncy, 4, &d->pilot[i], err);
  return rc;
}

static void progress(obs_render_ctx *ctx, double fraction) {
  if (ctx->progress) ctx->progress(ctx->progress_user, fraction);
}

/* The length of the longest chord of volume k's box in world units (its longest diagonal). */
static double world_diagonal(const obs_scene_volume *sv) {
  double best = 0;
  for (int c = 0; c < 4; c++) {
    double e[3] = {sv->v.n[0] * sv->v.spacing[0] * (c & 1 ? -1 : 1),
                   sv->v.n[1] * sv->v.spacing[1] * (c & 2 ? -1 : 1), sv->v.n[2] * sv->v.spacing[2]},
           w[3];
    obs_affine_dir(sv->to_world, e, w);
    best = fmax(best, sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]));
  }
  return best;
}

static double data_diagonal(const obs_scene_volume *sv) {
  double s = 0;
  for (int a = 0; a < 3; a++) s += pow(sv->v.n[a] * sv->v.spacing[a], 2);
  return sqrt(s);
}

/* Upper bounds of the shader's counted loop iterations (its `iters`): for one pixel sample apart
 * from its AO directions (the first hit over every volume: half-voxel steps across the box, one
 * per macrocell skipped, the bisection; sample streams, colormap, lights), and per direction
 * (the march in every volume b: its grid samples inside b's box, the direction's parameter being
 * data-space length in the volume hit, a; a chord of b is at most b's world diagonal times the
 * largest stretch of a's world-to-data map, bounded by its Frobenius norm). */
static void loop_bounds(const job *jb, double *per_sample, double *per_dir) {
  const obs_scene_volumes *vs = jb->vs;
  size_t cmap = 0;
  *per_sample = 64 + 16 + (double)vs->n + (double)punctual_lights(jb->sc);
  for (size_t k = 0; k < vs->n; k++) {
    const obs_scene_volume *sv = &vs->v[k];
    double smin = fmin(sv->v.spacing[0], fmin(sv->v.spacing[1], sv->v.spacing[2]));
    *per_sample +=
        2 * data_diagonal(sv) / smin + sv->cells.n[0] + sv->cells.n[1] + sv->cells.n[2] + 64;
    if (sv->ncolormap > cmap) cmap = sv->ncolormap;
  }
  *per_sample += (double)cmap;
  *per_dir = 0;
  for (size_t a = 0; a < vs->n; a++) {
    const double(*m)[4] = vs->v[a].to_data;
    double frob = 0, w = 1 + 64 + (double)vs->n;
    for (int i = 0; i < 3; i++)
      for (int j = 0; j < 3; j++) frob += m[i][j] * m[i][j];
    for (size_t b = 0; b < vs->n && jb->last >= 0; b++) {
      double len = b == a ? data_diagonal(&vs->v[a]) : world_diagonal(&vs->v[b]) * sqrt(frob);
      w += fmin(jb->last + 1.0, len / jb->p.step + 3);
    }
    *per_dir = fmax(*per_dir, w);
  }
}

/* The AO directions one dispatch marches: as many as the device's loop limit allows after the
 * first hit, at least one. */
static uint32_t chunk_directions(obs_vk *vk, const job *jb) {
  uint32_t limit = obs_vk_loop_limit(vk);
  double budget = limit ? (double)limit - 1024 : ITERS_UNLIMITED, per_sample, per_dir;
  loop_bounds(jb, &per_sample, &per_dir);
  double c = floor((budget - per_sample) / per_dir);
  if (!(c >= 1)) c = 1;
  return c < jb->p.samples ? (uint32_t)c : jb->p.samples;
}

/* One run's dispatches (GROUP of them at most), on the heap: a render thread's stack may be
 * small. */
typedef struct batch {
  obs_vk_pass pass[GROUP];
  obs_vao_push pc[GROUP];
  double ms[GROUP];
} batch;

/* Dispatch i of a band: pixel sample at / nchunks, its chunk at % nchunks. */
static void batch_put(batch *b, int i, const obs_vao_push *base, const dev *d, uint64_t at,
                      uint32_t chunk, uint32_t nchunks) {
  uint32_t n = base->samples, s = (uint32_t)(at / nchunks), c = (uint32_t)(at % nchunks);
  obs_vao_push *pc = &b->pc[i];
  obs_vk_image *const *img = base->pilot ? d->pilot : d->img;
  *pc = *base;
  pc->pixel_sample = (int32_t)s;
  pc->dir0 = c * chunk;
  pc->dir1 = c + 1 == nchunks ? n : (c + 1) * chunk;
  pc->phase = (c == 0 ? OBS_VAO_PH_FIRST_CHUNK : 0) |
              (c + 1 == nchunks ? OBS_VAO_PH_LAST_CHUNK : 0) |
              (s == 0 ? OBS_VAO_PH_FIRST_SAMPLE : 0) |
              (c + 1 == nchunks && (int32_t)s + 1 == base->spp ? OBS_VAO_PH_FINAL : 0);
  b->pass[i] = (obs_vk_pass){.name = "volume_ao",
                             .spirv = obs_spv_volume_ao_comp,
                             .spirv_size = obs_spv_volume_ao_comp_size,
                             .images = {img[0], img[1], img[2], img[3], img[4], img[5]},
                             .nimages = OBS_VAO_IMAGES,
                             .push = pc,
                             .push_size = sizeof *pc,
                             .groups_x = (uint32_t)(base->band[2] + 7) / 8,
                             .groups_y = (uint32_t)(base->band[3] + 7) / 8,
                             .textures = {d->atlas.data, d->atlas.cells, d->env},
                             .ntextures = 3,
                             .data = d->params};
}

/* The dispatches of one band: for each pixel sample, its directions chunk by chunk, GROUP
 * dispatches to a run. *done counts dispatches for progress. */
static int shade_band(obs_render_ctx *ctx, obs_vk *vk, const obs_vao_push *base, const dev *d,
                      uint32_t chunk, batch *b, double total, double *done, double *ms,
                      obs_err *err) {
  uint32_t nchunks = (base->samples + chunk - 1) / chunk;
  uint64_t count = (uint64_t)base->spp * nchunks;
  for (uint64_t first = 0; first < count; first += GROUP) {
    int rc = obs_driver_cancelled(ctx, err);
    if (rc) return rc;
    int m = count - first < GROUP ? (int)(count - first) : GROUP;
    for (int i = 0; i < m; i++) batch_put(b, i, base, d, first + (uint64_t)i, chunk, nchunks);
    if ((rc = obs_vk_run(vk, b->pass, m, b->ms, err))) return rc;
    for (int i = 0; i < m; i++) *ms += b->ms[i];
    *done += m;
    progress(ctx, 0.05 + 0.9 * *done / total);
  }
  return 0;
}

/* The push constants every dispatch of the render shares. */
static obs_vao_push push_base(obs_vk *vk, const job *jb, const obs_region *rg, const dev *d) {
  return (obs_vao_push){.origin = {rg->x0, rg->y0},
                    .size = {jb->sc->width, jb->sc->height},
                    .spp = jb->sc->spp,
                    .samples = jb->p.samples,
                    .sampler_kind = jb->p.sampler,
                    .seed = jb->p.seed,
                    .ibl = jb->p.ibl,
                    .crossing = jb->p.crossing,
                    .blinn = jb->p.blinn_phong,
                    .ortho = jb->rig.ortho,
                    .nvol = (int32_t)jb->vs->n,
                    .nlights = (int32_t)punctual_lights(jb->sc),
                    /* The environment texture is real when an ibl method reads it (else 1x1). */
                    .env_res = jb->env && reads_env(&jb->p) ? jb->env->res : 0,
                    .last = jb->last,
                    .flags = (d->atlas.linear ? 0 : OBS_VAO_FLAG_VOL_MANUAL) |
                             (d->env_linear ? 0 : OBS_VAO_FLAG_ENV_MANUAL) |
                             (jb->env ? OBS_VAO_FLAG_ENV : 0),
                    .iter_limit = obs_vk_loop_limit(vk)};
}

/* The dispatches over the region, a band of rows at a time, then those of the pooled prior's
 * pilots (driver.h, obs_pixel_prior: every cell's pilot OBS_PRIOR_REPLICAS times, with the
 * replicas' seeds, into the pilot images, read back after each replica into vals); *ms gets their
 * device time. */
static int shade(obs_render_ctx *ctx, obs_vk *vk, const job *jb, const obs_region *rg, const dev *d,
                 float *vals, double *ms, obs_err *err) {
  int rw = rg->x1 - rg->x0, rh = rg->y1 - rg->y0;
  uint32_t chunk = chunk_directions(vk, jb);
  obs_vao_push pc = push_base(vk, jb, rg, d);
  double per_row = (double)rw * chunk;
  int rows = per_row >= BAND_WORK ? 1 : (int)(BAND_WORK / per_row);
  if (rows > rh) rows = rh;
  int bands = (rh + rows - 1) / rows;
  uint32_t nchunks = (jb->p.samples + chunk - 1) / chunk;
  double total = (double)(bands + OBS_PRIOR_REPLICAS) * jb->sc->spp * nchunks, done = 0;
  batch *b = malloc(sizeof *b);
  size_t cells = (size_t)d->grid.ncx * (size_t)d->grid.ncy;
  float *px = malloc(cells * 4 * 3 * sizeof *px);
  if (!b || !px) {
    free(b);
    free(px);
    return obs_err_set(err, OBS_ENOMEM, "%s: volume_ao: out of memory", jb->sc->name);
  }
  *ms = 0;
  int rc = 0;
  for (int y = rg->y0; y < rg->y1 && !rc; y += rows) {
    int h = rg->y1 - y < rows ? rg->y1 - y : rows;
    pc.band[0] = rg->x0, pc.band[1] = y, pc.band[2] = rw, pc.band[3] = h;
    rc = shade_band(ctx, vk, &pc, d, chunk, b, total, &done, ms, err);
  }
  obs_vao_push pp = pc;
  pp.origin[0] = pp.origin[1] = 0;
  pp.band[0] = pp.band[1] = 0, pp.band[2] = d->grid.ncx, pp.band[3] = d->grid.ncy;
  pp.pilot = OBS_PRIOR_CELL, pp.cell0[0] = d->grid.cx0, pp.cell0[1] = d->grid.cy0;
  for (uint32_t k = 0; k < OBS_PRIOR_REPLICAS && !rc; k++) {
    pp.seed = obs_sampler_replica_seed(jb->p.seed, k + 1);
    rc = shade_band(ctx, vk, &pp, d, chunk, b, total, &done, ms, err);
    /* (R, G, B, ao), (normal, alpha), st1 (w: the loop-limit flag) */
    static const int pilot_image[3] = {OBS_VAO_B_ACC0, OBS_VAO_B_ACC2, OBS_VAO_B_ST1};
    for (int i = 0; i < 3 && !rc; i++)
      rc = obs_vk_image_download(vk, d->pilot[pilot_image[i]], px + (size_t)i * cells * 4, err);
    for (size_t c = 0; c < cells && !rc; c++) {
      if (px[2 * cells * 4 + 4 * c + 3] != 0) rc = OBS_EUNSUPPORTED;
      vals[(size_t)k * cells * 2 + 2 * c] = px[4 * c + 3];
      vals[(size_t)k * cells * 2 + 2 * c + 1] = px[cells * 4 + 4 * c + 3];
    }
    if (rc == OBS_EUNSUPPORTED)
      obs_err_set(err, rc, "%s: volume_ao on \"%s\": a pilot of the standard errors needs more "
                  "loop iterations than one shader invocation may run there; raise step or lower "
                  "max_distance", jb->sc->name, obs_vk_device_name(vk));
  }
  free(px);
  free(b);
  return rc;
}

/* The pooled prior: each cell's variance over its pilot's replicas (vals: per replica, per cell,
 * ao and alpha), combined into every pixel's standard error as the CPU's driver does. */
static double vk_df(const void *user, int c) {
  (void)c;
  const job *jb = user;
  return jb->sc->spp *
         (obs_rqmc_replicates((obs_sampler_kind)jb->p.sampler, jb->p.samples) - 1.0);
}

static uint64_t apply_prior(const job *jb, const obs_region *rg, dev *d, const float *vals,
                            obs_image *out) {
  static const obs_pixel_prior prior = {1, obs_volume_ao_se, obs_volume_ao_value, CH_ALPHA, 0, 0,
                                        vk_df};
  size_t cells = (size_t)d->grid.ncx * (size_t)d->grid.ncy;
  uint64_t rays = 0;
  for (int cy = 0; cy < d->grid.ncy; cy++)
    for (int cx = 0; cx < d->grid.ncx; cx++) {
      size_t c = (size_t)cy * (size_t)d->grid.ncx + (size_t)cx;
      double v[OBS_PRIOR_REPLICAS];
      int covered = 1;
      for (int k = 0; k < OBS_PRIOR_REPLICAS; k++) {
        float alpha = vals[(size_t)k * cells * 2 + 2 * c + 1];
        v[k] = vals[(size_t)k * cells * 2 + 2 * c];
        covered &= alpha > 0;
        rays += (uint64_t)jb->sc->spp + (uint64_t)round(alpha * jb->sc->spp) * jb->p.samples;
      }
      obs_prior_grid_set(&d->grid, cx, cy, 0, v, covered);
    }
  size_t plane = (size_t)out->width * (size_t)out->height;
  for (int y = rg->y0; y < rg->y1; y++)
    for (int x = rg->x0; x < rg->x1; x++) {
      size_t at = (size_t)y * (size_t)out->width + (size_t)x;
      float px[CH_COUNT];
      for (int c = 0; c < CH_COUNT; c++) px[c] = out->data[(size_t)c * plane + at];
      obs_prior_grid_apply(&d->grid, &prior, jb, x, y, px);
      out->data[(size_t)CH_AOSE * plane + at] = px[CH_AOSE];
    }
  return rays;
}

/* Downloads the outputs into the region of `out` and counts the rays as the CPU does (camera
 * rays, and `samples` per hit); refuses a render in which an invocation may have run into the
 * device's loop limit. */
static int readback(obs_render_ctx *ctx, obs_vk *vk, const job *jb, const obs_region *rg,
                    const dev *d, obs_image *out, obs_err *err) {
  int rw = rg->x1 - rg->x0, rh = rg->y1 - rg->y0, rc = 0;
  size_t n = (size_t)rw * (size_t)rh, plane = (size_t)out->width * (size_t)out->height;
  /* Where each channel is in the images downloaded: (R, G, B, ao), (bent normal, depth),
   * (normal, alpha), st1 (w: the loop-limit flag), st2 (w: the AO's standard error). */
  static const int src[CH_COUNT] = {0, 1, 2, 3, 19, 4, 5, 6, 8, 9, 10, 7, 11};
  static const int image[5] = {OBS_VAO_B_ACC0, OBS_VAO_B_ACC1, OBS_VAO_B_ACC2, OBS_VAO_B_ST1,
                               OBS_VAO_B_ST2};
  float *px = malloc(5 * n * 4 * sizeof *px);
  if (!px) return obs_err_set(err, OBS_ENOMEM, "%s: volume_ao: out of memory", jb->sc->name);
  for (int i = 0; i < 5 && !rc; i++)
    rc = obs_vk_image_download(vk, d->img[image[i]], px + i * n * 4, err);
  size_t limited = 0;
  for (size_t i = 0; i < n && !rc; i++) limited += px[3 * n * 4 + 4 * i + 3] != 0;
  if (limited)
    rc = obs_err_set(err, OBS_EUNSUPPORTED,
                     "%s: volume_ao on \"%s\": %zu pixel(s) need more loop iterations for one "
                     "AO direction and the first hit than one shader invocation may run there "
                     "(%u); raise step or lower max_distance",
                     jb->sc->name, obs_vk_device_name(vk), limited, obs_vk_loop_limit(vk));
  uint64_t rays = 0;
  for (size_t i = 0; i < n && !rc; i++) {
    size_t at = (size_t)(rg->y0 + (int)(i / (size_t)rw)) * (size_t)out->width + (size_t)rg->x0 +
                i % (size_t)rw;
    for (int c = 0; c < CH_COUNT; c++)
      out->data[(size_t)c * plane + at] = px[(size_t)(src[c] / 4) * n * 4 + 4 * i + src[c] % 4];
    double hits = round((double)out->data[(size_t)CH_ALPHA * plane + at] * jb->sc->spp);
    rays += (uint64_t)jb->sc->spp + (uint64_t)hits * jb->p.samples;
  }
  free(px);
  ctx->rays = rays;
  return rc;
}

/* The render on the device (obs_vk_session_fn): volumes, environment and parameters up, the
 * dispatches, the readback into the region of the image and the pooled prior. */
static int render(obs_render_ctx *ctx, obs_vk *vk, void *user, obs_err *err) {
  job *jb = user;
  const obs_region *rg = &jb->rg;
  dev d;
  memset(&d, 0, sizeof d);
  float *vals = NULL;
  double t0 = obs_now_ms();
  int rc = dev_build(vk, jb, rg, &d, err);
  if (rc) goto done;
  double t1 = obs_now_ms(), ms = 0;
  ctx->build_ms += t1 - t0;
  obs_driver_stage_add(ctx, "upload", t1 - t0);
  progress(ctx, 0.05);
  vals = malloc((size_t)OBS_PRIOR_REPLICAS * (size_t)d.grid.ncx * (size_t)d.grid.ncy * 2 *
                sizeof *vals);
  if (!vals) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: volume_ao: out of memory", jb->sc->name);
    goto done;
  }
  double ts = obs_now_ms();
  if ((rc = shade(ctx, vk, jb, rg, &d, vals, &ms, err))) goto done;
  obs_driver_stage_add(ctx, "shade", ms);
  /* What the passes' submission cost around their measured time: pipelines (compiled on first
   * use), descriptor sets, command buffers and the pilots' copies between replicas. */
  obs_driver_stage_add(ctx, "dispatch", obs_now_ms() - ts - ms);
  double t2 = obs_now_ms();
  if ((rc = readback(ctx, vk, jb, rg, &d, jb->out, err))) goto done;
  ctx->rays += apply_prior(jb, rg, &d, vals, jb->out);
  obs_driver_stage_add(ctx, "readback", obs_now_ms() - t2);
  ctx->render_ms = obs_now_ms() - t1;
done:
  free(vals);
  dev_free(vk, &d);
  return rc;
}

int obs_volume_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  memset(out, 0, sizeof *out);
  if (!ctx->volumes)
    return obs_err_set(err, OBS_EINTERNAL, "%s: volume_ao: the volumes were not read", sc->name);
  job jb = {.sc = sc, .vs = ctx->volumes, .env = ctx->environment, .out = out};
  jb.p = *(const obs_volume_ao_tparams *)ctx->bound;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &jb.rig);
  march_grid(&jb);
  int rc = obs_driver_image(ctx, CH_COUNT, obs_volume_ao_channels, out, &jb.rg, err);
  if (rc) return rc;
  obs_volume_ao_warn(ctx, jb.sc, &jb.p);
  if ((rc = obs_vk_session_run(ctx, "volume_ao", render, &jb, err))) obs_image_free(out);
  return rc;
}
