/* ssao_variance on Vulkan against its CPU twin: the same G-buffers through both bit for bit, full
 * renders through both backends, planes and extremes on the device, all under the validation
 * layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vk.h"
#include "vktest.h"
#include "ssao_variance/ssao_variance.h"

static const char *scene_doc(const char *camera_objects, int w, int h, const char *backend,
                             const char *params) {
  static char buf[8192];
  snprintf(buf, sizeof buf,
           "{%s,\"image\":{\"width\":%d,\"height\":%d},\"technique\":{\"name\":\"ssao_variance\","
           "\"backend\":\"%s\",\"params\":%s}}",
           camera_objects, w, h, backend, params);
  return buf;
}

static const char *ROOM =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0.3,1,3.4],\"look_at\":[0,0.8,0],"
    "\"fov_y\":50},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,2,-1],[-1,2,1],[1,2,1],[1,2,-1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,0,1],[-1,2,1],[-1,2,-1]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]},"
    "\"transform\":{\"rotate\":[0,20,0],\"translate\":[-0.35,0,-0.3]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,0.6,0.3]},"
    "\"transform\":{\"rotate\":[0,-15,0],\"translate\":[0.4,0,0.35]}}]";

static const char *SPHERE =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,2.6],\"look_at\":[0,0,0],"
    "\"fov_y\":45},\"objects\":[{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":6}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,-1.2,-3],[-3,-1.2,3],[3,-1.2,3],"
    "[3,-1.2,-3]]}}]";

static const char *ROOM_ORTHO =
    "\"camera\":{\"type\":\"orthographic\",\"position\":[2,3,3],\"look_at\":[0,0.6,0],"
    "\"height\":3},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]},"
    "\"transform\":{\"rotate\":[0,20,0],\"translate\":[-0.35,0,-0.3]}}]";

static void load(const char *json, obs_scene *sc) { obs_test_load(json, "svar_vk.json", sc); }

static const char *const param_sets[] = {
    "{\"radius\":0.4}",
    "{\"radius\":0.1}",
    "{\"radius\":2,\"variance_weight\":0.5,\"taps\":16}",
    "{\"radius\":2,\"taps\":1}",
    "{\"radius\":1e6}",
    "{\"method\":\"depth_unsharp\",\"radius\":0.4}",
    "{\"method\":\"depth_unsharp\",\"radius\":3,\"strength\":2}",
};

/* The same (ray-cast) G-buffer through both twins: every pixel's bits equal. The operations are
 * IEEE float32 adds, multiplies and divisions in one order on both sides (precise in GLSL), the
 * reciprocals 1/N a table from the host; lavapipe's division is correctly rounded, as the CPU's is
 * (a GPU whose division is not would differ in the last bits: docs, "Twins"). */
static void cross_backend(const char *scene, const char *label, int w, int h) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  load(scene_doc(scene, w, h, "cpu", "{}"), &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  obs_svar_projection proj = {g.ortho, g.half_w};
  size_t n = (size_t)w * (size_t)h;
  float *c = malloc(n * sizeof(float)), *v = malloc(n * sizeof(float));
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    obs_scene ps;
    load(scene_doc(scene, w, h, "cpu", param_sets[k]), &ps);
    obs_ssao_variance_params p;
    assert_int_equal(obs_params_bind(ps.technique, ps.params, &p, NULL), 0);
    obs_scene_free(&ps);
    obs_svar_plan pc, pv;
    double cms[OBS_SVAR_CPU_STAGES], vms[OBS_SVAR_VK_STAGES];
    vktest_check_rc(obs_svar_cpu_apply(&g, &p, 2, c, cms, &pc, &err), &err);
    vktest_check_rc(obs_svar_vk_apply(vk, &dev, &proj, &p, v, vms, &pv, &err), &err);
    assert_memory_equal(&pc, &pv, sizeof pc);
    size_t exact = 0, shaded = 0;
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
      assert_true(isfinite(v[i]) && v[i] >= 0.0f && v[i] <= 1.0f);
      exact += c[i] == v[i];
      shaded += c[i] < 1.0f;
      worst = fmax(worst, fabs((double)c[i] - v[i]));
    }
    printf("%-28s %-52s box %3d px: %zu/%zu bit-identical (max |d| %.2g), %zu shaded\n", label,
           param_sets[k], pc.radius_px, exact, n, worst, shaded);
    assert_int_equal(exact, n);
  }
  free(c);
  free(v);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_cross_room(void **state) {
  (void)state;
  cross_backend(ROOM, "room 96x72", 96, 72);
}

static void test_cross_room_ortho(void **state) {
  (void)state;
  cross_backend(ROOM_ORTHO, "room ortho 61x47", 61, 47);
}

static void test_cross_displaced_sphere(void **state) {
  (void)state;
  cross_backend(SPHERE, "displaced_sphere(6) 80x80", 80, 80);
}

static void render_backend(const char *json, obs_result *r) {
  obs_scene sc;
  load(json, &sc);
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  vktest_check_rc(obs_render(&sc, &o, r, &err), &err);
  obs_scene_free(&sc);
  obs_err_free(&err);
  obs_test_assert_finite(&r->image);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  const float *ao = obs_image_channel(&r->image, "ao"), *al = obs_image_channel(&r->image, "alpha");
  for (size_t i = 0; i < n; i++) {
    assert_true(ao[i] >= 0.0f && ao[i] <= 1.0f);
    if (al[i] == 0.0f) assert_true(ao[i] == 1.0f);
  }
}

/* Full renders: the rasterised G-buffer against the CPU's; they differ on silhouettes and facet
 * edges only, which the box spreads over its footprint. */
static void pipeline(const char *scene, const char *label, int w, int h, const char *params) {
  vktest_need_vk();
  obs_result c, v;
  render_backend(scene_doc(scene, w, h, "cpu", params), &c);
  render_backend(scene_doc(scene, w, h, "vulkan", params), &v);
  assert_int_equal(v.backend, OBS_BACKEND_VULKAN);
  static const char *const vst[] = {"prepare", "device", "gbuffer",  "geometry",
                                    "blur",    "ao",     "readback", "other"};
  assert_int_equal(v.nstages, 8);
  for (int i = 0; i < 8; i++) assert_string_equal(v.stage_names[i], vst[i]);
  size_t n = (size_t)w * (size_t)h, over = 0;
  const float *ca = obs_image_channel(&c.image, "ao"), *va = obs_image_channel(&v.image, "ao");
  double ss = 0;
  for (size_t i = 0; i < n; i++) {
    double e = fabs((double)ca[i] - va[i]);
    ss += e * e;
    over += e > 0.05;
  }
  printf("%-28s %s: %.2f %% of pixels differ by > 0.05 (rmse %.4f)\n", label, params,
         100.0 * (double)over / (double)n, sqrt(ss / (double)n));
  assert_true((double)over / (double)n < 0.01);
  obs_result_free(&c);
  obs_result_free(&v);
}

static void test_pipeline(void **state) {
  (void)state;
  pipeline(ROOM, "room 96x72", 96, 72, "{\"radius\":0.4}");
  pipeline(ROOM, "room 96x72", 96, 72, "{\"method\":\"depth_unsharp\",\"radius\":0.4}");
  pipeline(SPHERE, "displaced_sphere(6) 80x80", 80, 80, "{\"radius\":0.3}");
  pipeline(ROOM_ORTHO, "room ortho 64x48", 64, 48, "{\"radius\":0.5}");
}

/* A plane filling the frame reads exactly 1 on the device's own rasterised G-buffer too (its
 * depth errors lie under the 2^-20 tolerance). */
static void test_planes_open(void **state) {
  (void)state;
  vktest_need_vk();
  const char *planes[] = {
      "\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":50},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,-100,5],[100,-100,5],"
      "[100,100,5],[-100,100,5]]}}]",
      "\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":50},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,-56,-100],[100,-56,-100],"
      "[100,164,300],[-100,164,300]]}}]",
      "\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
      "\"height\":4},\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,-100,-50],"
      "[100,-100,-50],[100,100,70],[-100,100,70]]}}]"};
  for (size_t q = 0; q < 3; q++)
    for (int m = 0; m < 2; m++) {
      obs_result r;
      render_backend(
          scene_doc(planes[q], 48, 36, "vulkan",
                    m ? "{\"method\":\"depth_unsharp\",\"radius\":1}" : "{\"radius\":1}"),
          &r);
      const float *ao = obs_image_channel(&r.image, "ao");
      size_t off = 0;
      for (int i = 0; i < 48 * 36; i++) off += ao[i] != 1.0f;
      printf("plane %zu method %d on the device: %zu pixels not 1\n", q, m, off);
      assert_int_equal(off, 0);
      obs_result_free(&r);
    }
}

static void both_backends(const char *camera_objects, int w, int h, const char *params) {
  obs_result r;
  render_backend(scene_doc(camera_objects, w, h, "cpu", params), &r);
  obs_result_free(&r);
  render_backend(scene_doc(camera_objects, w, h, "vulkan", params), &r);
  obs_result_free(&r);
}

static void test_extremes(void **state) {
  (void)state;
  vktest_need_vk();
  const char *params[] = {"{\"radius\":1e-9}", "{\"radius\":1e30}",
                          "{\"method\":\"depth_unsharp\",\"radius\":1e30,\"strength\":1e6}",
                          "{\"radius\":0.3,\"variance_weight\":1e6}"};
  for (size_t i = 0; i < sizeof params / sizeof params[0]; i++) {
    both_backends(ROOM, 20, 14, params[i]);
    both_backends(ROOM, 1, 1, params[i]);
  }
  both_backends(
      "\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
      "\"fov_y\":50},\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e-4,"
      "-1e-4,1e-3],[1e-4,-1e-4,1e-3],[1e-4,1e-4,1e-3],[-1e-4,1e-4,1e-3]]}},{\"shape\":{"
      "\"type\":\"quad\",\"vertices\":[[-1e4,-1e4,1e3],[1e4,-1e4,1e3],[1e4,1e4,1e3],"
      "[-1e4,1e4,1e3]]}}]",
      16, 12, "{\"radius\":0.01}");
  both_backends(
      "\"camera\":{\"type\":\"perspective\",\"position\":[0,5,0],\"look_at\":[0,0,0],"
      "\"up\":[0,0,-1],\"fov_y\":60},\"objects\":[{\"shape\":{\"type\":\"quad\","
      "\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}}]",
      24, 24, "{\"radius\":0.3}");
  both_backends(ROOM, 4096, 16, "{\"radius\":0.5}");
  obs_result r;
  render_backend(scene_doc("\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":"
                           "[0,0,1],\"fov_y\":50},\"objects\":[]",
                           9, 7, "vulkan", "{}"),
                 &r);
  for (int i = 0; i < 63; i++) assert_true(obs_image_channel(&r.image, "ao")[i] == 1.0f);
  obs_result_free(&r);
}

/* Bad calls fail with a message and change nothing. */
static void test_bad_calls(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_ssao_variance_params p = {.method = 0, .radius = 1.0};
  obs_vk_gbuffer dev;
  memset(&dev, 0, sizeof dev);
  obs_svar_projection proj = {0, 0.5f};
  float out[1] = {-1.0f};
  assert_int_equal(obs_svar_vk_apply(vk, &dev, &proj, &p, out, NULL, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "ssao_variance"));
  assert_true(out[0] == -1.0f);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross_room, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_room_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_displaced_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_pipeline, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_planes_open, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_extremes, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_bad_calls, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
