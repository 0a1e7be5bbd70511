/* ss_obscurance on Vulkan against its CPU twin: identical G-buffers through both give the same
 * bits, full renders through both backends agree, and the open plane, extremes and bad calls on
 * the device, all under the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vk.h"
#include "vktest.h"
#include "../../renderer/techniques/ss_obscurance/ss_obscurance.h"

static const char *doc(const char *camera_objects, int w, int h, const char *backend,
                       const char *params) {
  static char buf[8192];
  snprintf(buf, sizeof buf,
           "{%s,\"image\":{\"width\":%d,\"height\":%d},\"technique\":{\"name\":\"ss_obscurance\","
           "\"backend\":\"%s\",\"params\":%s}}",
           camera_objects, w, h, backend, params);
  return buf;
}

/* The bundled scenes, a case each: file, camera override (NULL: the file's) and size. */
typedef struct scase {
  const char *file, *camera, *label;
  int w, h;
  double radius; /* R of the cross-backend cases (0.2 of the scene's size at most) */
} scase;

static const scase CORNELL = {"scenes/cornell_box.json", NULL, "cornell_box 96x72", 96, 72, 150};
static const scase CORNELL_ORTHO = {"scenes/cornell_box.json",
                                    "{\"type\":\"orthographic\",\"position\":[700,650,-500],"
                                    "\"look_at\":[278,200,280],\"height\":900}",
                                    "cornell_box ortho 64x48", 64, 48, 150};
static const scase SPHERE = {"scenes/displaced_sphere.json", NULL, "displaced_sphere 80x80", 80, 80,
                             0.5};

/* Loads a case with ss_obscurance on `backend` with `params`. */
static void load_case(const scase *c, const char *backend, const char *params, obs_scene *sc) {
  char w[16], h[16], tech[512];
  snprintf(w, sizeof w, "%d", c->w);
  snprintf(h, sizeof h, "%d", c->h);
  snprintf(tech, sizeof tech, "{\"name\":\"ss_obscurance\",\"backend\":\"%s\",\"params\":%s}",
           backend, params);
  obs_override ov[4] = {{"/image/width", w}, {"/image/height", h}, {"/technique", tech},
                        {"/camera", c->camera}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_scene_load_file(sc, obs_test_src(c->file), ov, c->camera ? 4 : 3, &err),
                  &err);
  obs_err_free(&err);
}

/* A room for the extremes: a floor, a wall and a block. */
static const char *ROOM =
    "\"camera\":{\"type\":\"perspective\",\"position\":[0,1,3.4],\"look_at\":[0,1,0],"
    "\"fov_y\":40},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[1,0,-1],[1,0,1],[-1,0,1]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,2,-1],[1,2,-1],[1,0,-1]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.3,0,-0.3],\"max\":[0.3,1.2,0.3]}}]";

static void load(const char *json, obs_scene *sc) { obs_test_load(json, "sso_vk.json", sc); }

/* Each with the case's R scaled by the factor in front. */
static const struct {
  double scale;
  const char *rest;
} param_sets[] = {
    {1, ""},
    {1, ",\"interleave\":false,\"samples\":32"},
    {1, ",\"membership\":\"binary\",\"samples\":4"},
    {0.6, ",\"membership\":\"exp\",\"tau\":5,\"samples\":64,\"seed\":7"},
    {1, ",\"sampling\":\"uniform\",\"interleave\":false"},
    {8, ""},
    {0.002, ""},
};

/* Both sides compute the same float operations in the same order on the same inputs (the
 * divisions of the projection included, which lavapipe rounds correctly), so every pixel has the
 * same bits, before and after the average. */
static void cross_backend(const scase *c) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  const int w = c->w, h = c->h;
  load_case(c, "cpu", "{}", &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  obs_sso_projection proj = {g.ortho, g.half_w, g.half_h};
  size_t n = (size_t)w * (size_t)h;
  float *ca = malloc(n * sizeof(float)), *cr = malloc(n * sizeof(float));
  float *va = malloc(n * sizeof(float)), *vr = malloc(n * sizeof(float));
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    char params[256];
    snprintf(params, sizeof params, "{\"radius\":%.9g%s}", c->radius * param_sets[k].scale,
             param_sets[k].rest);
    obs_scene ps;
    load_case(c, "cpu", params, &ps);
    obs_sso_params p;
    assert_int_equal(obs_params_bind(obs_technique_find("ss_obscurance"), ps.params, &p, NULL), 0);
    obs_scene_free(&ps);
    double cms[OBS_SSO_CPU_STAGES], vms[OBS_SSO_VK_STAGES];
    vktest_check_rc(obs_sso_cpu_apply(&g, &p, 2, ca, cr, cms, &err), &err);
    vktest_check_rc(obs_sso_vk_apply(vk, &dev, &proj, &p, va, vr, vms, &err), &err);
    size_t same_raw = 0, same = 0, open = 0;
    double mean = 0;
    for (size_t i = 0; i < n; i++) {
      same_raw += memcmp(&cr[i], &vr[i], sizeof(float)) == 0;
      same += memcmp(&ca[i], &va[i], sizeof(float)) == 0;
      open += ca[i] == 1.0f;
      mean += ca[i];
    }
    printf("%-24s %-72s same bits: ao_raw %zu/%zu, ao %zu/%zu (mean %.4f, %zu open)\n", c->label,
           params, same_raw, n, same, n, mean / (double)n, open);
    assert_int_equal(same_raw, n);
    assert_int_equal(same, n);
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

static void test_cross_cornell(void **state) {
  (void)state;
  cross_backend(&CORNELL);
}

static void test_cross_cornell_ortho(void **state) {
  (void)state;
  cross_backend(&CORNELL_ORTHO);
}

static void test_cross_displaced_sphere(void **state) {
  (void)state;
  cross_backend(&SPHERE);
}

/* Renders `sc` (freed) with 2 threads and checks what every output must satisfy. */
static void render_scene(obs_scene *sc, obs_result *r) {
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  vktest_check_rc(obs_render(sc, &o, r, &err), &err);
  obs_scene_free(sc);
  obs_err_free(&err);
  obs_test_assert_finite(&r->image);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  const float *ao = obs_image_channel(&r->image, "ao"), *raw = obs_image_channel(&r->image, "ao_raw");
  const float *al = obs_image_channel(&r->image, "alpha");
  for (size_t i = 0; i < n; i++) {
    assert_true(ao[i] >= 0.0f && ao[i] <= 1.0f && raw[i] >= 0.0f && raw[i] <= 1.0f);
    if (al[i] == 0.0f) assert_true(ao[i] == 1.0f && raw[i] == 1.0f);
  }
}

static void render_backend(const char *json, obs_result *r) {
  obs_scene sc;
  load(json, &sc);
  render_scene(&sc, r);
}

/* Full renders: the rasterised device G-buffer against the CPU's. They differ on silhouettes and
 * where facets meet, and the obscurance spreads such a pixel over its samples and the average;
 * elsewhere they agree. Asserted: under 1 % of the pixels beyond 0.05. */
static void pipeline(const scase *sc, const char *params) {
  vktest_need_vk();
  obs_result c, v;
  obs_scene s;
  load_case(sc, "cpu", params, &s);
  render_scene(&s, &c);
  load_case(sc, "vulkan", params, &s);
  render_scene(&s, &v);
  const int w = sc->w, h = sc->h;
  const char *label = sc->label;
  assert_int_equal(v.backend, OBS_BACKEND_VULKAN);
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
  assert_true((double)over < 0.01 * (double)n);
  obs_result_free(&c);
  obs_result_free(&v);
}

static void test_pipeline(void **state) {
  (void)state;
  pipeline(&CORNELL, "{\"radius\":150}");
  pipeline(&SPHERE, "{\"radius\":0.3,\"membership\":\"exp\"}");
  pipeline(&CORNELL_ORTHO, "{\"radius\":150,\"interleave\":false}");
}

/* On the device as on the CPU: an open plane (here tilted) reads exactly 1, an empty frame 1,
 * and the range's ends render finite and in range on both backends. */
static void test_open_plane_and_extremes(void **state) {
  (void)state;
  vktest_need_vk();
  const char *floor_scene =
      "\"camera\":{\"type\":\"perspective\",\"position\":[0.3,2,-4],\"look_at\":[0,0,0],"
      "\"fov_y\":50},\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1000,0,-1000],"
      "[-1000,0,1000],[1000,0,1000],[1000,0,-1000]]}}]";
  obs_result r;
  render_backend(doc(floor_scene, 40, 30, "vulkan", "{\"samples\":64}"), &r);
  for (int i = 0; i < 1200; i++) assert_true(obs_image_channel(&r.image, "ao")[i] == 1.0f);
  obs_result_free(&r);
  render_backend(doc("\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":"
                     "[0,0,1],\"fov_y\":50},\"objects\":[]",
                     9, 7, "vulkan", "{}"),
                 &r);
  for (int i = 0; i < 63; i++) assert_true(obs_image_channel(&r.image, "ao")[i] == 1.0f);
  obs_result_free(&r);
  const char *params[] = {"{\"radius\":1e-6,\"samples\":4}", "{\"radius\":1e30,\"samples\":64}",
                          "{\"membership\":\"exp\",\"tau\":1e-300}",
                          "{\"membership\":\"exp\",\"tau\":1e4,\"interleave\":false}"};
  const char *backends[] = {"cpu", "vulkan"};
  for (size_t i = 0; i < sizeof params / sizeof params[0]; i++)
    for (int b = 0; b < 2; b++) {
      render_backend(doc(ROOM, 20, 14, backends[b], params[i]), &r);
      obs_result_free(&r);
      render_backend(doc(ROOM, 1, 1, backends[b], params[i]), &r);
      obs_result_free(&r);
    }
  /* near/far 1e6 */
  render_backend(doc("\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":"
                     "[0,0,1],\"fov_y\":50},\"objects\":[{\"shape\":{\"type\":\"quad\","
                     "\"vertices\":[[-1e-4,-1e-4,1e-3],[1e-4,-1e-4,1e-3],[1e-4,1e-4,1e-3],"
                     "[-1e-4,1e-4,1e-3]]}},{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e4,"
                     "-1e4,1e3],[1e4,-1e4,1e3],[1e4,1e4,1e3],[-1e4,1e4,1e3]]}}]",
                     16, 12, "vulkan", "{\"radius\":10}"),
                 &r);
  obs_result_free(&r);
}

/* Bad calls fail with a message naming the problem and leave the layer silent. */
static void test_bad_calls(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_sso_params p = {.samples = 16, .radius = 1, .membership = 1, .tau = 3, .interleave = 1};
  obs_vk_gbuffer dev;
  memset(&dev, 0, sizeof dev);
  obs_sso_projection proj = {0, 1, 1};
  float out[1];
  assert_int_equal(obs_sso_vk_apply(vk, &dev, &proj, &p, out, NULL, NULL, &err), OBS_EINVAL);
  obs_err_clear(&err);
  obs_camera_rig rig;
  memset(&rig, 0, sizeof rig);
  rig.half_w = rig.half_h = 1;
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_alloc(&g, 1, 1, &rig, &err), &err);
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  p.samples = 65;
  assert_int_equal(obs_sso_vk_apply(vk, &dev, &proj, &p, out, NULL, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "samples"));
  obs_err_clear(&err);
  p.samples = 4;
  assert_int_equal(obs_sso_vk_apply(vk, &dev, NULL, &p, out, NULL, NULL, &err), OBS_EINVAL);
  obs_err_clear(&err);
  double ms[OBS_SSO_VK_STAGES];
  vktest_check_rc(obs_sso_vk_apply(vk, &dev, &proj, &p, out, NULL, ms, &err), &err);
  assert_true(out[0] == 1.0f);
  assert_true(ms[0] >= 0 && ms[1] >= 0 && ms[2] >= 0);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross_cornell, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_cornell_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_displaced_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_pipeline, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_open_plane_and_extremes, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_bad_calls, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
