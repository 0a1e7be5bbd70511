/* The conformance suite (tests/unit/conformance.c) over every registered technique's CPU backend. */
#include "conformance.h"
#include "testutil.h"

static void test_cpu_defaults(void **state) {
  (void)state;
  int ran = 0;
  assert_int_equal(obs_conformance_defaults(OBS_BACKEND_CPU, &ran), 0);
  assert_true(ran >= 1);
}

static void test_cpu_param_ends(void **state) {
  (void)state;
  assert_int_equal(obs_conformance_param_ends(OBS_BACKEND_CPU, NULL), 0);
}

static void test_cpu_threads(void **state) {
  (void)state;
  obs_test_numeric_only();
  assert_int_equal(obs_conformance_threads(OBS_BACKEND_CPU, NULL), 0);
}

static void test_cpu_scales(void **state) {
  (void)state;
  obs_test_numeric_only();
  assert_int_equal(obs_conformance_scales(OBS_BACKEND_CPU, NULL), 0);
}

static void test_cpu_cancellation(void **state) {
  (void)state;
  obs_test_numeric_only();
  assert_int_equal(obs_conformance_cancellation(OBS_BACKEND_CPU, NULL), 0);
}

static void test_cpu_refusals(void **state) {
  (void)state;
  assert_int_equal(obs_conformance_refusals(OBS_BACKEND_CPU, NULL), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_cpu_defaults),     cmocka_unit_test(test_cpu_param_ends),
      cmocka_unit_test(test_cpu_threads),      cmocka_unit_test(test_cpu_scales),
      cmocka_unit_test(test_cpu_cancellation), cmocka_unit_test(test_cpu_refusals),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
