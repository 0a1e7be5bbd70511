/* Benchmark of sss_single (ShaderX7 6.5) on scenes/sss_marble.json: the rendering conditions of
 * the article's Table 6.5.1 at its 1280 x 960 frame buffer (milliseconds per frame on the CPU,
 * and on Vulkan, next to the article's GeForce GTX 280 frame rates), then the error of shadow_maps against the
 * ray-traced reference (method trace) per path-sample count M. */
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
#define MAX_MS 8

typedef struct options {
  int threads, width, height, ref_samples, repeats, map_size, nm;
  int ms[MAX_MS];
  const char *png;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_sss_single [--threads N] [--width W] [--height H] [--map-size S]\n"
          "                        [--ref-samples R] [--m A,B,...] [--repeats K] [--png PREFIX]\n"
          "  Renders scenes/sss_marble.json at W x H (default 1280 x 960, the article's) with\n"
          "  shadow_maps under the conditions of the article's Table 6.5.1 (S x S maps, default\n"
          "  1024, the largest map_size; the article's are 2048; M = 10) and prints the median\n"
          "  of K renders' milliseconds (build + render), then the luminance RMSE of shadow_maps\n"
          "  (adaptive, jitter 1) at each M against trace with R paths per pixel. --png writes\n"
          "  PREFIX<method>.png.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(), .width = 1280, .height = 960, .ref_samples = 64,
                 .repeats = 3, .map_size = 1024, .nm = 5, .ms = {1, 2, 5, 10, 20}};
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--width", 4, 8192, &o->width),
      BENCH_OPT_INT("--height", 4, 8192, &o->height),
      BENCH_OPT_INT("--map-size", 16, 1024, &o->map_size),
      BENCH_OPT_INT("--ref-samples", 1, 4096, &o->ref_samples),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &o->repeats),
      BENCH_OPT_LIST("--m", 1, 4096, o->ms, &o->nm, MAX_MS),
      BENCH_OPT_STR("--png", &o->png),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

static int load(const options *o, const char *backend, const char *params, obs_scene *sc,
                obs_err *err) {
  json_t *doc = bench_scene_doc("sss_marble.json", err);
  return doc ? bench_scene_load(doc, o->width, o->height, "sss_single", backend, params, sc, err)
             : OBS_EIO;
}

/* Renders params `repeats` times: the median build + render milliseconds, and the median of the
 * same less the light-view maps (maps kept from an earlier frame: the article's static case). */
static int render(const options *o, const char *backend, const char *params, int repeats,
                  obs_result *res, double *med_ms, double *shade_ms, obs_err *err) {
  obs_scene sc;
  int rc = load(o, backend, params, &sc, err);
  if (rc) return rc;
  double ms[MAX_REPEATS], sh[MAX_REPEATS];
  for (int r = 0; r < repeats && !rc; r++) {
    obs_result_free(res);
    obs_render_opts opts = {.threads = o->threads};
    rc = obs_render(&sc, &opts, res, err);
    if (rc) break;
    ms[r] = res->timings.build_ms + res->timings.render_ms;
    sh[r] = ms[r];
    for (int k = 0; k < res->nstages; k++)
      if (!strcmp(res->stage_names[k], "light_maps")) sh[r] -= res->stage_ms[k];
  }
  obs_scene_free(&sc);
  if (rc) return rc;
  *med_ms = bench_median(ms, repeats);
  if (shade_ms) *shade_ms = bench_median(sh, repeats);
  return 0;
}

static int fail(obs_err *err) {
  fprintf(stderr, "bench_sss_single: %s\n", obs_err_message(err));
  return 1;
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  bench_print_machine();
  printf("scenes/sss_marble.json at %dx%d, %dx%d light-view map, %d threads; ms = build + render "
         "(BVH, maps, shading), median of %d\n",
         o.width, o.height, o.map_size, o.map_size, o.threads, o.repeats);
  /* Table 6.5.1's rows; row 6 (with direct illumination) has no counterpart: sss_single renders
   * single scattering only. */
  static const struct {
    const char *what;
    int m, adaptive, static_maps;
    double jitter, fps;
  } rows[] = {
      {"Deterministic sampling. Static light and object", 10, 0, 1, 0, 410.85},
      {"Deterministic sampling. Dynamic L&O", 10, 0, 0, 0, 363.07},
      {"Deterministic sampling with jittering. Dynamic L&O", 10, 0, 0, 1, 228.14},
      {"Adaptive sampling with jittering. Dynamic L&O", 10, 1, 0, 1, 225.95},
      {"Deterministic sampling with 2x samples. Dynamic L&O", 20, 0, 0, 0, 155.62},
  };
  obs_err err = OBS_ERR_INIT;
  obs_result res, ref;
  memset(&res, 0, sizeof res);
  memset(&ref, 0, sizeof ref);
  char params[256];
  const char *dev = bench_vulkan_device();
  int have_vk = dev != NULL;
  printf("vulkan: %s (a CPU rasteriser when lavapipe: its times are CPU times)\n",
         have_vk ? dev : "no device");
  printf("  %-3s %-52s %10s %10s %12s %14s %11s %11s\n", "no.", "condition", "ms (CPU)",
         "fps (CPU)", "ms (Vulkan)", "article fps", "maps (CPU)", "maps (Vk)");
  for (size_t r = 0; r < sizeof rows / sizeof rows[0]; r++) {
    snprintf(params, sizeof params,
             "{\"samples\":%d,\"adaptive\":%s,\"jitter\":%g,\"map_size\":%d}", rows[r].m,
             rows[r].adaptive ? "true" : "false", rows[r].jitter, o.map_size);
    double ms, shade, vms = NAN, vshade = NAN;
    if (render(&o, "cpu", params, o.repeats, &res, &ms, &shade, &err)) return fail(&err);
    if (have_vk && render(&o, "vulkan", params, o.repeats, &res, &vms, &vshade, &err))
      return fail(&err);
    double t = rows[r].static_maps ? shade : ms, vt = rows[r].static_maps ? vshade : vms;
    /* the maps' own milliseconds: cast with Embree on the CPU, rasterised on the device */
    printf("  %-3zu %-52s %10.1f %10.2f %12.1f %14.2f %11.1f %11.1f\n", r + 1, rows[r].what, t,
           1000.0 / t, vt, rows[r].fps, ms - shade, vms - vshade);
  }
  snprintf(params, sizeof params, "{\"method\":\"trace\",\"samples\":%d}", o.ref_samples);
  double ref_ms;
  if (render(&o, "cpu", params, 1, &ref, &ref_ms, NULL, &err)) return fail(&err);
  printf("reference: trace, %d paths per pixel: %.1f ms\n", o.ref_samples, ref_ms);
  char path[512];
  snprintf(path, sizeof path, "%strace.png", o.png ? o.png : "");
  if (o.png && bench_write_radiance_png(&ref.image, 3, path, "bench_sss_single")) return 1;
  printf("  %-6s %10s %14s %12s\n", "M", "ms", "lum RMSE", "ref noise");
  for (int k = 0; k < o.nm; k++) {
    snprintf(params, sizeof params, "{\"samples\":%d,\"map_size\":%d}", o.ms[k], o.map_size);
    double ms, noise;
    if (render(&o, "cpu", params, o.repeats, &res, &ms, NULL, &err)) return fail(&err);
    double e = bench_lum_rmse(&res.image, &ref.image, &noise);
    printf("  %-6d %10.1f %14.6f %12.6f\n", o.ms[k], ms, e, noise);
  }
  snprintf(path, sizeof path, "%sshadow_maps.png", o.png ? o.png : "");
  if (o.png && bench_write_radiance_png(&res.image, 3, path, "bench_sss_single")) return 1;
  obs_result_free(&res);
  obs_result_free(&ref);
  obs_err_free(&err);
  return 0;
}
