/* hbao on the CPU: analytic cases (planes, empty frame, a concave corner), early exit, parameter
 * sets, half resolution, scale invariance, determinism, and extremes of size, scale and params. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"
#include "screen_rule_cases.h"

#include "gbuffer_cpu.h"
#include "simd.h"
#include "hbao.h"


/* A whole scene document: camera JSON, image size, objects JSON (array body), params JSON. */
static const char *scene(const char *camera, int w, int h, const char *objects, const char *params) {
  static char buf[8192];
  snprintf(buf, sizeof buf,
           "{\"camera\":%s,\"image\":{\"width\":%d,\"height\":%d},\"objects\":[%s],"
           "\"technique\":{\"name\":\"hbao\",\"backend\":\"cpu\",\"params\":%s}}",
           camera, w, h, objects, params);
  return buf;
}

static float px(const obs_result *r, const char *ch, int x, int y) {
  const float *p = obs_image_channel(&r->image, ch);
  assert_non_null(p);
  return p[(size_t)y * (size_t)r->image.width + (size_t)x];
}

/* Renders on the CPU and checks what every output must satisfy. */
static void render(const char *json, obs_result *r) {
  obs_test_render(json, 2, r);
  assert_int_equal(r->backend, OBS_BACKEND_CPU);
  obs_test_assert_finite(&r->image);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  const float *ao = obs_image_channel(&r->image, "ao"), *raw = obs_image_channel(&r->image, "ao_raw");
  const float *al = obs_image_channel(&r->image, "alpha");
  assert_non_null(ao);
  assert_non_null(raw);
  assert_non_null(al);
  for (size_t i = 0; i < n; i++) {
    assert_true(ao[i] >= 0.0f && ao[i] <= 1.0f);
    assert_true(raw[i] >= 0.0f && raw[i] <= 1.0f);
    if (al[i] == 0.0f) {
      assert_true(ao[i] == 1.0f);
      assert_true(raw[i] == 1.0f);
    }
  }
}

static const char *FLOOR = "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1000,0,-1000],[-1000,0,1000],"
                           "[1000,0,1000],[1000,0,-1000]]}}";

/* Nothing rises above the tangent plane of a plane, from any view: AO is 1 with the default bias and
 * within rounding of 1 without bias (texel snapping is compensated, see hbao.md). */
static void test_plane_is_one(void **state) {
  (void)state;
  const char *cams[] = {
      "{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],\"fov_y\":90}",
      "{\"type\":\"perspective\",\"position\":[0.3,0.2,-6],\"look_at\":[1,0,4],\"fov_y\":60}",
      "{\"type\":\"perspective\",\"position\":[0,10,0],\"look_at\":[0.5,0,0.3],\"fov_y\":100}",
      "{\"type\":\"orthographic\",\"position\":[0,3,-3],\"look_at\":[0,0,0],\"height\":6}",
      "{\"type\":\"orthographic\",\"position\":[1,0.4,-5],\"look_at\":[0,0,0],\"height\":3}",
  };
  const char *params[] = {"{\"blur_radius\":0}", "{\"angle_bias\":0,\"blur_radius\":0}",
                          "{\"angle_bias\":0,\"directions\":32,\"steps\":32,\"radius\":5}",
                          "{\"angle_bias\":0,\"half_res\":true,\"radius\":0.3}"};
  for (size_t c = 0; c < sizeof cams / sizeof cams[0]; c++)
    for (size_t k = 0; k < sizeof params / sizeof params[0]; k++) {
      obs_result r;
      render(scene(cams[c], 40, 30, FLOOR, params[k]), &r);
      double lo = 1.0;
      int covered = 0;
      for (int y = 0; y < 30; y++)
        for (int x = 0; x < 40; x++) {
          if (px(&r, "alpha", x, y) == 0.0f) continue;
          covered++;
          lo = fmin(lo, px(&r, "ao", x, y));
          if (k == 0) assert_true(px(&r, "ao", x, y) == 1.0f);
        }
      printf("plane camera %zu params %s: %d covered, min ao %.8f\n", c, params[k], covered, lo);
      assert_true(covered > 100);
      assert_true(lo >= 1.0 - 1e-4);
      obs_result_free(&r);
    }
}

static void test_empty_frame(void **state) {
  (void)state;
  const char *params[] = {"{}", "{\"half_res\":true}", "{\"blur_radius\":16,\"radius\":1e30}"};
  for (int k = 0; k < 3; k++) {
    obs_result r;
    /* Geometry behind the camera only. */
    render(scene("{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":60}",
                 17, 9,
                 "{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,-5],\"radius\":1}}", params[k]),
           &r);
    for (int i = 0; i < 17 * 9; i++) {
      assert_true(r.image.data[i] == 1.0f);
      assert_true(px(&r, "alpha", i % 17, i / 17) == 0.0f);
      assert_true(px(&r, "ao_raw", i % 17, i / 17) == 1.0f);
    }
    obs_result_free(&r);
  }
}

/* Two perpendicular walls seen across the crease (orthographic, the crease is the middle row): the
 * rows next to the crease are occluded, rows further than R from it are not. */
static const char *CORNER = "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-50,0,-50],[-50,0,0],[50,0,0],"
                            "[50,0,-50]]}},{\"shape\":{\"type\":\"quad\",\"vertices\":[[-50,0,0],"
                            "[-50,50,0],[50,50,0],[50,0,0]]}}";

static void test_concave_corner(void **state) {
  (void)state;
  const char *params[] = {"{\"blur_radius\":0}", "{}", "{\"angle_bias\":0,\"blur_radius\":0}",
                          "{\"half_res\":true}"};
  for (int k = 0; k < 4; k++) {
    obs_result r;
    render(scene("{\"type\":\"orthographic\",\"position\":[0,5,-5],\"look_at\":[0,0,0],"
                 "\"height\":4}",
                 32, 32, CORNER, params[k]),
           &r);
    double near = 0, far = 0;
    for (int x = 4; x < 28; x++) {
      near += px(&r, "ao", x, 15) + px(&r, "ao", x, 16);
      far += px(&r, "ao", x, 1) + px(&r, "ao", x, 30);
    }
    near /= 48;
    far /= 48;
    printf("corner %s: ao near the crease %.4f, far from it %.4f\n", params[k], near, far);
    assert_true(far > 0.999);
    assert_true(near < far - 0.1);
    /* Darkening grows toward the crease. */
    assert_true(px(&r, "ao", 16, 16) <= px(&r, "ao", 16, 19) + 1e-6);
    obs_result_free(&r);
  }
  /* Perspective too, looking into the corner from above. */
  obs_result r;
  render(scene("{\"type\":\"perspective\",\"position\":[0,3,-3],\"look_at\":[0,0,0],\"fov_y\":40}",
               32, 32, CORNER, "{\"blur_radius\":0}"),
         &r);
  printf("corner perspective: crease %.4f, top %.4f, bottom %.4f\n", px(&r, "ao", 16, 16),
         px(&r, "ao", 16, 1), px(&r, "ao", 16, 30));
  assert_true(px(&r, "ao", 16, 16) < 0.9f);
  assert_true(px(&r, "ao", 16, 1) == 1.0f && px(&r, "ao", 16, 30) == 1.0f);
  obs_result_free(&r);
}

/* The projected radius under one texel exits early with exactly 1. */
static void test_tiny_radius(void **state) {
  (void)state;
  const char *params[] = {"{\"radius\":1e-6}", "{\"radius\":1e-6,\"half_res\":true}",
                          "{\"radius\":1e-300}", "{\"radius\":0.004,\"blur_radius\":0}"};
  for (int k = 0; k < 4; k++) {
    obs_result r;
    /* At distance ~5 with fov 40 and 32 pixels one pixel is ~0.11 units: R = 0.004 is far under. */
    render(scene("{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0,0],\"fov_y\":40}",
                 32, 32, CORNER, params[k]),
           &r);
    for (int i = 0; i < 32 * 32; i++) assert_true(r.image.data[i] == 1.0f);
    obs_result_free(&r);
  }
}

/* A Cornell-like room with blocks and a sphere, every object scaled by s about the origin. */
static const char *room(double s) {
  static char buf[4096];
  char t[96];
  snprintf(t, sizeof t, "\"transform\":{\"scale\":[%.17g,%.17g,%.17g]", s, s, s);
  snprintf(buf, sizeof buf,
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[556,0,0],[0,0,0],[0,0,559],[556,0,559]]},%s}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,559],[556,0,559],[556,548,559],[0,548,559]]},%s}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,0,559],[0,548,559],[0,548,0]]},%s}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[556,0,0],[556,548,0],[556,548,559],[556,0,559]]},%s}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,548,0],[0,548,559],[556,548,559],[556,548,0]]},%s}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[100,0,100],\"max\":[250,165,300]},%s}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[300,0,300],\"max\":[450,330,450]},%s,\"rotate\":[0,15,0]}},"
           "{\"shape\":{\"type\":\"sphere\",\"center\":[380,60,150],\"radius\":60},%s}}",
           t, t, t, t, t, t, t, t);
  return buf;
}

static const char *room_cam(double s) {
  static char buf[256];
  snprintf(buf, sizeof buf,
           "{\"type\":\"perspective\",\"position\":[%.17g,%.17g,%.17g],\"look_at\":[%.17g,%.17g,0],"
           "\"fov_y\":40}",
           278 * s, 273 * s, -800 * s, 278 * s, 273 * s);
  return buf;
}

#define ROOM room(1)
#define ROOM_CAM room_cam(1)

static void test_parameter_sets(void **state) {
  (void)state;
  const int sets[][2] = {{4, 4}, {8, 8}, {16, 16}, {1, 1}, {32, 32}};
  double prev = -1;
  for (int k = 0; k < 5; k++) {
    obs_result r;
    render(scene(ROOM_CAM, 48, 48, ROOM,
                 obs_test_fmt("{\"radius\":80,\"directions\":%d,\"steps\":%d}", sets[k][0], sets[k][1])),
           &r);
    obs_stats st;
    assert_int_equal(obs_metrics_stats(&r.image, "ao", "alpha", &st, NULL), 0);
    printf("room directions/steps %d/%d: mean ao %.4f min %.4f, stages:", sets[k][0], sets[k][1],
           st.mean, st.min);
    for (int i = 0; i < r.nstages; i++) printf(" %s=%.2fms", r.stage_names[i], r.stage_ms[i]);
    printf("\n");
    assert_true(st.min < (k < 3 ? 0.9 : 0.97)); /* corners and contacts are darkened */
    assert_true(st.mean > 0.75);                 /* most of the room is open */
    if (k > 0 && k < 3) assert_true(fabs(st.mean - prev) < 0.05);
    prev = st.mean;
    obs_result_free(&r);
  }
}

static void load(const char *json, obs_scene *sc) { obs_test_load(json, "hbao.json", sc); }

static double rmse(const float *a, const float *b, const float *mask, size_t n, double *maxd) {
  double s = 0, m = 0;
  size_t c = 0;
  for (size_t i = 0; i < n; i++) {
    if (mask && !(mask[i] > 0)) continue;
    double d = fabs((double)a[i] - (double)b[i]);
    s += d * d;
    m = fmax(m, d);
    c++;
  }
  if (maxd) *maxd = m;
  return c ? sqrt(s / (double)c) : 0.0;
}

/* half_res approximates full resolution; on even texels before the blur they agree exactly where
 * the projected radius is large enough for both to sample. */
static void test_half_res(void **state) {
  (void)state;
  obs_scene sc;
  load(scene(ROOM_CAM, 64, 64, ROOM, "{}"), &sc);
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), 0);
  size_t n = 64 * 64;
  float *full = malloc(4 * n * sizeof(float));
  assert_non_null(full);
  float *half = full + n, *full_raw = full + 2 * n, *half_raw = full + 3 * n;
  obs_hbao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
  p.radius = 60;
  double ms[OBS_HBAO_PASS_COUNT];
  assert_int_equal(obs_hbao_cpu_apply_ex(&g, &p, 2, full, full_raw, ms, &err), 0);
  p.half_res = 1;
  assert_int_equal(obs_hbao_cpu_apply_ex(&g, &p, 2, half, half_raw, ms, &err), 0);
  assert_true(ms[OBS_HBAO_PASS_DOWNSAMPLE] >= 0 && ms[OBS_HBAO_PASS_UPSAMPLE] >= 0);
  double md, mdr;
  double e = rmse(full, half, g.coverage, n, &md), er = rmse(full_raw, half_raw, g.coverage, n, &mdr);
  printf("half_res vs full: blurred rmse %.5f (max %.4f), raw rmse %.5f (max %.4f)\n", e, md, er,
         mdr);
  assert_true(e < 0.03);
  assert_true(er < 0.06);
  free(full);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The same room scaled by 1e-4 and 1e4 with R scaled alike gives the same AO up to rounding. */
static void test_scale_invariance(void **state) {
  (void)state;
  obs_result base;
  char *cam = strdup(room_cam(1));
  render(scene(cam, 40, 40, ROOM, "{\"radius\":80}"), &base);
  free(cam);
  const double scales[] = {1e-4, 1e4};
  for (int i = 0; i < 2; i++) {
    double s = scales[i];
    obs_result r;
    cam = strdup(room_cam(s));
    render(scene(cam, 40, 40, room(s), obs_test_fmt("{\"radius\":%.17g}", 80 * s)), &r);
    free(cam);
    double md, e = rmse(obs_image_channel(&r.image, "ao"), obs_image_channel(&base.image, "ao"),
                        NULL, 1600, &md);
    printf("scale %g: rmse vs scale 1 = %.2e (max %.2e)\n", s, e, md);
    assert_true(e < 1e-3 && md < 0.05);
    obs_result_free(&r);
  }
  obs_result_free(&base);
}

static void test_thread_independence(void **state) {
  (void)state;
  obs_scene sc;
  load(scene(ROOM_CAM, 70, 50, ROOM, "{}"), &sc);
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), 0);
  size_t n = 70 * 50;
  float *a = malloc(2 * n * sizeof(float));
  assert_non_null(a);
  obs_hbao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
  p.radius = 70;
  for (int h = 0; h < 2; h++) {
    p.half_res = h;
    assert_int_equal(obs_hbao_cpu_apply(&g, &p, 1, a, NULL, &err), 0);
    assert_int_equal(obs_hbao_cpu_apply(&g, &p, 7, a + n, NULL, &err), 0);
    assert_memory_equal(a, a + n, n * sizeof(float));
  }
  free(a);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The AVX2 spans (renderer/core/simd.h) promise the scalar code's bits: compare every dispatch
 * path (OBS_SIMD_PATHS) with the scalar one, raw and blurred, on a width that leaves scalar tails,
 * for both projections, both resolutions and the branches the parameters select. */
static void test_simd_matches_scalar(void **state) {
  (void)state;
  const char *cams[] = {ROOM_CAM, "{\"type\":\"orthographic\",\"position\":[278,273,-800],"
                                  "\"look_at\":[278,273,0],\"height\":560}"};
  const int sets[][5] = {/* directions, steps, half_res, blur_radius, bias (degrees) */
                         {4, 4, 0, 4, 0},  {8, 8, 0, 8, 10}, {16, 16, 1, 16, 30},
                         {8, 8, 1, 0, 0},  {1, 2, 0, 1, 40}, {8, 8, 0, 0, 10},
                         {8, 8, 1, 2, 10}, {8, 8, 0, 0, 0}};
  /* Per set: a radius a few texels wide, and huge ones (squared distances at the ends of float
   * range, where the spans' cheap pre-test must leave the decision to the exact code). */
  const float radii[] = {90, 90, 90, 90, 90, 3, 1e7f, 1e30f};
  /* The blur's depth weight: default, weights that underflow to 0 (exp's clamp), plain Gaussian. */
  const float sharps[] = {16, 1e6f, 0, 16, 16, 16, 1e3f, 16};
  if (!obs_simd_avx2()) printf("(no AVX2 here: every path runs the scalar code)\n");
  for (int c = 0; c < 2; c++) {
    obs_scene sc;
    load(scene(cams[c], 77, 50, ROOM, "{}"), &sc);
    obs_gbuffer g;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), 0);
    size_t n = 77 * 50;
    float *v = malloc(4 * n * sizeof(float));
    assert_non_null(v);
    for (size_t k = 0; k < sizeof sets / sizeof sets[0]; k++) {
      obs_hbao_params p;
      assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
      p.radius = radii[k];
      p.directions = sets[k][0];
      p.steps = sets[k][1];
      p.half_res = sets[k][2];
      p.blur_radius = sets[k][3];
      p.angle_bias = (float)(sets[k][4] * 3.14159265358979 / 180);
      p.blur_sharpness = sharps[k];
      static const char *const paths[][2] = OBS_SIMD_PATHS;
      for (size_t q = 0; q < sizeof paths / sizeof paths[0]; q++) {
        setenv("OBSCURA_ISA", paths[q][0], 1);
        setenv("OBSCURA_GATHER", paths[q][1], 1);
        float *o = q ? v + 2 * n : v;
        assert_int_equal(obs_hbao_cpu_apply_ex(&g, &p, 2, o, o + n, NULL, &err), 0);
        if (q) assert_memory_equal(v, v + 2 * n, 2 * n * sizeof(float));
      }
      unsetenv("OBSCURA_ISA");
      unsetenv("OBSCURA_GATHER");
      /* The comparison is not of two blank images (the orthographic view of the room has little
       * occlusion within the radius: its walls are edge-on or face-on). */
      size_t shaded = 0;
      for (size_t i = 0; i < n; i++) shaded += v[n + i] > 0.0f && v[n + i] < 1.0f;
      if (k < 4) assert_true(shaded > n / 100); /* set 4's bias leaves almost nothing */
    }
    free(v);
    obs_gbuffer_free(&g);
    obs_scene_free(&sc);
    obs_err_free(&err);
  }
}

/* Sizes, scales and parameters at their limits: finite, in [0,1], uncovered = 1. */
static void test_extremes(void **state) {
  (void)state;
  const char *params[] = {
      "{\"radius\":1e6}", "{\"radius\":1e30,\"half_res\":true}",
      "{\"directions\":1,\"steps\":1,\"blur_radius\":0}",
      "{\"directions\":32,\"steps\":32,\"blur_radius\":16}",
      "{\"scale\":1e6,\"blur_sharpness\":0}", "{\"scale\":0}",
      "{\"blur_sharpness\":1e6,\"angle_bias\":1.5707963}", "{\"seed\":4294967295,\"half_res\":true}"};
  char *copies[6];
  /* the room */
  copies[0] = strdup(scene(ROOM_CAM, 24, 24, ROOM, "%s"));
  /* near/far ratio 1e6: a floor from 1e-3 to 1e3 seen at a grazing angle */
  copies[1] = strdup(scene(
      "{\"type\":\"perspective\",\"position\":[0,1e-3,0],\"look_at\":[0,0,1],\"fov_y\":60}", 24, 24,
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e3,0,1e-3],[-1e3,0,1e3],[1e3,0,1e3],"
      "[1e3,0,1e-3]]}},{\"shape\":{\"type\":\"sphere\",\"center\":[0,0.5,3],\"radius\":0.5}}",
      "%s"));
  /* camera inside a box */
  copies[2] = strdup(scene("{\"type\":\"perspective\",\"position\":[0.1,0.2,0.3],\"look_at\":[1,0,"
                           "0.5],\"fov_y\":120}",
                           24, 24, "{\"shape\":{\"type\":\"box\",\"min\":[-1,-1,-1],\"max\":[1,1,1]}}",
                           "%s"));
  /* 1x1 */
  copies[3] = strdup(scene(ROOM_CAM, 1, 1, ROOM, "%s"));
  /* 4096x16 */
  copies[4] = strdup(scene(ROOM_CAM, 4096, 16, ROOM, "%s"));
  /* a displaced sphere filling the view, orthographic */
  copies[5] = strdup(scene("{\"type\":\"orthographic\",\"position\":[0,0,-4],\"look_at\":[0,0,0],"
                           "\"height\":2.5}",
                           32, 32, "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":5}}",
                           "%s"));
  for (int s = 0; s < 6; s++)
    for (size_t k = 0; k < sizeof params / sizeof params[0]; k++) {
      if (s == 4 && k != 0 && k != 3) continue; /* keep the wide image cheap */
      obs_result r;
      render(obs_test_fmt(copies[s], params[k]), &r);
      obs_result_free(&r);
    }
  for (int s = 0; s < 6; s++) free(copies[s]);
}

/* Radii far beyond the scene: the squared distance in units of R must not underflow. A plane
 * reads 1; a ball on it reads what a radius just beyond the scene gives. */
static void test_huge_radius(void **state) {
  (void)state;
  const char *cam = "{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0.3,0],"
                    "\"fov_y\":30}";
  const char *ball = "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-20,0,-20],[-20,0,20],"
                     "[20,0,20],[20,0,-20]]}},{\"shape\":{\"type\":\"sphere\",\"center\":[0,0.5,0],"
                     "\"radius\":0.5}}";
  const char *radii[] = {"{\"radius\":1e25}", "{\"radius\":1e30,\"angle_bias\":0}"};
  for (int k = 0; k < 2; k++) {
    obs_result r;
    render(scene(cam, 32, 32, FLOOR, radii[k]), &r);
    for (int y = 0; y < 32; y++)
      for (int x = 0; x < 32; x++) assert_true(px(&r, "ao", x, y) == 1.0f);
    obs_result_free(&r);
  }
  obs_result a, b;
  render(scene(cam, 32, 32, ball, "{\"radius\":1e25}"), &a);
  render(scene(cam, 32, 32, ball, "{\"radius\":1e6}"), &b);
  double lo = 1, mx = 0;
  for (int y = 0; y < 32; y++)
    for (int x = 0; x < 32; x++) {
      lo = fmin(lo, px(&a, "ao", x, y));
      mx = fmax(mx, fabs(px(&a, "ao", x, y) - px(&b, "ao", x, y)));
    }
  printf("ball on a plane, radius 1e25: min ao %.4f, max |ao - ao(radius 1e6)| %.2e\n", lo, mx);
  assert_true(lo < 0.9);
  assert_true(mx <= 1e-5);
  obs_result_free(&a);
  obs_result_free(&b);
}

/* Fields of view down to 1e-4 degrees: a pixel's footprint is a few ulps of depth there, and the
 * depth's rounding must not read as occlusion. A plane reads 1, with and without bias. */
static void test_tiny_fov(void **state) {
  (void)state;
  const char *cams[] = {
      "{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],\"fov_y\":1e-4}",
      "{\"type\":\"perspective\",\"position\":[0.3,0.2,-6],\"look_at\":[1,0,4],\"fov_y\":1e-3}",
      "{\"type\":\"perspective\",\"position\":[0,10,0],\"look_at\":[0.5,0,0.3],\"fov_y\":1e-4}"};
  const char *params[] = {"{\"radius\":1e-5,\"blur_radius\":0}",
                          "{\"radius\":1,\"angle_bias\":0,\"blur_radius\":0}",
                          "{\"radius\":1e-6,\"directions\":32,\"steps\":32,\"half_res\":true}"};
  for (int c = 0; c < 3; c++)
    for (int k = 0; k < 3; k++) {
      obs_result r;
      render(scene(cams[c], 24, 24, FLOOR, params[k]), &r);
      double lo = 1;
      for (int y = 0; y < 24; y++)
        for (int x = 0; x < 24; x++) {
          assert_true(px(&r, "alpha", x, y) == 1.0f);
          lo = fmin(lo, px(&r, "ao", x, y));
        }
      printf("plane, camera %d, %s: min ao %.8f\n", c, params[k], lo);
      assert_true(lo == 1.0);
      obs_result_free(&r);
    }
}

static void test_params(void **state) {
  (void)state;
  obs_hbao_params p, d;
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &d, NULL), 0);
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
  assert_memory_equal(&p, &d, sizeof p);
  /* The schema's defaults bind as the defaults. */
  json_t *sch = obs_technique_params_schema(obs_technique_find("hbao"));
  assert_non_null(sch);
  json_t *props = json_object_get(sch, "properties"), *defs = json_object();
  const char *key;
  json_t *v;
  json_object_foreach(props, key, v) json_object_set(defs, key, json_object_get(v, "default"));
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), defs, &p, NULL), 0);
  assert_memory_equal(&p, &d, sizeof p);
  json_decref(defs);
  json_decref(sch);
  const char *bad[] = {"{\"radius\":0}",        "{\"radius\":-1}",      "{\"directions\":0}",
                       "{\"directions\":33}",   "{\"steps\":1.5}",      "{\"angle_bias\":1.5707963267948966}",
                       "{\"scale\":-1}",        "{\"blur_radius\":17}", "{\"half_res\":1}",
                       "{\"seed\":-1}",         "{\"radius\":\"big\"}"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    json_t *j = json_loads(bad[i], 0, NULL);
    assert_non_null(j);
    assert_int_equal(obs_params_bind(obs_technique_find("hbao"), j, &p, NULL), OBS_EINVAL);
    json_decref(j);
    /* The loader rejects them too, naming the parameter. */
    obs_scene sc;
    obs_err err = OBS_ERR_INIT;
    int rc = obs_scene_load_string(&sc, scene(ROOM_CAM, 8, 8, ROOM, bad[i]), "bad.json", NULL, NULL,
                                   0, &err);
    assert_int_equal(rc, OBS_EINVAL);
    assert_non_null(strstr(obs_err_message(&err), "/technique/params/"));
    obs_err_free(&err);
  }
  /* The direction table: unit directions, evenly spaced, jitter in [0,1), seed-dependent. */
  obs_hbao_params q = d;
  q.directions = 5;
  float t1[16 * 5 * 4], t2[16 * 5 * 4];
  obs_hbao_directions(&q, t1);
  q.seed = 2;
  obs_hbao_directions(&q, t2);
  assert_true(memcmp(t1, t2, sizeof t1) != 0);
  for (int c = 0; c < 16; c++)
    for (int i = 0; i < 5; i++) {
      const float *e = t1 + (c * 5 + i) * 4;
      assert_true(fabsf(e[0] * e[0] + e[1] * e[1] - 1.0f) < 1e-6f);
      assert_true(e[2] >= 0.0f && e[2] < 1.0f && e[2] == t1[c * 20 + 2]);
      const float *nx = t1 + (c * 5 + (i + 1) % 5) * 4;
      assert_true(fabsf(e[0] * nx[0] + e[1] * nx[1] - cosf(2.0f * 3.14159265f / 5)) < 1e-5f);
    }
}

/* The screen-space rule on the CPU (screen_rule_cases.c). */
static void test_screen_rule(void **state) {
  (void)state;
  assert_int_equal(obs_screen_rule_hbao_cases(OBS_BACKEND_CPU), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plane_is_one),     cmocka_unit_test(test_empty_frame),
      cmocka_unit_test(test_concave_corner),   cmocka_unit_test(test_tiny_radius),
      cmocka_unit_test(test_parameter_sets),   cmocka_unit_test(test_half_res),
      cmocka_unit_test(test_scale_invariance), cmocka_unit_test(test_thread_independence),
      cmocka_unit_test(test_extremes),         cmocka_unit_test(test_params),
      cmocka_unit_test(test_simd_matches_scalar), cmocka_unit_test(test_huge_radius),
      cmocka_unit_test(test_tiny_fov),
      cmocka_unit_test(test_screen_rule),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
