/* Benchmark of the reported standard errors: for every Monte-Carlo technique and sampler, renders
 * at N samples and a reference at 64 N (another seed) and prints how the reported stderr compares
 * with the actual error (obs_metrics_stderr_calib): RMS stderr / RMSE, the share of values within
 * 3 stderr, the share reporting 0 with a non-zero error, and the RMSE itself (the mean image's
 * accuracy). The figures of docs/accuracy.md's stderr calibration table. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "obscura/obscura.h"
#include "stderr_run.h"

#define MAX_LIST 16

/* The rows: every Monte-Carlo technique and sampler; 0 as size renders at --size. */
static const obs_stderr_case cases[] = {
    {"rt_ao sobol", "scenes/cornell_box.json", "rt_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "ao", "ao_stderr", 0, 0},
    {"rt_ao halton", "scenes/cornell_box.json", "rt_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"halton\",\"seed\":$S}", "ao", "ao_stderr", 0, 0},
    {"rt_ao random", "scenes/cornell_box.json", "rt_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "ao", "ao_stderr", 0, 0},
    {"rt_ao sobol exp", "scenes/cornell_box.json", "rt_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"sobol\",\"falloff\":\"exp\",\"tau\":0.02,"
     "\"seed\":$S}",
     "ao", "ao_stderr", 0, 0},
    {"obscurance W sobol", "scenes/cornell_box.json", "obscurance", "cpu",
     "{\"samples\":$N,\"sequence\":\"sobol\",\"d_max\":150,\"seed\":$S}", "obscurance",
     "obscurance_stderr", 0, 0},
    {"obscurance W halton", "scenes/cornell_box.json", "obscurance", "cpu",
     "{\"samples\":$N,\"sequence\":\"halton\",\"d_max\":150,\"seed\":$S}", "obscurance",
     "obscurance_stderr", 0, 0},
    {"obscurance final sobol", "scenes/cornell_box.json", "obscurance", "cpu",
     "{\"samples\":$N,\"light_samples\":$L,\"sequence\":\"sobol\",\"d_max\":150,"
     "\"seed\":$S}",
     "final", "final_stderr", 0, 0},
    {"obscurance final halton", "scenes/cornell_box.json", "obscurance", "cpu",
     "{\"samples\":$N,\"light_samples\":$L,\"sequence\":\"halton\",\"d_max\":150,"
     "\"seed\":$S}",
     "final", "final_stderr", 0, 0},
    {"path_trace random", "scenes/cornell_box.json", "path_trace", "cpu",
     "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "radiance", "radiance_stderr", 0, 0},
    {"path_trace sobol", "scenes/cornell_box.json", "path_trace", "cpu",
     "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "radiance", "radiance_stderr", 0, 0},
    {"obscurance_map rays", "scenes/cornell_box.json", "obscurance_map", "cpu",
     "{\"method\":\"rays\",\"samples\":$N,\"patch_size\":100,\"d_max\":150,\"seed\":$S}",
     "obscurance", "obscurance_stderr", 1, 0},
    {"obscurance_map global_lines", "scenes/cornell_box.json", "obscurance_map", "cpu",
     "{\"method\":\"global_lines\",\"lines\":$G,\"patch_size\":100,\"d_max\":150,"
     "\"seed\":$S}",
     "obscurance", "obscurance_stderr", 1, 0},
    {"obscurance_map bundles", "scenes/cornell_box.json", "obscurance_map", "cpu",
     "{\"method\":\"bundles\",\"directions\":$N,\"bundle_resolution\":128,"
     "\"patch_size\":100,\"d_max\":150,\"seed\":$S}",
     "obscurance", "obscurance_stderr", 1, 0},
    {"volume_ao sobol", "scenes/volume_torus.json", "volume_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
    {"volume_ao halton", "scenes/volume_torus.json", "volume_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"halton\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
    {"volume_ao random", "scenes/volume_torus.json", "volume_ao", "cpu",
     "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
    {"volume_ao sobol (vulkan)", "scenes/volume_torus.json", "volume_ao", "vulkan",
     "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
};
#define NCASES (sizeof cases / sizeof cases[0])

typedef struct options {
  int threads, size, factor;
  int n[MAX_LIST], nn;
  const char *only;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_stderr [--threads T] [--size W] [--n 4,16,64] [--factor F] [--only TEXT]\n"
          "  For each technique x sampler (rows whose label contains TEXT), renders a W x W\n"
          "  image (64 x 64 for the volume, whose torus covers little of it; one pixel sample)\n"
          "  at each N samples with seed 1 and a reference at F x N (default 64) with seed\n"
          "  1000003, and prints RMS stderr / RMSE, the share of values (pixel channels or patch\n"
          "  channels) within 3 stderr of the reference, the share reporting 0 with a non-zero\n"
          "  error, and the RMSE. N is the samples parameter (rays per point, paths per pixel,\n"
          "  obscurance's AO rays with light_samples N/4 (at least 4), bundles' directions at a\n"
          "  128 x 128 grid, global lines 4096 N).\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(), .size = 48, .factor = 64};
  o->n[0] = 4, o->n[1] = 16, o->n[2] = 64, o->nn = 3;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 1024, &o->threads),
      BENCH_OPT_INT("--size", 1, 4096, &o->size),
      BENCH_OPT_INT("--factor", 4, 4096, &o->factor),
      BENCH_OPT_LIST("--n", 1, 65536, o->n, &o->nn, MAX_LIST),
      BENCH_OPT_STR("--only", &o->only),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

static int row(const options *o, const obs_stderr_case *c, long n) {
  obs_err err = OBS_ERR_INIT;
  obs_stderr_calib k;
  double ms = 0;
  if (obs_stderr_run(c, n, n * o->factor, o->size, o->threads, &k, &ms, &err))
    printf("| %s | %ld | %s |\n", c->label, n, obs_err_message(&err));
  else
    printf("| %s | %ld | %.2f | %.1f %% | %.2f %% | %.4g | %lld | %.0f |\n", c->label, n, k.ratio,
           100 * k.within3, 100 * k.zero_with_error, k.rmse, (long long)k.values, ms);
  fflush(stdout);
  obs_err_free(&err);
  return 0;
}

int main(int argc, char **argv) {
  options o;
  int a = parse_args(argc, argv, &o);
  if (a) return 2;
  bench_print_machine();
  printf("%d x %d pixels, one pixel sample, reference at %d x N (seed 1000003), %d threads\n\n",
         o.size, o.size, o.factor, o.threads);
  printf("| technique, sampler | N | RMS stderr / RMSE | within 3σ | zero with error | RMSE | "
         "values | ms |\n|---|---|---|---|---|---|---|---|\n");
  for (size_t i = 0; i < NCASES; i++) {
    if (o.only && !strstr(cases[i].label, o.only)) continue;
    for (int j = 0; j < o.nn; j++) row(&o, &cases[i], o.n[j]);
  }
  return 0;
}
