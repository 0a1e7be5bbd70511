/* Benchmark of volume_ao in the shape of the RTPara report's Tables 3.1 and 3.2: frames per
 * second by AO samples (32, 64, 128, 256) on the engine-shaped volume (256 x 256 x 118,
 * scenes/volume_engine.json) and a 512^3 procedural volume, at W x W, on each backend that runs
 * here, against the report's single-node figures, with the error of each ibl method against the
 * reference on the same view. Multi-rank figures come from bench/volume_mpi.sh (mpirun). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "obscura/obscura.h"

#define MAX_REPEATS 16

typedef struct options {
  int threads, size, repeats, nsamples, samples[8], big;
  const char *backends;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_volume_ao [--threads N] [--size W] [--repeats R] [--samples 32,64,...]\n"
          "                       [--big N] [--backends cpu,vulkan]\n"
          "  Renders scenes/volume_engine.json (256x256x118) and a procedural N^3 Marschner-Lobb\n"
          "  volume (default N 512; 0 skips it) with volume_ao at W x W (default 512) for each\n"
          "  sample count, R times each, and prints the median frames per second beside the\n"
          "  report's single-node figures, then each ibl method's RMSE against the reference.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(),
                 .size = 512,
                 .repeats = 3,
                 .nsamples = 4,
                 .samples = {32, 64, 128, 256},
                 .big = 512,
                 .backends = "cpu,vulkan"};
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--size", 8, 8192, &o->size),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &o->repeats),
      BENCH_OPT_LIST("--samples", 1, 65536, o->samples, &o->nsamples, 8),
      BENCH_OPT_INT("--big", 0, 1024, &o->big),
      BENCH_OPT_STR("--backends", &o->backends),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* The report's fps on one node (Tables 3.1, 3.2) for 32, 64, 128, 256 samples. */
static double report_fps(int big, int samples) {
  static const double engine[4] = {3.6, 1.9, 1.0, 0.5}, human[4] = {2.8, 1.5, 0.8, 0.4};
  int k = samples == 32 ? 0 : samples == 64 ? 1 : samples == 128 ? 2 : samples == 256 ? 3 : -1;
  return k < 0 ? NAN : (big ? human : engine)[k];
}

/* Loads scenes/volume_engine.json with the overrides (the big volume replaces the engine's). */
static int load(const options *o, int big, const char *backend, const char *params, const char *env,
                obs_scene *sc, obs_err *err) {
  char size[16], dims[64], be[32];
  snprintf(size, sizeof size, "%d", o->size);
  snprintf(dims, sizeof dims, "[%d, %d, %d]", o->big, o->big, o->big);
  snprintf(be, sizeof be, "\"%s\"", backend);
  obs_override ov[7] = {{"/image/width", size},
                        {"/image/height", size},
                        {"/technique/backend", be},
                        {"/technique/params", params},
                        {"/objects/0/shape/dims", dims}};
  size_t n = big ? 5 : 4;
  if (env) ov[n++] = (obs_override){"/environment", env};
  return obs_scene_load_file(sc, OBS_SOURCE_DIR "/scenes/volume_engine.json", ov, n, err);
}

/* Median render time in ms of the scene with `params` on `backend`; the last image in *keep. */
static double time_render(const options *o, int big, const char *backend, const char *params,
                          const char *env, obs_result *keep) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  if (load(o, big, backend, params, env, &sc, &err)) {
    fprintf(stderr, "bench_volume_ao: %s\n", obs_err_message(&err));
    exit(1);
  }
  double ms[MAX_REPEATS];
  for (int r = 0; r < o->repeats; r++) {
    obs_result res;
    obs_render_opts opts = {.threads = o->threads};
    if (obs_render(&sc, &opts, &res, &err)) {
      fprintf(stderr, "bench_volume_ao: %s\n", obs_err_message(&err));
      exit(1);
    }
    ms[r] = res.timings.render_ms;
    if (keep && r == o->repeats - 1)
      *keep = res;
    else
      obs_result_free(&res);
  }
  obs_scene_free(&sc);
  return bench_median(ms, o->repeats);
}

static double rmse_final(const obs_image *a, const obs_image *b) {
  const char *ch[3] = {"final.R", "final.G", "final.B"};
  size_t n = (size_t)a->width * (size_t)a->height;
  double s = 0;
  for (int k = 0; k < 3; k++) {
    const float *x = obs_image_channel(a, ch[k]), *y = obs_image_channel(b, ch[k]);
    for (size_t i = 0; i < n; i++) s += (double)(x[i] - y[i]) * (x[i] - y[i]);
  }
  return sqrt(s / (3.0 * (double)n));
}

/* Each ibl method's RMSE against the reference at the same samples, on the engine under a sky. */
static void ibl_errors(const options *o) {
  static const char *const ibls[] = {"reference", "bent_normal_lookup", "irradiance"};
  obs_result r[3];
  double ms[3];
  for (int m = 0; m < 3; m++) {
    char p[160];
    snprintf(p, sizeof p, "{\"samples\": %d, \"ibl\": \"%s\", \"seed\": 1}", o->samples[0],
             ibls[m]);
    ms[m] = time_render(o, 0, "cpu", p, "{\"map\": \"sky\", \"resolution\": 64}", &r[m]);
  }
  for (int m = 1; m < 3; m++)
    printf("  ibl %-18s %.1f ms (reference %.1f ms), RMSE of final vs reference %.4g\n", ibls[m],
           ms[m], ms[0], rmse_final(&r[m].image, &r[0].image));
  for (int m = 0; m < 3; m++) obs_result_free(&r[m]);
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  bench_print_machine();
  for (int big = 0; big <= (o.big > 0); big++) {
    for (const char *b = o.backends; *b;) {
      char be[16];
      size_t l = strcspn(b, ",");
      snprintf(be, sizeof be, "%.*s", (int)l, b);
      b += l + (b[l] == ',');
      obs_backend kind;
      const obs_technique *t = obs_technique_find("volume_ao");
      if (obs_backend_parse(be, &kind) || !obs_technique_has_backend(t, kind)) {
        printf("%s: no %s backend here, skipped\n", big ? "procedural" : "engine", be);
        continue;
      }
      for (int i = 0; i < o.nsamples; i++) {
        char p[96];
        snprintf(p, sizeof p, "{\"samples\": %d, \"seed\": 1}", o.samples[i]);
        double ms = time_render(&o, big, be, p, NULL, NULL);
        double want = report_fps(big, o.samples[i]);
        printf(
            "volume_ao %s %s %dx%d, %d samples, %d threads: %.1f ms = %.3g fps "
            "(report, one node: %.2g fps; ratio %.3g)\n",
            big ? "marschner_lobb" : "engine 256x256x118", be, o.size, o.size, o.samples[i],
            o.threads, ms, 1e3 / ms, want, 1e3 / ms / want);
      }
    }
  }
  printf("ibl methods on the engine volume under the default sky, %d samples:\n", o.samples[0]);
  ibl_errors(&o);
  return 0;
}
