/* Unit tests for obs_metrics: channel statistics and RMSE against hand-computed small images. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static void assert_msg_has(const obs_err *err, const char *needle) {
  const char *msg = obs_err_message(err);
  if (!strstr(msg, needle)) {
    fprintf(stderr, "message \"%s\" lacks \"%s\"\n", msg, needle);
    fail();
  }
}

/* Builds a w x h image with channels "v" and "alpha" from the given values (alpha may be NULL). */
static void make_image(obs_image *img, int w, int h, const float *v, const float *alpha) {
  const char *names[] = {"v", "alpha"};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(img, w, h, 2, names, &err), 0);
  size_t n = (size_t)w * (size_t)h;
  memcpy(obs_image_channel(img, "v"), v, n * sizeof(float));
  float *a = obs_image_channel(img, "alpha");
  for (size_t i = 0; i < n; i++) a[i] = alpha ? alpha[i] : 1.0f;
  obs_err_free(&err);
}

static void test_stats_unmasked(void **state) {
  (void)state;
  const float v[] = {1.0f, 2.0f, NAN, INFINITY, -INFINITY, 3.0f};
  obs_image img;
  make_image(&img, 3, 2, v, NULL);
  obs_err err = OBS_ERR_INIT;
  obs_stats s;
  assert_int_equal(obs_metrics_stats(&img, "v", NULL, &s, &err), 0);
  assert_int_equal(s.count, 3);
  assert_int_equal(s.nan_count, 1);
  assert_int_equal(s.inf_count, 2);
  assert_true(s.mean == 2.0);
  assert_true(s.min == 1.0);
  assert_true(s.max == 3.0);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_stats_signed_values(void **state) {
  (void)state;
  const float v[] = {-5.0f, 0.5f, 10.0f, -0.0f};
  obs_image img;
  make_image(&img, 2, 2, v, NULL);
  obs_stats s;
  assert_int_equal(obs_metrics_stats(&img, "v", NULL, &s, NULL), 0);
  assert_int_equal(s.count, 4);
  assert_true(s.mean == 1.375); /* (-5 + 0.5 + 10 + 0) / 4 */
  assert_true(s.min == -5.0);
  assert_true(s.max == 10.0);
  assert_int_equal(s.nan_count, 0);
  assert_int_equal(s.inf_count, 0);
  obs_image_free(&img);
}

static void test_stats_masked(void **state) {
  (void)state;
  /* alpha > 0 selects pixels 0, 2, 4 (NaN and negative alpha deselect, like 0). */
  const float v[] = {1.0f, 100.0f, NAN, 7.0f, -INFINITY, 50.0f};
  const float a[] = {1.0f, 0.0f, 0.5f, -1.0f, 1e-20f, NAN};
  obs_image img;
  make_image(&img, 6, 1, v, a);
  obs_err err = OBS_ERR_INIT;
  obs_stats s;
  assert_int_equal(obs_metrics_stats(&img, "v", "alpha", &s, &err), 0);
  assert_int_equal(s.count, 1);
  assert_int_equal(s.nan_count, 1);
  assert_int_equal(s.inf_count, 1);
  assert_true(s.mean == 1.0);
  assert_true(s.min == 1.0);
  assert_true(s.max == 1.0);

  /* The mask channel's own statistics: 0.5 and 1 and 1e-20 are the only values > 0 in it. */
  assert_int_equal(obs_metrics_stats(&img, "alpha", "alpha", &s, &err), 0);
  assert_int_equal(s.count, 3);
  assert_true(s.min == (double)1e-20f);
  assert_true(s.max == 1.0);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_stats_no_finite_values(void **state) {
  (void)state;
  const float v[] = {NAN, INFINITY, NAN, 5.0f};
  const float a[] = {1.0f, 1.0f, 1.0f, 0.0f};
  obs_image img;
  make_image(&img, 2, 2, v, a);
  obs_stats s;
  memset(&s, 0x7f, sizeof s); /* garbage, to prove every field is written */
  assert_int_equal(obs_metrics_stats(&img, "v", "alpha", &s, NULL), 0);
  assert_int_equal(s.count, 0);
  assert_int_equal(s.nan_count, 2);
  assert_int_equal(s.inf_count, 1);
  assert_true(s.mean == 0.0);
  assert_true(s.min == 0.0);
  assert_true(s.max == 0.0);
  obs_image_free(&img);
}

static void test_stats_errors(void **state) {
  (void)state;
  const float v[] = {1.0f};
  obs_image img;
  make_image(&img, 1, 1, v, NULL);
  obs_err err = OBS_ERR_INIT;
  obs_stats s;
  assert_int_equal(obs_metrics_stats(&img, "ao_stderr", NULL, &s, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "ao_stderr");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_stats(&img, "v", "coverage", &s, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "coverage");
  assert_int_equal(obs_metrics_stats(&img, "v", NULL, NULL, &err), OBS_EINVAL);
  assert_int_equal(obs_metrics_stats(NULL, "v", NULL, &s, &err), OBS_EINVAL);
  obs_image_free(&img);
  obs_err_free(&err);
}

/* Half a million pixels of 2^24 interleaved with as many of 1/3: adding the small values to a
 * running double sum near 2^43 drops their low bits every time, so an uncompensated accumulator
 * drifts by about 1e-10 relative, while the mean must come out right to about 1e-15. */
static void test_stats_large_sum_accuracy(void **state) {
  (void)state;
  const char *names[] = {"v"};
  obs_image img;
  assert_int_equal(obs_image_init(&img, 1000, 1000, 1, names, NULL), 0);
  const float big = 16777216.0f, small = 1.0f / 3.0f;
  for (size_t i = 0; i < 1000000; i++) img.data[i] = (i & 1) ? small : big;
  obs_stats s;
  assert_int_equal(obs_metrics_stats(&img, "v", NULL, &s, NULL), 0);
  assert_int_equal(s.count, 1000000);
  double want = ((double)big + (double)small) / 2.0;
  assert_true(fabs(s.mean - want) <= 1e-15 * want);
  assert_true(s.min == (double)small);
  assert_true(s.max == (double)big);
  obs_image_free(&img);
}

static void test_rmse_hand_computed(void **state) {
  (void)state;
  const float va[] = {0.0f, 1.0f, 2.0f, 3.0f};
  const float vb[] = {1.0f, 1.0f, 1.0f, 1.0f};
  obs_image a, b;
  make_image(&a, 2, 2, va, NULL);
  make_image(&b, 2, 2, vb, NULL);
  obs_err err = OBS_ERR_INIT;
  double r = -1.0;
  /* squared errors 1, 0, 1, 4 -> mean 1.5 */
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", NULL, &r, &err), 0);
  assert_true(fabs(r - sqrt(1.5)) < 1e-15);
  /* symmetric */
  assert_int_equal(obs_metrics_rmse(&b, &a, "v", NULL, &r, &err), 0);
  assert_true(fabs(r - sqrt(1.5)) < 1e-15);
  /* against itself */
  assert_int_equal(obs_metrics_rmse(&a, &a, "v", NULL, &r, &err), 0);
  assert_true(r == 0.0);
  assert_int_equal(err.count, 0);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_err_free(&err);
}

static void test_rmse_masked_by_b(void **state) {
  (void)state;
  const float va[] = {0.0f, 1.0f, 2.0f, 3.0f};
  const float vb[] = {1.0f, 1.0f, 1.0f, 1.0f};
  const float mask_a[] = {0.0f, 0.0f, 0.0f, 0.0f}; /* ignored: the mask is taken from b */
  const float mask_b[] = {1.0f, 0.0f, 0.0f, 0.25f};
  obs_image a, b;
  make_image(&a, 4, 1, va, mask_a);
  make_image(&b, 4, 1, vb, mask_b);
  double r = -1.0;
  /* pixels 0 and 3: squared errors 1 and 4 -> mean 2.5 */
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", "alpha", &r, NULL), 0);
  assert_true(fabs(r - sqrt(2.5)) < 1e-15);
  /* with a's all-zero mask nothing is selected: 0 by convention */
  assert_int_equal(obs_metrics_rmse(&b, &a, "v", "alpha", &r, NULL), 0);
  assert_true(r == 0.0);
  obs_image_free(&a);
  obs_image_free(&b);
}

static void test_rmse_non_finite(void **state) {
  (void)state;
  const float va[] = {0.0f, NAN, INFINITY, 1.0f};
  const float vb[] = {0.0f, 0.0f, INFINITY, 1.0f};
  const float m_nan[] = {1.0f, 1.0f, 1.0f, 1.0f};
  const float m_inf[] = {1.0f, 0.0f, 1.0f, 1.0f};
  obs_image a, b;
  make_image(&a, 4, 1, va, NULL);
  make_image(&b, 4, 1, vb, m_nan);
  double r = 0.0;
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", "alpha", &r, NULL), 0);
  assert_true(isnan(r)); /* a NaN in a selected pixel must not be hidden */
  obs_image_free(&b);

  make_image(&b, 4, 1, vb, m_inf);
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", "alpha", &r, NULL), 0);
  assert_true(r == 0.0); /* NaN pixel masked out; equal infinities are no error */
  obs_image_free(&b);

  const float vc[] = {0.0f, 0.0f, 5.0f, 1.0f};
  make_image(&b, 4, 1, vc, m_inf);
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", "alpha", &r, NULL), 0);
  assert_true(isinf(r) && r > 0);
  obs_image_free(&b);
  obs_image_free(&a);
}

static void test_rmse_errors(void **state) {
  (void)state;
  const float v6[] = {0, 1, 2, 3, 4, 5};
  obs_image a, b, c;
  make_image(&a, 2, 2, v6, NULL);
  make_image(&b, 3, 2, v6, NULL);
  obs_err err = OBS_ERR_INIT;
  double r = 0.0;
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", NULL, &r, &err), OBS_EINVAL);
  assert_msg_has(&err, "2x2");
  assert_msg_has(&err, "3x2");
  obs_err_clear(&err);

  const char *other[] = {"ao"};
  assert_int_equal(obs_image_init(&c, 2, 2, 1, other, &err), 0);
  assert_int_equal(obs_metrics_rmse(&a, &c, "v", NULL, &r, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "\"v\"");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_rmse(&a, &a, "v", "depth.Z", &r, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "depth.Z");
  assert_int_equal(obs_metrics_rmse(&a, &a, "v", NULL, NULL, &err), OBS_EINVAL);
  obs_image_free(&c);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_err_free(&err);
}

/* SSIM: identical images give 1; constant images reduce to the luminance term, computed by hand;
 * noise lowers it; windows follow the mask. */
static void test_ssim(void **state) {
  (void)state;
  float va[256], vb[256], vn[256], mask[256];
  uint32_t s = 12345;
  for (int i = 0; i < 256; i++) {
    va[i] = 0.5f;
    vb[i] = 0.25f;
    s = s * 1664525u + 1013904223u;
    vn[i] = 0.5f + 0.2f * ((float)(s >> 8) / 16777216.0f - 0.5f);
    mask[i] = (i % 16) < 8 ? 1.0f : 0.0f;
  }
  obs_image a, b, n, nm;
  make_image(&a, 16, 16, va, NULL);
  make_image(&b, 16, 16, vb, NULL);
  make_image(&n, 16, 16, vn, NULL);
  make_image(&nm, 16, 16, vn, mask);
  obs_err err = OBS_ERR_INIT;
  double r;
  assert_int_equal(obs_metrics_ssim(&n, &n, "v", NULL, &r, &err), 0);
  assert_true(fabs(r - 1.0) < 1e-12);
  assert_int_equal(obs_metrics_ssim(&a, &b, "v", NULL, &r, &err), 0);
  double expect = (2 * 0.5 * 0.25 + 1e-4) / (0.25 + 0.0625 + 1e-4);
  assert_true(fabs(r - expect) < 1e-9);
  assert_int_equal(obs_metrics_ssim(&a, &n, "v", NULL, &r, &err), 0);
  assert_true(r < 0.5 && r > -1.0); /* no shared structure: the contrast term collapses */
  double masked;
  assert_int_equal(obs_metrics_ssim(&a, &nm, "v", "alpha", &masked, &err), 0);
  assert_true(masked < 0.5);
  /* Tiny images use one window of their own size. */
  obs_image t1, t2;
  make_image(&t1, 1, 1, va, NULL);
  make_image(&t2, 1, 1, vb, NULL);
  assert_int_equal(obs_metrics_ssim(&t1, &t2, "v", NULL, &r, &err), 0);
  assert_true(fabs(r - expect) < 1e-9);
  assert_int_equal(obs_metrics_ssim(&t1, &a, "v", NULL, &r, &err), OBS_EINVAL);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&n);
  obs_image_free(&nm);
  obs_image_free(&t1);
  obs_image_free(&t2);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_stats_unmasked),
      cmocka_unit_test(test_stats_signed_values),
      cmocka_unit_test(test_stats_masked),
      cmocka_unit_test(test_stats_no_finite_values),
      cmocka_unit_test(test_stats_errors),
      cmocka_unit_test(test_stats_large_sum_accuracy),
      cmocka_unit_test(test_rmse_hand_computed),
      cmocka_unit_test(test_rmse_masked_by_b),
      cmocka_unit_test(test_rmse_non_finite),
      cmocka_unit_test(test_rmse_errors),
      cmocka_unit_test(test_ssim),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
