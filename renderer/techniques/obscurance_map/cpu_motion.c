/* obscurance_map for scenes with moving objects: frame 0 in full, then per frame the moving
 * meshes placed, the BVH refitted and the map updated as `update` says (every patch; the patches
 * a moving object can reach, exactly; or the article's influenced list), with each frame's times
 * and, when asked, its speed-up and error against a full recompute of the same frame. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "obscura/metrics.h"
#include "obscura/render.h"
#include "obscurance_map_cpu.h"

typedef struct motion {
  obs_render_ctx *ctx;
  obs_rt *rt;
  obs_omap_job job;
  obs_omap *map; /* carried from frame to frame */
  obs_omap full; /* a full recompute of the frame, to measure against */
  int64_t count;
  double (*pbox)[2][3];      /* count: each patch's box in frame 0 (still patches stay there) */
  unsigned char *own;        /* count: the patch is on a moving mesh */
  unsigned char *influenced; /* count: one of its samples met a moving mesh (the job's) */
  atomic_uchar *seen;        /* count: a moving patch's sample met it (article) */
  unsigned char *first;      /* count: in the article's first list of this frame */
  int64_t *list;             /* count: the patches a frame samples */
  double mbox[2][3];         /* the moving meshes' bounds in the frame before */
  float *all;                /* frames x count x 3 */
  float *all_se;             /* frames x count x 3: each frame's standard errors */
  int frame, frames, stage, stages;
} motion;

/* Progress over all frames: each frame's runs (`stages`) share its slice. */
static void motion_progress(void *user, double fraction) {
  const motion *m = user;
  if (!m->ctx->progress) return;
  double within = fmin(m->stage + fraction, m->stages) / m->stages;
  double f = (m->frame + within) / m->frames;
  m->ctx->progress(m->ctx->progress_user, f);
}

/* The runs of one frame after the first, for progress: the update's (two for the article's
 * lists) and the full recompute's. */
static int frame_stages(const obs_obscurance_map_params *p) {
  return (p->update == OBS_OMAP_UPDATE_ARTICLE ? 2 : 1) + (p->measure_full ? 1 : 0);
}

static void moving_bounds(const obs_rt *rt, double b[2][3]) {
  int first = 1;
  for (int k = 0; k < 3; k++) b[0][k] = INFINITY, b[1][k] = -INFINITY;
  for (size_t i = 0; i < rt->geo.nmeshes; i++) {
    const obs_mesh *me = &rt->geo.meshes[i];
    if (!me->obj_pos) continue;
    for (size_t v = 0; v < me->nverts; v++)
      for (int k = 0; k < 3; k++) {
        double c = me->pos[3 * v + k];
        if (first || c < b[0][k]) b[0][k] = c;
        if (first || c > b[1][k]) b[1][k] = c;
        first = 0;
      }
  }
}

/* Squared distance between two boxes (0 when they overlap). */
static double box_gap2(const double a[2][3], const double b[2][3]) {
  double d2 = 0;
  for (int k = 0; k < 3; k++) {
    double g = fmax(0.0, fmax(b[0][k] - a[1][k], a[0][k] - b[1][k]));
    d2 += g * g;
  }
  return d2;
}

/* Each patch's box and whether it moves. */
static void patch_boxes(motion *m) {
  const obs_patch_mesh *pm = &m->map->pm;
  size_t mesh = 0;
  for (int64_t p = 0; p < m->count; p++) {
    int64_t sub;
    size_t t = obs_patch_mesh_owner(pm, p, &sub);
    while (pm->mesh_tri[mesh + 1] <= t) mesh++;
    const obs_mesh *me = &m->rt->geo.meshes[mesh];
    const uint32_t *tri = me->idx + 3 * (t - pm->mesh_tri[mesh]);
    double uv[3][2];
    obs_patch_sub_corners(pm->split[t], sub, uv);
    for (int k = 0; k < 3; k++) m->pbox[p][0][k] = INFINITY, m->pbox[p][1][k] = -INFINITY;
    for (int q = 0; q < 3; q++)
      for (int k = 0; k < 3; k++) {
        const float *v0 = me->pos + 3 * (size_t)tri[0], *v1 = me->pos + 3 * (size_t)tri[1],
                    *v2 = me->pos + 3 * (size_t)tri[2];
        double c = v0[k] + uv[q][0] * ((double)v1[k] - v0[k]) + uv[q][1] * ((double)v2[k] - v0[k]);
        m->pbox[p][0][k] = fmin(m->pbox[p][0][k], c);
        m->pbox[p][1][k] = fmax(m->pbox[p][1][k], c);
      }
    m->own[p] = me->obj_pos != NULL;
  }
}

/* exact: every moving patch, and every still patch within reach of a moving mesh's bounds in the
 * frame before or this one. A sample of any other patch cannot meet the moving meshes in either
 * frame (its ray ends within d_max), so it meets what it met before: its value is unchanged bit
 * for bit. The reach is d_max plus far more than the rays' offsets and float rounding. */
static int64_t select_exact(motion *m, const double now[2][3]) {
  double reach = m->job.p.d_max * (1 + 1e-5) + 1e-5 * m->rt->geo.extent;
  double r2 = isinf(reach) ? INFINITY : reach * reach;
  int64_t n = 0;
  for (int64_t p = 0; p < m->count; p++)
    if (m->own[p] || box_gap2(m->pbox[p], m->mbox) <= r2 || box_gap2(m->pbox[p], now) <= r2)
      m->list[n++] = p;
  return n;
}

static int run_list(motion *m, obs_omap *out, const int64_t *list, int64_t n) {
  m->job.list = list;
  m->job.nlist = n;
  int rc = obs_omap_job_run(&m->job, out, m->ctx->cancel, motion_progress, m);
  m->stage++;
  return rc;
}

/* The article's update: the influenced patches and the moving ones, then the patches the moving
 * ones' samples met that were not among them. Returns the patches sampled, or a negative code. */
static int64_t update_article(motion *m) {
  int64_t n = 0;
  for (int64_t p = 0; p < m->count; p++) {
    atomic_store_explicit(&m->seen[p], 0, memory_order_relaxed);
    m->first[p] = m->own[p] || m->influenced[p];
    if (m->first[p]) m->list[n++] = p;
  }
  m->job.seen = m->seen;
  int rc = run_list(m, m->map, m->list, n);
  m->job.seen = NULL;
  if (rc) return rc;
  int64_t k = n;
  for (int64_t p = 0; p < m->count; p++)
    if (atomic_load_explicit(&m->seen[p], memory_order_relaxed) && !m->first[p]) m->list[k++] = p;
  if (k > n && (rc = run_list(m, m->map, m->list + n, k - n))) return rc;
  return k;
}

/* The frame's map against a full recompute: area-weighted RMSE over the channels, the largest
 * difference, and how many patches differ in any bit. */
static void measure(const motion *m, json_t *fj) {
  obs_patches a, b;
  memset(&a, 0, sizeof a);
  a.count = m->count, a.components = 3, a.frames = 1, a.values = m->map->w;
  a.area = m->map->pm.area;
  b = a;
  b.values = m->full.w;
  double rmse = 0, maxd = 0;
  obs_metrics_patch_rmse(&a, &b, &rmse, NULL);
  int64_t differ = 0;
  for (int64_t p = 0; p < m->count; p++) {
    int d = 0;
    for (int c = 0; c < 3; c++) {
      float x = m->map->w[3 * p + c], y = m->full.w[3 * p + c];
      maxd = fmax(maxd, fabs((double)x - y));
      d |= memcmp(&x, &y, sizeof x) != 0;
    }
    differ += d;
  }
  json_object_set_new(fj, "rmse_vs_full", json_real(rmse));
  json_object_set_new(fj, "max_abs_vs_full", json_real(maxd));
  json_object_set_new(fj, "patches_differing", json_integer((json_int_t)differ));
}

/* One frame after the first: place, update, measure. */
static int next_frame(motion *m, json_t *frames, obs_err *err) {
  const obs_scene *sc = m->ctx->scene;
  double t0 = obs_now_ms();
  int rc = obs_rt_place(m->rt, sc, m->frame, err);
  if (rc) return rc;
  double now[2][3];
  moving_bounds(m->rt, now);
  double t1 = obs_now_ms();
  int64_t n;
  switch (m->job.p.update) {
    case OBS_OMAP_UPDATE_EXACT:
      n = select_exact(m, now);
      rc = run_list(m, m->map, m->list, n);
      break;
    case OBS_OMAP_UPDATE_ARTICLE:
      n = update_article(m);
      rc = n < 0 ? (int)n : 0;
      break;
    default:
      n = m->count;
      rc = run_list(m, m->map, NULL, n);
      break;
  }
  double t2 = obs_now_ms();
  if (rc) return rc;
  memcpy(m->mbox, now, sizeof now);
  json_t *fj = json_pack("{s:i, s:f, s:f, s:I}", "frame", m->frame, "bvh_ms", t1 - t0, "update_ms",
                         t2 - t1, "patches_updated", (json_int_t)n);
  if (m->job.p.measure_full) {
    unsigned char *keep = m->job.hits_moving;
    m->job.hits_moving = NULL; /* the influenced list is the update's own */
    rc = run_list(m, &m->full, NULL, m->count);
    m->job.hits_moving = keep;
    double t3 = obs_now_ms();
    json_object_set_new(fj, "full_ms", json_real(t3 - t2));
    json_object_set_new(fj, "speedup", json_real(t2 > t1 ? (t3 - t2) / (t2 - t1) : 0));
    if (!rc) measure(m, fj);
  }
  json_array_append_new(frames, fj);
  return rc;
}

static void motion_free(motion *m) {
  obs_omap_job_free(&m->job);
  free(m->full.w);
  free(m->full.se);
  free(m->full.n);
  free(m->pbox);
  free(m->own);
  free(m->influenced);
  free(m->seen);
  free(m->first);
  free(m->list);
  free(m->all);
  free(m->all_se);
}

static int motion_init(motion *m, obs_render_ctx *ctx, obs_rt *rt,
                       const obs_obscurance_map_params *p, obs_omap *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  memset(m, 0, sizeof *m);
  m->ctx = ctx, m->rt = rt, m->map = out, m->frames = sc->frames;
  m->stages = frame_stages(p);
  int rc = obs_omap_job_init(&m->job, rt, sc, p, ctx->threads, out, err);
  if (rc) return rc;
  m->count = out->pm.count;
  size_t n1 = m->count ? (size_t)m->count : 1;
  double bytes = (double)m->frames * (double)n1 * 6 * sizeof(float); /* values and errors */
  if (bytes > (double)((size_t)1 << 31))
    return obs_err_set(err, OBS_EINVAL,
                       "%s: /objects: %d frames of %lld patches need %.1f GiB of maps, more than "
                       "2 GiB; use fewer frames or a larger /technique/params/patch_size",
                       sc->name, m->frames, (long long)m->count, bytes / (1 << 30));
  m->pbox = malloc(n1 * sizeof *m->pbox);
  m->own = calloc(n1, 1);
  m->influenced = calloc(n1, 1);
  m->seen = calloc(n1, sizeof *m->seen);
  m->first = calloc(n1, 1);
  m->list = malloc(n1 * sizeof *m->list);
  m->all = malloc((size_t)m->frames * n1 * 3 * sizeof *m->all);
  m->all_se = malloc((size_t)m->frames * n1 * 3 * sizeof *m->all_se);
  if (p->measure_full) {
    m->full.w = malloc(3 * n1 * sizeof *m->full.w);
    m->full.se = malloc(3 * n1 * sizeof *m->full.se);
    m->full.n = malloc(n1 * sizeof *m->full.n);
  }
  if (!m->pbox || !m->own || !m->influenced || !m->seen || !m->first || !m->list || !m->all ||
      !m->all_se ||
      (p->measure_full && (!m->full.w || !m->full.se || !m->full.n)))
    return obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory for %d frames", sc->name,
                       m->frames);
  m->full.pm = out->pm; /* shared, read only: not freed through `full` */
  patch_boxes(m);
  moving_bounds(rt, m->mbox);
  m->job.hits_moving = m->influenced;
  return 0;
}

int obs_omap_frames(obs_render_ctx *ctx, obs_rt *rt, const obs_obscurance_map_params *p,
                    obs_omap *out, obs_err *err) {
  const obs_scene *sc = ctx->scene;
  motion m;
  json_t *frames = json_array();
  int rc = motion_init(&m, ctx, rt, p, out, err);
  double t0 = obs_now_ms();
  if (!rc) {
    m.stages = 1; /* frame 0 is computed once, in full */
    rc = run_list(&m, m.map, NULL, m.count);
    m.stages = frame_stages(p);
  }
  if (!rc) {
    json_array_append_new(frames,
                          json_pack("{s:i, s:f, s:I}", "frame", 0, "update_ms", obs_now_ms() - t0,
                                    "patches_updated", (json_int_t)m.count));
    memcpy(m.all, out->w, (size_t)m.count * 3 * sizeof *m.all);
    memcpy(m.all_se, out->se, (size_t)m.count * 3 * sizeof *m.all_se);
  }
  for (m.frame = 1; !rc && m.frame < m.frames; m.frame++) {
    m.stage = 0;
    if ((rc = next_frame(&m, frames, err))) break; /* m.frame: the frame that failed */
    memcpy(m.all + (size_t)m.frame * (size_t)m.count * 3, out->w,
           (size_t)m.count * 3 * sizeof *m.all);
    memcpy(m.all_se + (size_t)m.frame * (size_t)m.count * 3, out->se,
           (size_t)m.count * 3 * sizeof *m.all_se);
  }
  if (rc == OBS_ECANCELED)
    obs_err_set(err, rc, "%s: render cancelled", sc->name);
  else if (rc && err && !err->count)
    obs_err_set(err, rc, "%s: obscurance_map failed in frame %d", sc->name, m.frame);
  if (!rc) rc = obs_patch_mesh_publish_frames(ctx, "obscurance", &out->pm, m.frames, 3, m.all, err);
  if (!rc)
    rc = obs_patch_mesh_publish_frames(ctx, "obscurance_stderr", &out->pm, m.frames, 3, m.all_se,
                                       err);
  if (!rc) {
    ctx->frames = frames;
    frames = NULL;
    out->rays += m.full.rays; /* the measurements were work too */
  }
  json_decref(frames);
  motion_free(&m);
  return rc;
}
