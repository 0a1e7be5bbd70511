/* Benchmark: obscurance_map's estimators on displaced spheres and, when present, the meshes of
 * ../shared/models/: time against per-patch RMSE for bundles and global lines over a range of
 * direction counts, and rays at a matching number of Embree queries, against a reference: the
 * mean of two independent `rays` maps with many samples per patch, whose own error is measured
 * from their difference. Prints one table row per run. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "bench_args.h"
#include "obscura/obscura.h"
#include "obscurance_map_cpu.h"
#include "raytrace.h"

#define MAX_LIST 16

typedef struct options {
  int threads, res, ref_samples;
  int subdiv[MAX_LIST], nsubdiv;
  int dirs[MAX_LIST], ndirs;
  int rays[MAX_LIST], nrays; /* extra rays rows: samples per patch */
  const char *models;        /* directory, or NULL: none */
  const char *mesh[MAX_LIST];
  int nmesh;
  double dmax_frac; /* d_max as a fraction of the bounding sphere's radius */
} options;

static void usage(FILE *f) {
  fprintf(
      f,
      "usage: bench_obscurance_map [--threads N] [--subdiv 8,9|none] [--dirs 32,64,128,256,512]\n"
      "         [--rays 8,16,32]\n"
      "         [--res R] [--ref-samples S] [--models DIR|none] [--mesh ogre.obj,...]\n"
      "         [--dmax F]\n"
      "  Per-patch obscurance maps (no colour bleeding, sqrt falloff, d_max = F x the\n"
      "  bounding radius, one patch per triangle): bundles and global lines with each\n"
      "  direction count at an R x R grid (global lines: the same number of lines), rays at\n"
      "  the bundles' query count, each timed and compared per patch with the mean of two\n"
      "  independent maps of S rays per patch, less the reference's own error (measured from\n"
      "  the difference of its halves): the per-patch RMSE against the converged map, plain\n"
      "  (rmse) and weighted by patch area (rmse_area). Then rays at each\n"
      "  --rays count per patch. cpu_s is the process's CPU time (robust to a busy machine).\n");
}

/* --subdiv 8,9 or none. */
static int parse_subdiv(const char *v, void *dst) {
  options *o = dst;
  if (!strcmp(v, "none")) return o->nsubdiv = 0;
  return (o->nsubdiv = parse_list(v, o->subdiv, MAX_LIST, 0, 11)) < 0 ? -1 : 0;
}

static int parse_args(int argc, char **argv, options *o) {
  memset(o, 0, sizeof *o);
  o->threads = 2;
  o->res = 512;
  o->ref_samples = 512;
  o->subdiv[0] = 8, o->subdiv[1] = 9, o->nsubdiv = 2;
  const int dirs[] = {32, 64, 128, 256, 512};
  for (int i = 0; i < 5; i++) o->dirs[i] = dirs[i];
  o->ndirs = 5;
  o->rays[0] = 8, o->rays[1] = 16, o->rays[2] = 32, o->nrays = 3;
  o->models = "../shared/models";
  o->mesh[0] = "ogre.obj", o->mesh[1] = "nefertiti.obj", o->nmesh = 2;
  o->dmax_frac = 0.25;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 1024, &o->threads),
      BENCH_OPT_INT("--res", 2, 512, &o->res),
      BENCH_OPT_INT("--ref-samples", 1, 65536, &o->ref_samples),
      BENCH_OPT_CUSTOM("--subdiv", parse_subdiv, "up to 16 levels from 0 to 11, or none", o),
      BENCH_OPT_LIST0("--dirs", 1, 4096, o->dirs, &o->ndirs, MAX_LIST),
      BENCH_OPT_LIST0("--rays", 1, 65536, o->rays, &o->nrays, MAX_LIST),
      BENCH_OPT_STR0("--models", &o->models),
      BENCH_OPT_REAL("--dmax", 0, HUGE_VAL, BENCH_OPEN_LO, &o->dmax_frac),
      BENCH_OPT_NAMES("--mesh", o->mesh, &o->nmesh, MAX_LIST, 1),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

typedef struct run {
  double ms, cpu_ms; /* wall and process CPU time (the latter robust to a busy machine) */
  uint64_t rays;
  obs_omap m;
} run;

static double cpu_ms(void) {
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return (u.ru_utime.tv_sec + u.ru_stime.tv_sec) * 1e3 +
         (u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e3;
}

static int map_run(const obs_rt *rt, const obs_scene *sc, const obs_obscurance_map_params *p,
                   int threads, run *r) {
  obs_err err = OBS_ERR_INIT;
  double c0 = cpu_ms(), t0 = obs_now_ms();
  int rc = obs_omap_compute(rt, sc, p, threads, NULL, NULL, NULL, &r->m, &err);
  r->ms = obs_now_ms() - t0;
  r->cpu_ms = cpu_ms() - c0;
  if (rc) fprintf(stderr, "bench_obscurance_map: %s\n", obs_err_message(&err));
  r->rays = rc ? 0 : r->m.rays;
  obs_err_free(&err);
  return rc;
}

/* Per-patch RMSE of `m` against `ref` (first channel: no colour bleeding) with the reference's
 * own mean square error `ref_ms` taken out, unweighted and weighted by patch area. */
static void rmse_of(const obs_omap *m, const obs_omap *ref, const double ref_ms[2], double *conv,
                    double *conv_area) {
  double d2 = 0, a2 = 0, area = 0;
  int64_t n = m->pm.count;
  for (int64_t i = 0; i < n; i++) {
    double d = (double)m->w[3 * i] - ref->w[3 * i], a = ref->pm.area[i];
    d2 += d * d;
    a2 += a * d * d;
    area += a;
  }
  *conv = sqrt(fmax(0.0, d2 / (double)n - ref_ms[0]));
  *conv_area = sqrt(fmax(0.0, a2 / area - ref_ms[1]));
}

static obs_obscurance_map_params base_params(double dmax) {
  obs_obscurance_map_params p;
  memset(&p, 0, sizeof p);
  p.d_max = dmax;
  p.falloff = OBS_FALLOFF_SQRT;
  p.tau = 1;
  p.color_bleeding = 0;
  p.samples = 64;
  p.directions = 64;
  p.bundle_resolution = 64;
  p.patch_size = INFINITY;
  p.seed = 7;
  return p;
}

static void row(const char *scene, int64_t patches, const char *method, const char *budget,
                const run *r, const obs_omap *ref, const double ref_ms[2]) {
  double conv, conv_area;
  rmse_of(&r->m, ref, ref_ms, &conv, &conv_area);
  double samples = 0;
  for (int64_t i = 0; i < r->m.pm.count; i++) samples += (double)r->m.n[i];
  printf("%-18s %8lld  %-12s %-14s %8.3f %8.3f %8.1f %9.1f  %7.4f %7.4f %8lld\n", scene,
         (long long)patches, method, budget, r->ms / 1e3, r->cpu_ms / 1e3, (double)r->rays / 1e6,
         samples / (double)patches, conv, conv_area, (long long)r->m.unsampled);
  fflush(stdout);
}

static int bench_scene(const options *o, const char *name, const char *doc, const char *base) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  if (obs_scene_load_string(&sc, doc, name, base, NULL, 0, &err)) {
    fprintf(stderr, "bench_obscurance_map: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    return 1;
  }
  obs_rt rt;
  double t0 = obs_now_ms();
  if (obs_rt_build_ex(&sc, &rt, o->threads, OBS_RT_FRAME_GEOMETRY, &err)) {
    fprintf(stderr, "bench_obscurance_map: %s\n", obs_err_message(&err));
    obs_scene_free(&sc);
    return 1;
  }
  double build_ms = obs_now_ms() - t0;
  obs_bound_sphere bs;
  obs_bound_sphere_of(&rt.geo, &bs);
  obs_obscurance_map_params p = base_params(o->dmax_frac * bs.radius);
  run ref, ref2;
  p.method = OBS_OMAP_RAYS;
  p.samples = (uint32_t)o->ref_samples;
  p.seed = 1001;
  int bad = map_run(&rt, &sc, &p, o->threads, &ref);
  p.seed = 1002;
  if (!bad && (bad = map_run(&rt, &sc, &p, o->threads, &ref2))) obs_omap_free(&ref.m);
  double ref_ms[2] = {0, 0}, area = 0;
  if (!bad) {
    /* The mean of the two halves errs by half the root mean square of their difference. */
    int64_t n = ref.m.pm.count;
    for (int64_t i = 0; i < n; i++) {
      double d = (double)ref.m.w[3 * i] - ref2.m.w[3 * i], a = ref.m.pm.area[i];
      ref_ms[0] += d * d / 4;
      ref_ms[1] += a * d * d / 4;
      area += a;
      for (int c = 0; c < 3; c++)
        ref.m.w[3 * i + c] = (float)(0.5 * ((double)ref.m.w[3 * i + c] + ref2.m.w[3 * i + c]));
    }
    ref_ms[0] /= (double)n;
    ref_ms[1] /= area;
    obs_omap_free(&ref2.m);
    printf(
        "# %s: %zu triangles, BVH %.0f ms, d_max %.4g; reference: rays, 2 x %d per patch, "
        "%.1f s, its own RMSE %.4f\n",
        name, rt.geo.ntris, build_ms, p.d_max, o->ref_samples, (ref.ms + ref2.ms) / 1e3,
        sqrt(ref_ms[0]));
    printf("%-18s %8s  %-12s %-14s %8s %8s %8s %9s  %7s %7s %8s\n", "scene", "patches", "method",
           "budget", "wall_s", "cpu_s", "Mqueries", "samp/pat", "rmse", "rmse_area", "unsampled");
  }
  for (int k = 0; !bad && k < o->ndirs; k++) {
    char budget[64];
    run r;
    p = base_params(o->dmax_frac * bs.radius);
    p.directions = (uint32_t)o->dirs[k];
    p.bundle_resolution = (uint32_t)o->res;
    p.method = OBS_OMAP_BUNDLES;
    snprintf(budget, sizeof budget, "%ux%u^2", p.directions, p.bundle_resolution);
    if ((bad = map_run(&rt, &sc, &p, o->threads, &r))) break;
    row(name, ref.m.pm.count, "bundles", budget, &r, &ref.m, ref_ms);
    uint64_t bundle_queries = r.rays;
    obs_omap_free(&r.m);
    p.method = OBS_OMAP_GLOBAL_LINES;
    if ((bad = map_run(&rt, &sc, &p, o->threads, &r))) break;
    snprintf(budget, sizeof budget, "%llu lines", (unsigned long long)obs_omap_global_count(&p));
    row(name, ref.m.pm.count, "global_lines", budget, &r, &ref.m, ref_ms);
    obs_omap_free(&r.m);
    /* rays at the bundles' number of Embree queries */
    p.method = OBS_OMAP_RAYS;
    double s = (double)bundle_queries / (double)ref.m.pm.count;
    p.samples = s < 1 ? 1 : (uint32_t)lround(s);
    snprintf(budget, sizeof budget, "%u/patch", p.samples);
    if ((bad = map_run(&rt, &sc, &p, o->threads, &r))) break;
    row(name, ref.m.pm.count, "rays", budget, &r, &ref.m, ref_ms);
    obs_omap_free(&r.m);
  }
  for (int k = 0; !bad && k < o->nrays; k++) {
    char budget[64];
    run r;
    p = base_params(o->dmax_frac * bs.radius);
    p.method = OBS_OMAP_RAYS;
    p.samples = (uint32_t)o->rays[k];
    snprintf(budget, sizeof budget, "%u/patch", p.samples);
    if ((bad = map_run(&rt, &sc, &p, o->threads, &r))) break;
    row(name, ref.m.pm.count, "rays", budget, &r, &ref.m, ref_ms);
    obs_omap_free(&r.m);
  }
  if (!bad) obs_omap_free(&ref.m);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return bad;
}

int main(int argc, char **argv) {
  options o;
  int a = parse_args(argc, argv, &o);
  if (a) return 2;
  printf("# bench_obscurance_map: %d threads, %d CPUs online\n", o.threads,
         (int)sysconf(_SC_NPROCESSORS_ONLN));
  int bad = 0;
  const char *cam =
      "\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,3.2],"
      "\"look_at\":[0,0,0],\"up\":[0,1,0],\"fov_y\":40},"
      "\"image\":{\"width\":64,\"height\":64}";
  for (int i = 0; i < o.nsubdiv; i++) {
    char doc[1024], name[64];
    snprintf(doc, sizeof doc,
             "{%s,\"objects\":[{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":%d},"
             "\"material\":{\"reflectivity\":[0.6,0.6,0.6]}}],"
             "\"technique\":{\"name\":\"obscurance_map\"}}",
             cam, o.subdiv[i]);
    snprintf(name, sizeof name, "displaced_sphere/%d", o.subdiv[i]);
    bad |= bench_scene(&o, name, doc, NULL);
  }
  for (int i = 0; o.models && i < o.nmesh; i++) {
    char path[1024], doc[1024];
    snprintf(path, sizeof path, "%s/%s", o.models, o.mesh[i]);
    if (access(path, R_OK)) {
      printf("# %s: not present, skipped\n", path);
      continue;
    }
    char *base = realpath(o.models, NULL);
    snprintf(doc, sizeof doc,
             "{%s,\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"%s\"},"
             "\"material\":{\"reflectivity\":[0.6,0.6,0.6]}}],"
             "\"technique\":{\"name\":\"obscurance_map\"}}",
             cam, o.mesh[i]);
    bad |= bench_scene(&o, o.mesh[i], doc, base);
    free(base);
  }
  return bad;
}
