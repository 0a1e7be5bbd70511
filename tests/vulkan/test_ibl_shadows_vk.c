/* ibl_shadows on Vulkan against its CPU twin, under the validation layer: one G-buffer, one BVH
 * and one environment through both fit and blur implementations fed the same (ray-cast) maps (bit
 * for bit, every output) and through the Vulkan backend's own rasterised maps (within the bounds
 * below), perspective and orthographic; and full renders through both backends. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "environment.h"
#include "gbuffer_cpu.h"
#include "raytrace.h"
#include "vktest.h"
#include "vk.h"
#include "../../renderer/techniques/ibl_shadows/ibl_shadows.h"

/* scenes/ibl_sky.json (w x h) with ibl_shadows' `params` on `backend`, seen by `camera` (JSON, or
 * NULL for the scene's own). */
static void sky_load(int w, int h, const char *backend, const char *params, const char *camera,
                     obs_scene *sc) {
  char tech[512], size[64];
  snprintf(tech, sizeof tech, "{\"name\":\"ibl_shadows\",\"backend\":\"%s\",\"params\":%s}",
           backend, params);
  snprintf(size, sizeof size, "{\"width\":%d,\"height\":%d,\"spp\":1}", w, h);
  const obs_override ov[] = {{"/technique", tech}, {"/image", size}, {"/camera", camera}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(
      obs_scene_load_file(sc, obs_test_src("scenes/ibl_sky.json"), ov, camera ? 3 : 2, &err),
      &err);
  obs_err_free(&err);
}

static const char *const ORTHO_CAMERA =
    "{\"type\":\"orthographic\",\"position\":[3,4,-3],\"look_at\":[0,0.4,0],\"height\":4}";

/* Small maps: the twins' agreement does not depend on their size. */
static const char *const param_sets[] = {
    "{\"map_size\":64}",
    "{\"map_size\":64,\"blur\":false}",
    "{\"map_size\":48,\"shadow_maps\":16,\"sh_order\":2,\"tikhonov\":0.05}",
    "{\"map_size\":32,\"shadow_maps\":5,\"sh_order\":3,\"bias\":0}",
    "{\"map_size\":64,\"shadow_maps\":64,\"sh_order\":1}",
};

static void cross_backend(const char *camera, const char *label) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  const int w = 40, h = 30;
  obs_scene sc;
  sky_load(w, h, "cpu", "{}", camera, &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_cpu(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  obs_rt rt;
  vktest_check_rc(obs_rt_build_ex(&sc, &rt, 2, OBS_RT_FRAME_GEOMETRY, &err), &err);
  obs_env env;
  vktest_check_rc(obs_env_from_scene(&sc, &env, &err), &err);
  const size_t n = (size_t)w * (size_t)h, planes = 2 + OBS_IBL_EXTRA;
  float *c = malloc(planes * n * sizeof(float)), *v = malloc(planes * n * sizeof(float));
  const obs_technique *t = obs_technique_find("ibl_shadows");
  for (size_t k = 0; k < sizeof param_sets / sizeof param_sets[0]; k++) {
    obs_ibl_shadows_params p;
    obs_scene ps;
    sky_load(w, h, "cpu", param_sets[k], camera, &ps);
    assert_int_equal(obs_params_bind(t, ps.params, &p, NULL), 0);
    memset(c, 0, planes * n * sizeof(float));
    memset(v, 0xff, planes * n * sizeof(float));
    vktest_check_rc(obs_ibl_shadows_cpu_apply(&ps, &rt, &env, &g, &p, 2, c, c + n, c + 2 * n,
                                              NULL, &err), &err);
    vktest_check_rc(obs_ibl_shadows_vk_apply(vk, &dev, &ps, &rt, &env, &g, &p, 1, 2, v, v + n,
                                             v + 2 * n, NULL, &err), &err);
    size_t same = 0, shadowed = 0, covered = 0;
    for (size_t i = 0; i < planes * n; i++) {
      assert_true(isfinite(c[i]));
      same += memcmp(&c[i], &v[i], sizeof(float)) == 0;
    }
    for (size_t i = 0; i < n; i++) {
      covered += g.depth[i] > 0.0f;
      shadowed += g.depth[i] > 0.0f && c[n + i] < 0.8f;
    }
    printf("%-6s %-70s %zu/%zu exact, %zu of %zu covered pixels with raw ao < 0.8\n", label,
           param_sets[k], same, planes * n, shadowed, covered);
    /* Fed the same maps: the same float operations in the same order on the same inputs, so the
     * same bits. */
    assert_int_equal(same, planes * n);
    assert_true(shadowed > 0);
    /* The device's own maps, rasterised. */
    memset(v, 0xff, planes * n * sizeof(float));
    vktest_check_rc(obs_ibl_shadows_vk_apply(vk, &dev, &ps, &rt, &env, &g, &p, 0, 2, v, v + n,
                                             v + 2 * n, NULL, &err), &err);
    double dao = 0, dmax = 0, se = 0, sum = 0;
    size_t off = 0;
    for (size_t i = 0; i < planes * n; i++) assert_true(isfinite(v[i]));
    for (size_t i = 0; i < n; i++) {
      if (!(g.depth[i] > 0.0f)) continue;
      double d = fabs((double)v[n + i] - c[n + i]);
      dao += d, dmax = fmax(dmax, d), off += d > 0.05;
      for (int ch = 0; ch < 3; ch++) {
        double a = c[(2 + ch) * n + i], b = v[(2 + ch) * n + i];
        se += (a - b) * (a - b), sum += a;
      }
    }
    const double rel = sqrt(se / (3.0 * covered)) / (sum / (3.0 * covered));
    printf("%-6s raster: raw ao mean |diff| %.2e max %.3f, %zu px > 0.05; radiance rmse/mean %.2e\n",
           label, dao / covered, dmax, off, rel);
    /* A rasterised texel holds what the ray through its centre hits except where a silhouette
     * edge passes that centre (the rasteriser's tie rule against Embree's, and sphere facets up to
     * a quarter texel inside the surface), so only receivers on a shadow's edge may change their
     * test, by one map each. Measured on these sets (bias 1.5): mean |diff| <= 6.5e-4, at most
     * 0.85% of pixels past 0.05, radiance RMSE <= 0.98% of its mean (unblurred coefficients); the
     * bounds leave 2.5 to 3x. With bias 0 a lit plane's own depth ties with its test and flips by the ulp
     * (acne, the same on both backends only in kind): measured 8e-3, bounded at 2e-2. */
    const int unbiased = p.bias == 0.0f;
    assert_true(dao / covered <= (unbiased ? 2e-2 : 2e-3));
    if (!unbiased) {
      assert_true((double)off <= 0.0225 * covered);
      assert_true(rel <= 2.5e-2);
    }
    obs_scene_free(&ps);
  }
  free(c);
  free(v);
  obs_env_free(&env);
  obs_rt_free(&rt);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_cross(void **state) {
  (void)state;
  cross_backend(NULL, "sky");
}

static void test_cross_ortho(void **state) {
  (void)state;
  cross_backend(ORTHO_CAMERA, "ortho");
}

static void pipeline_load(const char *backend, obs_scene *sc) {
  sky_load(48, 36, backend, "{\"map_size\":64}", NULL, sc);
}

/* Full renders on both backends: G-buffers and shadow maps that differ only on silhouettes
 * (rasterised vs ray cast), the same shading, so the radiance agrees within an RMSE of 1% of its
 * mean (measured 0.31%), and every output is finite. */
static void test_pipeline(void **state) {
  (void)state;
  obs_result r[2];
  double mean, rmse = vktest_pipeline_rmse(pipeline_load, r, &mean);
  assert_true(rmse <= 1e-2 * mean);
  obs_result_free(&r[0]);
  obs_result_free(&r[1]);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_pipeline, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
