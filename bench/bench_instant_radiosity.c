/* Benchmark of instant_radiosity against path_trace: on the Cornell box (scenes/cornell_box.json)
 * and on the box with a panel under its light (the floor below lit only indirectly, the light
 * that reaches it occluded on its way), the luminance RMSE against a path_trace reference of the
 * same bounces and the render time, per visibility mode, VPL count and backend; optionally the
 * tone-mapped pictures of docs/techniques/instant_radiosity.md. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "bench_scene.h"
#include "bench_png.h"
#include "obscura/obscura.h"

#define MAX_REPEATS 16
#define MAX_VPLS 8

typedef struct options {
  int threads, size, ref_samples, repeats, max_bounces, nvpls;
  int vpls[MAX_VPLS];
  double exposure, clamp;
  const char *png; /* prefix */
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_instant_radiosity [--threads N] [--size W] [--ref-samples S]\n"
          "                               [--vpls A,B,...] [--max-bounces B] [--repeats R]\n"
          "                               [--clamp NC] [--png PREFIX] [--exposure EV]\n"
          "  Renders the Cornell box and the box with a panel under its light at W x W with\n"
          "  path_trace (S paths per pixel, max_bounces B: the reference) and with\n"
          "  instant_radiosity at each VPL count, visibility none, approximate and exact on the\n"
          "  CPU and none and approximate on Vulkan when a device exists, R times each; prints the median render time and the\n"
          "  luminance RMSE against the reference over the pixels both cover. --clamp sets\n"
          "  clamp_distance (default 19.2: 0.02 of the box's 960.7 diagonal, the size default).\n"
          "  --png writes\n"
          "  PREFIX<scene>_<backend>_<visibility>.png of the largest VPL count and\n"
          "  PREFIX<scene>_path_trace.png, radiance scaled by 2^EV, sRGB.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(), .size = 256, .ref_samples = 256, .repeats = 3,
                 .max_bounces = 3, .nvpls = 3, .vpls = {128, 512, 2048}, .clamp = 19.2};
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--size", 4, 4096, &o->size),
      BENCH_OPT_INT("--ref-samples", 1, 65536, &o->ref_samples),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &o->repeats),
      BENCH_OPT_INT("--max-bounces", 1, 16, &o->max_bounces),
      BENCH_OPT_LIST("--vpls", 1, 16384, o->vpls, &o->nvpls, MAX_VPLS),
      BENCH_OPT_REAL("--clamp", 0, 1e6, BENCH_OPEN_LO | BENCH_OPEN_HI, &o->clamp),
      BENCH_OPT_STR("--png", &o->png),
      BENCH_OPT_REAL("--exposure", -30, 30, 0, &o->exposure),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* The panel: a grey quad 150 units below the light, larger than it, facing both ways as every
 * quad does in the G-buffer; the floor under it sees no emitter. */
static const char *const PANEL =
    "{\"name\":\"panel\",\"shape\":{\"type\":\"quad\",\"vertices\":[[378,400,180],[178,400,180],"
    "[178,400,380],[378,400,380]]},\"material\":{\"reflectivity\":[0.725,0.71,0.68]}}";

/* Loads the Cornell box (with the panel when `panel`) rendered by technique `name` with params. */
static int load(const options *o, int panel, const char *name, const char *backend,
                const char *params, obs_scene *sc, obs_err *err) {
  json_t *doc = bench_scene_doc("cornell_box.json", err);
  if (!doc) return OBS_EIO;
  if (panel) json_array_append_new(json_object_get(doc, "objects"), json_loads(PANEL, 0, NULL));
  json_object_set_new(json_object_get(doc, "image"), "spp", json_integer(1));
  return bench_scene_load(doc, o->size, o->size, name, backend, params, sc, err);
}

static int render(const options *o, const obs_scene *sc, int repeats, obs_result *res,
                  double *med_ms, obs_err *err) {
  double ms[MAX_REPEATS];
  for (int r = 0; r < repeats; r++) {
    obs_result_free(res);
    obs_render_opts opts = {.threads = o->threads};
    int rc = obs_render(sc, &opts, res, err);
    if (rc) return rc;
    ms[r] = res->timings.build_ms + res->timings.render_ms;
  }
  *med_ms = bench_median(ms, repeats);
  return 0;
}

static int bench_scene(const options *o, int panel, int have_vk) {
  const char *scene = panel ? "cornell_panel" : "cornell_box";
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  obs_result ref, res;
  memset(&ref, 0, sizeof ref);
  memset(&res, 0, sizeof res);
  char params[192], path[512];
  snprintf(params, sizeof params, "{\"samples\":%d,\"max_bounces\":%d}", o->ref_samples,
           o->max_bounces);
  double ref_ms;
  int rc = load(o, panel, "path_trace", "cpu", params, &sc, &err);
  if (!rc) rc = render(o, &sc, 1, &ref, &ref_ms, &err);
  if (!rc) obs_scene_free(&sc);
  if (rc) {
    fprintf(stderr, "bench_instant_radiosity: %s\n", obs_err_message(&err));
    return 1;
  }
  printf("%s %dx%d: path_trace %d paths per pixel, max_bounces %d: %.1f ms; clamp_distance %g\n",
         scene, o->size, o->size, o->ref_samples, o->max_bounces, ref_ms, o->clamp);
  if (o->png) {
    snprintf(path, sizeof path, "%s%s_path_trace.png", o->png, scene);
    if (bench_write_radiance_png(&ref.image, o->exposure, path, "bench_instant_radiosity"))
      return 1;
  }
  printf("  %-7s %-11s %6s %12s %14s %12s\n", "backend", "visibility", "vpls", "ms",
         "lum RMSE", "ref noise");
  static const char *const modes[5][2] = {{"cpu", "none"},
                                          {"cpu", "approximate"},
                                          {"cpu", "exact"},
                                          {"vulkan", "none"},
                                          {"vulkan", "approximate"}};
  for (int m = 0; m < 5; m++) {
    if (!strcmp(modes[m][0], "vulkan") && !have_vk) continue;
    for (int v = 0; v < o->nvpls; v++) {
      snprintf(params, sizeof params,
               "{\"vpls\":%d,\"max_bounces\":%d,\"visibility\":\"%s\",\"clamp_distance\":%g}",
               o->vpls[v], o->max_bounces, modes[m][1], o->clamp);
      double ms, noise;
      rc = load(o, panel, "instant_radiosity", modes[m][0], params, &sc, &err);
      if (!rc) rc = render(o, &sc, o->repeats, &res, &ms, &err);
      if (!rc) obs_scene_free(&sc);
      if (rc) {
        fprintf(stderr, "bench_instant_radiosity: %s\n", obs_err_message(&err));
        return 1;
      }
      double e = bench_lum_rmse(&res.image, &ref.image, &noise);
      printf("  %-7s %-11s %6d %12.1f %14.5f %12.5f\n", modes[m][0], modes[m][1], o->vpls[v], ms,
             e, noise);
      if (o->png && v + 1 == o->nvpls) {
        snprintf(path, sizeof path, "%s%s_%s_%s.png", o->png, scene, modes[m][0], modes[m][1]);
        if (bench_write_radiance_png(&res.image, o->exposure, path, "bench_instant_radiosity"))
          return 1;
      }
    }
  }
  obs_result_free(&res);
  obs_result_free(&ref);
  obs_err_free(&err);
  return 0;
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  bench_print_machine();
  const char *dev = bench_vulkan_device();
  int have_vk = dev != NULL;
  printf("vulkan: %s; %d threads; times are build + render (G-buffer, BVH, walk, emission, gather, filter; not the device's start)\n",
         have_vk ? dev : "no device", o.threads);
  int rc = bench_scene(&o, 0, have_vk);
  if (!rc) rc = bench_scene(&o, 1, have_vk);
  return rc;
}
