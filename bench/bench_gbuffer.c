/* bench_gbuffer: the CPU G-buffer's two ways (rasterised, ray cast) on scenes from few to many
 * triangles per pixel and from one to many surfaces behind each pixel, at two image sizes: geometry
 * and BVH build plus the pass over the pixels, median and fastest of R runs each, the raster's
 * pixel tests per pixel and what obs_gbuffer_method picks. The data behind the choice rule of
 * renderer/cpu/gbuffer_raster.c. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "gbuffer_cpu.h"
#include "obscura/obscura.h"

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Median and minimum of `runs` timings (ms) of one way. */
static int time_way(const obs_scene *sc, int raster, int threads, int runs, double *med,
                    double *min) {
  double t[64];
  for (int r = -1; r < runs; r++) { /* r = -1: warm-up */
    obs_gbuffer g;
    obs_err err = OBS_ERR_INIT;
    double b = 0, p = 0;
    int rc = raster ? obs_gbuffer_raster(sc, &g, threads, &b, &p, &err)
                    : obs_gbuffer_raycast(sc, &g, threads, &b, &p, &err);
    if (rc) {
      fprintf(stderr, "bench_gbuffer: %s\n", obs_err_message(&err));
      obs_err_free(&err);
      return -1;
    }
    obs_gbuffer_free(&g);
    if (r >= 0) t[r] = b + p;
  }
  qsort(t, (size_t)runs, sizeof *t, cmp_double);
  *med = t[runs / 2];
  *min = t[0];
  return 0;
}

static const struct {
  const char *file, *subdiv;
} scenes[] = {{"cornell_box.json", NULL},     {"sphere_on_plane.json", NULL},
              {"teapot.json", NULL},          {"displaced_sphere.json", "7"},
              {"displaced_sphere.json", "8"}, {"displaced_sphere.json", "9"},
              {"displaced_sphere.json", "10"}};
enum { NSCENES = sizeof scenes / sizeof *scenes, NSTACKS = 4 };

/* Scene s (< NSCENES: bundled; else 4^(s - NSCENES + 1) screen-filling quads one behind another,
 * listed far to near, the raster's worst order: depth complexity without many triangles) at
 * w x h. */
static int load(size_t s, const char *ws, const char *hs, obs_scene *sc, char *label,
                size_t label_size, obs_err *err) {
  if (s < NSCENES) {
    char path[PATH_MAX + 64], dir[PATH_MAX];
    /* Where scenes/models really lies (it may be a link): a scene reads only inside its tree. */
    if (!realpath(OBS_SOURCE_DIR "/scenes/models", dir))
      return obs_err_set(err, OBS_EIO, "scenes/models: not found");
    *strrchr(dir, '/') = 0;
    snprintf(path, sizeof path, "%s/%s", dir, scenes[s].file);
    obs_override ov[3] = {{"/image/width", ws}, {"/image/height", hs}, {NULL, NULL}};
    size_t nov = 2;
    if (scenes[s].subdiv)
      ov[nov++] = (obs_override){"/objects/0/shape/subdivisions", scenes[s].subdiv};
    snprintf(label, label_size, "%s%s%s", scenes[s].file, scenes[s].subdiv ? " s" : "",
             scenes[s].subdiv ? scenes[s].subdiv : "");
    return obs_scene_load_file(sc, path, ov, nov, err);
  }
  const int layers = 4 << (2 * (s - NSCENES));
  size_t cap = 512 + (size_t)layers * 128, len = 0;
  char *doc = malloc(cap);
  if (!doc) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  len += (size_t)snprintf(doc + len, cap - len,
                          "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":["
                          "0,0,1],\"up\":[0,1,0],"
                          "\"fov_y\":60},\"image\":{\"width\":%s,\"height\":%s},\"objects\":[",
                          ws, hs);
  for (int q = 0; q < layers; q++)
    len += (size_t)snprintf(doc + len, cap - len,
                            "%s{\"shape\":{\"type\":\"quad\",\"vertices\":[[-9,-9,%d],[9,-9,%d],"
                            "[9,9,%d],[-9,9,%d]]}}",
                            q ? "," : "", layers + 1 - q, layers + 1 - q, layers + 1 - q,
                            layers + 1 - q);
  snprintf(doc + len, cap - len, "],\"technique\":{\"name\":\"ssao\"}}");
  snprintf(label, label_size, "%d stacked quads", layers);
  int rc = obs_scene_load_string(sc, doc, "stack.json", NULL, NULL, 0, err);
  free(doc);
  return rc;
}

static void usage(FILE *f) {
  fprintf(f, "usage: bench_gbuffer [--repeats R] [--threads N] [--only TEXT]\n"
             "  Times the CPU G-buffer rasterised and ray cast (geometry and BVH build\n"
             "  plus the pass; median and fastest of R runs, default 5, after a warm-up)\n"
             "  on the bundled scenes at 1280x720 and 320x240, the displaced sphere at\n"
             "  subdivisions 7 to 10 and 4 to 256 stacked screen-filling quads; prints the\n"
             "  raster's pixel tests per pixel and the way obs_gbuffer_method picks.\n"
             "  --only: the rows whose scene and size (\"cornell_box.json 1280x720\")\n"
             "  contain TEXT.\n");
}

int main(int argc, char **argv) {
  int runs = 5, threads = 2;
  const char *only = NULL;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--repeats", 1, 64, &runs),
      BENCH_OPT_INT("--threads", 1, 256, &threads),
      BENCH_OPT_STR("--only", &only),
  };
  if (bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage)) return 2;
  unsetenv("OBSCURA_GBUFFER");
  bench_print_machine();
  static const int sizes[][2] = {{1280, 720}, {320, 240}};
  printf("%-26s %-9s %9s %9s %9s %14s %14s %7s  %s\n", "scene", "size", "triangles", "tris/px",
         "tests/px", "raster ms", "raycast ms", "ratio", "picked");
  for (size_t s = 0; s < NSCENES + NSTACKS; s++)
    for (size_t z = 0; z < sizeof sizes / sizeof *sizes; z++) {
      char ws[16], hs[16], label[64], size[24];
      snprintf(ws, sizeof ws, "%d", sizes[z][0]);
      snprintf(hs, sizeof hs, "%d", sizes[z][1]);
      obs_scene sc;
      obs_err err = OBS_ERR_INIT;
      obs_geometry geo;
      double tests;
      if (load(s, ws, hs, &sc, label, sizeof label, &err)) {
        fprintf(stderr, "bench_gbuffer: %s\n", obs_err_message(&err));
        return 1;
      }
      char row[96];
      snprintf(row, sizeof row, "%s %dx%d", label, sc.width, sc.height);
      if (only && !strstr(row, only)) {
        obs_scene_free(&sc);
        continue;
      }
      const double eye[3] = {sc.camera.position.x, sc.camera.position.y, sc.camera.position.z};
      if (obs_geometry_build_at(&sc, eye, &geo, &err) ||
          obs_gbuffer_raster_tests(&sc, threads, &tests, &err)) {
        fprintf(stderr, "bench_gbuffer: %s\n", obs_err_message(&err));
        return 1;
      }
      const size_t ntris = geo.ntris, px = (size_t)sc.width * (size_t)sc.height;
      obs_geometry_free(&geo);
      double rm, rmin, cm, cmin;
      if (time_way(&sc, 1, threads, runs, &rm, &rmin) ||
          time_way(&sc, 0, threads, runs, &cm, &cmin))
        return 1;
      snprintf(size, sizeof size, "%dx%d", sc.width, sc.height);
      printf("%-26s %-9s %9zu %9.3f %9.2f %6.1f (%5.1f) %6.1f (%5.1f) %7.2f  %s\n", label, size,
             ntris, (double)ntris / (double)px, tests / (double)px, rm, rmin, cm, cmin, rm / cm,
             obs_gbuffer_method(tests, px) == OBS_GBUFFER_RASTER ? "raster" : "raycast");
      fflush(stdout);
      obs_scene_free(&sc);
    }
  return 0;
}
