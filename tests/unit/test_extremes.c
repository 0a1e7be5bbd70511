/* Guaranteed ranges on the CPU: every registered technique with a CPU backend holds its declared
 * range at both ends (tests/unit/extremes.c), and warns just outside it. */
#include "extremes.h"
#include "testutil.h"

#include <stdio.h>

static void test_cpu_ranges_hold(void **state) {
  (void)state;
  int ran = 0;
  int bad = obs_extremes_check_backend(OBS_BACKEND_CPU, &ran);
  assert_true(ran >= 1);
  assert_int_equal(bad, 0);
}

static void test_cpu_warns_outside(void **state) {
  (void)state;
  assert_int_equal(obs_extremes_check_warnings(OBS_BACKEND_CPU), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cpu_ranges_hold),
      cmocka_unit_test(test_cpu_warns_outside),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
