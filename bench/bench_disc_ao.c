/* Benchmark: disc_ao in the shape of ShaderX7 6.8's Table 6.8.1 on the Stanford bunny (quad and
 * pyramid proxies at 640x480, 1024x768 and 1280x1024: the pass's time, the fragments shaded and
 * the most on one pixel), the CPU twin's time on the same G-buffer and discs, and the
 * over-darkening against rt_ao (cosine, unbounded and at the discs' median reach). */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench_args.h"
#include "bench_machine.h"
#include "disc_ao.h"
#include "gbuffer_cpu.h"
#include "obscura/obscura.h"
#include "vk.h"

typedef struct options {
  const char *models; /* directory holding the bunny */
  const char *mesh;
  float influence;
  int ref_samples;
  int repeats;
  int threads;
} options;

static void usage(FILE *f) {
  fprintf(f, "usage: bench_disc_ao [--models DIR] [--mesh FILE] [--influence K] "
             "[--ref-samples S] [--repeats N] [--threads T]\n");
}

static options parse(int argc, char **argv) {
  options o = {.models = "../shared/models", .mesh = "stanford-bunny.obj", .influence = 4.0f,
               .ref_samples = 256, .repeats = 3, .threads = 0};
  double influence = o.influence;
  const bench_opt opts[] = {
      BENCH_OPT_STR("--models", &o.models),
      BENCH_OPT_STR("--mesh", &o.mesh),
      BENCH_OPT_REAL("--influence", 0, FLT_MAX, BENCH_OPEN_LO, &influence),
      BENCH_OPT_INT("--ref-samples", 1, INT_MAX, &o.ref_samples),
      BENCH_OPT_INT("--repeats", 1, INT_MAX, &o.repeats),
      BENCH_OPT_INT("--threads", INT_MIN, INT_MAX, &o.threads),
  };
  if (bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage)) exit(2);
  o.influence = (float)influence;
  return o;
}

/* The bunny seen from the front, filling most of the frame (the article's Figure 6.8.8). */
static const char *doc(const options *o, int w, int h, const char *technique, const char *params) {
  static char buf[2048];
  snprintf(buf, sizeof buf,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[-0.02,0.13,0.32],"
           "\"look_at\":[-0.02,0.105,0],\"fov_y\":40},\"image\":{\"width\":%d,\"height\":%d},"
           "\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"%s\"}}],"
           "\"technique\":{\"name\":\"%s\",\"backend\":\"cpu\",\"params\":%s}}",
           w, h, o->mesh, technique, params);
  return buf;
}

static int load(const options *o, const char *json, obs_scene *sc) {
  obs_err err = OBS_ERR_INIT;
  char *base = realpath(o->models, NULL);
  int rc = obs_scene_load_string(sc, json, "bunny.json", base, NULL, 0, &err);
  free(base);
  if (rc) fprintf(stderr, "bench_disc_ao: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

static obs_disc_ao_params params_of(const options *o, int proxy, int side) {
  obs_disc_ao_params p = {.proxy = proxy, .area_over_pi = 1, .influence_scale = o->influence,
                          .side = side, .subdivide = 0.05f};
  return p;
}

/* Table 6.8.1's rows at one resolution: per proxy the device pass (best of the repeats), its
 * fragments and largest overdraw; the CPU twin once per resolution (its work does not depend on
 * the proxy). */
static int table_row(const options *o, obs_vk *vk, int w, int h) {
  obs_scene sc;
  if (load(o, doc(o, w, h, "disc_ao", "{}"), &sc)) return 1;
  obs_err err = OBS_ERR_INIT;
  obs_gbuffer g = {0};
  obs_vk_gbuffer dev = {0};
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, w, h, &rig);
  obs_disc_set s = {0};
  size_t n = (size_t)w * (size_t)h;
  float *ao = malloc(n * sizeof *ao);
  int rc = obs_gbuffer_cpu(&sc, &g, o->threads, NULL, NULL, &err);
  obs_disc_ao_params p = params_of(o, OBS_DISC_PROXY_QUAD, OBS_DISC_SIDE_FRONT);
  double t0 = obs_now_ms();
  if (!rc) rc = obs_disc_set_build(&sc, &rig, &p, &s, &err);
  double build_ms = obs_now_ms() - t0;
  if (!rc && vk) rc = obs_vk_gbuffer_upload(vk, &g, &dev, &err);
  for (int proxy = 0; !rc && vk && proxy < 2; proxy++) {
    p.proxy = proxy;
    double best = INFINITY;
    obs_disc_ao_stats st = {0};
    for (int k = 0; !rc && k <= o->repeats; k++) {
      double ms;
      rc = obs_disc_ao_vk_apply(vk, &dev, &g, &s, &p, ao, NULL, &st, &ms, &err);
      if (k) best = fmin(best, ms); /* the first is the warm-up */
    }
    if (!rc)
      printf("%4dx%-5d %-8s %7zu %9.1f %8.2f %11.2f %9u %8.1f\n", w, h,
             proxy ? "pyramid" : "quad", s.n, best, 1e3 / best, (double)st.fragments / 1e6,
             st.max_overdraw, build_ms);
  }
  if (!rc) {
    obs_disc_ao_stats st = {0};
    double best = INFINITY;
    for (int k = 0; !rc && k < o->repeats; k++) {
      double c0 = obs_now_ms();
      rc = obs_disc_ao_cpu_apply(&g, &s, &p, o->threads, ao, NULL, &st, &err);
      best = fmin(best, obs_now_ms() - c0);
    }
    if (!rc)
      printf("%4dx%-5d %-8s %7zu %9.1f %8.2f %11.2f %9u %8.1f\n", w, h, "cpu twin", s.n, best,
             1e3 / best, (double)st.fragments / 1e6, st.max_overdraw, build_ms);
  }
  if (rc) fprintf(stderr, "bench_disc_ao: %s\n", obs_err_message(&err));
  if (vk && dev.depth) obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_disc_set_free(&s);
  free(ao);
  obs_scene_free(&sc);
  obs_err_free(&err);
  fflush(stdout);
  return rc != 0;
}

/* Mean AO over the pixels both cover, and the RMSE and bias of `a` against `ref`. */
static void against(const char *label, const float *a, const float *ref, const float *alpha,
                    size_t n) {
  double sa = 0, sr = 0, se = 0, sb = 0;
  size_t m = 0, darker = 0;
  for (size_t i = 0; i < n; i++) {
    if (!(alpha[i] > 0)) continue;
    double e = (double)a[i] - (double)ref[i];
    sa += a[i], sr += ref[i], se += e * e, sb += e, m++, darker += e < -0.05;
  }
  if (!m) return;
  printf("%-34s mean %.4f (rt_ao %.4f)  bias %+.4f  rmse %.4f  darker by >0.05: %.1f%%\n", label,
         sa / (double)m, sr / (double)m, sb / (double)m, sqrt(se / (double)m),
         100.0 * (double)darker / (double)m);
}

static int render(const options *o, const char *json, obs_result *res) {
  obs_scene sc;
  if (load(o, json, &sc)) return 1;
  obs_err err = OBS_ERR_INIT;
  obs_render_opts ro = {.threads = o->threads};
  int rc = obs_render(&sc, &ro, res, &err);
  if (rc) fprintf(stderr, "bench_disc_ao: %s\n", obs_err_message(&err));
  obs_scene_free(&sc);
  obs_err_free(&err);
  return rc != 0;
}

static int cmp_float(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

/* The median reach of the discs of `json`'s scene (0 when it cannot be built). */
static double median_reach(const options *o, const char *json, float influence) {
  obs_scene sc;
  if (load(o, json, &sc)) return 0;
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, 1, 1, &rig);
  obs_disc_ao_params p = params_of(o, OBS_DISC_PROXY_QUAD, OBS_DISC_SIDE_FRONT);
  p.influence_scale = influence;
  obs_disc_set s;
  obs_err err = OBS_ERR_INIT;
  double reach = 0;
  if (!obs_disc_set_build(&sc, &rig, &p, &s, &err) && s.n) {
    float *r2 = malloc(s.n * sizeof *r2);
    for (size_t i = 0; r2 && i < s.n; i++) r2[i] = s.d[i].r2;
    if (r2) {
      qsort(r2, s.n, sizeof *r2, cmp_float);
      size_t k = s.n / 2;
      reach = sqrt(r2[k]);
    }
    free(r2);
    obs_disc_set_free(&s);
  }
  obs_err_free(&err);
  obs_scene_free(&sc);
  return reach;
}

/* The bunny is closed but for the holes in its base: without visibility every disc within reach
 * occludes a receiver independently (the article's "double shadowing"). Against rt_ao unbounded
 * and at the discs' median reach, for the influence scale asked and four times it. */
static int darkening(const options *o) {
  const int w = 320, h = 240;
  char buf[256];
  obs_result ref;
  snprintf(buf, sizeof buf, "{\"samples\":%d}", o->ref_samples);
  if (render(o, doc(o, w, h, "rt_ao", buf), &ref)) return 1;
  const size_t n = (size_t)w * (size_t)h;
  const float *alpha = obs_image_channel(&ref.image, "alpha");
  printf("\nover-darkening at %dx%d against rt_ao (%d samples, cosine, binary):\n", w, h,
         o->ref_samples);
  int bad = 0;
  for (int m = 0; m < 2 && !bad; m++) {
    const float k = m ? 4.0f * o->influence : o->influence;
    double reach = median_reach(o, doc(o, w, h, "disc_ao", "{}"), k);
    obs_result ref_m;
    snprintf(buf, sizeof buf, "{\"samples\":%d,\"max_distance\":%.9g}", o->ref_samples, reach);
    if (!(reach > 0) || render(o, doc(o, w, h, "rt_ao", buf), &ref_m)) {
      bad = 1;
      break;
    }
    for (int side = 0; side < 2 && !bad; side++) {
      obs_result c;
      snprintf(buf, sizeof buf, "{\"influence_scale\":%g,\"side\":\"%s\"}", (double)k,
               side ? "back" : "front");
      if ((bad = render(o, doc(o, w, h, "disc_ao", buf), &c))) break;
      char label[96];
      snprintf(label, sizeof label, "k %g %s, unbounded", (double)k, side ? "back" : "front");
      against(label, obs_image_channel(&c.image, "ao"), obs_image_channel(&ref.image, "ao"),
              alpha, n);
      snprintf(label, sizeof label, "k %g %s, reach %.3g", (double)k, side ? "back" : "front",
               reach);
      against(label, obs_image_channel(&c.image, "ao"), obs_image_channel(&ref_m.image, "ao"),
              alpha, n);
      obs_result_free(&c);
    }
    obs_result_free(&ref_m);
  }
  obs_result_free(&ref);
  return bad;
}

int main(int argc, char **argv) {
  options o = parse(argc, argv);
  char path[1024];
  snprintf(path, sizeof path, "%s/%s", o.models, o.mesh);
  if (access(path, R_OK)) {
    printf("# %s: not present, nothing to measure\n", path);
    return 0;
  }
  bench_print_machine();
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  if (obs_vk_acquire(&vk, 0, &err)) {
    printf("# no Vulkan device (%s): CPU twin only\n", obs_err_message(&err));
    vk = NULL;
  } else {
    printf("# Vulkan: %s (%s: its timings are CPU timings)\n", obs_vk_device_name(vk),
           obs_vk_device_kind(vk));
  }
  obs_err_free(&err);
  printf("# %s, influence_scale %g, area_over_pi, side front, best of %d\n", o.mesh,
         (double)o.influence, o.repeats);
  printf("# cpu twin rows: its fragments are the receiver-disc pairs within reach, its overdraw\n"
         "# the most such pairs on one pixel\n");
  printf("%-10s %-8s %7s %9s %8s %11s %9s %8s\n", "size", "proxy", "discs", "pass ms", "fps",
         "fragments M", "overdraw", "discs ms");
  static const int sizes[3][2] = {{640, 480}, {1024, 768}, {1280, 1024}};
  int bad = 0;
  for (int i = 0; i < 3 && !bad; i++) bad = table_row(&o, vk, sizes[i][0], sizes[i][1]);
  if (vk) obs_vk_release(vk);
  if (!bad) bad = darkening(&o);
  return bad;
}
