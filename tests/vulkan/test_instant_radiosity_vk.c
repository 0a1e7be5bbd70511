/* instant_radiosity on Vulkan against its CPU twin: one G-buffer and one set of VPLs through both
 * gather and filter implementations (bit for bit), and full renders through both backends, under
 * the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vktest.h"
#include "vk.h"
#include "../../renderer/techniques/instant_radiosity/instant_radiosity.h"

/* The Cornell box (w x h) with instant_radiosity's `params` on `backend`, seen by `camera` (JSON,
 * or NULL for the scene's own). */
static void cornell_load(int w, int h, const char *backend, const char *params, const char *camera,
                         obs_scene *sc) {
  char tech[512], size[64];
  snprintf(tech, sizeof tech, "{\"name\":\"instant_radiosity\",\"backend\":\"%s\",\"params\":%s}",
           backend, params);
  snprintf(size, sizeof size, "{\"width\":%d,\"height\":%d,\"spp\":1}", w, h);
  const obs_override ov[] = {{"/technique", tech}, {"/image", size}, {"/camera", camera}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(
      obs_scene_load_file(sc, obs_test_src("scenes/cornell_box.json"), ov, camera ? 3 : 2, &err),
      &err);
  obs_err_free(&err);
}

/* The Cornell box seen from above by an orthographic camera, so both projections are checked. */
static const char *const ORTHO_CAMERA =
    "{\"type\":\"orthographic\",\"position\":[600,700,-300],\"look_at\":[278,200,280],"
    "\"height\":700}";

/* Few VPLs: the twins' agreement does not depend on their number. 10 VPLs of 2 bounces make 5
 * paths, so 5 classes; a large clamp_distance clamps most receivers; approximate visibility
 * marches the same pyramid and reads the same cube (the VPLs beyond the view need it). */
static const char *const param_sets[] = {
    "{\"vpls\":64}",
    "{\"vpls\":64,\"filter\":false}",
    "{\"vpls\":10,\"max_bounces\":2}",
    "{\"vpls\":48,\"max_bounces\":1,\"clamp_distance\":200,\"filter_depth\":0.2}",
    "{\"vpls\":64,\"max_bounces\":4,\"filter_normal\":-1,\"seed\":9,\"frame\":5}",
    "{\"vpls\":64,\"visibility\":\"approximate\"}",
    "{\"vpls\":32,\"visibility\":\"approximate\",\"shadow_bias\":0.05,\"shadow_thickness\":1e6}",
};

static size_t exact_count(const float *a, const float *b, size_t n, double *rmse) {
  size_t same = 0;
  double ss = 0;
  for (size_t i = 0; i < n; i++) {
    assert_true(isfinite(a[i]) && isfinite(b[i]));
    double e = (double)a[i] - (double)b[i];
    ss += e * e;
    same += a[i] == b[i];
  }
  *rmse = sqrt(ss / (double)n);
  return same;
}

static void cross_backend(const char *camera, const char *label) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  const int w = 40, h = 32;
  obs_scene sc;
  cornell_load(w, h, "cpu", "{}", camera, &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_cpu(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  size_t n = (size_t)w * (size_t)h;
  float *cr = malloc(4 * n * sizeof(float)), *co = malloc(4 * n * sizeof(float));
  float *vr = malloc(4 * n * sizeof(float)), *vo = malloc(4 * n * sizeof(float));
  const obs_technique *t = obs_technique_find("instant_radiosity");
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    obs_instant_radiosity_params p;
    obs_scene ps;
    cornell_load(w, h, "cpu", param_sets[k], camera, &ps);
    assert_int_equal(obs_params_bind(t, ps.params, &p, NULL), 0);
    obs_irad_light l;
    vktest_check_rc(obs_irad_light_make(&ps, &p, 2, NULL, &l, NULL, &err), &err);
    if (p.visibility == OBS_IRAD_VIS_APPROX)
      vktest_check_rc(obs_irad_approx_make(&g, &l, 2, NULL, NULL, &err), &err);
    memset(co, 0, 4 * n * sizeof(float));
    memset(vo, 0, 4 * n * sizeof(float));
    vktest_check_rc(obs_irad_cpu_apply(&g, &l, &p, 2, cr, co, NULL, &err), &err);
    vktest_check_rc(obs_irad_vk_apply(vk, &dev, &g, &l, &p, vr, vo, NULL, &err), &err);
    double rr, ro;
    size_t sr = exact_count(cr, vr, 4 * n, &rr), so = exact_count(co, vo, 4 * n, &ro);
    size_t lit = 0;
    for (size_t i = 0; i < n; i++) lit += cr[4 * i] > 0.0f;
    printf("%-7s %-70s %d VPLs in %d classes: raw %zu/%zu exact (rmse %.2g), filtered %zu/%zu "
           "exact (rmse %.2g), %zu pixels lit\n",
           label, param_sets[k], l.vpls.n, l.vpls.classes, sr, 4 * n, rr, so, 4 * n, ro, lit);
    /* The same float operations in the same order on the same inputs: the same bits. */
    assert_int_equal(sr, 4 * n);
    assert_int_equal(so, 4 * n);
    assert_true(lit > n / 8);
    obs_irad_light_free(&l);
    obs_scene_free(&ps);
  }
  free(cr);
  free(co);
  free(vr);
  free(vo);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_cross_cornell(void **state) {
  (void)state;
  cross_backend(NULL, "cornell");
}

static void test_cross_cornell_ortho(void **state) {
  (void)state;
  cross_backend(ORTHO_CAMERA, "ortho");
}

static void pipeline_load(const char *backend, obs_scene *sc) {
  cornell_load(32, 32, backend, "{\"vpls\":64}", NULL, sc);
}

/* Full renders on both backends: the same VPLs and emission, G-buffers that may differ only on
 * silhouettes (rasterised vs CPU), so the radiance agrees within an RMSE of 1e-3 of its mean and
 * each output is finite and in range. */
static void test_pipeline(void **state) {
  (void)state;
  obs_result r[2];
  double mean, rmse = vktest_pipeline_rmse(pipeline_load, r, &mean);
  size_t n = 32 * 32;
  for (size_t i = 0; i < n; i++) assert_true(obs_image_channel(&r[1].image, "ao")[i] == 1.0f);
  assert_true(rmse <= 1e-3 * mean);
  obs_result_free(&r[0]);
  obs_result_free(&r[1]);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross_cornell, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_cornell_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_pipeline, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
