/* The conformance suite (tests/unit/conformance.c) over every registered technique's Vulkan
 * backend on lavapipe; the validation layer stays silent throughout. */
#include "conformance.h"
#include "vktest.h"

static void test_vulkan_defaults(void **state) {
  (void)state;
  vktest_need_vk();
  int ran = 0;
  assert_int_equal(obs_conformance_defaults(OBS_BACKEND_VULKAN, &ran), 0);
  assert_true(ran >= 1);
}

static void test_vulkan_param_ends(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_conformance_param_ends(OBS_BACKEND_VULKAN, NULL), 0);
}

static void test_vulkan_threads(void **state) {
  (void)state;
  obs_test_numeric_only();
  vktest_need_vk();
  assert_int_equal(obs_conformance_threads(OBS_BACKEND_VULKAN, NULL), 0);
}

static void test_vulkan_scales(void **state) {
  (void)state;
  obs_test_numeric_only();
  vktest_need_vk();
  assert_int_equal(obs_conformance_scales(OBS_BACKEND_VULKAN, NULL), 0);
}

static void test_vulkan_cancellation(void **state) {
  (void)state;
  obs_test_numeric_only();
  vktest_need_vk();
  assert_int_equal(obs_conformance_cancellation(OBS_BACKEND_VULKAN, NULL), 0);
}

static void test_vulkan_refusals(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_conformance_refusals(OBS_BACKEND_VULKAN, NULL), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_vulkan_defaults, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_param_ends, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_threads, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_scales, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_cancellation, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_refusals, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
