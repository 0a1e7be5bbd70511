/* bench_writer: what writing a render's outputs costs against the whole render, and what each EXR
 * compression and PNG setting would cost in time and bytes, measured on one render in one run. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "bench_args.h"
#include "obscura/image.h"
#include "obscura/render.h"
#include "obscura/scene.h"

#ifndef OBS_SOURCE_DIR
#define OBS_SOURCE_DIR "."
#endif

typedef struct opts {
  int threads, size, subdiv, repeats;
  const char *scene;
} opts;

static void usage(FILE *f) {
  fprintf(f, "usage: bench_writer [--threads N] [--size W] [--subdiv L] [--repeats R] [--scene F]\n");
}

static int parse(int argc, char **argv, opts *o) {
  o->threads = obs_cpu_count();
  o->size = 512;
  o->subdiv = 9;
  o->repeats = 5;
  o->scene = OBS_SOURCE_DIR "/scenes/displaced_sphere.json";
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 1024, &o->threads),
      BENCH_OPT_INT("--size", 1, 8192, &o->size),
      BENCH_OPT_INT("--subdiv", 2, 11, &o->subdiv),
      BENCH_OPT_INT("--repeats", 1, 1000, &o->repeats),
      BENCH_OPT_STR("--scene", &o->scene),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}


/* CPU seconds of the whole process (every thread), in ms: on a shared machine this moves far less
 * than the wall clock, and for one thread it is what the wall time would be on an idle core. */
static double cpu_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static long file_size(const char *path) {
  struct stat st;
  return stat(path, &st) ? -1 : (long)st.st_size;
}

/* Bit-identity of two images' planes, matched by name. */
static int same_bits(const obs_image *a, const obs_image *b) {
  if (a->width != b->width || a->height != b->height || a->nchannels != b->nchannels) return 0;
  size_t n = (size_t)a->width * (size_t)a->height * sizeof(float);
  for (int c = 0; c < a->nchannels; c++) {
    const float *pb = obs_image_channel(b, a->names[c]);
    if (!pb || memcmp(obs_image_channel(a, a->names[c]), pb, n)) return 0;
  }
  return 1;
}

static const char *const exr_names[OBS_EXR_NCOMPRESSIONS] = {"none", "RLE", "ZIPS", "ZIP", "PIZ"};

/* One EXR candidate: median write time over R runs, file size, and a bit-exact read-back. */
static int exr_candidate(const obs_image *img, const char *dir, obs_exr_opts eo, int repeats,
                         double raw_bytes) {
  char path[4200];
  snprintf(path, sizeof path, "%s/cand.exr", dir);
  double *t = calloc(2 * (size_t)repeats, sizeof *t), *c = t + repeats;
  if (!t) return 1;
  obs_err err = OBS_ERR_INIT;
  for (int r = 0; r < repeats; r++) {
    double t0 = obs_now_ms(), c0 = cpu_ms();
    if (obs_image_write_exr_opts(img, path, &eo, &err)) {
      fprintf(stderr, "bench_writer: %s\n", obs_err_message(&err));
      obs_err_free(&err);
      free(t);
      return 1;
    }
    t[r] = obs_now_ms() - t0;
    c[r] = cpu_ms() - c0;
  }
  obs_image back;
  int ok = obs_image_read_exr(&back, path, &err) == 0 && same_bits(img, &back);
  if (ok) obs_image_free(&back);
  obs_err_free(&err);
  long sz = file_size(path);
  char name[32];
  if (eo.zip_level)
    snprintf(name, sizeof name, "%s-%d", exr_names[eo.compression], eo.zip_level);
  else
    snprintf(name, sizeof name, "%s", exr_names[eo.compression]);
  printf(
      "  exr %-8s threads %2d  %7.1f ms (cpu %7.1f)  %9ld bytes (%5.1f %% of raw)  read-back %s\n",
      name, eo.threads, bench_median(t, repeats), bench_median(c, repeats), sz,
      100.0 * (double)sz / raw_bytes, ok ? "bit-exact" : "DIFFERS");
  free(t);
  unlink(path);
  return !ok;
}

static const char *const png_filters[OBS_PNG_NFILTERS] = {"adaptive", "none", "sub", "up", "paeth"};

static void png_candidate(const obs_image *img, int nch, const char *dir, obs_png_opts po,
                          int repeats, const char *label) {
  static const char *const rgb[3] = {"R", "G", "B"}, *const y[1] = {"Y"}, *const ao[1] = {"ao"};
  const char *const *ch = nch == 3 ? rgb : (obs_image_channel(img, "ao") ? ao : y);
  char path[4200];
  snprintf(path, sizeof path, "%s/cand.png", dir);
  double *t = calloc(2 * (size_t)repeats, sizeof *t), *c = t + repeats;
  if (!t) return;
  obs_err err = OBS_ERR_INIT;
  for (int r = 0; r < repeats; r++) {
    double t0 = obs_now_ms(), c0 = cpu_ms();
    if (obs_image_write_png_opts(img, ch, nch, 0, path, &po, &err)) {
      fprintf(stderr, "bench_writer: %s\n", obs_err_message(&err));
      obs_err_free(&err);
      free(t);
      return;
    }
    t[r] = obs_now_ms() - t0;
    c[r] = cpu_ms() - c0;
  }
  char mode[24];
  if (po.strategy == OBS_PNG_STRATEGY_RLE)
    snprintf(mode, sizeof mode, "rle");
  else if (po.strategy == OBS_PNG_STRATEGY_HUFFMAN)
    snprintf(mode, sizeof mode, "huffman");
  else
    snprintf(mode, sizeof mode, "level %d", po.level < 0 ? 6 : po.level);
  printf("  png %-16s %-8s filter %-8s  %6.1f ms (cpu %6.1f)  %8ld bytes\n", label, mode,
         png_filters[po.filter], bench_median(t, repeats), bench_median(c, repeats),
         file_size(path));
  free(t);
  unlink(path);
}

/* The outputs as obs_result_write writes them, R times: median write time against the whole. */
static int whole(const obs_scene *sc, obs_result *res, const char *dir, const opts *o,
                 double load_ms, double render_ms) {
  double *t = calloc((size_t)o->repeats, sizeof *t);
  if (!t) return 1;
  obs_err err = OBS_ERR_INIT;
  for (int r = 0; r < o->repeats; r++) {
    if (obs_result_write(res, sc, dir, &err)) {
      fprintf(stderr, "bench_writer: %s\n", obs_err_message(&err));
      obs_err_free(&err);
      free(t);
      return 1;
    }
    t[r] = res->timings.write_ms;
  }
  double w = bench_median(t, o->repeats);
  free(t);
  static const char *const files[] = {"ao.exr", "ao.png", "bent_normal.png", "depth.png"};
  long total = 0;
  printf("outputs as written (obs_result_write, %d threads):", res->threads);
  for (int i = 0; i < 4; i++) {
    char p[4200];
    snprintf(p, sizeof p, "%s/%s", dir, files[i]);
    long s = file_size(p);
    total += s > 0 ? s : 0;
    printf(" %s %ld", files[i], s);
  }
  printf(" bytes (%ld in all)\n", total);
  printf("load %.1f ms, render %.1f ms (build included), write %.1f ms (medians of %d)\n", load_ms,
         render_ms, w, o->repeats);
  printf("ratio write/whole: %.3f  (goal <= 0.10)\n", w / (load_ms + render_ms + w));
  return 0;
}

static int candidates(const obs_result *res, const char *dir, const opts *o) {
  const obs_image *img = &res->image;
  double raw = (double)img->width * img->height * img->nchannels * 4.0;
  printf("EXR candidates (%dx%d, %d float channels, %.0f raw bytes; median of %d):\n", img->width,
         img->height, img->nchannels, raw, o->repeats);
  static const struct {
    int c, level;
  } list[] = {{OBS_EXR_NONE, 0}, {OBS_EXR_RLE, 0}, {OBS_EXR_ZIPS, 0},
              {OBS_EXR_ZIP, 1},  {OBS_EXR_ZIP, 2}, {OBS_EXR_ZIP, 3},
              {OBS_EXR_ZIP, 4},  {OBS_EXR_ZIP, 0}, {OBS_EXR_PIZ, 0}};
  int nthreads[2] = {1, o->threads}, bad = 0;
  for (size_t i = 0; i < sizeof list / sizeof list[0]; i++)
    for (int k = 0; k < (o->threads > 1 ? 2 : 1); k++) {
      obs_exr_opts eo = {list[i].c, list[i].level, nthreads[k]};
      bad |= exr_candidate(img, dir, eo, o->repeats, raw);
    }

  printf("PNG candidates (median of %d):\n", o->repeats);
  /* Levels with libspng's own strategy; run-length deflate ignores the level (zlib's Z_RLE). */
  static const struct { int level, strategy; } modes[] = {
      {-1, OBS_PNG_STRATEGY_DEFAULT}, {3, OBS_PNG_STRATEGY_DEFAULT}, {1, OBS_PNG_STRATEGY_DEFAULT},
      {0, OBS_PNG_STRATEGY_DEFAULT},  {6, OBS_PNG_STRATEGY_RLE},     {6, OBS_PNG_STRATEGY_HUFFMAN}};
  static const int filters[] = {OBS_PNG_FILTER_ADAPTIVE, OBS_PNG_FILTER_NONE, OBS_PNG_FILTER_SUB,
                                OBS_PNG_FILTER_UP, OBS_PNG_FILTER_PAETH};
  static const char *const pngs[] = {"ao.png", "bent_normal.png", "depth.png"};
  for (int f = 0; f < 3; f++) {
    obs_image src;
    obs_err err = OBS_ERR_INIT;
    char p[4200];
    snprintf(p, sizeof p, "%s/%s", dir, pngs[f]);
    /* The display images are re-read from the files just written: 8-bit values read back as
     * v/255 quantise to the same bytes, so the candidates encode exactly what was written. */
    if (f == 0) {
      src = *img;
    } else if (obs_image_read_png(&src, p, &err)) {
      obs_err_free(&err);
      continue;
    }
    for (size_t m = 0; m < sizeof modes / sizeof modes[0]; m++)
      for (size_t k = 0; k < sizeof filters / sizeof filters[0]; k++) {
        obs_png_opts po = {modes[m].level, filters[k], modes[m].strategy};
        png_candidate(&src, f == 1 ? 3 : 1, dir, po, o->repeats, pngs[f]);
      }
    if (f) obs_image_free(&src);
  }
  return bad;
}

int main(int argc, char **argv) {
  opts o;
  if (parse(argc, argv, &o)) return 2;
  char sub[16], size[16];
  snprintf(sub, sizeof sub, "%d", o.subdiv);
  snprintf(size, sizeof size, "%d", o.size);
  obs_override ov[3] = {
      {"/objects/0/shape/subdivisions", sub}, {"/image/width", size}, {"/image/height", size}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  double t0 = obs_now_ms();
  if (obs_scene_load_file(&sc, o.scene, ov, 3, &err)) {
    fprintf(stderr, "bench_writer: %s\n", obs_err_message(&err));
    return 1;
  }
  double load_ms = obs_now_ms() - t0;
  obs_render_opts ro = {.threads = o.threads};
  obs_result res;
  double *rt = calloc((size_t)o.repeats, sizeof *rt);
  if (!rt) return 1;
  /* R renders, the last one kept: the median is the "render" the write is weighed against. */
  for (int r = 0; r < o.repeats; r++) {
    if (r) obs_result_free(&res);
    t0 = obs_now_ms();
    if (obs_render(&sc, &ro, &res, &err)) {
      fprintf(stderr, "bench_writer: %s\n", obs_err_message(&err));
      obs_scene_free(&sc);
      free(rt);
      return 1;
    }
    rt[r] = obs_now_ms() - t0;
  }
  double render_ms = bench_median(rt, o.repeats);
  free(rt);
  char dir[] = "/tmp/bench_writer.XXXXXX";
  if (!mkdtemp(dir)) {
    fprintf(stderr, "bench_writer: cannot create a directory in /tmp: %s\n", strerror(errno));
    return 1;
  }
  printf("scene %s, subdivisions %d, %dx%d, %d threads\n", o.scene, o.subdiv, o.size, o.size,
         o.threads);
  int bad = whole(&sc, &res, dir, &o, load_ms, render_ms);
  if (!bad) bad = candidates(&res, dir, &o);
  static const char *const files[] = {"ao.exr", "ao.png", "bent_normal.png", "depth.png",
                                      "summary.json"};
  for (int i = 0; i < 5; i++) {
    char p[4200];
    snprintf(p, sizeof p, "%s/%s", dir, files[i]);
    unlink(p);
  }
  rmdir(dir);
  obs_result_free(&res);
  obs_scene_free(&sc);
  return bad;
}
