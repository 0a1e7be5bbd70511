/* Benchmark of analytic_ao in the article's setting (Shopf et al., ShaderX7 6.3: a demo of 5,000
 * spheres): fields of 3, 1,000 and 5,000 spheres resting on a plane, analytic_ao (CPU, and Vulkan
 * where a device exists) and rt_ao at equal error timed side by side in one run. The error of
 * each is its RMSE against rt_ao at unlimited range, cosine-weighted, with --ref-samples; rt_ao's
 * equal-error sample count is the fewest (a power of two) whose RMSE against that reference is
 * no larger than analytic_ao's, both errors less the reference's own noise (its mean squared
 * standard error). The pass alone (the AO over one ray-cast G-buffer, the same on both sides) is
 * timed on the CPU and on the Vulkan device, whose own G-buffer rasterises tessellated spheres
 * and would dominate a whole render there; a first table times the Vulkan pass under both
 * methods (compute, and the article's rasterised proxies). Prints the machine, the tables and
 * the time ratios. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "bench_args.h"
#include "bench_machine.h"
#include "camera.h"
#include "gbuffer_cpu.h"
#include "obscura/obscura.h"
#include "vk.h"

#define MAX_REPEATS 16
#define MAX_COUNTS 8

static struct {
  int threads, width, height, repeats, ref_samples, ncounts, methods_only;
  int counts[MAX_COUNTS];
} opt;

static void usage(FILE *f) {
  fprintf(f, "usage: bench_analytic_ao [--threads N] [--size W] [--repeats R] [--ref-samples S]\n"
             "                         [--spheres 3,1000,5000] [--methods-only]\n"
             "  W x 3W/4 images (default 320), medians of R runs (default 3), the reference rt_ao\n"
             "  with S samples (default 2048). --methods-only: only the Vulkan methods' table.\n");
}

static int parse_args(int argc, char **argv) {
  opt.threads = obs_cpu_count();
  opt.width = 320;
  opt.repeats = 3;
  opt.ref_samples = 2048;
  opt.ncounts = 3;
  opt.counts[0] = 3, opt.counts[1] = 1000, opt.counts[2] = 5000;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &opt.threads),
      BENCH_OPT_INT("--size", 16, 8192, &opt.width),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &opt.repeats),
      BENCH_OPT_INT("--ref-samples", 1, 65536, &opt.ref_samples),
      BENCH_OPT_LIST("--spheres", 1, 100000, opt.counts, &opt.ncounts, MAX_COUNTS),
      BENCH_OPT_FLAG("--methods-only", &opt.methods_only),
  };
  if (bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage)) return 2;
  opt.height = opt.width * 3 / 4;
  return 0;
}

/* A uniform number in [0, 1) from a xorshift state: the layout is the same in every run. */
static double unit(uint32_t *s) {
  *s ^= *s << 13;
  *s ^= *s >> 17;
  *s ^= *s << 5;
  return (*s >> 8) * 0x1p-24;
}

/* n spheres of radius 1 resting on a plane, on a jittered grid of pitch 3, seen obliquely;
 * technique `tech` (a JSON object). Caller frees. */
static char *field_scene(int n, const char *tech) {
  int side = (int)ceil(sqrt((double)n));
  double half = 1.5 * side, plane = 2 * half + 6;
  size_t cap = 4096 + (size_t)n * 96;
  char *buf = malloc(cap);
  if (!buf) return NULL;
  size_t at = (size_t)snprintf(
      buf, cap,
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,%.6g,%.6g],\"look_at\":[0,0,%.6g],"
      "\"up\":[0,1,0],\"fov_y\":45},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
      "\"objects\":[{\"name\":\"plane\",\"shape\":{\"type\":\"quad\",\"vertices\":[[-%g,0,-%g],"
      "[-%g,0,%g],[%g,0,%g],[%g,0,-%g]]}}",
      1.0 * half + 4, -1.4 * half - 5, 0.15 * half, opt.width, opt.height, plane, plane, plane,
      plane, plane, plane, plane, plane);
  uint32_t s = 12345;
  for (int i = 0; i < n; i++) {
    double jx = (unit(&s) - 0.5) * 0.8, jz = (unit(&s) - 0.5) * 0.8;
    double x = -half + 1.5 + 3 * (i % side) + jx, z = -half + 1.5 + 3 * (i / side) + jz;
    at += (size_t)snprintf(buf + at, cap - at,
                           ",{\"shape\":{\"type\":\"sphere\",\"center\":[%.6f,1,%.6f],"
                           "\"radius\":1}}", x, z);
  }
  snprintf(buf + at, cap - at, "],\"technique\":%s}", tech);
  return buf;
}

/* Renders `json` (freed here) on `backend`; 0 on success. */
static int render(char *json, obs_result *res) {
  if (!json) return -1;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, json, "bench_analytic_ao.json", NULL, NULL, 0, &err);
  free(json);
  if (!rc) {
    obs_render_opts o = {.threads = opt.threads};
    rc = obs_render(&sc, &o, res, &err);
    obs_scene_free(&sc);
  }
  if (rc) fprintf(stderr, "bench_analytic_ao: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

/* RMSE and mean difference of `a`'s AO against `ref`'s over the covered pixels. */
static void error_of(const obs_result *a, const obs_result *ref, double *rmse, double *bias) {
  const float *x = obs_image_channel(&a->image, "ao"), *y = obs_image_channel(&ref->image, "ao");
  const float *al = obs_image_channel(&ref->image, "alpha");
  double s2 = 0, s1 = 0;
  size_t n = 0;
  for (size_t i = 0; i < (size_t)opt.width * (size_t)opt.height; i++) {
    if (al[i] < 0.5f) continue;
    double d = (double)x[i] - y[i];
    s2 += d * d, s1 += d, n++;
  }
  *rmse = n ? sqrt(s2 / n) : 0;
  *bias = n ? s1 / n : 0;
}

/* The reference's own noise: the root of its mean squared standard error over covered pixels. */
static double noise_of(const obs_result *ref) {
  const float *se = obs_image_channel(&ref->image, "ao_stderr");
  const float *al = obs_image_channel(&ref->image, "alpha");
  double s2 = 0;
  size_t n = 0;
  for (size_t i = 0; i < (size_t)opt.width * (size_t)opt.height; i++)
    if (al[i] >= 0.5f) s2 += (double)se[i] * se[i], n++;
  return n ? sqrt(s2 / n) : 0;
}

/* An RMSE against the reference less the reference's noise (in quadrature). */
static double less_noise(double rmse, double noise) {
  return sqrt(fmax(0.0, rmse * rmse - noise * noise));
}

/* The ray-cast G-buffer of n spheres and its occluders at `extent` (the caller frees all three). */
static void field_gbuffer(int n, double extent, obs_scene *sc, obs_gbuffer *g,
                          obs_aao_occluder **occ, size_t *nocc) {
  obs_err err = OBS_ERR_INIT;
  char *json = field_scene(n, "{\"name\":\"analytic_ao\",\"backend\":\"cpu\"}");
  obs_camera_rig rig;
  if (!json || obs_scene_load_string(sc, json, "bench.json", NULL, NULL, 0, &err)) exit(1);
  free(json);
  if (obs_gbuffer_raycast(sc, g, opt.threads, NULL, NULL, &err)) exit(1);
  obs_camera_setup(&sc->camera, g->width, g->height, &rig);
  if (obs_aao_occluders(sc, &rig, extent, NULL, occ, nocc, NULL, &err)) exit(1);
  obs_err_free(&err);
}

/* The AO pass alone over one ray-cast G-buffer of n spheres, on the CPU and (vk set) on the
 * device: median ms of each into cpu_ms and vk_ms (NAN without a device). */
static void pass_times(obs_vk *vk, int n, double extent, int resolution, double *cpu_ms,
                       double *vk_ms) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  obs_gbuffer g;
  obs_aao_occluder *occ = NULL;
  size_t nocc = 0;
  field_gbuffer(n, extent, &sc, &g, &occ, &nocc);
  obs_analytic_ao_params p = {.extent = extent, .resolution = resolution, .occluders = {.count = -1}};
  float *ao = malloc((size_t)g.width * (size_t)g.height * sizeof *ao);
  double tc[MAX_REPEATS];
  obs_vk_gbuffer dev;
  int up = vk && !obs_vk_gbuffer_upload(vk, &g, &dev, &err);
  for (int r = 0; r < opt.repeats; r++) {
    double t0 = obs_now_ms();
    if (obs_analytic_ao_cpu_apply(&g, occ, nocc, &p, opt.threads, ao, NULL, &err)) exit(1);
    tc[r] = obs_now_ms() - t0;
  }
  /* Twice on the device, the second timed: lavapipe compiles a pipeline at its first dispatch,
   * inside the timestamps. Not more: it takes seconds at 5,000 occluders. */
  double ms[OBS_AAO_STAGES] = {NAN, NAN, NAN};
  for (int r = 0; up && r < 2; r++)
    if (obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc, &p, ao, ms, &err)) exit(1);
  *cpu_ms = bench_median(tc, opt.repeats);
  *vk_ms = ms[0] + ms[1] + ms[2];
  if (up) obs_vk_gbuffer_free(vk, &dev);
  if (obs_err_message(&err)[0]) fprintf(stderr, "bench_analytic_ao: %s\n", obs_err_message(&err));
  free(ao);
  free(occ);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The Vulkan pass under each method (compute, raster) over one ray-cast G-buffer of n spheres:
 * wall-clock ms of the second of two calls (lavapipe compiles a pipeline at its first use), each
 * with its setup (occluder upload, pipelines, readback), into ms[2]; and the worst |difference|
 * between the two images into *diff. */
static void method_times(obs_vk *vk, int n, double extent, double ms[2], double *diff) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  obs_gbuffer g;
  obs_aao_occluder *occ = NULL;
  size_t nocc = 0;
  field_gbuffer(n, extent, &sc, &g, &occ, &nocc);
  obs_vk_gbuffer dev;
  if (obs_vk_gbuffer_upload(vk, &g, &dev, &err)) exit(1);
  size_t npx = (size_t)g.width * (size_t)g.height;
  float *ao[2] = {malloc(npx * sizeof(float)), malloc(npx * sizeof(float))};
  for (int m = 0; m < 2; m++) {
    obs_analytic_ao_params p = {.extent = extent, .occluders = {.count = -1}, .method = m};
    for (int r = 0; r < 2; r++) {
      double t0 = obs_now_ms();
      if (obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc, &p, ao[m], NULL, &err)) {
        fprintf(stderr, "bench_analytic_ao: %s\n", obs_err_message(&err));
        exit(1);
      }
      ms[m] = obs_now_ms() - t0;
    }
  }
  *diff = 0;
  for (size_t i = 0; i < npx; i++) *diff = fmax(*diff, fabs((double)ao[0][i] - ao[1][i]));
  free(ao[0]);
  free(ao[1]);
  obs_vk_gbuffer_free(vk, &dev);
  free(occ);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The Vulkan methods side by side (on lavapipe these are CPU timings, not a GPU's). */
static void methods_table(obs_vk *vk) {
  printf("Vulkan methods on %s%s: wall ms of the whole pass (second call)\n\n",
         obs_vk_device_name(vk),
         strstr(obs_vk_device_name(vk), "llvmpipe") ? " (lavapipe: CPU timings)" : "");
  printf("| spheres | extent | compute ms | raster ms | raster / compute | max |d| |\n"
         "|---|---|---|---|---|---|\n");
  for (int c = 0; c < opt.ncounts; c++)
    for (int e = 0; e < 2; e++) {
      double ms[2], diff;
      method_times(vk, opt.counts[c], e ? INFINITY : 16.0, ms, &diff);
      printf("| %d | %s | %.1f | %.1f | %.2f | %.3g |\n", opt.counts[c], e ? "null" : "16", ms[0],
             ms[1], ms[1] / ms[0], diff);
      fflush(stdout);
    }
  printf("\n");
}

/* Median total time (build + render) of `repeats` renders of technique `tech` over n spheres;
 * the last render's result stays in *keep (freed by the caller) when keep is set. */
static double timed(int n, const char *tech, obs_result *keep) {
  double t[MAX_REPEATS];
  for (int r = 0; r < opt.repeats; r++) {
    obs_result res;
    if (render(field_scene(n, tech), &res)) exit(1);
    t[r] = res.timings.total_ms;
    if (keep && r == opt.repeats - 1)
      *keep = res;
    else
      obs_result_free(&res);
  }
  return bench_median(t, opt.repeats);
}

/* rt_ao at unlimited range, cosine-weighted: the reference with the random sampler (whose
 * standard error is honest, so its noise can be taken out), the candidates with Sobol's (rt_ao's
 * default and its best at few samples). */
static const char *rt_tech(int samples, int reference) {
  static char buf[256];
  snprintf(buf, sizeof buf,
           "{\"name\":\"rt_ao\",\"backend\":\"cpu\",\"params\":{\"samples\":%d,"
           "\"seed\":%d,\"sampler\":\"%s\",\"max_distance\":null,\"weighting\":\"cosine\"}}",
           samples, reference ? 1 : 2, reference ? "random" : "sobol");
  return buf;
}

int main(int argc, char **argv) {
  int rc = parse_args(argc, argv);
  if (rc) return rc;
  bench_print_machine();
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  if (obs_vk_open(&vk, NULL, 0, &err)) vk = NULL;
  obs_err_free(&err);
  printf("images %dx%d, %d threads, medians of %d; reference rt_ao %d samples (cosine, "
         "unlimited range); Vulkan: %s\n\n", opt.width, opt.height, opt.threads, opt.repeats,
         opt.ref_samples, vk ? obs_vk_device_name(vk) : "none");
  if (vk) methods_table(vk);
  if (opt.methods_only) {
    if (vk) obs_vk_close(vk);
    return 0;
  }
  printf("| spheres | extent, resolution | analytic_ao ms (render) | AO pass ms CPU | AO pass ms Vulkan | "
         "error | bias | rt_ao spp at equal error | its error | rt_ao ms (render) | "
         "rt_ao / analytic_ao |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int c = 0; c < opt.ncounts; c++) {
    int n = opt.counts[c];
    obs_result ref;
    if (render(field_scene(n, rt_tech(opt.ref_samples, 1)), &ref)) return 1;
    double noise = noise_of(&ref);
    static const char *const extents[3] = {"16", "null", "16"};
    static const char *const resolutions[3] = {"full", "full", "half"};
    for (int e = 0; e < 3; e++) {
      char tech[256];
      snprintf(tech, sizeof tech,
               "{\"name\":\"analytic_ao\",\"backend\":\"cpu\",\"params\":{\"extent\":%s,"
               "\"resolution\":\"%s\"}}", extents[e], resolutions[e]);
      obs_result a;
      double ms = timed(n, tech, &a), rmse, bias;
      error_of(&a, &ref, &rmse, &bias);
      obs_result_free(&a);
      double err_a = less_noise(rmse, noise), cpu_pass, vk_pass;
      pass_times(vk, n, e == 1 ? INFINITY : 16.0, e == 2 ? OBS_AAO_HALF : OBS_AAO_FULL,
                 &cpu_pass, &vk_pass);
      /* rt_ao's fewest samples (powers of two) reaching analytic_ao's error. */
      int spp = 1, reached = 0;
      double err_r = 0, rt_rmse, rt_bias;
      for (; spp <= opt.ref_samples / 4; spp *= 2) {
        obs_result r;
        if (render(field_scene(n, rt_tech(spp, 0)), &r)) return 1;
        error_of(&r, &ref, &rt_rmse, &rt_bias);
        obs_result_free(&r);
        err_r = less_noise(rt_rmse, noise);
        if ((reached = err_r <= err_a)) break;
      }
      if (!reached) spp /= 2;
      double rms = timed(n, rt_tech(spp, 0), NULL);
      printf("| %d | %s, %s | %.1f | %.1f | %.1f | %.4f | %+.4f | %s%d | %.4f | %.1f | %s%.1f |\n",
             n, extents[e], resolutions[e], ms, cpu_pass, vk_pass, err_a, bias, reached ? "" : "> ", spp, err_r,
             rms, reached ? "" : "> ", rms / ms);
      fflush(stdout);
    }
    printf("| %d | (reference noise %.4f) |  |  |  |  |  |  |  |  |  |\n", n, noise);
    obs_result_free(&ref);
  }
  if (vk) obs_vk_close(vk);
  return 0;
}
