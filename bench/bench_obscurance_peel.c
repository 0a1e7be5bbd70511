/* Benchmark: obscurance_map's depth_peeling (Vulkan) against bundles (CPU) on the same
 * directions and grids: time and per-patch RMSE against a reference (the mean of two independent
 * `rays` maps with many samples per patch, its own error taken out) for a range of direction
 * counts, on displaced spheres. Prints one table row per run. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench_args.h"
#include "obscura/obscura.h"
#include "obscurance_map_cpu.h"
#include "omap_peel.h"
#include "raytrace.h"

#define MAX_LIST 16

typedef struct options {
  int threads, res, ref_samples;
  int subdiv[MAX_LIST], nsubdiv;
  int dirs[MAX_LIST], ndirs;
  double dmax_frac;
} options;

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_obscurance_peel [--threads N] [--subdiv 6,8] [--dirs 32,64,128,256,512]\n"
          "         [--res R] [--ref-samples S] [--dmax F]\n"
          "  Per-patch obscurance maps of displaced spheres (no colour bleeding, sqrt falloff,\n"
          "  d_max = F x the bounding radius, one patch per triangle) by bundles on the CPU (N\n"
          "  threads) and depth_peeling on the Vulkan device, R x R grids, each timed and\n"
          "  compared per patch with the mean of two maps of S rays per patch; rmse_c takes out\n"
          "  the reference's own error.\n");
}

static int parse_args(int argc, char **argv, options *o) {
  memset(o, 0, sizeof *o);
  o->threads = 2, o->res = 512, o->ref_samples = 512, o->dmax_frac = 0.25;
  o->subdiv[0] = 6, o->subdiv[1] = 8, o->nsubdiv = 2;
  const int dirs[] = {32, 64, 128, 256, 512};
  for (int i = 0; i < 5; i++) o->dirs[i] = dirs[i];
  o->ndirs = 5;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 1024, &o->threads),
      BENCH_OPT_INT("--res", 2, 512, &o->res),
      BENCH_OPT_INT("--ref-samples", 1, 65536, &o->ref_samples),
      BENCH_OPT_LIST0("--subdiv", 0, 11, o->subdiv, &o->nsubdiv, MAX_LIST),
      BENCH_OPT_LIST0("--dirs", 1, 4096, o->dirs, &o->ndirs, MAX_LIST),
      BENCH_OPT_REAL("--dmax", 0, HUGE_VAL, BENCH_OPEN_LO, &o->dmax_frac),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}

/* Per-patch RMSE of w (first channel) against ref, raw and with the reference's own mean square
 * error ref_ms taken out. */
static void rmse_of(const float *w, const float *ref, int64_t n, double ref_ms, double *raw,
                    double *conv) {
  double d2 = 0;
  for (int64_t i = 0; i < n; i++) {
    double d = (double)w[3 * i] - ref[3 * i];
    d2 += d * d;
  }
  *raw = sqrt(d2 / (double)n);
  *conv = sqrt(fmax(0.0, d2 / (double)n - ref_ms));
}

static void row(const char *scene, int64_t n, const char *method, const char *budget, double ms,
                const float *w, const uint64_t *samples, int64_t unsampled, const float *ref,
                double ref_ms, const char *extra) {
  double raw, conv, s = 0;
  rmse_of(w, ref, n, ref_ms, &raw, &conv);
  for (int64_t i = 0; i < n; i++) s += (double)samples[i];
  printf("%-18s %8lld  %-14s %-12s %9.3f %9.1f  %7.4f %7.4f %8lld  %s\n", scene, (long long)n,
         method, budget, ms / 1e3, s / (double)n, raw, conv, (long long)unsampled, extra);
  fflush(stdout);
}

static obs_obscurance_map_params base_params(double dmax) {
  obs_obscurance_map_params p;
  memset(&p, 0, sizeof p);
  p.d_max = dmax, p.falloff = OBS_FALLOFF_SQRT, p.tau = 1, p.color_bleeding = 0;
  p.samples = 64, p.directions = 64, p.bundle_resolution = 64, p.patch_size = INFINITY;
  p.seed = 7;
  return p;
}

static int bench_scene(const options *o, obs_vk *vk, const char *name, const char *doc) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  obs_rt rt;
  int bad = obs_scene_load_string(&sc, doc, name, NULL, NULL, 0, &err);
  if (!bad && (bad = obs_rt_build_ex(&sc, &rt, o->threads, OBS_RT_FRAME_GEOMETRY, &err)))
    obs_scene_free(&sc);
  if (bad) {
    fprintf(stderr, "bench_obscurance_peel: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    return 1;
  }
  obs_bound_sphere bs;
  obs_bound_sphere_of(&rt.geo, &bs);
  obs_obscurance_map_params p = base_params(o->dmax_frac * bs.radius);
  obs_omap ref, ref2;
  p.method = OBS_OMAP_RAYS;
  p.samples = (uint32_t)o->ref_samples;
  p.seed = 1001;
  double t0 = obs_now_ms();
  bad = obs_omap_compute(&rt, &sc, &p, o->threads, NULL, NULL, NULL, &ref, &err);
  p.seed = 1002;
  if (!bad && (bad = obs_omap_compute(&rt, &sc, &p, o->threads, NULL, NULL, NULL, &ref2, &err)))
    obs_omap_free(&ref);
  double ref_ms = 0;
  int64_t n = bad ? 0 : ref.pm.count;
  if (!bad) {
    for (int64_t i = 0; i < 3 * n; i++) {
      double d = (double)ref.w[i] - ref2.w[i];
      ref_ms += d * d / 4;
      ref.w[i] = (float)(0.5 * ((double)ref.w[i] + ref2.w[i]));
    }
    ref_ms /= 3.0 * (double)n;
    obs_omap_free(&ref2);
    printf(
        "# %s: %zu triangles, d_max %.4g; reference: rays, 2 x %d per patch, %.1f s, its own "
        "RMSE %.4f\n",
        name, rt.geo.ntris, p.d_max, o->ref_samples, (obs_now_ms() - t0) / 1e3, sqrt(ref_ms));
    printf("%-18s %8s  %-14s %-12s %9s %9s  %7s %7s %8s  %s\n", "scene", "patches", "method",
           "budget", "time_s", "samp/pat", "rmse", "rmse_c", "unsampled", "");
  }
  obs_geometry geo;
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, sc.width, sc.height, &rig);
  if (!bad) bad = obs_geometry_build_at(&sc, rig.origin, &geo, &err);
  for (int k = 0; !bad && k < o->ndirs; k++) {
    char budget[64], extra[64] = "";
    p = base_params(o->dmax_frac * bs.radius);
    p.directions = (uint32_t)o->dirs[k];
    p.bundle_resolution = (uint32_t)o->res;
    snprintf(budget, sizeof budget, "%ux%u^2", p.directions, p.bundle_resolution);
    p.method = OBS_OMAP_BUNDLES;
    obs_omap m;
    t0 = obs_now_ms();
    if ((bad = obs_omap_compute(&rt, &sc, &p, o->threads, NULL, NULL, NULL, &m, &err))) break;
    row(name, n, "bundles (cpu)", budget, obs_now_ms() - t0, m.w, m.n, m.unsampled, ref.w, ref_ms,
        extra);
    obs_omap_free(&m);
    if (!vk) continue;
    p.method = OBS_OMAP_DEPTH_PEELING;
    obs_omap_peel g;
    t0 = obs_now_ms();
    if ((bad = obs_omap_peel_compute(vk, &sc, &geo, &p, NULL, NULL, NULL, NULL, &g, NULL, &err)))
      break;
    double ms = obs_now_ms() - t0;
    snprintf(extra, sizeof extra, "%.1f layers/direction", (double)g.layers / p.directions);
    row(name, n, "depth_peeling", budget, ms, g.w, g.n, g.unsampled, ref.w, ref_ms, extra);
    obs_omap_peel_free(&g);
  }
  if (bad) fprintf(stderr, "bench_obscurance_peel: %s\n", obs_err_message(&err));
  if (n) obs_omap_free(&ref);
  obs_geometry_free(&geo);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return bad != 0;
}

int main(int argc, char **argv) {
  options o;
  int a = parse_args(argc, argv, &o);
  if (a) return 2;
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  if (obs_vk_open(&vk, NULL, 0, &err)) {
    printf("# no Vulkan device (%s): bundles only\n", obs_err_message(&err));
    vk = NULL;
  }
  obs_err_free(&err);
  printf("# bench_obscurance_peel: %d threads, %d CPUs online, Vulkan device: %s\n", o.threads,
         (int)sysconf(_SC_NPROCESSORS_ONLN), vk ? obs_vk_device_name(vk) : "none");
  int bad = 0;
  for (int i = 0; i < o.nsubdiv; i++) {
    char doc[1024], name[64];
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,3.2],\"look_at\":[0,0,0],"
             "\"up\":[0,1,0],\"fov_y\":40},\"image\":{\"width\":64,\"height\":64},"
             "\"objects\":[{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":%d},"
             "\"material\":{\"reflectivity\":[0.6,0.6,0.6]}}],"
             "\"technique\":{\"name\":\"obscurance_map\"}}",
             o.subdiv[i]);
    snprintf(name, sizeof name, "displaced_sphere/%d", o.subdiv[i]);
    bad |= bench_scene(&o, vk, name, doc);
  }
  obs_vk_close(vk);
  return bad;
}
