/* ssao on Vulkan against its CPU twin: identical G-buffers through both, full renders through both
 * backends, the analytic cases and extremes on the device, all under the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vktest.h"
#include "screen_rule_cases.h"
#include "vk.h"
#include "ssao.h"

/* ---- scenes ---- */

static const char *scene_doc(const char *camera_objects, int w, int h, const char *backend,
                             const char *params) {
  static char buf[8192];
  snprintf(buf, sizeof buf,
           "{%s,\"image\":{\"width\":%d,\"height\":%d},\"technique\":{\"name\":\"ssao\","
           "\"backend\":\"%s\",\"params\":%s}}",
           camera_objects, w, h, backend, params);
  return buf;
}

/* A Cornell-like room (open at the front) with two rotated blocks. */
static const char *ROOM =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0,1,3.4],\"look_at\":[0,1,0],"
    "\"fov_y\":40},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,2,-1],[-1,2,1],[1,2,1],[1,2,-1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,0,1],[-1,2,1],[-1,2,-1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[1,0,-1],[1,2,-1],[1,2,1],[1,0,1]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]},"
    "\"transform\":{\"rotate\":[0,20,0],\"translate\":[-0.35,0,-0.3]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,0.6,0.3]},"
    "\"transform\":{\"rotate\":[0,-15,0],\"translate\":[0.4,0,0.35]}}]";

static const char *SPHERE =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,2.6],\"look_at\":[0,0,0],"
    "\"fov_y\":45},\"objects\":[{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":7}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,-1.2,-3],[-3,-1.2,3],[3,-1.2,3],"
    "[3,-1.2,-3]]}}]";

/* The room seen by an orthographic camera from above and to the side. */
static const char *ROOM_ORTHO =
    "\"camera\":{\"type\":\"orthographic\",\"position\":[2,3,3],\"look_at\":[0,0.6,0],"
    "\"height\":3},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]},"
    "\"transform\":{\"rotate\":[0,20,0],\"translate\":[-0.35,0,-0.3]}}]";

static void load(const char *json, obs_scene *sc) { obs_test_load(json, "ssao_vk.json", sc); }

/* ---- (1) the same G-buffer through both implementations ---- */

typedef struct diff_stats {
  double rmse, max;
  size_t over, exact, n;
} diff_stats;

static diff_stats compare(const float *a, const float *b, size_t n) {
  diff_stats d = {0, 0, 0, 0, n};
  double ss = 0;
  for (size_t i = 0; i < n; i++) {
    assert_true(isfinite(a[i]) && isfinite(b[i]));
    assert_true(a[i] >= 0.0f && a[i] <= 1.0f && b[i] >= 0.0f && b[i] <= 1.0f);
    double e = fabs((double)a[i] - (double)b[i]);
    ss += e * e;
    if (e > d.max) d.max = e;
    d.over += e > 1e-2;
    d.exact += a[i] == b[i];
  }
  d.rmse = sqrt(ss / (double)n);
  return d;
}

/* Both sides compute the same float operations in the same order on the same inputs, so they
 * should agree bit for bit. What may still differ: the device's division (zp - zs) / zs, which
 * only feeds the continuous range term (a difference of ulps, never a flipped comparison), and
 * flushing of denormals, which these depths never produce. So no pixel may differ by more than
 * 1e-2 at all; the bound allows 0.1 % of the pixels as a margin over that expectation, and the
 * count is printed so any such pixel is seen. */
static void assert_agree(const char *what, const diff_stats *d) {
  printf("%-62s rmse %.3g max %.3g >1e-2: %zu exact: %zu/%zu\n", what, d->rmse, d->max, d->over,
         d->exact, d->n);
  assert_true(d->rmse <= 1e-3);
  assert_true((double)d->over <= 0.001 * (double)d->n);
}

static const char *const param_sets[] = {
    "{}",
    "{\"samples\":8}",
    "{\"samples\":24}",
    "{\"normal_oriented\":true}",
    "{\"normal_oriented\":true,\"samples\":24,\"radius\":0.05}",
    "{\"blur\":false}",
    "{\"blur\":false,\"normal_oriented\":true,\"samples\":8}",
    "{\"radius\":0.002,\"blur_depth_threshold\":0.01}",
    "{\"radius\":0.1,\"samples\":8,\"seed\":7,\"blur_depth_threshold\":0.5}",
};

static void cross_backend(const char *scene, const char *label, int w, int h) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  load(scene_doc(scene, w, h, "cpu", "{}"), &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  obs_ssao_projection proj = obs_ssao_projection_of(&g);
  size_t n = (size_t)w * (size_t)h;
  float *ca = malloc(n * sizeof(float)), *cr = malloc(n * sizeof(float));
  float *va = malloc(n * sizeof(float)), *vr = malloc(n * sizeof(float));
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    obs_scene ps;
    load(scene_doc(scene, w, h, "cpu", param_sets[k]), &ps);
    obs_ssao_params p;
    assert_int_equal(obs_params_bind(obs_technique_find("ssao"), ps.params, &p, NULL), 0);
    obs_scene_free(&ps);
    double cms[OBS_SSAO_CPU_STAGES], vms[OBS_SSAO_VK_STAGES];
    vktest_check_rc(obs_ssao_cpu_apply_ex(&g, &p, 2, ca, cr, cms, &err), &err);
    vktest_check_rc(obs_ssao_vk_apply_ex(vk, &dev, &proj, &p, va, vr, vms, &err), &err);
    char what[160];
    snprintf(what, sizeof what, "%s %s ao_raw", label, param_sets[k]);
    diff_stats d = compare(cr, vr, n);
    assert_agree(what, &d);
    snprintf(what, sizeof what, "%s %s ao", label, param_sets[k]);
    d = compare(ca, va, n);
    assert_agree(what, &d);
    /* The short form (no projection) must agree where it applies. */
    if (!p.normal_oriented) {
      vktest_check_rc(obs_ssao_vk_apply(vk, &dev, &p, vr, NULL, &err), &err);
      assert_memory_equal(va, vr, n * sizeof(float));
    } else {
      assert_int_equal(obs_ssao_vk_apply(vk, &dev, &p, vr, NULL, &err), OBS_EINVAL);
      obs_err_clear(&err);
    }
  }
  free(ca);
  free(cr);
  free(va);
  free(vr);
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
  cross_backend(ROOM_ORTHO, "room ortho 64x48", 64, 48);
}

static void test_cross_displaced_sphere(void **state) {
  (void)state;
  cross_backend(SPHERE, "displaced_sphere(7) 80x80", 80, 80);
}

/* ---- (2) full pipeline: rasterised vs ray-cast G-buffer ---- */

static void render_backend(const char *json, obs_result *r) {
  obs_scene sc;
  load(json, &sc);
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  int rc = obs_render(&sc, &o, r, &err);
  vktest_check_rc(rc, &err);
  obs_scene_free(&sc);
  obs_err_free(&err);
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
    if (al[i] == 0.0f) assert_true(ao[i] == 1.0f && raw[i] == 1.0f);
  }
}

static void pipeline(const char *scene, const char *label, int w, int h, const char *params) {
  vktest_need_vk();
  obs_result c, v;
  render_backend(scene_doc(scene, w, h, "cpu", params), &c);
  render_backend(scene_doc(scene, w, h, "vulkan", params), &v);
  assert_int_equal(v.backend, OBS_BACKEND_VULKAN);
  static const char *const vst[] = {"prepare", "device", "gbuffer", "geometry",
                                    "ao",      "blur",   "readback", "other"};
  assert_int_equal(v.nstages, 8);
  for (int i = 0; i < 8; i++) assert_string_equal(v.stage_names[i], vst[i]);
  size_t n = (size_t)w * (size_t)h, over = 0, alpha_diff = 0;
  const float *ca = obs_image_channel(&c.image, "ao"), *va = obs_image_channel(&v.image, "ao");
  const float *cal = obs_image_channel(&c.image, "alpha");
  const float *val = obs_image_channel(&v.image, "alpha");
  double ss = 0;
  for (size_t i = 0; i < n; i++) {
    double e = fabs((double)ca[i] - va[i]);
    ss += e * e;
    over += e > 0.05;
    alpha_diff += cal[i] != val[i];
  }
  double frac = (double)over / (double)n;
  printf("%-40s %s: %.2f %% of pixels differ by > 0.05 (rmse %.4f, coverage differs on %zu)\n",
         label, params, 100.0 * frac, sqrt(ss / (double)n), alpha_diff);
  /* Rasterised and ray-cast G-buffers differ on silhouettes and where facets meet, and SSAO
   * spreads each such pixel over its sample footprint and the blur; elsewhere they agree
   * (measured: at most 0.04 % of pixels beyond 0.05; 1 % is asserted, well inside the 5 % that
   * separates a G-buffer difference from a broken pass). */
  assert_true(frac < 0.01);
  obs_result_free(&c);
  obs_result_free(&v);
}

static void test_pipeline(void **state) {
  (void)state;
  pipeline(ROOM, "room 96x72", 96, 72, "{}");
  pipeline(ROOM, "room 96x72", 96, 72, "{\"normal_oriented\":true,\"samples\":24}");
  pipeline(SPHERE, "displaced_sphere(7) 80x80", 80, 80, "{}");
  pipeline(ROOM_ORTHO, "room ortho 64x48", 64, 48, "{\"samples\":8}");
}

/* Far from the world origin and at extreme scales each backend's render equals its render at the
 * origin and scale 1 (ssao's radius is a fraction of the image: nothing to scale). Measured:
 * 1.8e-7 at most on either backend; asserted: 1e-5, on every pixel. */
static void test_moved_and_scaled(void **state) {
  (void)state;
  vktest_need_vk();
  const double cases[][2] = {{1, 1e6}, {1, 1e7}, {1, 1e9}, {1e-9, 0}, {1e9, 0}, {1e9, 1e9}};
  const char *backends[] = {"vulkan", "cpu"};
  char body[4096];
  for (int b = 0; b < 2; b++) {
    obs_result ref;
    vktest_moved_scene(1, 0, 20, 30, body, sizeof body);
    render_backend(scene_doc(body, 48, 48, backends[b], "{}"), &ref);
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
      obs_result r;
      vktest_moved_scene(cases[c][0], cases[c][1], 20, 30, body, sizeof body);
      render_backend(scene_doc(body, 48, 48, backends[b], "{}"), &r);
      double mx;
      size_t over;
      vktest_ao_diff(&ref, &r, "ao", 1e-5, &mx, &over);
      printf("ssao %s scale %g translate %g: max |ao - ao(origin, scale 1)| = %.2e\n",
             backends[b], cases[c][0], cases[c][1], mx);
      assert_int_equal(over, 0);
      obs_result_free(&r);
    }
    obs_result_free(&ref);
  }
}

/* ---- (3) extremes, on both backends ---- */

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
  const char *params[] = {"{\"radius\":1e-6}",
                          "{\"radius\":1e6,\"samples\":24}",
                          "{\"radius\":1e6,\"normal_oriented\":true,\"samples\":8}",
                          "{\"samples\":8,\"blur_depth_threshold\":0}",
                          "{\"samples\":24,\"blur_depth_threshold\":1e6,\"normal_oriented\":true}"};
  for (size_t i = 0; i < sizeof params / sizeof params[0]; i++)
    both_backends(ROOM, 20, 14, params[i]);
  /* near/far ratio 1e6 */
  both_backends("\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
                "\"fov_y\":50},\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e-4,"
                "-1e-4,1e-3],[1e-4,-1e-4,1e-3],[1e-4,1e-4,1e-3],[-1e-4,1e-4,1e-3]]}},{\"shape\":{"
                "\"type\":\"quad\",\"vertices\":[[-1e4,-1e4,1e3],[1e4,-1e4,1e3],[1e4,1e4,1e3],"
                "[-1e4,1e4,1e3]]}}]",
                16, 12, "{\"normal_oriented\":true}");
  /* camera inside geometry */
  both_backends("\"camera\":{\"type\":\"perspective\",\"position\":[0.1,0.2,0.3],\"look_at\":[1,0,"
                "0.5],\"fov_y\":120},\"objects\":[{\"shape\":{\"type\":\"box\",\"min\":[-1,-1,-1],"
                "\"max\":[1,1,1]}}]",
                16, 16, "{\"samples\":24}");
  /* empty frame: all 1 */
  obs_result r;
  render_backend(scene_doc("\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":"
                           "[0,0,1],\"fov_y\":50},\"objects\":[]",
                           9, 7, "vulkan", "{}"),
                 &r);
  for (int i = 0; i < 63; i++) assert_true(obs_image_channel(&r.image, "ao")[i] == 1.0f);
  obs_result_free(&r);
  /* 1x1 and 4096x16 */
  both_backends(ROOM, 1, 1, "{}");
  both_backends(ROOM, 1, 1, "{\"samples\":24,\"normal_oriented\":true}");
  both_backends(ROOM, 4096, 16, "{\"samples\":8}");
  both_backends(SPHERE, 4096, 16, "{\"samples\":24,\"normal_oriented\":true}");
}

/* ---- (4) the analytic cases on the device ---- */

static const char *WALL =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":50},"
    "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,-100,5],[100,-100,5],"
    "[100,100,5],[-100,100,5]]}}]";

static void test_wall(void **state) {
  (void)state;
  vktest_need_vk();
  obs_result r;
  render_backend(scene_doc(WALL, 40, 30, "vulkan", "{}"), &r);
  const float *raw = obs_image_channel(&r.image, "ao_raw"), *ao = obs_image_channel(&r.image, "ao");
  for (int i = 0; i < 1200; i++) {
    assert_true(fabsf(raw[i] - 0.75f) < 1e-5f);
    assert_true(fabsf(ao[i] - 0.75f) < 1e-5f);
  }
  obs_result_free(&r);
  render_backend(scene_doc(WALL, 40, 30, "vulkan", "{\"normal_oriented\":true}"), &r);
  raw = obs_image_channel(&r.image, "ao_raw");
  for (int i = 0; i < 1200; i++) assert_true(raw[i] == 1.0f);
  obs_result_free(&r);
}

/* Bad calls fail with a message and leave the layer silent. */
static void test_bad_calls(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_ssao_params p = {.samples = 12, .radius = 0.01f, .blur = 1, .blur_depth_threshold = 0.05f};
  obs_vk_gbuffer dev;
  memset(&dev, 0, sizeof dev);
  float out[1];
  assert_int_equal(obs_ssao_vk_apply(vk, &dev, &p, out, NULL, &err), OBS_EINVAL);
  obs_err_clear(&err);
  obs_camera_rig rig;
  memset(&rig, 0, sizeof rig);
  rig.half_w = rig.half_h = 1;
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_alloc(&g, 1, 1, &rig, &err), &err);
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  assert_int_equal(obs_ssao_vk_apply(vk, &dev, &p, out, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "samples"));
  obs_err_clear(&err);
  p.samples = 8;
  double ms[OBS_SSAO_VK_STAGES];
  vktest_check_rc(obs_ssao_vk_apply(vk, &dev, &p, out, ms, &err), &err);
  assert_true(out[0] == 1.0f);
  assert_true(ms[0] >= 0 && ms[1] >= 0 && ms[2] >= 0);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_err_free(&err);
}

/* The screen-space rule on Vulkan: the same cases and words as on the CPU. */
static void test_screen_rule(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_screen_rule_ssao_cases(OBS_BACKEND_VULKAN), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross_room, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_room_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_displaced_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_pipeline, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_extremes, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_wall, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_bad_calls, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_moved_and_scaled, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_screen_rule, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
