/* The standard errors every Monte-Carlo technique reports, per sampler, against references at
 * 64 times the samples (stderr_check.h): RMS stderr / RMSE within [0.67, 1.5], no zero stderr
 * with an error, and from 16 samples at least 97 % of pixel (or patch) values within 3 stderr.
 * docs/accuracy.md, "Standard errors", has the same figures at more sizes (bench/bench_stderr). */
#include <stdio.h>

#include "stderr_check.h"
#include "testutil.h"

#define CORNELL "scenes/cornell_box.json"

/* rt_ao with binary rays: replicates and the floor where every ray agrees; at 4 rays only the
 * ratio is asked (4 replicates of one ray: a Student t with 3 degrees of freedom). */
static void test_rt_ao(void **state) {
  (void)state;
  static const obs_stderr_case cases[] = {
      {"rt_ao sobol", CORNELL, "rt_ao", "cpu", "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}",
       "ao", "ao_stderr", 0, 24},
      {"rt_ao halton", CORNELL, "rt_ao", "cpu",
       "{\"samples\":$N,\"sampler\":\"halton\",\"seed\":$S}", "ao", "ao_stderr", 0, 24},
      {"rt_ao random", CORNELL, "rt_ao", "cpu",
       "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "ao", "ao_stderr", 0, 24},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    obs_test_stderr_check(&cases[i], 16);
    obs_test_stderr_check(&cases[i], 4);
  }
}

/* A continuous falloff: skewed values (rare near hits), made up for by the pooled prior. */
static void test_rt_ao_exp(void **state) {
  (void)state;
  static const obs_stderr_case c = {
      "rt_ao sobol exp", CORNELL, "rt_ao", "cpu",
      "{\"samples\":$N,\"sampler\":\"sobol\",\"falloff\":\"exp\",\"tau\":0.02,\"seed\":$S}", "ao",
      "ao_stderr", 0, 32};
  obs_test_stderr_check(&c, 16);
}

/* obscurance's W (colour bleeding, the article's sqrt falloff) and its final image (W's error
 * and the direct light's). */
static void test_obscurance(void **state) {
  (void)state;
  static const obs_stderr_case cases[] = {
      {"obscurance W sobol", CORNELL, "obscurance", "cpu",
       "{\"samples\":$N,\"sequence\":\"sobol\",\"d_max\":150,\"seed\":$S}", "obscurance",
       "obscurance_stderr", 0, 20},
      {"obscurance W halton", CORNELL, "obscurance", "cpu",
       "{\"samples\":$N,\"sequence\":\"halton\",\"d_max\":150,\"seed\":$S}", "obscurance",
       "obscurance_stderr", 0, 20},
      {"obscurance final sobol", CORNELL, "obscurance", "cpu",
       "{\"samples\":$N,\"light_samples\":$L,\"sequence\":\"sobol\",\"d_max\":150,\"seed\":$S}",
       "final", "final_stderr", 0, 20},
      {"obscurance final halton", CORNELL, "obscurance", "cpu",
       "{\"samples\":$N,\"light_samples\":$L,\"sequence\":\"halton\",\"d_max\":150,\"seed\":$S}",
       "final", "final_stderr", 0, 20},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) obs_test_stderr_check(&cases[i], 16);
}

/* path_trace: before the pooled prior 9 % of its pixel channels lay outside 3 sigma at 16 paths
 * (the paths that reach the light rarely were missed, and with them the spread). */
static void test_path_trace(void **state) {
  (void)state;
  static const obs_stderr_case cases[] = {
      {"path_trace random", CORNELL, "path_trace", "cpu",
       "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "radiance", "radiance_stderr", 0, 16},
      {"path_trace sobol", CORNELL, "path_trace", "cpu",
       "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "radiance", "radiance_stderr", 0, 16},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    obs_test_stderr_check(&cases[i], 16);
    obs_test_stderr_check(&cases[i], 4);
  }
}

/* obscurance_map per patch, each estimator: N rays per patch, 4096 N global lines, N bundle
 * directions (a 128 x 128 grid each). */
static void test_obscurance_map(void **state) {
  (void)state;
  static const obs_stderr_case cases[] = {
      {"obscurance_map rays", CORNELL, "obscurance_map", "cpu",
       "{\"method\":\"rays\",\"samples\":$N,\"patch_size\":100,\"d_max\":150,\"seed\":$S}",
       "obscurance", "obscurance_stderr", 1, 8},
      {"obscurance_map global_lines", CORNELL, "obscurance_map", "cpu",
       "{\"method\":\"global_lines\",\"lines\":$G,\"patch_size\":100,\"d_max\":150,\"seed\":$S}",
       "obscurance", "obscurance_stderr", 1, 8},
      {"obscurance_map bundles", CORNELL, "obscurance_map", "cpu",
       "{\"method\":\"bundles\",\"directions\":$N,\"bundle_resolution\":128,\"patch_size\":100,"
       "\"d_max\":150,\"seed\":$S}",
       "obscurance", "obscurance_stderr", 1, 8},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) obs_test_stderr_check(&cases[i], 16);
}

/* volume_ao on the CPU, each sampler (its Vulkan twin: tests/vulkan/test_volume_ao_vk.c). */
static void test_volume_ao(void **state) {
  (void)state;
  static const obs_stderr_case cases[] = {
      {"volume_ao sobol", "scenes/volume_torus.json", "volume_ao", "cpu",
       "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
      {"volume_ao halton", "scenes/volume_torus.json", "volume_ao", "cpu",
       "{\"samples\":$N,\"sampler\":\"halton\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
      {"volume_ao random", "scenes/volume_torus.json", "volume_ao", "cpu",
       "{\"samples\":$N,\"sampler\":\"random\",\"seed\":$S}", "ao", "ao_stderr", 0, 64},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) obs_test_stderr_check(&cases[i], 16);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_rt_ao),      cmocka_unit_test(test_rt_ao_exp),
      cmocka_unit_test(test_obscurance), cmocka_unit_test(test_path_trace),
      cmocka_unit_test(test_obscurance_map), cmocka_unit_test(test_volume_ao),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
