/* ssao on the CPU: the article's analytic cases, the edge-preserving blur, tables, extremes. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"
#include "screen_rule_cases.h"

#include "gbuffer_cpu.h"
#include "simd.h"
#include "ssao.h"


static void load(const char *json, obs_scene *sc) { obs_test_load(json, "ssao.json", sc); }

static int load_fails(const char *json) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, json, "ssao.json", NULL, NULL, 0, &err);
  if (rc) printf("rejected as expected: %s\n", obs_err_message(&err));
  else obs_scene_free(&sc);
  obs_err_free(&err);
  return rc != 0;
}

static const char *TECH = "\"technique\":{\"name\":\"ssao\",\"backend\":\"cpu\",\"params\":%s}";

/* The technique member with `params` (own buffer, so it can be an argument of fmt). */
static const char *tech(const char *params) {
  static char buf[1024];
  snprintf(buf, sizeof buf, TECH, params);
  return buf;
}

/* A wall facing the camera (constant depth 5) filling the frame. */
static const char *wall_scene(const char *camera, int w, int h, const char *params) {
  static char buf[4096];
  char tech[1024];
  snprintf(tech, sizeof tech, TECH, params);
  snprintf(buf, sizeof buf,
           "{\"camera\":%s,\"image\":{\"width\":%d,\"height\":%d},\"objects\":[{\"shape\":{"
           "\"type\":\"quad\",\"vertices\":[[-100,-100,5],[100,-100,5],[100,100,5],"
           "[-100,100,5]]}}],%s}",
           camera, w, h, tech);
  return buf;
}

static const char *PERSP = "{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
                           "\"fov_y\":50}";
static const char *ORTHO = "{\"type\":\"orthographic\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
                           "\"height\":4}";

/* Renders on the CPU backend and checks the invariants every output must satisfy. */
static void render(const char *json, obs_result *r) {
  obs_test_render(json, 2, r);
  assert_int_equal(r->backend, OBS_BACKEND_CPU);
  obs_test_assert_finite(&r->image);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  const float *ao = obs_image_channel(&r->image, "ao");
  const float *raw = obs_image_channel(&r->image, "ao_raw");
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

static double mean_rect(const obs_result *r, const char *ch, int x0, int y0, int x1, int y1) {
  const float *p = obs_image_channel(&r->image, ch);
  double s = 0;
  for (int y = y0; y < y1; y++)
    for (int x = x0; x < x1; x++) s += p[(size_t)y * (size_t)r->image.width + (size_t)x];
  return s / ((double)(x1 - x0) * (y1 - y0));
}

static void test_params(void **state) {
  (void)state;
  obs_scene sc;
  load(wall_scene(PERSP, 4, 4, "{}"), &sc);
  obs_ssao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("ssao"), sc.params, &p, NULL), 0);
  assert_int_equal(p.samples, 16);
  assert_true(p.radius == 0.01f);
  assert_int_equal(p.normal_oriented, 0);
  assert_int_equal(p.blur, 1);
  assert_true(p.blur_depth_threshold == 0.05f);
  assert_int_equal(p.seed, 1);
  obs_scene_free(&sc);
  load(wall_scene(PERSP, 4, 4,
                  "{\"samples\":24,\"radius\":1e6,\"normal_oriented\":true,\"blur\":false,"
                  "\"blur_depth_threshold\":0,\"seed\":4294967295}"),
       &sc);
  assert_int_equal(obs_params_bind(obs_technique_find("ssao"), sc.params, &p, NULL), 0);
  assert_int_equal(p.samples, 24);
  assert_int_equal(p.normal_oriented, 1);
  assert_int_equal(p.blur, 0);
  assert_true(p.seed == 4294967295u);
  obs_scene_free(&sc);
  const char *bad[] = {"{\"samples\":12}",           "{\"samples\":16.5}",
                       "{\"radius\":0}",             "{\"radius\":1000001}",
                       "{\"radius\":-1}",            "{\"normal_oriented\":1}",
                       "{\"blur\":\"yes\"}",         "{\"blur_depth_threshold\":-0.1}",
                       "{\"seed\":-1}",              "{\"seed\":4294967296}",
                       "{\"kernel\":3}"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
    assert_true(load_fails(wall_scene(PERSP, 4, 4, bad[i])));
  /* Direct callers bypassing the loader get an error, not garbage. */
  json_t *js = json_loads("{\"samples\":12,\"radius\":0.01,\"normal_oriented\":false,"
                          "\"blur\":true,\"blur_depth_threshold\":0.05,\"seed\":1}",
                          0, NULL);
  assert_int_equal(obs_params_bind(obs_technique_find("ssao"), js, &p, NULL), OBS_EINVAL);
  json_decref(js);
}

static void test_tables(void **state) {
  (void)state;
  obs_ssao_params p = {.samples = 24, .radius = 0.01f, .seed = 1};
  obs_ssao_tables a, b, c;
  obs_ssao_tables_make(&p, &a);
  obs_ssao_tables_make(&p, &b);
  assert_memory_equal(&a, &b, sizeof a);
  p.seed = 2;
  obs_ssao_tables_make(&p, &c);
  assert_memory_not_equal(a.rotation, c.rotation, sizeof a.rotation);
  for (int j = 0; j < 16; j++) {
    double l = sqrt((double)a.rotation[j][0] * a.rotation[j][0] +
                    (double)a.rotation[j][1] * a.rotation[j][1] +
                    (double)a.rotation[j][2] * a.rotation[j][2]);
    assert_true(fabs(l - 1.0) < 1e-6);
  }
  /* Sample k (from 1) has length radius * (1 + 2.4/N)^k along a cube diagonal. */
  for (int k = 0; k < 24; k++) {
    double l = sqrt((double)a.offsets[k][0] * a.offsets[k][0] +
                    (double)a.offsets[k][1] * a.offsets[k][1] +
                    (double)a.offsets[k][2] * a.offsets[k][2]);
    assert_true(fabs(l / (0.01 * pow(1.1, k + 1)) - 1.0) < 1e-5);
    assert_true(fabsf(fabsf(a.offsets[k][0]) - fabsf(a.offsets[k][2])) == 0.0f);
  }
  assert_true(a.inv_samples == 1.0f / 24.0f);
}

/* Half of every antipodal pair of offsets lies behind a wall facing the camera: accessibility
 * 0.5 before the curve, 0.75 after it, on a perspective and an orthographic camera. */
static void test_flat_wall(void **state) {
  (void)state;
  const char *cams[2] = {PERSP, ORTHO};
  for (int c = 0; c < 2; c++)
    for (int s = 8; s <= 24; s += 8) {
      obs_result r;
      render(wall_scene(cams[c], 40, 30, obs_test_fmt("{\"samples\":%d}", s)), &r);
      const float *raw = obs_image_channel(&r.image, "ao_raw");
      const float *ao = obs_image_channel(&r.image, "ao");
      int off = 0;
      for (int i = 0; i < 40 * 30; i++) {
        off += raw[i] != 0.75f;
        /* Depths an ulp apart across the wall give range terms of ~1e-7, nothing more. */
        assert_true(fabsf(raw[i] - 0.75f) < 1e-5f);
        assert_true(fabsf(ao[i] - 0.75f) < 1e-5f);
      }
      printf("%s wall, %d samples: %d of 1200 pixels not exactly 0.75\n", c ? "ortho" : "persp",
             s, off);
      obs_result_free(&r);
    }
}

/* With the hemisphere about the normal every offset lies in front of the wall: raw accessibility 1,
 * saturate(1 + 1) = 1. */
static void test_flat_wall_normal_oriented(void **state) {
  (void)state;
  const char *cams[2] = {PERSP, ORTHO};
  for (int c = 0; c < 2; c++) {
    obs_result r;
    render(wall_scene(cams[c], 40, 30, "{\"normal_oriented\":true,\"samples\":24}"), &r);
    const float *raw = obs_image_channel(&r.image, "ao_raw");
    const float *ao = obs_image_channel(&r.image, "ao");
    for (int i = 0; i < 40 * 30; i++) {
      assert_true(raw[i] == 1.0f);
      assert_true(ao[i] == 1.0f);
    }
    obs_result_free(&r);
  }
}

static void test_empty_frame(void **state) {
  (void)state;
  obs_result r;
  render(obs_test_fmt("{\"camera\":%s,\"image\":{\"width\":9,\"height\":7},\"objects\":[],%s}", PERSP,
             tech("{}")),
         &r);
  const float *ao = obs_image_channel(&r.image, "ao"), *raw = obs_image_channel(&r.image, "ao_raw");
  for (int i = 0; i < 63; i++) assert_true(ao[i] == 1.0f && raw[i] == 1.0f);
  /* Stages are reported by name, with obs_render's own around the technique's. */
  static const char *const st[] = {"prepare", "gbuffer", "ao", "blur", "other"};
  assert_int_equal(r.nstages, 5);
  for (int i = 0; i < 5; i++) assert_string_equal(r.stage_names[i], st[i]);
  obs_result_free(&r);
}

/* Two walls at 45 degrees meeting in a vertical crease straight ahead: next to the crease the
 * depth buffer bends towards the camera, so more offsets fall behind it than on an open wall. */
static void test_concave_corner(void **state) {
  (void)state;
  const char *params[2] = {"{\"radius\":0.02,\"blur\":false}",
                           "{\"radius\":0.02,\"blur\":false,\"normal_oriented\":true}"};
  for (int k = 0; k < 2; k++) {
    obs_result r;
    render(obs_test_fmt("{\"camera\":%s,\"image\":{\"width\":64,\"height\":32},\"objects\":["
               "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-50,-50,-45],[0,-50,5],[0,50,5],"
               "[-50,50,-45]]}},{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,-50,5],[50,-50,"
               "-45],[50,50,-45],[0,50,5]]}}],%s}",
               PERSP, tech(params[k])),
           &r);
    double crease = mean_rect(&r, "ao", 30, 8, 34, 24);
    double open = (mean_rect(&r, "ao", 4, 8, 12, 24) + mean_rect(&r, "ao", 52, 8, 60, 24)) / 2;
    printf("%s: crease %.4f, open wall %.4f\n", params[k], crease, open);
    assert_true(crease < open - 0.02);
    obs_result_free(&r);
  }
}

/* The blur only averages pixels of similar depth: on a synthetic G-buffer with a near plane on the
 * left and a far one on the right, each blurred pixel is the mean of its own side's raw values. */
static void test_blur_keeps_edges(void **state) {
  (void)state;
  const int w = 24, h = 16;
  obs_camera_rig rig;
  memset(&rig, 0, sizeof rig);
  rig.half_w = 0.6;
  rig.half_h = 0.4;
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_alloc(&g, w, h, &rig, &err), 0);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      size_t i = (size_t)y * w + x;
      g.depth[i] = x < 12 ? 1.0f : 3.0f;
      g.normal[3 * i + 2] = -1.0f;
      g.coverage[i] = 1.0f;
    }
  obs_ssao_params p = {.samples = 16, .radius = 0.05f, .blur = 1, .blur_depth_threshold = 0.05f,
                       .seed = 1};
  float *ao = malloc(sizeof(float) * w * h), *raw = malloc(sizeof(float) * w * h);
  double ms[OBS_SSAO_CPU_STAGES];
  assert_int_equal(obs_ssao_cpu_apply_ex(&g, &p, 2, ao, raw, ms, &err), 0);
  /* The near side sees the far plane behind its offsets: brighter than 0.75 at the edge. */
  double near_edge = 0, far_edge = 0;
  for (int y = 0; y < h; y++) {
    near_edge += raw[y * w + 11];
    far_edge += raw[y * w + 12];
  }
  printf("raw next to the edge: near side %.4f, far side %.4f\n", near_edge / h, far_edge / h);
  assert_true(near_edge / h > far_edge / h + 0.05);
  int differs_from_naive = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double s = 0, all = 0;
      int n = 0, nall = 0;
      for (int dy = OBS_SSAO_BLUR_LO; dy <= OBS_SSAO_BLUR_HI; dy++)
        for (int dx = OBS_SSAO_BLUR_LO; dx <= OBS_SSAO_BLUR_HI; dx++) {
          int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          all += raw[yy * w + xx];
          nall++;
          if ((xx < 12) != (x < 12)) continue;
          s += raw[yy * w + xx];
          n++;
        }
      assert_true(fabs(ao[y * w + x] - s / n) < 1e-6);
      if (fabs(all / nall - s / n) > 0.01) differs_from_naive++;
    }
  /* The pixels beside the silhouette are where a plain box blur would have mixed the sides. */
  printf("pixels where a depth-blind blur would differ: %d\n", differs_from_naive);
  assert_true(differs_from_naive >= 2 * h);
  /* Without the blur, ao is ao_raw. */
  p.blur = 0;
  float *ao2 = malloc(sizeof(float) * w * h), *raw2 = malloc(sizeof(float) * w * h);
  assert_int_equal(obs_ssao_cpu_apply_ex(&g, &p, 3, ao2, raw2, ms, &err), 0);
  assert_memory_equal(ao2, raw, sizeof(float) * w * h);
  assert_memory_equal(raw2, raw, sizeof(float) * w * h);
  assert_true(ms[1] == 0.0);
  /* A threshold of 0 still mixes equal depths; an uncovered pixel stays 1 and is never mixed. */
  g.depth[5 * w + 5] = 0.0f;
  g.coverage[5 * w + 5] = 0.0f;
  p.blur = 1;
  p.blur_depth_threshold = 0.0f;
  assert_int_equal(obs_ssao_cpu_apply_ex(&g, &p, 1, ao2, raw2, NULL, &err), 0);
  assert_true(ao2[5 * w + 5] == 1.0f && raw2[5 * w + 5] == 1.0f);
  for (int i = 0; i < w * h; i++) assert_true(ao2[i] >= 0.0f && ao2[i] <= 1.0f);
  free(ao);
  free(raw);
  free(ao2);
  free(raw2);
  obs_gbuffer_free(&g);
  obs_err_free(&err);
}

static const char *room_scene(int w, int h, const char *params) {
  static char buf[4096];
  char tech[1024];
  snprintf(tech, sizeof tech, TECH, params);
  snprintf(buf, sizeof buf,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,1,3.4],\"look_at\":[0,1,0],"
           "\"fov_y\":40},\"image\":{\"width\":%d,\"height\":%d},\"objects\":["
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,2,-1],[-1,2,1],[1,2,1],[1,2,-1]]}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,0,1],[-1,2,1],[-1,2,-1]]}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[1,0,-1],[1,2,-1],[1,2,1],[1,0,1]]}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]},"
           "\"transform\":{\"rotate\":[0,20,0],\"translate\":[-0.35,0,-0.3]}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,0.6,0.3]},"
           "\"transform\":{\"rotate\":[0,-15,0],\"translate\":[0.4,0,0.35]}}],%s}",
           w, h, tech);
  return buf;
}

static void test_thread_independence(void **state) {
  (void)state;
  obs_scene sc;
  load(room_scene(70, 45, "{\"samples\":24,\"normal_oriented\":true}"), &sc);
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), 0);
  obs_ssao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("ssao"), sc.params, &p, NULL), 0);
  size_t n = 70 * 45;
  float *a = malloc(n * sizeof(float)), *b = malloc(n * sizeof(float));
  assert_int_equal(obs_ssao_cpu_apply(&g, &p, 1, a, NULL, &err), 0);
  assert_int_equal(obs_ssao_cpu_apply(&g, &p, 5, b, NULL, &err), 0);
  assert_memory_equal(a, b, n * sizeof(float));
  free(a);
  free(b);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The AVX2 spans (renderer/core/simd.h) promise the scalar code's bits: compare every dispatch path
 * with the scalar one on a width that leaves scalar tails and on the parameters that change the
 * kernel's branches. */
static void test_simd_matches_scalar(void **state) {
  (void)state;
  const char *params[] = {"{\"samples\":8}", "{\"samples\":16,\"blur\":false}",
                          "{\"samples\":24,\"normal_oriented\":true}",
                          "{\"samples\":16,\"radius\":0.2,\"normal_oriented\":true}",
                          /* the blur's two branches: threshold at most 1/2, and above */
                          "{\"samples\":8,\"blur_depth_threshold\":0.5}",
                          "{\"samples\":8,\"blur_depth_threshold\":3}"};
  if (!obs_simd_avx2()) printf("(no AVX2 here: every path runs the scalar code)\n");
  for (size_t c = 0; c < sizeof params / sizeof params[0]; c++) {
    obs_scene sc;
    load(room_scene(77, 45, params[c]), &sc);
    obs_gbuffer g;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), 0);
    obs_ssao_params p;
    assert_int_equal(obs_params_bind(obs_technique_find("ssao"), sc.params, &p, NULL), 0);
    size_t n = 77 * 45;
    float *v = malloc(4 * n * sizeof(float));
    assert_non_null(v);
    static const char *const paths[][2] = OBS_SIMD_PATHS;
    for (size_t q = 0; q < sizeof paths / sizeof paths[0]; q++) {
      setenv("OBSCURA_ISA", paths[q][0], 1);
      setenv("OBSCURA_GATHER", paths[q][1], 1);
      float *o = q ? v + 2 * n : v;
      assert_int_equal(obs_ssao_cpu_apply_ex(&g, &p, 2, o, o + n, NULL, &err), 0);
      if (q) assert_memory_equal(v, v + 2 * n, 2 * n * sizeof(float));
    }
    unsetenv("OBSCURA_ISA");
    unsetenv("OBSCURA_GATHER");
    size_t shaded = 0; /* the comparison is not of two blank images */
    for (size_t i = 0; i < n; i++) shaded += v[n + i] > 0.0f && v[n + i] < 1.0f;
    assert_true(shaded > n / 20);
    free(v);
    obs_gbuffer_free(&g);
    obs_scene_free(&sc);
    obs_err_free(&err);
  }
}

/* Scales, sizes and parameter limits: every output finite, in [0,1], uncovered pixels 1. */
static void test_extremes(void **state) {
  (void)state;
  const char *params[] = {"{\"radius\":1e-6}",
                          "{\"radius\":1e6,\"samples\":24}",
                          "{\"radius\":1e6,\"normal_oriented\":true,\"samples\":8}",
                          "{\"samples\":8,\"blur_depth_threshold\":0}",
                          "{\"samples\":24,\"blur_depth_threshold\":1e6,\"normal_oriented\":true}"};
  for (size_t i = 0; i < sizeof params / sizeof params[0]; i++) {
    obs_result r;
    render(room_scene(20, 14, params[i]), &r);
    obs_result_free(&r);
    render(wall_scene(ORTHO, 5, 3, params[i]), &r);
    obs_result_free(&r);
  }
  /* near/far ratio 1e6: a tiny quad 1e-3 in front of the camera over a wall at 1e3 */
  obs_result r;
  render(obs_test_fmt("{\"camera\":%s,\"image\":{\"width\":16,\"height\":12},\"objects\":[{\"shape\":{"
             "\"type\":\"quad\",\"vertices\":[[-1e-4,-1e-4,1e-3],[1e-4,-1e-4,1e-3],"
             "[1e-4,1e-4,1e-3],[-1e-4,1e-4,1e-3]]}},{\"shape\":{\"type\":\"quad\",\"vertices\":["
             "[-1e4,-1e4,1e3],[1e4,-1e4,1e3],[1e4,1e4,1e3],[-1e4,1e4,1e3]]}}],%s}",
             PERSP, tech("{\"normal_oriented\":true}")),
         &r);
  obs_result_free(&r);
  /* camera inside a box */
  render(obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0.1,0.2,0.3],\"look_at\":[1,0,"
             "0.5],\"fov_y\":120},\"image\":{\"width\":16,\"height\":16},\"objects\":[{\"shape\":{"
             "\"type\":\"box\",\"min\":[-1,-1,-1],\"max\":[1,1,1]}}],%s}",
             tech("{\"samples\":24}")),
         &r);
  obs_result_free(&r);
  /* 1x1 and 4096x16 */
  render(room_scene(1, 1, "{}"), &r);
  obs_result_free(&r);
  render(room_scene(4096, 16, "{\"samples\":8}"), &r);
  obs_result_free(&r);
  render(wall_scene(PERSP, 1, 1, "{\"samples\":24,\"normal_oriented\":true}"), &r);
  obs_result_free(&r);
}

/* The screen-space rule on the CPU: a radius under a pixel or a depth step warns, with the share
 * of pixels and the smallest radius that reaches one (screen_rule_cases.c). */
static void test_screen_rule(void **state) {
  (void)state;
  assert_int_equal(obs_screen_rule_ssao_cases(OBS_BACKEND_CPU), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_params),
      cmocka_unit_test(test_tables),
      cmocka_unit_test(test_flat_wall),
      cmocka_unit_test(test_flat_wall_normal_oriented),
      cmocka_unit_test(test_empty_frame),
      cmocka_unit_test(test_concave_corner),
      cmocka_unit_test(test_blur_keeps_edges),
      cmocka_unit_test(test_thread_independence),
      cmocka_unit_test(test_simd_matches_scalar),
      cmocka_unit_test(test_extremes),
      cmocka_unit_test(test_screen_rule),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
