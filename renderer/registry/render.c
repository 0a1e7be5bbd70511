/* Running a scene's technique on a backend, and writing its images and summary: the registry's
 * orchestration, which finds the technique's run and asks the backend's table for its needs. */
#include "obscura/render.h"

#include <errno.h>
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
#include "environment.h"
#include "registry.h"
#include "volume_scene.h"

/* A volume technique leaves surfaces out, with a warning naming them. (A surface technique
 * renders a volume object as its extracted isosurface mesh: obs_geometry_build.) */
static void warn_ignored(const obs_scene *sc, obs_render_ctx *ctx) {
  int volumes = (sc->technique->needs & OBS_NEED_VOLUME) != 0;
  if (!volumes) return;
  char names[200] = "";
  size_t n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    if ((sc->objects[i].shape.type == OBS_SHAPE_VOLUME) == volumes) continue;
    size_t l = strlen(names);
    if (n++ < 4) snprintf(names + l, sizeof names - l, "%s\"%s\"", l ? ", " : "",
                          sc->objects[i].name);
  }
  if (!n) return;
  obs_render_ctx_warn(ctx, "technique \"%s\" renders volumes only: it ignores the surface "
                      "object%s %s%s", sc->technique->name, n > 1 ? "s" : "", names,
                      n > 4 ? " and more" : "");
}

int obs_render_brick_check(const obs_scene *sc, obs_err *err) {
  const obs_technique *t = sc->technique;
  if (!(t->needs & OBS_NEED_VOLUME))
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "%s: technique \"%s\" renders no volumes, so it cannot render one brick "
                       "of them (a data-parallel render needs a volume technique such as "
                       "volume_ao)",
                       sc->name, t->name);
  if (obs_render_brick_backend(sc) != OBS_BACKEND_CPU || !t->run[OBS_BACKEND_CPU])
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "%s: technique \"%s\" renders one brick of a volume (a data-parallel "
                       "render) on the cpu backend only, not on %s",
                       sc->name, t->name, obs_backend_name(sc->backend));
  return 0;
}

obs_backend obs_render_brick_backend(const obs_scene *sc) {
  return sc->backend == OBS_BACKEND_AUTO ? OBS_BACKEND_CPU : sc->backend;
}

/* What obs_render builds for a technique's needs before its run, released after it. */
typedef struct render_needs {
  const obs_needs_builder *nb; /* the backend's builder (BVH, ...), or NULL */
  void *state;                 /* what it built */
  obs_scene_volumes vols;
  const obs_technique *t;      /* whose prepare hook built `prepared` */
  obs_prepared *prepared;
  obs_env env;
} render_needs;

static void needs_release(render_needs *n) {
  obs_scene_volumes_free(&n->vols);
  if (n->prepared && n->t->release) n->t->release(n->prepared);
  n->prepared = NULL;
  obs_env_free(&n->env);
  if (n->nb) n->nb->release(n->state);
  n->nb = NULL;
}

/* Builds what the technique's needs ask, once, for every backend its way, into `n` and the
 * context (ctx->rt and the like, ctx->volumes, ctx->prepared, ctx->environment; ctx->built
 * lists what has a size). On failure releases what it built. */
static int needs_build(obs_render_ctx *ctx, const obs_technique *t, obs_backend be,
                       const obs_brick *brick, const void *bound, render_needs *n, obs_err *err) {
  memset(n, 0, sizeof *n);
  const obs_scene *scene = ctx->scene;
  n->nb = obs_backend_needs_builder(be);
  int rc = n->nb ? n->nb->build(ctx, t->needs, &n->state, err) : 0;
  if (rc) n->nb = NULL;
  /* Volumes are read the same way for every backend, so here rather than by a backend's builder. */
  if (!rc && t->needs & OBS_NEED_VOLUME) {
    double reach = brick && t->volume_reach ? t->volume_reach(bound) : 0;
    int sides = obs_backend_volume_sides(be);
    rc = obs_scene_volumes_load_brick(scene, brick, reach, sides, &n->vols, err);
    if (!rc) ctx->volumes = &n->vols;
  }
  /* What only this technique needs, its own way (proximity_ao: its proximity fields). */
  if (!rc && t->prepare) {
    n->t = t;
    rc = t->prepare(ctx, be, &n->prepared, err);
    if (!rc) ctx->prepared = n->prepared;
  }
  if (!rc && t->needs & OBS_NEED_ENV_MAP && scene->has_environment) {
    rc = obs_env_from_scene(scene, &n->env, err);
    if (!rc) ctx->environment = &n->env;
  }
  if (rc) needs_release(n);
  return rc;
}

/* Adds stage `name` with what of `span_ms` the stages from index `from` on do not cover; a
 * negative rest (stages that overlap) is kept as it is, so the accounting shows the fault. */
static void stage_rest(obs_render_ctx *ctx, const char *name, double span_ms, int from) {
  double named = 0;
  for (int i = from; i < ctx->nstages; i++) named += ctx->stage_ms[i];
  obs_driver_stage_add(ctx, name, span_ms - named);
}

static int render(const obs_scene *scene, const obs_render_opts *opts, obs_result *res,
                  obs_err *err) {
  if (!scene || !scene->technique)
    return obs_err_set(err, OBS_EINVAL, "render: no loaded scene");
  const obs_technique *t = scene->technique;
  obs_backend be;
  int rc = obs_technique_pick_backend(t, scene->backend, &be, err);
  if (rc) return rc;
  /* A moving scene runs only where the technique renders frames (the loader refuses another
   * backend asked for by name; auto picks among them). */
  be = obs_technique_motion_backend(t, scene, be);
  if (scene->frames > 1 && !(t->motion_backends & (1u << be)))
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "%s: /technique/backend: technique \"%s\" renders no moving objects "
                       "(motion) on the %s backend",
                       scene->name, t->name, obs_backend_name(be));
  obs_render_ctx ctx;
  memset(&ctx, 0, sizeof ctx);
  ctx.scene = scene;
  ctx.params = scene->params;
  ctx.threads = opts && opts->threads > 0 ? opts->threads : obs_cpu_count();
  ctx.patches = res->patches;
  if (opts) {
    ctx.progress = opts->progress;
    ctx.progress_user = opts->progress_user;
    ctx.cancel = opts->cancel;
    ctx.region = opts->region;
    ctx.tiles = opts->tiles;
    ctx.watch = opts->watch;
  }
  obs_region region;
  if ((rc = obs_driver_region(&ctx, scene->width, scene->height, &region, err))) return rc;
  const obs_brick *brick = opts && opts->brick.count > 0 ? &opts->brick : NULL;
  if (brick && (rc = obs_render_brick_check(scene, err))) return rc;
  if (brick) be = obs_render_brick_backend(scene);
  /* Outside its backend's guaranteed range a render still runs, but says so (docs/accuracy.md). */
  obs_extent ex;
  rc = obs_scene_extent(scene, &ex, err);
  if (rc) return rc;
  obs_range_check(&t->range[be], t->name, obs_backend_name(be), scene, &ex, &ctx);
  void *bound = NULL;
  rc = obs_params_bind_new(t, scene->params, &bound, err);
  if (rc) return rc;
  ctx.bound = bound;
  double t0 = obs_now_ms();
  ctx.built = json_array();
  render_needs needs;
  if ((rc = needs_build(&ctx, t, be, brick, bound, &needs, err))) {
    json_decref(ctx.built);
    free(bound);
    return rc;
  }
  warn_ignored(scene, &ctx);
  double t1 = obs_now_ms();
  ctx.build_ms = t1 - t0;
  /* Every millisecond of the total lands in one stage: what the needs took beyond the stages
   * they named ("prepare": BVH, volumes, environment), then the technique's own stages, then what
   * its run spent outside them ("other": allocations, host copies, output assembly). */
  stage_rest(&ctx, "prepare", ctx.build_ms, 0);
  int named = ctx.nstages;
  if ((rc = obs_driver_cancelled(&ctx, err)) == 0) rc = t->run[be](&ctx, &res->image, err);
  needs_release(&needs);
  free(bound);
  res->npatches = ctx.npatches;
  res->frames = ctx.frames;
  res->built = ctx.built;
  if (rc) {
    json_decref(res->frames);
    json_decref(res->built);
    res->frames = res->built = NULL;
    for (int i = 0; i < res->npatches && i < OBS_MAX_PATCH_OUTPUTS; i++)
      obs_patches_free(&res->patches[i]);
    res->npatches = 0;
    return rc;
  }
  res->technique = t;
  res->backend = be;
  res->rays = ctx.rays;
  res->threads = ctx.threads;
  res->tiled = ctx.tiled;
  res->timings.build_ms = ctx.build_ms;
  res->timings.render_ms = ctx.render_ms;
  double t2 = obs_now_ms();
  stage_rest(&ctx, "other", t2 - t1, named);
  res->timings.total_ms = t2 - t0;
  res->nstages = ctx.nstages;
  for (int i = 0; i < ctx.nstages; i++) {
    res->stage_names[i] = ctx.stage_names[i];
    res->stage_ms[i] = ctx.stage_ms[i];
  }
  res->nwarnings = ctx.nwarnings;
  memcpy(res->warnings, ctx.warnings, sizeof res->warnings);
  return 0;
}

int obs_render(const obs_scene *scene, const obs_render_opts *opts, obs_result *res,
               obs_err *err) {
  memset(res, 0, sizeof *res);
  int rc = render(scene, opts, res, err);
  /* Files the scene reads (volumes, environment maps) are named as the scene names them. */
  if (rc && scene) obs_path_err_relative(err, scene->base_dir);
  return rc;
}

static json_t *stats_json(const obs_stats *st) {
  return json_pack("{s:f, s:f, s:f, s:I, s:I}", "mean", st->mean, "min", st->min, "max", st->max,
                   "count", (json_int_t)st->count,
                   "nonfinite", (json_int_t)(st->nan_count + st->inf_count));
}

/* Statistics of every declared output present in the result, over the covered pixels (alpha > 0
 * when the image has alpha; every pixel for alpha itself) or over the patches: per channel, and
 * for RGB outputs also of the luminance (Rec. 709 weights). */
static json_t *outputs_summary_json(const obs_result *r) {
  json_t *all = json_object();
  const char *mask = obs_image_channel(&r->image, "alpha") ? "alpha" : NULL;
  char ch[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  for (const obs_output *x = r->technique->outputs; x && x->name; x++) {
    json_t *o = json_object(), *chs = json_object();
    json_object_set_new(o, "kind", json_string(obs_output_kind_name(x->kind)));
    int n = obs_output_channels(x, ch), present = 0;
    for (int c = 0; c < n; c++) {
      obs_stats st;
      const char *m = strcmp(ch[c], "alpha") ? mask : NULL;
      if (obs_metrics_stats(&r->image, ch[c], m, &st, NULL) == 0) {
        json_object_set_new(chs, ch[c], stats_json(&st));
        present++;
      }
    }
    if (present) json_object_set_new(o, "channels", chs);
    else json_decref(chs);
    double lum;
    if (x->kind == OBS_OUTPUT_RGB && present == 3 &&
        obs_metrics_luminance_mean(&r->image, x->name, mask, &lum, NULL) == 0)
      json_object_set_new(o, "luminance_mean", json_real(lum));
    for (int i = 0; i < r->npatches; i++) {
      const obs_patches *p = &r->patches[i];
      if (strcmp(p->name, x->name)) continue;
      obs_stats st;
      obs_metrics_patch_stats(p, &st);
      json_object_set_new(o, "patches", json_integer((json_int_t)p->count));
      json_object_set_new(o, "patch_values", stats_json(&st));
      present = 1;
    }
    if (present) json_object_set_new(all, x->name, o);
    else json_decref(o);
  }
  return all;
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
  /* The technique's cost rule evaluated on these params (what the server's limits and estimates
   * multiply by the pixel samples), so a page can show the number rather than the rule. */
  json_object_set_new(o, "work_per_pixel_sample",
                      json_real(obs_technique_cost(r->technique, sc->params)));
  json_object_set_new(o, "threads", json_integer(r->threads));
  if (r->ranks > 1) json_object_set_new(o, "ranks", json_integer(r->ranks));
  json_t *t = json_object();
  json_object_set_new(t, "load", json_real(r->timings.load_ms));
  json_object_set_new(t, "build", json_real(r->timings.build_ms));
  json_object_set_new(t, "render", json_real(r->timings.render_ms));
  json_object_set_new(t, "write", json_real(r->timings.write_ms));
  json_object_set_new(t, "total", json_real(r->timings.total_ms));
  /* The stages partition the total: the caller's load and write around the render's own. */
  json_t *stages = json_object();
  json_object_set_new(stages, "load", json_real(r->timings.load_ms));
  for (int i = 0; i < r->nstages; i++)
    json_object_set_new(stages, r->stage_names[i], json_real(r->stage_ms[i]));
  json_object_set_new(stages, "write", json_real(r->timings.write_ms));
  json_object_set_new(t, "stages", stages);
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
  const obs_output *prim = obs_technique_primary(r->technique);
  json_object_set_new(o, "primary_output", prim ? json_string(prim->name) : json_null());
  json_object_set_new(o, "outputs", outputs_summary_json(r));
  json_t *w = json_array();
  for (int i = 0; i < r->nwarnings; i++) json_array_append_new(w, json_string(r->warnings[i]));
  json_object_set_new(o, "warnings", w);
  if (r->frames) json_object_set_new(o, "frames", json_deep_copy(r->frames));
  if (r->built && json_array_size(r->built))
    json_object_set_new(o, "built", json_deep_copy(r->built));
  return o;
}

/* depth.png: linear view depth, nearest covered pixel white and farthest 10 % grey (so the farthest
 * surface still stands out from the black background), linear in between. */
#define DEPTH_PNG_FAR 0.1f

/* Most files one result may have: the EXR, a PNG and a patch file per output, the summary. */
#define MAX_FILES 24

/* The exposure in EV of a tone-mapped output: the number in the parameter it names, else 0. */
static double output_exposure(const obs_output *o, const obs_scene *sc) {
  json_t *v = o->exposure && sc ? json_object_get(sc->params, o->exposure) : NULL;
  return json_is_number(v) ? json_number_value(v) : 0.0;
}

/* Blue-to-yellow false-colour ramp (viridis' end points and midpoint), t in [0, 1]. */
static void false_colour(float t, float rgb[3]) {
  static const float stops[3][3] = {{0.267f, 0.005f, 0.329f}, {0.128f, 0.567f, 0.551f},
                                    {0.993f, 0.906f, 0.144f}};
  float u = t * 2.0f;
  int k = u >= 1.0f ? 1 : 0;
  float f = u - (float)k;
  for (int c = 0; c < 3; c++) rgb[c] = stops[k][c] + (stops[k + 1][c] - stops[k][c]) * f;
}

/* The display image of one output for its PNG, in channels "R","G","B" or "Y": normal-as-colour
 * (n * 0.5 + 0.5), depth (see DEPTH_PNG_FAR), false colour over the covered range, or tone-mapped
 * (scaled by 2^exposure; the sRGB curve is applied by the PNG writer). Background pixels
 * (alpha <= 0, or a non-finite first channel) are black, except for tone-mapped ones, which show
 * what the technique computed there (a sky). Returns 1 when the channels are absent. */
static int display_image(const obs_image *img, const obs_output *o, double exposure,
                         obs_image *out, obs_err *err) {
  static const char *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"};
  char names[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  int nch = obs_output_channels(o, names);
  const float *a = obs_image_channel(img, "alpha");
  const float *src[3] = {NULL, NULL, NULL};
  for (int c = 0; c < nch; c++)
    if (!(src[c] = obs_image_channel(img, names[c]))) return 1;
  if (nch == 0) return 1;
  int nout = o->show == OBS_SHOW_NORMAL || o->show == OBS_SHOW_FALSE ? 3 : nch;
  int rc = obs_image_init(out, img->width, img->height, nout, nout == 3 ? rgb : y, err);
  if (rc) return rc;
  size_t n = (size_t)img->width * (size_t)img->height;
#define COVERED(i) ((a ? a[i] > 0.0f : 1) && isfinite(src[0][i]))
  float *o0 = out->data, *o1 = out->data + (nout == 3 ? n : 0), *o2 = o1 + (nout == 3 ? n : 0);
  if (o->show == OBS_SHOW_DEPTH || o->show == OBS_SHOW_FALSE) {
    int depth = o->show == OBS_SHOW_DEPTH;
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++)
      if (COVERED(i) && (!depth || src[0][i] > 0.0f)) {
        if (src[0][i] < lo) lo = src[0][i];
        if (src[0][i] > hi) hi = src[0][i];
      }
    for (size_t i = 0; i < n; i++) {
      if (!COVERED(i) || (depth && !(src[0][i] > 0.0f))) continue;
      float t = hi > lo ? (src[0][i] - lo) / (hi - lo) : 0.0f;
      if (depth) {
        o0[i] = 1.0f - (1.0f - DEPTH_PNG_FAR) * t;
      } else {
        float c[3];
        false_colour(t, c);
        o0[i] = c[0], o1[i] = c[1], o2[i] = c[2];
      }
    }
  } else if (o->show == OBS_SHOW_NORMAL) {
    for (int c = 0; c < 3; c++) {
      float *d = out->data + (size_t)c * n;
      const float *s = src[nch == 3 ? c : 0];
      for (size_t i = 0; i < n; i++)
        if (COVERED(i)) d[i] = s[i] * 0.5f + 0.5f;
    }
  } else { /* tone-mapped */
    float scale = (float)exp2(exposure);
    for (int c = 0; c < nch; c++) {
      float *d = out->data + (size_t)c * n;
      for (size_t i = 0; i < n; i++) d[i] = src[c][i] * scale;
    }
  }
#undef COVERED
  return 0;
}

/* Every image file takes the writer's defaults (obs_exr_opts_default, obs_png_opts_default): the
 * candidates were measured per output on the displaced sphere (docs/performance.md, "Writing
 * outputs") and the same setting won for ao.png, bent_normal.png and depth.png. */

/* One output file being written on some thread; its own obs_err so threads never share one. */
typedef struct out_job {
  const obs_image *img;
  const char *const *ch;
  int nch;
  int png;                 /* 0: the EXR */
  int gamma;               /* PNG: apply the sRGB curve */
  int threads;             /* EXR chunk threads */
  const char *path;
  int rc;
  obs_err err;
} out_job;

static void out_job_run(out_job *j) {
  if (j->png) {
    j->rc = obs_image_write_png(j->img, j->ch, j->nch, j->gamma, j->path, &j->err);
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
  pthread_t tid[MAX_FILES];
  int started[MAX_FILES] = {0};
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

/* The files of one write: names, staging and final paths, display images, what was written. */
typedef struct out_files {
  int n;
  char name[MAX_FILES][OBS_OUTPUT_FILE_MAX];
  char stage[MAX_FILES][4200], final[MAX_FILES][4200];
  int written[MAX_FILES];
  obs_image disp[MAX_FILES];
  char ch[MAX_FILES][OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  const char *chp[MAX_FILES][OBS_OUTPUT_MAX_CHANNELS];
} out_files;

static int out_files_add(out_files *f, const char *dir, const char *name) {
  if (f->n >= MAX_FILES) return -1;
  int i = f->n++;
  snprintf(f->name[i], sizeof f->name[i], "%s", name);
  snprintf(f->stage[i], sizeof f->stage[i], "%s/.%s.new", dir, name);
  snprintf(f->final[i], sizeof f->final[i], "%s/%s", dir, name);
  return i;
}

/* Queues the PNG of output `o` as file `fi` (nothing when its channels are absent). */
static int queue_png(out_files *f, int fi, const obs_result *r, const obs_scene *sc,
                     const obs_output *o, out_job *job, obs_err *err) {
  static const char *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"};
  int nch = obs_output_channels(o, f->ch[fi]);
  for (int c = 0; c < nch; c++) {
    if (!obs_image_channel(&r->image, f->ch[fi][c])) return 1;
    f->chp[fi][c] = f->ch[fi][c];
  }
  if (nch == 0) return 1;
  if (o->show == OBS_SHOW_GREY) { /* the channels as they are, linear */
    *job = (out_job){&r->image, f->chp[fi], nch, 1, 0, 1, f->stage[fi], 0, OBS_ERR_INIT};
    return 0;
  }
  int have = display_image(&r->image, o, output_exposure(o, sc), &f->disp[fi], err);
  if (have) return have;
  int n = f->disp[fi].nchannels;
  *job = (out_job){&f->disp[fi], n == 3 ? rgb : y, n, 1, o->show == OBS_SHOW_TONEMAP, 1,
                   f->stage[fi], 0, OBS_ERR_INIT};
  return 0;
}

/* Writes the per-patch files (after the images, on the calling thread: they are small). */
static int write_patches(out_files *f, const obs_result *r, const char *dir, obs_err *err) {
  char name[OBS_OUTPUT_FILE_MAX];
  for (int i = 0; i < r->npatches; i++) {
    const obs_output *o = obs_technique_output(r->technique, r->patches[i].name);
    if (!o || o->kind != OBS_OUTPUT_PATCH)
      return obs_err_set(err, OBS_EINVAL, "write: \"%s\" is no per-patch output of %s",
                         r->patches[i].name, r->technique->name);
    obs_output_patch_file(o, name, sizeof name);
    int fi = out_files_add(f, dir, name);
    if (fi < 0) return obs_err_set(err, OBS_EINVAL, "write: too many output files");
    int rc = obs_patches_write(&r->patches[i], f->stage[fi], err);
    if (rc) return rc;
    f->written[fi] = 1;
  }
  return 0;
}

/* Renames the written files into place, or removes them all; then removes an earlier render's
 * files of any technique that this one did not write. */
static int publish(out_files *f, const char *dir, int rc, obs_err *err) {
  for (int i = 0; !rc && i < f->n; i++)
    if (f->written[i] && rename(f->stage[i], f->final[i]))
      rc = obs_err_set(err, OBS_EIO, "%s: cannot rename into place: %s", f->final[i],
                       strerror(errno));
  if (rc) {
    for (int i = 0; i < f->n; i++) unlink(f->stage[i]);
    return rc;
  }
  char known[64][OBS_OUTPUT_FILE_MAX], path[4200];
  size_t nk = obs_output_file_names(known, 64);
  for (size_t k = 0; k < nk; k++) {
    int mine = 0;
    for (int i = 0; i < f->n; i++) mine |= f->written[i] && !strcmp(f->name[i], known[k]);
    if (mine) continue;
    snprintf(path, sizeof path, "%s/%s", dir, known[k]);
    unlink(path);
  }
  return 0;
}

int obs_result_write(obs_result *r, const obs_scene *sc, const char *dir, obs_err *err) {
  double t0 = obs_now_ms();
  if (!r || !r->technique || !obs_technique_primary(r->technique))
    return obs_err_set(err, OBS_EINVAL, "write: the result names no technique with outputs");
  for (const obs_output *o = r->technique->outputs; o->name; o++)
    if (o->kind == OBS_OUTPUT_VOXEL)
      return obs_err_set(err, OBS_EUNSUPPORTED, "write: voxel output \"%s\" has no file format",
                         o->name);
  int rc = obs_path_make_dirs(dir, err);
  if (rc) return rc;
  /* Every file is written under a staging name first and the set is renamed into place only
   * when all succeeded, so a failure never mixes new and old outputs. */
  out_files *f = calloc(1, sizeof *f);
  if (!f) return obs_err_set(err, OBS_ENOMEM, "write: out of memory");
  out_job jobs[MAX_FILES];
  int file_of[MAX_FILES], njobs = 0;
  char exr[OBS_OUTPUT_FILE_MAX];
  obs_technique_exr_name(r->technique, exr, sizeof exr);
  int fi = out_files_add(f, dir, exr);
  jobs[njobs] = (out_job){&r->image, NULL, 0, 0, 0, 1, f->stage[fi], 0, OBS_ERR_INIT};
  file_of[njobs++] = fi;
  for (const obs_output *o = r->technique->outputs; o->name && !rc; o++) {
    if (!o->png || o->show == OBS_SHOW_NONE) continue;
    if ((fi = out_files_add(f, dir, o->png)) < 0) {
      rc = obs_err_set(err, OBS_EINVAL, "write: too many output files");
      break;
    }
    int have = queue_png(f, fi, r, sc, o, &jobs[njobs], err);
    if (have < 0) rc = have;
    if (have == 0) file_of[njobs++] = fi;
  }
  if (!rc) {
    rc = write_images(jobs, njobs, r->threads > 0 ? r->threads : 1, err);
    for (int i = 0; i < njobs; i++) f->written[file_of[i]] = jobs[i].rc == 0;
  } else {
    for (int i = 0; i < njobs; i++) obs_err_free(&jobs[i].err);
  }
  for (int i = 0; i < MAX_FILES; i++) obs_image_free(&f->disp[i]);
  if (!rc) rc = write_patches(f, r, dir, err);
  if (!rc && (fi = out_files_add(f, dir, "summary.json")) < 0)
    rc = obs_err_set(err, OBS_EINVAL, "write: too many output files");
  if (!rc) {
    /* A second write of the same result (the server retries after a disk fault) replaces the
     * first one's time in the total instead of adding to it. */
    r->timings.total_ms -= r->timings.write_ms;
    r->timings.write_ms = obs_now_ms() - t0;
    r->timings.total_ms += r->timings.write_ms;
    json_t *sum = obs_result_summary_json(r, sc);
    if (json_dump_file(sum, f->stage[fi], JSON_INDENT(2) | JSON_REAL_PRECISION(9)))
      rc = obs_err_set(err, OBS_EIO, "%s: cannot write summary", f->stage[fi]);
    else
      f->written[fi] = 1;
    json_decref(sum);
  }
  rc = publish(f, dir, rc, err);
  free(f);
  return rc;
}
