/* Benchmark: obscurance_map with a moving object. A box orbits a ~100k-triangle scene (displaced
 * spheres on a floor; with --models, a mesh of ../shared/models/ instead) for F frames, one patch
 * per triangle, rays; each update mode renders every frame and, in the same run, a full
 * recompute of the same frame (measure_full). Prints per mode the median time per frame (BVH
 * refit + update), the frames per second that makes, the patches sampled, the speed-up over the
 * full recompute and the update's error against it. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "geometry.h"
#include "obscura/obscura.h"

typedef struct options {
  int threads, frames, samples;
  double d_max;
  const char *models; /* NULL: the synthetic scene only */
  const char *mesh;
  const char *updates[3];
  int nupdates;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_obscurance_motion [--threads N] [--frames F] [--samples S] [--dmax D]\n"
          "         [--models DIR|none] [--mesh ogre.obj] [--updates exact,article,full]\n"
          "  A 0.3-wide box orbits the scene, grazing it, for F frames (default 24); "
          "obscurance_map by\n"
          "  rays (S per patch, default 25; d_max D, default 0.3 scene units; one patch per\n"
          "  triangle, no colour bleeding). Scenes: a floor with displaced spheres of 65,536 +\n"
          "  2 x 16,384 triangles; and, when DIR/MESH exists, that mesh scaled to a radius of 1\n"
          "  on the floor. Per update mode: frame_ms (median over frames 1..F-1 of BVH refit +\n"
          "  update; bvh_ms the refit alone), fps = 1000 / frame_ms, patches sampled per frame, "
          "speedup = full\n"
          "  recompute / update (same frame, same run), and rmse / max_abs of the update\n"
          "  against the full recompute (mean, max over frames).\n");
}

static int parse_args(int argc, char **argv, options *o) {
  memset(o, 0, sizeof *o);
  o->threads = 2, o->frames = 24, o->samples = 25, o->d_max = 0.3;
  o->models = "../shared/models", o->mesh = "ogre.obj";
  o->updates[0] = "exact", o->updates[1] = "article", o->nupdates = 2;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--frames", 2, 1025, &o->frames),
      BENCH_OPT_INT("--samples", 1, 65536, &o->samples),
      BENCH_OPT_REAL("--dmax", 0, HUGE_VAL, BENCH_OPEN_LO, &o->d_max),
      BENCH_OPT_STR0("--models", &o->models),
      BENCH_OPT_STR("--mesh", &o->mesh),
      BENCH_OPT_NAMES("--updates", o->updates, &o->nupdates, 3, 0),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* The moving box's transforms: an orbit of radius `orbit` about the y axis, turning as it goes. */
static void motion_json(const options *o, double orbit, char *buf, size_t n) {
  size_t l = (size_t)snprintf(buf, n, "[");
  for (int f = 1; f < o->frames && l < n; f++) {
    double a = 2 * 3.14159265358979 * f / o->frames;
    l +=
        (size_t)snprintf(buf + l, n - l, "%s{\"translate\":[%.6f,0.45,%.6f],\"rotate\":[0,%.3f,0]}",
                         f > 1 ? "," : "", orbit * cos(a), orbit * sin(a), -a * 180 / 3.14159265);
  }
  if (l < n) snprintf(buf + l, n - l, "]");
}

/* The transform that puts a mesh's box (from the document: obs_geometry_object_points) into a
 * sphere of radius 1 about (0, 1, 0); returns the radius of an orbit that grazes the box's sides.
 */
static double fit_mesh(const char *mesh, const char *dir, char *out, size_t n) {
  char doc[1024];
  snprintf(doc, sizeof doc,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,1e6],\"look_at\":[0,0,0],"
           "\"fov_y\":45},\"image\":{\"width\":4,\"height\":4},\"objects\":[{\"shape\":"
           "{\"type\":\"mesh\",\"file\":\"%s\"}}],\"technique\":{\"name\":\"rt_ao\"}}",
           mesh);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  double pts[8][3], r, lo[3] = {INFINITY, INFINITY, INFINITY},
                       hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  if (obs_scene_load_string(&sc, doc, "fit.json", dir, NULL, 0, &err)) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    exit(1);
  }
  int np = obs_geometry_object_points(&sc.objects[0], 0, NULL, pts, &r);
  for (int i = 0; i < np; i++)
    for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], pts[i][k]), hi[k] = fmax(hi[k], pts[i][k]);
  double half = 0;
  for (int k = 0; k < 3; k++) half += 0.25 * (hi[k] - lo[k]) * (hi[k] - lo[k]);
  double s = 1 / sqrt(half);
  snprintf(out, n, "{\"scale\":[%.9g,%.9g,%.9g],\"translate\":[%.9g,%.9g,%.9g]}", s, s, s,
           -s * 0.5 * (lo[0] + hi[0]), 1 - s * 0.5 * (lo[1] + hi[1]), -s * 0.5 * (lo[2] + hi[2]));
  obs_scene_free(&sc);
  obs_err_free(&err);
  return s * 0.5 * fmax(hi[0] - lo[0], hi[2] - lo[2]) + 0.2;
}

static char *scene_doc(const options *o, const char *what, const char *dir, const char *update) {
  static char motion[65536], body[1024];
  double orbit = 1.35; /* the displaced spheres' radius is about 1.15 */
  if (!strcmp(what, "synthetic"))
    snprintf(body, sizeof body,
             "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":8},"
             "\"material\":{\"reflectivity\":[0.7,0.6,0.5]},\"transform\":{\"translate\":[0,1,0]}},"
             "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":7},"
             "\"material\":{\"reflectivity\":[0.5,0.7,0.5]},"
             "\"transform\":{\"scale\":[0.5,0.5,0.5],\"translate\":[-1.8,0.5,0.6]}},"
             "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":7},"
             "\"material\":{\"reflectivity\":[0.5,0.5,0.7]},"
             "\"transform\":{\"scale\":[0.5,0.5,0.5],\"translate\":[1.6,0.5,-0.9]}}");
  else {
    char fit[256];
    orbit = fit_mesh(what, dir, fit, sizeof fit);
    snprintf(body, sizeof body,
             "{\"shape\":{\"type\":\"mesh\",\"file\":\"%s\"},"
             "\"material\":{\"reflectivity\":[0.7,0.6,0.5]},\"transform\":%s}",
             what, fit);
  }
  motion_json(o, orbit, motion, sizeof motion);
  size_t n = strlen(motion) + 4096;
  char *doc = malloc(n);
  snprintf(doc, n,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,6],\"look_at\":[0,0.8,0],"
           "\"fov_y\":45},\"image\":{\"width\":64,\"height\":48},\"objects\":["
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]]},"
           "\"material\":{\"reflectivity\":[0.6,0.6,0.6]}},%s,"
           "{\"name\":\"box\",\"shape\":{\"type\":\"box\",\"min\":[-0.15,-0.15,-0.15],"
           "\"max\":[0.15,0.15,0.15]},\"material\":{\"reflectivity\":[0.9,0.2,0.2]},"
           "\"transform\":{\"translate\":[%.6f,0.45,0]},\"motion\":%s}],"
           "\"technique\":{\"name\":\"obscurance_map\",\"params\":{\"method\":\"rays\","
           "\"samples\":%d,\"d_max\":%g,\"color_bleeding\":false,\"update\":\"%s\"}}}",
           body, orbit, motion, o->samples, o->d_max, update);
  return doc;
}

static double fig(json_t *fr, const char *k) { return json_number_value(json_object_get(fr, k)); }

/* Renders one mode and prints its row. */
static int run_mode(const options *o, const char *what, const char *dir, const char *update) {
  char *doc = scene_doc(o, what, dir, update);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "motion.json", dir, NULL, 0, &err);
  free(doc);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  obs_render_opts opts = {.threads = o->threads};
  obs_result r;
  if ((rc = obs_render(&sc, &opts, &r, &err))) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_scene_free(&sc);
    obs_err_free(&err);
    return rc;
  }
  int nf = (int)json_array_size(r.frames) - 1;
  double *frame_ms = malloc((size_t)nf * sizeof *frame_ms),
         *ratio = malloc((size_t)nf * sizeof *ratio);
  double patches = 0, rmse = 0, rmse_max = 0, abs_max = 0, *bvh = malloc((size_t)nf * sizeof *bvh);
  for (int f = 1; f <= nf; f++) {
    json_t *fr = json_array_get(r.frames, (size_t)f);
    frame_ms[f - 1] = fig(fr, "bvh_ms") + fig(fr, "update_ms");
    bvh[f - 1] = fig(fr, "bvh_ms");
    ratio[f - 1] = fig(fr, "speedup");
    patches += fig(fr, "patches_updated") / nf;
    rmse += fig(fr, "rmse_vs_full") / nf;
    rmse_max = fmax(rmse_max, fig(fr, "rmse_vs_full"));
    abs_max = fmax(abs_max, fig(fr, "max_abs_vs_full"));
  }
  double ms = bench_median(frame_ms, nf), sp = bench_median(ratio, nf), bm = bench_median(bvh, nf);
  double frame0 = fig(json_array_get(r.frames, 0), "update_ms");
  printf("%-16s %-8s %8lld %9.1f %8.1f %6.2f %6.1f %10.0f %8.2f %10.5f %10.5f %9.5f\n", what,
         update, (long long)r.patches[0].count, frame0, ms, bm, 1000.0 / ms, patches, sp, rmse,
         rmse_max, abs_max);
  fflush(stdout);
  free(frame_ms);
  free(ratio);
  free(bvh);
  obs_result_free(&r);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return 0;
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  printf("obscurance_map, a moving box: %d frames, rays %d per patch, d_max %g, %d threads\n",
         o.frames, o.samples, o.d_max, o.threads);
  printf("%-16s %-8s %8s %9s %8s %6s %6s %10s %8s %10s %10s %9s\n", "scene", "update", "patches",
         "frame0_ms", "frame_ms", "bvh_ms", "fps", "patches/f", "speedup", "rmse_mean", "rmse_max",
         "abs_max");
  for (int m = 0; m < o.nupdates; m++)
    if (run_mode(&o, "synthetic", NULL, o.updates[m])) return 1;
  if (o.models) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", o.models, o.mesh);
    FILE *f = fopen(path, "r");
    if (f) {
      fclose(f);
      char real[4096];
      if (!realpath(o.models, real)) return 1;
      for (int m = 0; m < o.nupdates; m++)
        if (run_mode(&o, o.mesh, real, o.updates[m])) return 1;
    } else {
      printf("(%s not present: skipped)\n", path);
    }
  }
  return 0;
}
