/* sss_single's shadow_maps on Vulkan against its CPU twin under the validation layer: the marble
 * scene with several parameter sets (jitter, adaptive, a point light, pixel samples), the slab's
 * closed form on the device, and method trace refused on Vulkan. The CPU casts the light-view
 * maps with Embree; the device rasterises them (the G-buffer pipeline from the light's camera)
 * and walks in float: the radiance agrees within the measured tolerances below, and coverage
 * (the host's camera hits on both) exactly. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vktest.h"

static const char *const RGB[3] = {"radiance.R", "radiance.G", "radiance.B"};

static void render_marble(const char *backend, const char *params, const char *lights, int spp,
                          obs_result *r) {
  char tech[512], image[96];
  snprintf(tech, sizeof tech, "{\"name\":\"sss_single\",\"backend\":\"%s\",\"params\":%s}",
           backend, params);
  snprintf(image, sizeof image, "{\"width\":64,\"height\":48,\"spp\":%d}", spp);
  const obs_override ov[] = {{"/technique", tech}, {"/image", image}, {"/lights", lights}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_scene_load_file(&sc, obs_test_src("scenes/sss_marble.json"), ov,
                                      lights ? 3 : 2, &err),
                  &err);
  obs_render_opts o = {.threads = 2};
  vktest_check_rc(obs_render(&sc, &o, r, &err), &err);
  obs_scene_free(&sc);
  obs_err_free(&err);
  obs_test_assert_finite(&r->image);
}

/* The twins' tolerances. The device's maps come from the G-buffer raster, whose sphere facets
 * tilt by up to 1.5 degrees from the analytic normal the CPU's rays see (gbuffer_vk.c), and sit
 * within a quarter texel inside it; a tilt moves n.w, and with it E_t, Eq. 6.5.6 and the phase
 * angle, by up to sin 1.5 deg = 2.6 % at normal incidence, and a silhouette or shadow texel may
 * change object. Measured on the four cases (64 x 48, lavapipe): RMSE 0.35 to 0.57 % of the mean,
 * bias within 0.02 %, at most 3 of 9216 values off by more than 5 % of the mean. The bounds: an
 * RMSE within 2 % of the mean (below the largest tilt's 2.6 %, 3.5 times the measured), a bias
 * within 0.5 % (facet tilts average out over the walk), and at most 0.5 % of the values off by
 * more than 5 % of the mean (the texels that change object). */
#define RMSE 0.02
#define BIAS 0.005
#define FAR 0.05
#define FAR_SHARE 0.005

static void test_twins(void **state) {
  (void)state;
  vktest_need_vk();
  static const struct {
    const char *params, *lights;
    int spp;
  } cases[] = {
      {"{}", NULL, 1},
      {"{\"jitter\":0,\"adaptive\":false,\"samples\":20}", NULL, 1},
      {"{\"jitter\":3,\"map_size\":128,\"seed\":7}", NULL, 4},
      {"{\"samples\":5}",
       "[{\"type\":\"point\",\"position\":[-2,5,2],\"emission\":[40,40,40]},"
       "{\"type\":\"directional\",\"direction\":[0,-1,0],\"emission\":[1,0.5,0.25]}]",
       1},
  };
  for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
    obs_result r[2];
    render_marble("cpu", cases[k].params, cases[k].lights, cases[k].spp, &r[0]);
    render_marble("vulkan", cases[k].params, cases[k].lights, cases[k].spp, &r[1]);
    assert_int_equal(r[1].backend, OBS_BACKEND_VULKAN);
    size_t n = 64 * 48, far = 0;
    double ss = 0, sum = 0, sumv = 0;
    for (int c = 0; c < 3; c++) {
      const float *a = obs_image_channel(&r[0].image, RGB[c]);
      const float *v = obs_image_channel(&r[1].image, RGB[c]);
      for (size_t i = 0; i < n; i++) {
        ss += ((double)a[i] - v[i]) * ((double)a[i] - v[i]);
        sum += a[i], sumv += v[i];
      }
    }
    double rmse = sqrt(ss / (3.0 * n)), mean = sum / (3.0 * n), bias = (sumv - sum) / (3.0 * n);
    for (int c = 0; c < 3; c++) {
      const float *a = obs_image_channel(&r[0].image, RGB[c]);
      const float *v = obs_image_channel(&r[1].image, RGB[c]);
      for (size_t i = 0; i < n; i++) far += fabs((double)a[i] - v[i]) > FAR * mean;
    }
    const float *aa = obs_image_channel(&r[0].image, "alpha");
    const float *va = obs_image_channel(&r[1].image, "alpha");
    for (size_t i = 0; i < n; i++) assert_true(aa[i] == va[i]);
    printf("%s (spp %d): radiance rmse %.3g = %.2f %% of the mean %.3g, bias %.2f %%, %zu of %zu "
           "values off by > %g of the mean\n",
           cases[k].params, cases[k].spp, rmse, 100 * rmse / mean, mean, 100 * bias / mean, far,
           3 * n, FAR);
    assert_true(mean > 0);
    assert_true(rmse <= RMSE * mean);
    assert_true(fabs(bias) <= BIAS * mean);
    assert_true(far <= 3 * n * FAR_SHARE);
    obs_result_free(&r[0]);
    obs_result_free(&r[1]);
  }
}

/* The half-space of test_sss_single.c's slab on the device: within 2 % of
 * L = F_t(0)^2 E p(-1) sigma_s / (2 sigma_t). */
static void test_slab(void **state) {
  (void)state;
  vktest_need_vk();
  const double sa[3] = {0.2, 0.5, 1.0}, ss[3] = {1.0, 1.5, 0.5}, g = 0.3, eta = 1.4, e = 2;
  char doc[2048];
  snprintf(doc, sizeof doc,
           "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,5,0],\"look_at\":[0,0,0],"
           "\"up\":[0,0,-1],\"height\":2},\"image\":{\"width\":16,\"height\":16},\"objects\":["
           "{\"shape\":{\"type\":\"box\",\"min\":[-4,-6,-4],\"max\":[4,0,4]},\"material\":{"
           "\"reflectivity\":[0.5,0.5,0.5],\"medium\":{\"sigma_a\":[%g,%g,%g],\"sigma_s\":[%g,%g,"
           "%g],\"g\":%g,\"eta\":%g}}}],\"lights\":[{\"type\":\"directional\",\"direction\":"
           "[0,-1,0],\"emission\":[%g,%g,%g]}],\"technique\":{\"name\":\"sss_single\","
           "\"backend\":\"vulkan\",\"params\":{\"map_size\":1024}}}",
           sa[0], sa[1], sa[2], ss[0], ss[1], ss[2], g, eta, e, e, e);
  obs_result r;
  obs_test_render(doc, 2, &r);
  assert_int_equal(r.backend, OBS_BACKEND_VULKAN);
  double r0 = (eta - 1) / (eta + 1) * (eta - 1) / (eta + 1);
  double p = (1 - g * g) / (4 * M_PI * pow(1 + g, 3));
  for (int c = 0; c < 3; c++) {
    const float *v = obs_image_channel(&r.image, RGB[c]);
    double m = 0;
    for (int i = 0; i < 256; i++) m += v[i] / 256.0;
    double want = (1 - r0) * (1 - r0) * e * p * ss[c] / (2 * (sa[c] + ss[c]));
    printf("vulkan half-space %s: %.6g, closed form %.6g (%.2f %%)\n", RGB[c], m, want,
           100 * (m / want - 1));
    assert_true(fabs(m / want - 1) < 0.01);
  }
  obs_result_free(&r);
}

static void test_trace_refused(void **state) {
  (void)state;
  char tech[] = "{\"name\":\"sss_single\",\"backend\":\"vulkan\",\"params\":{\"method\":\"trace\"}}";
  const obs_override ov[] = {{"/technique", tech}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src("scenes/sss_marble.json"), ov, 1, &err);
  if (!rc) obs_scene_free(&sc);
  assert_int_not_equal(rc, 0);
  printf("refused: %s\n", obs_err_message(&err));
  assert_non_null(strstr(obs_err_message(&err), "/technique/params/method"));
  assert_non_null(strstr(obs_err_message(&err), "cpu backend only"));
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_twins, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_slab, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_trace_refused, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
