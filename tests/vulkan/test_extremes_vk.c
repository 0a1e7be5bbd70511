/* Guaranteed ranges on Vulkan: every registered technique with a Vulkan backend holds its declared
 * range at both ends (tests/unit/extremes.c), and warns just outside it; the validation layer
 * stays silent throughout. */
#include "extremes.h"
#include "vktest.h"

static void test_vulkan_ranges_hold(void **state) {
  (void)state;
  vktest_need_vk();
  int ran = 0;
  int bad = obs_extremes_check_backend(OBS_BACKEND_VULKAN, &ran);
  assert_true(ran >= 1);
  assert_int_equal(bad, 0);
}

static void test_vulkan_warns_outside(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_extremes_check_warnings(OBS_BACKEND_VULKAN), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_vulkan_ranges_hold, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_vulkan_warns_outside, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
