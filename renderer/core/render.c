/* Running a scene's technique on a backend, and writing its images and summary. */
#include "obscura/render.h"

#include <errno.h>
#if defined(__GLIBC__) || defined(__linux__)
#include <malloc.h>
#endif
#include <jansson.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "driver.h"
#include "extent.h"
#include "obscura/path.h"

void obs_render_keep_memory(void) {
#if defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
  /* 32 MiB is glibc's ceiling for the mmap threshold: larger blocks are always mapped afresh. */
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

double obs_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

int obs_cpu_count(void) {
  long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? (int)n : 1;
}

int obs_render(const obs_scene *scene, const obs_render_opts *opts, obs_result *res,
               obs_err *err) {
  memset(res, 0, sizeof *res);
  if (!scene || !scene->technique)
    return obs_err_set(err, OBS_EINVAL, "render: no loaded scene");
  const obs_technique *t = scene->technique;
  obs_backend be;
  int rc = obs_technique_pick_backend(t, scene->backend, &be, err);
  if (rc) return rc;
  obs_render_ctx ctx;
  memset(&ctx, 0, sizeof ctx);
  ctx.scene = scene;
  ctx.params = scene->params;
  ctx.threads = opts && opts->threads > 0 ? opts->threads : obs_cpu_count();
  if (opts) {
    ctx.progress = opts->progress;
    ctx.progress_user = opts->progress_user;
    ctx.cancel = opts->cancel;
    ctx.region = opts->region;
  }
  obs_region region;
  if ((rc = obs_driver_region(&ctx, scene->width, scene->height, &region, err))) return rc;
  /* Outside its backend's guaranteed range a render still runs, but says so (docs/accuracy.md). */
  obs_extent ex;
  rc = obs_scene_extent(scene, &ex, err);
  if (rc) return rc;
  obs_range_check(&t->range[be], t->name, be, scene, &ex, &ctx);
  void *bound = NULL;
  rc = obs_params_bind_new(t, scene->params, &bound, err);
  if (rc) return rc;
  ctx.bound = bound;
  double t0 = obs_now_ms();
  /* What the technique's needs ask is built once here, before its run, which is handed it. */
  const obs_needs_builder *nb = obs_backend_needs_builder(be);
  void *built = NULL;
  if (nb && (rc = nb->build(&ctx, t->needs, &built, err))) {
    free(bound);
    return rc;
  }
  ctx.build_ms = obs_now_ms() - t0;
  if ((rc = obs_driver_cancelled(&ctx, err)) == 0) rc = t->run[be](&ctx, &res->image, err);
  if (nb) nb->release(built);
  free(bound);
  if (rc) return rc;
  res->technique = t;
  res->backend = be;
  res->rays = ctx.rays;
  res->threads = ctx.threads;
  res->timings.build_ms = ctx.build_ms;
  res->timings.render_ms = ctx.render_ms;
  res->timings.total_ms = obs_now_ms() - t0;
  res->nstages = ctx.nstages;
  for (int i = 0; i < ctx.nstages; i++) {
    res->stage_names[i] = ctx.stage_names[i];
    res->stage_ms[i] = ctx.stage_ms[i];
  }
  res->nwarnings = ctx.nwarnings;
  memcpy(res->warnings, ctx.warnings, sizeof res->warnings);
  return 0;
}

void obs_render_ctx_stage(obs_render_ctx *ctx, const char *name, double ms) {
  if (ctx->nstages >= OBS_MAX_STAGES) return;
  ctx->stage_names[ctx->nstages] = name;
  ctx->stage_ms[ctx->nstages++] = ms;
}

void obs_render_ctx_warn(obs_render_ctx *ctx, const char *fmt, ...) {
  if (ctx->nwarnings >= OBS_MAX_WARNINGS) return;
  char *w = ctx->warnings[ctx->nwarnings];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(w, OBS_WARNING_LEN, fmt, ap);
  va_end(ap);
  for (int i = 0; i < ctx->nwarnings; i++)
    if (!strcmp(ctx->warnings[i], w)) return;
  ctx->nwarnings++;
}

void obs_result_free(obs_result *res) {
  if (!res) return;
  obs_image_free(&res->image);
  memset(res, 0, sizeof *res);
}

json_t *obs_result_summary_json(const obs_result *r, const obs_scene *sc) {
  json_t *o = json_object();
  json_object_set_new(o, "scene", json_string(sc->name));
  json_object_set_new(o, "technique", json_string(r->technique->name));
  json_object_set_new(o, "backend", json_string(obs_backend_name(r->backend)));
  json_object_set_new(o, "width", json_integer(r->image.width));
  json_object_set_new(o, "height", json_integer(r->image.height));
  json_object_set_new(o, "spp", json_integer(sc->spp));
  json_t *samples = json_object_get(sc->params, "samples");
  json_object_set_new(o, "samples", samples ? json_copy(samples) : json_null());
  json_object_set_new(o, "params", json_deep_copy(sc->params));
  json_object_set_new(o, "threads", json_integer(r->threads));
  json_t *t = json_object();
  json_object_set_new(t, "load", json_real(r->timings.load_ms));
  json_object_set_new(t, "build", json_real(r->timings.build_ms));
  json_object_set_new(t, "render", json_real(r->timings.render_ms));
  json_object_set_new(t, "write", json_real(r->timings.write_ms));
  json_object_set_new(t, "total", json_real(r->timings.total_ms));
  if (r->nstages) {
    json_t *st = json_object();
    for (int i = 0; i < r->nstages; i++)
      json_object_set_new(st, r->stage_names[i], json_real(r->stage_ms[i]));
    json_object_set_new(t, "stages", st);
  }
  json_object_set_new(o, "timings_ms", t);
  json_object_set_new(o, "rays", json_integer((json_int_t)r->rays));
  double secs = r->timings.render_ms / 1e3;
  json_object_set_new(o, "rays_per_second", json_real(secs > 0 ? (double)r->rays / secs : 0));
  obs_stats st;
  int64_t nonfinite = 0;
  for (int c = 0; c < r->image.nchannels; c++) {
    if (obs_metrics_stats(&r->image, r->image.names[c], NULL, &st, NULL) == 0)
      nonfinite += st.nan_count + st.inf_count;
  }
  if (obs_metrics_stats(&r->image, "ao", NULL, &st, NULL) == 0) {
    json_t *a = json_object();
    json_object_set_new(a, "mean", json_real(st.mean));
    json_object_set_new(a, "min", json_real(st.min));
    json_object_set_new(a, "max", json_real(st.max));
    json_object_set_new(o, "ao", a);
  }
  if (obs_image_channel(&r->image, "ao_stderr") &&
      obs_metrics_stats(&r->image, "ao_stderr", "alpha", &st, NULL) == 0)
    json_object_set_new(o, "ao_stderr_mean", json_real(st.mean));
  json_object_set_new(o, "nan_count", json_integer(nonfinite));
  json_t *w = json_array();
  for (int i = 0; i < r->nwarnings; i++) json_array_append_new(w, json_string(r->warnings[i]));
  json_object_set_new(o, "warnings", w);
  return o;
}

/* depth.png: linear view depth, nearest covered pixel white and farthest 10 % grey (so the farthest
 * surface still stands out from the black background), linear in between. */
#define DEPTH_PNG_FAR 0.1f

/* The display images derived from the AO image: "bent_normal" (RGB = n * 0.5 + 0.5 where covered)
 * and "depth" (see DEPTH_PNG_FAR); background pixels (alpha <= 0) are black in both. Fills `out`
 * with channels R, G, B or Y; returns 1 when the source channels are absent (nothing to write). */
static int display_image(const obs_image *img, int depth, obs_image *out, obs_err *err) {
  static const char *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"};
  const float *a = obs_image_channel(img, "alpha");
  const float *src[3] = {NULL, NULL, NULL};
  if (depth) {
    src[0] = obs_image_channel(img, "depth.Z");
    if (!src[0]) return 1;
  } else {
    src[0] = obs_image_channel(img, "bent_normal.X");
    src[1] = obs_image_channel(img, "bent_normal.Y");
    src[2] = obs_image_channel(img, "bent_normal.Z");
    if (!src[0] || !src[1] || !src[2]) return 1;
  }
  int rc = obs_image_init(out, img->width, img->height, depth ? 1 : 3, depth ? y : rgb, err);
  if (rc) return rc;
  size_t n = (size_t)img->width * (size_t)img->height;
#define COVERED(i) ((a ? a[i] > 0.0f : 1) && isfinite(src[0][i]))
  if (depth) {
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++)
      if (COVERED(i) && src[0][i] > 0.0f) {
        if (src[0][i] < lo) lo = src[0][i];
        if (src[0][i] > hi) hi = src[0][i];
      }
    float *o = out->data;
    for (size_t i = 0; i < n; i++) {
      if (!COVERED(i) || !(src[0][i] > 0.0f)) continue;
      float t = hi > lo ? (src[0][i] - lo) / (hi - lo) : 0.0f;
      o[i] = 1.0f - (1.0f - DEPTH_PNG_FAR) * t;
    }
  } else {
    for (int c = 0; c < 3; c++) {
      float *o = out->data + (size_t)c * n;
      for (size_t i = 0; i < n; i++)
        if (COVERED(i)) o[i] = src[c][i] * 0.5f + 0.5f;
    }
  }
#undef COVERED
  return 0;
}

/* Every image file takes the writer's defaults (obs_exr_opts_default, obs_png_opts_default): the
 * candidates were measured per output on the displaced sphere (docs/performance.md, "Writing
 * outputs") and the same setting won for ao.png, bent_normal.png and depth.png. */
enum { F_EXR, F_PNG, F_BENT, F_DEPTH, F_SUMMARY, NFILES };

/* One output file being written on some thread; its own obs_err so threads never share one. */
typedef struct out_job {
  const obs_image *img;
  const char *const *ch;
  int nch;
  int png;                 /* 0: the EXR */
  int threads;             /* EXR chunk threads */
  const char *path;
  int rc;
  obs_err err;
} out_job;

static void out_job_run(out_job *j) {
  if (j->png) {
    j->rc = obs_image_write_png(j->img, j->ch, j->nch, 0, j->path, &j->err);
  } else {
    obs_exr_opts eo = obs_exr_opts_default();
    eo.threads = j->threads;
    j->rc = obs_image_write_exr_opts(j->img, j->path, &eo, &j->err);
  }
}

static void *out_job_thread(void *arg) {
  out_job_run(arg);
  return NULL;
}

/* Writes the image files: with one thread in file order; with more, the EXR on the calling
 * thread (its chunks compressed on threads - 1 threads) while each PNG has a thread of its own.
 * Each file's bytes are the same either way. Returns the first failure in file order. */
static int write_images(out_job *jobs, int njobs, int threads, obs_err *err) {
  pthread_t tid[NFILES];
  int started[NFILES] = {0};
  if (threads > 1)
    for (int i = 1; i < njobs; i++)
      started[i] = pthread_create(&tid[i], NULL, out_job_thread, &jobs[i]) == 0;
  jobs[0].threads = threads > 1 ? threads - 1 : 1;
  out_job_run(&jobs[0]);
  for (int i = 1; i < njobs; i++) {
    if (started[i])
      pthread_join(tid[i], NULL);
    else
      out_job_run(&jobs[i]);
  }
  int rc = 0;
  for (int i = 0; i < njobs; i++) {
    if (jobs[i].rc && !rc) {
      rc = jobs[i].rc;
      obs_err_set(err, rc, "%s", obs_err_message(&jobs[i].err));
    }
    obs_err_free(&jobs[i].err);
  }
  return rc;
}

int obs_result_write(obs_result *r, const obs_scene *sc, const char *dir, obs_err *err) {
  double t0 = obs_now_ms();
  int rc = obs_path_make_dirs(dir, err);
  if (rc) return rc;
  /* Every file is written under a staging name first and the set is renamed into place only
   * when all succeeded, so a failure never mixes new and old outputs. */
  static const char *const names[NFILES] = {"ao.exr", "ao.png", "bent_normal.png", "depth.png",
                                            "summary.json"};
  static const char *const ao[1] = {"ao"}, *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"};
  char stage[NFILES][4200], final[NFILES][4200];
  int written[NFILES] = {0};
  for (int i = 0; i < NFILES; i++) {
    snprintf(stage[i], sizeof stage[i], "%s/.%s.new", dir, names[i]);
    snprintf(final[i], sizeof final[i], "%s/%s", dir, names[i]);
  }
  obs_image disp[2];
  memset(disp, 0, sizeof disp);
  out_job jobs[NFILES];
  int file_of[NFILES], njobs = 0;
  memset(jobs, 0, sizeof jobs);
  jobs[njobs] = (out_job){&r->image, NULL, 0, 0, 1, stage[F_EXR], 0, OBS_ERR_INIT};
  file_of[njobs++] = F_EXR;
  jobs[njobs] = (out_job){&r->image, ao, 1, 1, 1, stage[F_PNG], 0, OBS_ERR_INIT};
  file_of[njobs++] = F_PNG;
  for (int f = F_BENT; f <= F_DEPTH && !rc; f++) {
    obs_image *d = &disp[f - F_BENT];
    int have = display_image(&r->image, f == F_DEPTH, d, err);
    if (have < 0) rc = have;
    if (have != 0) continue;
    jobs[njobs] = (out_job){d, f == F_DEPTH ? y : rgb, f == F_DEPTH ? 1 : 3, 1, 1, stage[f], 0,
                            OBS_ERR_INIT};
    file_of[njobs++] = f;
  }
  if (!rc) {
    rc = write_images(jobs, njobs, r->threads > 0 ? r->threads : 1, err);
    for (int i = 0; i < njobs; i++) written[file_of[i]] = jobs[i].rc == 0;
  }
  obs_image_free(&disp[0]);
  obs_image_free(&disp[1]);
  if (!rc) {
    /* A second write of the same result (the server retries after a disk fault) replaces the
     * first one's time in the total instead of adding to it. */
    r->timings.total_ms -= r->timings.write_ms;
    r->timings.write_ms = obs_now_ms() - t0;
    r->timings.total_ms += r->timings.write_ms;
    json_t *sum = obs_result_summary_json(r, sc);
    if (json_dump_file(sum, stage[F_SUMMARY], JSON_INDENT(2) | JSON_REAL_PRECISION(9)))
      rc = obs_err_set(err, OBS_EIO, "%s: cannot write summary", stage[F_SUMMARY]);
    else
      written[F_SUMMARY] = 1;
    json_decref(sum);
  }
  for (int i = 0; !rc && i < NFILES; i++)
    if (written[i] && rename(stage[i], final[i]))
      rc = obs_err_set(err, OBS_EIO, "%s: cannot rename into place: %s", final[i],
                       strerror(errno));
  if (rc)
    for (int i = 0; i < NFILES; i++) unlink(stage[i]);
  else /* an earlier render's display images must not outlive it (this technique has none) */
    for (int i = 0; i < NFILES; i++)
      if (!written[i]) unlink(final[i]);
  return rc;
}
