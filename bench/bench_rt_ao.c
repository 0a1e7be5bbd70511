/* Benchmark: obscura's CPU rt_ao against a minimal raw Embree AO loop on the same displaced sphere,
 * resolution and thread count; prints build/render times, rays per second and their ratio. */
#include <embree3/rtcore.h>
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "camera.h"
#include "geometry.h"
#include "obscura/obscura.h"
#include "parallel.h"
#include "sampling.h"

#define MAX_SUBDIV 8
#define MAX_REPEATS 64
/* obscura's rays per second over the raw loop's, at least. */
#define GOAL_RATIO 0.9

typedef struct options {
  int threads, size, samples, repeats;
  int run_obscura, run_raw; /* --side: which sides to run (profiling one at a time) */
  int subdiv[MAX_SUBDIV];
  int nsubdiv;
} options;

/* One timed run of either side. */
typedef struct run_stats {
  double build_ms, render_ms, ao_mean;
  uint64_t rays;
} run_stats;

static const obs_camera bench_camera = {
    OBS_CAMERA_PERSPECTIVE, {0, 0.6, 3.2}, {0, 0, 0}, {0, 1, 0}, 40.0, 0.0};

static void usage(FILE *f) {
  fprintf(f,
          "usage: bench_rt_ao [--threads N] [--size W] [--samples S] [--subdiv 9,10] "
          "[--repeats R] [--side both|obscura|raw]\n"
          "  Renders a displaced_sphere with obscura's rt_ao (CPU) and with a raw Embree loop\n"
          "  doing the same work, R times each, and compares median rays per second.\n"
          "  --side runs one side only (for profiling); no ratio is printed then.\n");
}

/* --side both|obscura|raw. */
static int parse_side(const char *v, void *dst) {
  options *o = dst;
  o->run_obscura = !strcmp(v, "both") || !strcmp(v, "obscura");
  o->run_raw = !strcmp(v, "both") || !strcmp(v, "raw");
  return o->run_obscura || o->run_raw ? 0 : -1;
}

static int parse_args(int argc, char **argv, options *o) {
  o->threads = obs_cpu_count();
  o->size = 512;
  o->samples = 16;
  o->repeats = 3;
  o->run_obscura = o->run_raw = 1;
  o->subdiv[0] = 9;
  o->subdiv[1] = 10;
  o->nsubdiv = 2;
  const bench_opt opts[] = {
      BENCH_OPT_INT("--threads", 1, 256, &o->threads),
      BENCH_OPT_INT("--size", 1, 16384, &o->size),
      BENCH_OPT_INT("--samples", 1, 65536, &o->samples),
      BENCH_OPT_INT("--repeats", 1, MAX_REPEATS, &o->repeats),
      BENCH_OPT_CUSTOM("--side", parse_side, "both, obscura or raw", o),
      BENCH_OPT_LIST("--subdiv", 1, 12, o->subdiv, &o->nsubdiv, MAX_SUBDIV),
  };
  return bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage);
}


/* ---- obscura side ------------------------------------------------------------------------- */

static int obscura_load(const options *o, int subdiv, obs_scene *sc) {
  char json[1024];
  snprintf(json, sizeof json,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,3.2],\"look_at\":[0,0,0],"
           "\"up\":[0,1,0],\"fov_y\":40},"
           "\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{\"name\":\"bumpy\",\"shape\":{\"type\":\"displaced_sphere\","
           "\"subdivisions\":%d}}],"
           "\"technique\":{\"name\":\"rt_ao\",\"backend\":\"cpu\",\"params\":{\"samples\":%d,"
           "\"max_distance\":0.5,\"falloff\":\"binary\",\"weighting\":\"cosine\","
           "\"sampler\":\"sobol\"}}}",
           o->size, o->size, subdiv, o->samples);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(sc, json, "bench", NULL, NULL, 0, &err);
  if (rc) fprintf(stderr, "bench_rt_ao: scene: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

static int obscura_run(const obs_scene *sc, int threads, run_stats *st) {
  obs_render_opts opts = {.threads = threads};
  obs_result res;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_render(sc, &opts, &res, &err);
  if (rc) {
    fprintf(stderr, "bench_rt_ao: obscura render: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  obs_stats ao;
  rc = obs_metrics_stats(&res.image, "ao", NULL, &ao, &err);
  if (rc) fprintf(stderr, "bench_rt_ao: ao stats: %s\n", obs_err_message(&err));
  st->build_ms = res.timings.build_ms;
  st->render_ms = res.timings.render_ms;
  st->rays = res.rays;
  st->ao_mean = ao.mean;
  obs_result_free(&res);
  obs_err_free(&err);
  return rc;
}

/* ---- raw Embree side ---------------------------------------------------------------------- */

typedef struct raw_job {
  RTCScene scene;
  float eye[3], fwd[3], right[3], up[3];
  float half_w, half_h;
  int width, height;
  uint32_t samples;
  float tfar;   /* occlusion distance */
  float eps;    /* origin offset along the normal */
  float *ao;    /* width*height */
  _Atomic uint64_t rays;
} raw_job;

static int raw_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread;
  raw_job *j = user;
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  uint64_t rays = 0;
  const float inv_w = 2.0f / (float)j->width, inv_h = 2.0f / (float)j->height;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) {
      float sx = ((float)x + 0.5f) * inv_w - 1.0f, sy = 1.0f - ((float)y + 0.5f) * inv_h;
      sx *= j->half_w;
      sy *= j->half_h;
      float d[3];
      for (int k = 0; k < 3; k++) d[k] = j->fwd[k] + sx * j->right[k] + sy * j->up[k];
      float dl = 1.0f / sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (int k = 0; k < 3; k++) d[k] *= dl;
      struct RTCRayHit rh;
      rh.ray.org_x = j->eye[0], rh.ray.org_y = j->eye[1], rh.ray.org_z = j->eye[2];
      rh.ray.dir_x = d[0], rh.ray.dir_y = d[1], rh.ray.dir_z = d[2];
      rh.ray.tnear = 0.0f;
      rh.ray.tfar = INFINITY;
      rh.ray.time = 0.0f;
      rh.ray.mask = ~0u;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(j->scene, &ctx, &rh);
      rays++;
      size_t pix = (size_t)y * (size_t)j->width + (size_t)x;
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        j->ao[pix] = 1.0f;
        continue;
      }
      float n[3] = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
      float nl = 1.0f / sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0) nl = -nl;
      float org[3], t[3], b[3];
      for (int k = 0; k < 3; k++) {
        n[k] *= nl;
        org[k] = j->eye[k] + rh.ray.tfar * d[k] + j->eps * n[k];
      }
      obs_onb(n, t, b);
      uint32_t seed = obs_hash32((uint32_t)pix * 0x9e3779b9u + 0x632be5abu);
      uint32_t open = 0;
      for (uint32_t i = 0; i < j->samples; i++) {
        float u = obs_u32_to_unit(obs_hash32(seed + 2 * i));
        float v = obs_u32_to_unit(obs_hash32(seed + 2 * i + 1));
        float r = sqrtf(u), phi = 6.28318530717958647692f * v;
        float lx = r * cosf(phi), ly = r * sinf(phi), lz = sqrtf(1.0f - u);
        struct RTCRay ray;
        ray.org_x = org[0], ray.org_y = org[1], ray.org_z = org[2];
        ray.dir_x = lx * t[0] + ly * b[0] + lz * n[0];
        ray.dir_y = lx * t[1] + ly * b[1] + lz * n[1];
        ray.dir_z = lx * t[2] + ly * b[2] + lz * n[2];
        ray.tnear = 0.0f;
        ray.tfar = j->tfar;
        ray.time = 0.0f;
        ray.mask = ~0u;
        ray.id = 0;
        ray.flags = 0;
        rtcOccluded1(j->scene, &ctx, &ray);
        open += ray.tfar >= 0.0f;
      }
      rays += j->samples;
      j->ao[pix] = (float)open / (float)j->samples;
    }
  atomic_fetch_add(&j->rays, rays);
  return 0;
}

static int raw_run(const options *o, int subdiv, run_stats *st) {
  double t0 = obs_now_ms();
  obs_mesh m;
  if (obs_geometry_displaced_sphere(subdiv, &m)) {
    fprintf(stderr, "bench_rt_ao: raw: out of memory\n");
    return OBS_ENOMEM;
  }
  double extent = 0;
  for (size_t i = 0; i < 3 * m.nverts; i++) extent = fmax(extent, fabs((double)m.pos[i]));
  /* Embree's defaults, under the same instruction-set cap as renderer/cpu/raytrace.c. */
  char config[64];
  obs_rt_device_config(0, config, sizeof config);
  RTCDevice dev = rtcNewDevice(config);
  if (!dev) {
    fprintf(stderr, "bench_rt_ao: raw: cannot create Embree device\n");
    free(m.pos), free(m.idx), free(m.nrm);
    return OBS_EINTERNAL;
  }
  RTCScene scene = rtcNewScene(dev);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                      3 * sizeof(float), m.nverts);
  unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                         3 * sizeof(unsigned), m.ntris);
  memcpy(vb, m.pos, m.nverts * 3 * sizeof(float));
  memcpy(ib, m.idx, m.ntris * 3 * sizeof(unsigned));
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(scene);
  free(m.pos), free(m.idx), free(m.nrm);
  int rc = rtcGetDeviceError(dev) == RTC_ERROR_NONE ? 0 : OBS_EINTERNAL;
  st->build_ms = obs_now_ms() - t0;

  raw_job j;
  memset(&j, 0, sizeof j);
  j.scene = scene;
  obs_camera_rig rig;
  obs_camera_setup(&bench_camera, o->size, o->size, &rig);
  for (int k = 0; k < 3; k++) {
    j.eye[k] = (float)rig.origin[k];
    j.fwd[k] = (float)rig.forward[k];
    j.right[k] = (float)rig.right[k];
    j.up[k] = (float)rig.up[k];
  }
  j.half_w = (float)rig.half_w;
  j.half_h = (float)rig.half_h;
  j.width = j.height = o->size;
  j.samples = (uint32_t)o->samples;
  j.tfar = 0.5f;
  j.eps = (float)(1e-4 * extent);
  size_t npix = (size_t)o->size * (size_t)o->size;
  j.ao = calloc(npix, sizeof *j.ao);
  atomic_init(&j.rays, 0);
  if (!j.ao) rc = OBS_ENOMEM;
  if (!rc) {
    double t1 = obs_now_ms();
    rc = obs_parallel_tiles(o->size, o->size, o->threads, raw_tile, &j, NULL, NULL, NULL);
    st->render_ms = obs_now_ms() - t1;
    st->rays = atomic_load(&j.rays);
    double sum = 0;
    for (size_t i = 0; i < npix; i++) sum += j.ao[i];
    st->ao_mean = sum / (double)npix;
  }
  if (rc) fprintf(stderr, "bench_rt_ao: raw render failed (%d)\n", rc);
  free(j.ao);
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return rc;
}

/* ---- driver ------------------------------------------------------------------------------- */

typedef struct summary {
  double build_ms, render_ms, mrays, ao_mean;
  uint64_t rays;
} summary;

static void summarise(run_stats *runs, int n, summary *s) {
  double b[MAX_REPEATS], r[MAX_REPEATS], a[MAX_REPEATS];
  for (int i = 0; i < n; i++) {
    b[i] = runs[i].build_ms;
    r[i] = runs[i].render_ms;
    a[i] = runs[i].ao_mean;
  }
  s->build_ms = bench_median(b, n);
  s->render_ms = bench_median(r, n);
  s->ao_mean = bench_median(a, n);
  s->rays = runs[0].rays;
  s->mrays = s->render_ms > 0 ? (double)s->rays / (s->render_ms * 1e3) : 0;
}

int main(int argc, char **argv) {
  options o;
  if (parse_args(argc, argv, &o)) return 2;
  printf("bench_rt_ao: %dx%d, spp 1, %d AO samples (max_distance 0.5, binary, cosine, sobol), "
         "%d threads, %d repeats (median)\n",
         o.size, o.size, o.samples, o.threads, o.repeats);
  bench_print_machine();
  printf("%10s  %-7s  %9s  %10s  %8s  %11s  %8s\n", "triangles", "side", "build ms", "render ms",
         "Mrays/s", "rays", "AO mean");
  double ratios[MAX_SUBDIV], paired[MAX_SUBDIV], paired_lo[MAX_SUBDIV], paired_hi[MAX_SUBDIV];
  size_t tris[MAX_SUBDIV];
  int status = 0;
  for (int si = 0; si < o.nsubdiv; si++) {
    int sd = o.subdiv[si];
    tris[si] = (size_t)1 << (2 * sd);
    obs_scene sc;
    if (obscura_load(&o, sd, &sc)) return 1;
    run_stats obs_runs[MAX_REPEATS], raw_runs[MAX_REPEATS];
    /* Interleaved so slow drifts (thermal, other load) hit both sides alike. */
    for (int r = 0; r < o.repeats; r++) {
      if ((o.run_obscura && obscura_run(&sc, o.threads, &obs_runs[r])) ||
          (o.run_raw && raw_run(&o, sd, &raw_runs[r]))) {
        obs_scene_free(&sc);
        return 1;
      }
    }
    obs_scene_free(&sc);
    summary so, sr;
    if (o.run_obscura) {
      summarise(obs_runs, o.repeats, &so);
      printf("%10zu  %-7s  %9.1f  %10.1f  %8.2f  %11llu  %8.5f\n", tris[si], "obscura",
             so.build_ms, so.render_ms, so.mrays, (unsigned long long)so.rays, so.ao_mean);
    }
    if (o.run_raw) {
      summarise(raw_runs, o.repeats, &sr);
      printf("%10zu  %-7s  %9.1f  %10.1f  %8.2f  %11llu  %8.5f\n", tris[si], "raw", sr.build_ms,
             sr.render_ms, sr.mrays, (unsigned long long)sr.rays, sr.ao_mean);
    }
    if (o.run_obscura && o.run_raw) {
      /* Each run's render time over the raw run beside it (same rays on both sides), then the
       * median: a pair shares the machine's state, so drift and other load cancel. */
      double pr[MAX_REPEATS];
      for (int r = 0; r < o.repeats; r++)
        pr[r] = obs_runs[r].render_ms > 0 ? raw_runs[r].render_ms / obs_runs[r].render_ms : 0;
      bench_median(pr, o.repeats);
      paired[si] = pr[o.repeats / 2];
      paired_lo[si] = pr[0];
      paired_hi[si] = pr[o.repeats - 1];
      ratios[si] = sr.mrays > 0 ? so.mrays / sr.mrays : 0;
      double diff = so.ao_mean - sr.ao_mean;
      printf("%10s  AO mean difference obscura - raw: %+.5f%s\n", "", diff,
             fabs(diff) > 0.01 ? "  (larger than 0.01: the two sides disagree)" : "");
      if (fabs(diff) > 0.01) status = 1;
    }
  }
  if (o.run_obscura && o.run_raw) {
    printf("\n");
    char label[96];
    bench_isa_label(label, sizeof label);
    for (int si = 0; si < o.nsubdiv; si++)
      printf("ratio %zu tris: %.2f (median of per-pair ratios %.2f, range %.2f-%.2f)\n", tris[si],
             ratios[si], paired[si], paired_lo[si], paired_hi[si]);
    for (int si = 0; si < o.nsubdiv; si++)
      printf("goal rt_ao >= %.1fx raw rays/s at %zu tris [%s]: %s (paired %.2f)\n", GOAL_RATIO,
             tris[si], label, paired[si] >= GOAL_RATIO ? "PASS" : "FAIL", paired[si]);
  }
  return status;
}
