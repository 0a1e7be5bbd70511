/* The statistical check of reported standard errors (stderr_check.h). */
#include "stderr_check.h"

#include <stdio.h>

#include "testutil.h"

obs_stderr_calib obs_test_stderr_calib(const obs_stderr_case *c, long n) {
  obs_stderr_calib k;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_stderr_run(c, n, n * OBS_TEST_STDERR_FACTOR, 0, 2, &k, NULL, &err);
  if (rc) printf("%s: %s\n", c->label, obs_err_message(&err));
  assert_int_equal(rc, 0);
  printf("%s at %ld: RMS stderr / RMSE %.3f (RMSE %.4g), %.2f %% within 3 sigma, %.2f %% zero with "
         "an error, over %lld values\n",
         c->label, n, k.ratio, k.rmse, 100 * k.within3, 100 * k.zero_with_error,
         (long long)k.values);
  obs_err_free(&err);
  return k;
}

void obs_test_stderr_check(const obs_stderr_case *c, long n) {
  obs_test_numeric_only(); /* a statistical check: renders at 64 n samples */
  obs_stderr_calib k = obs_test_stderr_calib(c, n);
  assert_true(k.values >= 100);
  assert_int_equal(k.nonfinite, 0);
  assert_true(k.ratio >= 0.67 && k.ratio <= 1.5);
  assert_true(k.zero_with_error == 0.0);
  if (n >= 16) assert_true(k.within3 >= 0.97);
}
