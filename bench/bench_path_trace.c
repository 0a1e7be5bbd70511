/* Benchmark and picture of path_trace on the Cornell box (scenes/cornell_box.json): time per
 * sample path and rays per second, the image's mean radiance and a few patches, and optionally the
 * tone-mapped image (exposure, then sRGB) as a PNG for docs/images. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "bench_png.h"
#include "obscura/obscura.h"

#define MAX_REPEATS 64

typedef struct options {
  int threads, size, spp, repeats;
  double exposure;
  const char *png;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_path_trace [--threads N] [--size W] [--spp S] [--repeats R]\n"
          "                        [--png PATH] [--exposure EV]\n"
          "  Renders scenes/cornell_box.json with path_trace (defaults: max_bounces 64,\n"
          "  rr_depth 3, mis, sobol) at W x W with S paths per pixel (the samples parameter, one\n"
          "  pixel sample through the centre), R times, and prints the\n"
          "  median time per sample path and rays per second. --png writes the last render\n"
          "  as an sRGB PNG after scaling radiance by 2^EV.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  *o = (options){.threads = obs_cpu_count(), .size = 256, .spp = 16, .repeats = 3};
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--size", 1, 16384, &o->size),
      BENCH_OPT_INT("--spp", 1, 1024, &o->spp),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &o->repeats),
      BENCH_OPT_STR("--png", &o->png),
      BENCH_OPT_REAL("--exposure", -30, 30, 0, &o->exposure),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* Mean radiance over the square of half-width h pixels around (cx, cy), as fractions of W. */
static void patch(const obs_image *img, double cx, double cy, double out[3]) {
  static const char *const rgb[3] = {"radiance.R", "radiance.G", "radiance.B"};
  int w = img->width, h = img->height, r = w / 32 > 0 ? w / 32 : 1;
  int x0 = (int)(cx * w), y0 = (int)(cy * h);
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(img, rgb[k]);
    double sum = 0;
    int n = 0;
    for (int y = y0 - r; y <= y0 + r; y++)
      for (int x = x0 - r; x <= x0 + r; x++)
        if (x >= 0 && y >= 0 && x < w && y < h) sum += v[(size_t)y * (size_t)w + (size_t)x], n++;
    out[k] = n ? sum / n : 0;
  }
}

static void print_figures(const obs_image *img) {
  static const struct {
    const char *name;
    double x, y;
  } at[] = {{"whole image", -1, -1},           {"back wall, centre", 0.5, 0.35},
            {"floor, front", 0.5, 0.93},       {"red wall (left)", 0.07, 0.5},
            {"green wall (right)", 0.93, 0.5}, {"ceiling, near the light", 0.5, 0.08}};
  for (size_t i = 0; i < sizeof at / sizeof at[0]; i++) {
    double m[3] = {0, 0, 0};
    if (at[i].x < 0) {
      obs_stats st;
      static const char *const rgb[3] = {"radiance.R", "radiance.G", "radiance.B"};
      for (int k = 0; k < 3; k++)
        if (obs_metrics_stats(img, rgb[k], NULL, &st, NULL) == 0) m[k] = st.mean;
    } else {
      patch(img, at[i].x, at[i].y, m);
    }
    printf("  %-24s radiance %.4f %.4f %.4f\n", at[i].name, m[0], m[1], m[2]);
  }
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  bench_print_machine();
  char size[16], params[48];
  snprintf(size, sizeof size, "%d", o.size);
  /* Paths per pixel through the pixel's centre: one pixel sample, `samples` paths. */
  snprintf(params, sizeof params, "{\"samples\":%d}", o.spp);
  const obs_override ov[] = {{"/image/width", size},
                             {"/image/height", size},
                             {"/image/spp", "1"},
                             {"/technique/name", "\"path_trace\""},
                             {"/technique/params", params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  if (obs_scene_load_file(&sc, OBS_SOURCE_DIR "/scenes/cornell_box.json", ov, 5, &err)) {
    fprintf(stderr, "bench_path_trace: %s\n", obs_err_message(&err));
    return 1;
  }
  double ms[MAX_REPEATS], rays_s[MAX_REPEATS];
  obs_result res;
  memset(&res, 0, sizeof res);
  for (int r = 0; r < o.repeats; r++) {
    obs_result_free(&res);
    obs_render_opts opts = {.threads = o.threads};
    if (obs_render(&sc, &opts, &res, &err)) {
      fprintf(stderr, "bench_path_trace: %s\n", obs_err_message(&err));
      return 1;
    }
    ms[r] = res.timings.render_ms;
    rays_s[r] = (double)res.rays / (res.timings.render_ms * 1e-3);
  }
  double paths = (double)o.size * o.size * o.spp, med = bench_median(ms, o.repeats);
  printf(
      "path_trace cornell_box %dx%d, %d paths per pixel, %d threads: build %.1f ms, render %.1f ms "
      "(median of %d)\n",
      o.size, o.size, o.spp, o.threads, res.timings.build_ms, med, o.repeats);
  printf(
      "  %.3f us per sample path (wall), %.3f us per path per thread, %.1f rays per path, "
      "%.2f Mrays/s\n",
      med * 1e3 / paths, med * 1e3 * o.threads / paths, (double)res.rays / paths,
      bench_median(rays_s, o.repeats) * 1e-6);
  print_figures(&res.image);
  int rc = o.png ? bench_write_radiance_png(&res.image, o.exposure, o.png, "bench_path_trace") : 0;
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return rc ? 1 : 0;
}
