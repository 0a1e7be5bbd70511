/* ss_radiosity on Vulkan against its CPU twin: one G-buffer and one direct buffer through both
 * gather and blur implementations (bit for bit), and full renders through both backends, under
 * the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vktest.h"
#include "vk.h"
#include "../../renderer/techniques/ss_radiosity/ss_radiosity.h"

/* The Cornell box (w x h) with ss_radiosity's `params` on `backend`. */
/* `probes`: the scene's probes member (JSON), or NULL for none. */
static void cornell_load_probes(int w, int h, const char *backend, const char *params,
                                const char *probes, obs_scene *sc) {
  char tech[512], size[64];
  snprintf(tech, sizeof tech, "{\"name\":\"ss_radiosity\",\"backend\":\"%s\",\"params\":%s}",
           backend, params);
  snprintf(size, sizeof size, "{\"width\":%d,\"height\":%d,\"spp\":1}", w, h);
  const obs_override ov[] = {{"/technique", tech}, {"/image", size}, {"/probes", probes}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(
      obs_scene_load_file(sc, obs_test_src("scenes/cornell_box.json"), ov, probes ? 3 : 2, &err),
      &err);
  obs_err_free(&err);
}

static void cornell_load(int w, int h, const char *backend, const char *params, obs_scene *sc) {
  cornell_load_probes(w, h, backend, params, NULL, sc);
}

/* Probes inside the two blocks and one in the room's air (which darkens what faces it). */
static const char *const PROBES =
    "[{\"position\":[185,80,170],\"radius\":60},{\"position\":[370,150,350],\"radius\":70},"
    "{\"position\":[300,400,250],\"radius\":40}]";

/* The Cornell box seen from above by an orthographic camera, so both projections are checked. */
static const char *const ORTHO_CAMERA =
    "{\"type\":\"orthographic\",\"position\":[600,700,-300],\"look_at\":[278,200,280],"
    "\"height\":700}";

static const char *const param_sets[] = {
    "{\"kernel_size\":100,\"bias\":100}",
    "{\"kernel_size\":60,\"bias\":200,\"samples\":16,\"directivity\":0}",
    "{\"kernel_size\":150,\"bias\":50,\"samples\":1,\"directivity\":1}",
    "{\"kernel_size\":100,\"bias\":100,\"exclude_self\":true,\"blur\":false}",
    "{\"kernel_size\":300,\"bias\":100,\"attenuation\":0.002,\"strength\":3,\"seed\":9}",
    "{\"kernel_size\":100,\"bias\":100,\"samples\":32,\"blur_depth_threshold\":0.5}",
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

static void cross_backend(int ortho, const char *label) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  const int w = 64, h = 48;
  obs_scene sc;
  cornell_load(w, h, "cpu", "{}", &sc);
  if (ortho) {
    obs_scene_free(&sc);
    char tech[256], size[64];
    snprintf(tech, sizeof tech, "{\"name\":\"ss_radiosity\",\"backend\":\"cpu\"}");
    snprintf(size, sizeof size, "{\"width\":%d,\"height\":%d,\"spp\":1}", w, h);
    const obs_override ov[] = {{"/technique", tech}, {"/image", size}, {"/camera", ORTHO_CAMERA}};
    vktest_check_rc(obs_scene_load_file(&sc, obs_test_src("scenes/cornell_box.json"), ov, 3, &err),
                    &err);
  }
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_cpu(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  size_t n = (size_t)w * (size_t)h;
  float *direct = malloc(4 * n * sizeof(float));
  float *cr = malloc(4 * n * sizeof(float)), *co = malloc(4 * n * sizeof(float));
  float *vr = malloc(4 * n * sizeof(float)), *vo = malloc(4 * n * sizeof(float));
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    const obs_technique *t = obs_technique_find("ss_radiosity");
    obs_ss_radiosity_params p;
    obs_scene ps;
    /* The last two sets with the probes, multiplied and added. */
    int with_probes = k + 2 >= sizeof param_sets / sizeof param_sets[0];
    char params[256];
    snprintf(params, sizeof params, "%.*s%s}", (int)strlen(param_sets[k]) - 1, param_sets[k],
             k + 1 == sizeof param_sets / sizeof param_sets[0] ? ",\"probe_combine\":\"add\"" : "");
    cornell_load_probes(w, h, "cpu", params, with_probes ? PROBES : NULL, &ps);
    assert_int_equal(obs_params_bind(t, ps.params, &p, NULL), 0);
    vktest_check_rc(obs_ss_radiosity_direct(&sc, &p, 2, NULL, direct, NULL, &err), &err);
    memset(co, 0, 4 * n * sizeof(float));
    memset(vo, 0, 4 * n * sizeof(float));
    float probes[4 * OBS_SRAD_MAX_PROBES];
    int np = obs_ss_radiosity_probes_make(&ps, probes);
    vktest_check_rc(obs_ss_radiosity_cpu_apply(&g, direct, probes, np, &p, 2, cr, co, NULL, &err),
                    &err);
    vktest_check_rc(
        obs_ss_radiosity_vk_apply(vk, &dev, &g, direct, probes, np, &p, vr, vo, NULL, &err), &err);
    double rr, ro;
    size_t sr = exact_count(cr, vr, 4 * n, &rr), so = exact_count(co, vo, 4 * n, &ro);
    obs_scene_free(&ps);
    size_t gathered = 0;
    for (size_t i = 0; i < n; i++) gathered += cr[4 * i + 3] < 1.0f;
    printf(
        "%-10s %-78s raw %zu/%zu exact (rmse %.2g), blurred %zu/%zu exact (rmse %.2g), "
        "%zu pixels gathered\n",
        label, params, sr, 4 * n, rr, so, 4 * n, ro, gathered);
    /* The same float operations in the same order on the same inputs: the same bits. */
    assert_int_equal(sr, 4 * n);
    assert_int_equal(so, 4 * n);
    assert_true(gathered > n / 200);
  }
  free(direct);
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
  cross_backend(0, "cornell");
}

static void test_cross_cornell_ortho(void **state) {
  (void)state;
  cross_backend(1, "ortho");
}

/* Full renders on both backends: the same direct pass, G-buffers that differ only on silhouettes
 * (rasterised vs CPU), so final agrees within a small RMSE and each output is finite and in range.
 */
static void test_pipeline(void **state) {
  (void)state;
  vktest_need_vk();
  obs_result r[2];
  for (int b = 0; b < 2; b++) {
    obs_scene sc;
    cornell_load(48, 48, b ? "vulkan" : "cpu", "{\"kernel_size\":100,\"bias\":100}", &sc);
    obs_err err = OBS_ERR_INIT;
    obs_render_opts o = {.threads = 2};
    vktest_check_rc(obs_render(&sc, &o, &r[b], &err), &err);
    obs_scene_free(&sc);
    obs_err_free(&err);
    obs_test_assert_finite(&r[b].image);
  }
  assert_int_equal(r[1].backend, OBS_BACKEND_VULKAN);
  size_t n = 48 * 48;
  double ss = 0, sb = 0;
  for (int k = 0; k < 3; k++) {
    static const char *const f[3] = {"final.R", "final.G", "final.B"};
    const float *a = obs_image_channel(&r[0].image, f[k]),
                *v = obs_image_channel(&r[1].image, f[k]);
    for (size_t i = 0; i < n; i++) ss += ((double)a[i] - v[i]) * ((double)a[i] - v[i]);
  }
  const float *ba = obs_image_channel(&r[0].image, "bounce.R");
  const float *bv = obs_image_channel(&r[1].image, "bounce.R");
  for (size_t i = 0; i < n; i++) sb += fabs((double)ba[i] - bv[i]);
  printf("pipeline cpu vs vulkan: final rmse %.3g, bounce.R mean |d| %.3g\n",
         sqrt(ss / (3.0 * (double)n)), sb / (double)n);
  for (size_t i = 0; i < n; i++) {
    float ao = obs_image_channel(&r[1].image, "ao")[i];
    assert_true(ao >= 0.0f && ao <= 1.0f);
  }
  /* Silhouette pixels of the two G-buffers differ; the direct pass is the same buffer. */
  assert_true(sqrt(ss / (3.0 * (double)n)) < 0.05);
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
