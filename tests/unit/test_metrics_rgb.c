/* Unit tests for the metrics of RGB outputs (RMSE per channel and on luminance, SSIM on
 * luminance, relative MSE) and of per-patch values (area-weighted RMSE), against hand-computed
 * values on tiny images and patch sets. */
#include "testutil.h"

#include <math.h>
#include <string.h>

/* A 2 x 1 image with RGB output "rad" from six values (pixel-major) and an alpha channel. */
static void make_rgb(obs_image *img, const float rgb[6], const float alpha[2]) {
  const char *names[] = {"rad.R", "rad.G", "rad.B", "alpha"};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(img, 2, 1, 4, names, &err), 0);
  for (int c = 0; c < 3; c++)
    for (int i = 0; i < 2; i++) obs_image_channel(img, names[c])[i] = rgb[3 * i + c];
  for (int i = 0; i < 2; i++) obs_image_channel(img, "alpha")[i] = alpha[i];
}

static const float cand_v[6] = {1.0f, 0.0f, 0.0f, 0.5f, 0.5f, 0.5f};
static const float ref_v[6] = {0.5f, 0.0f, 0.0f, 0.5f, 0.5f, 1.0f};
static const float both[2] = {1.0f, 1.0f};

static void test_rgb_by_hand(void **state) {
  (void)state;
  obs_image c, r;
  make_rgb(&c, cand_v, both);
  make_rgb(&r, ref_v, both);
  obs_compare_rgb m;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_compare_rgb(&c, &r, "rad", "alpha", &m, &err), 0);
  assert_int_equal(m.pixels, 2);
  /* R differs by 0.5 in pixel 0, B by -0.5 in pixel 1, G nowhere. */
  assert_true(fabs(m.rmse[0] - sqrt(0.125)) < 1e-12);
  assert_true(m.rmse[1] == 0.0);
  assert_true(fabs(m.rmse[2] - sqrt(0.125)) < 1e-12);
  /* Y = 0.2126 R + 0.7152 G + 0.0722 B: pixel 0 0.2126 vs 0.1063, pixel 1 0.5 vs 0.5361. */
  double d0 = 0.2126 - 0.1063, d1 = 0.5 - 0.5361;
  assert_true(fabs(m.rmse_luminance - sqrt((d0 * d0 + d1 * d1) / 2)) < 1e-7);
  /* relMSE: (0.5^2 / (0.5^2 + 0.01) + 0.5^2 / (1 + 0.01)) / (3 channels x 2 pixels). */
  double rel = (0.25 / 0.26 + 0.25 / 1.01) / 6.0;
  assert_true(fabs(m.rel_mse - rel) < 1e-12);
  /* SSIM on luminance is obs_metrics_ssim on hand-made luminance planes: both undefined (NaN) on
   * a 2x1 image, smaller than SSIM's 11x11 window (test_metric_table.c compares them on a larger
   * one). */
  const char *yn[] = {"Y", "alpha"};
  obs_image yc, yr;
  assert_int_equal(obs_image_init(&yc, 2, 1, 2, yn, &err), 0);
  assert_int_equal(obs_image_init(&yr, 2, 1, 2, yn, &err), 0);
  float *a = obs_image_channel(&yc, "Y"), *b = obs_image_channel(&yr, "Y");
  a[0] = 0.2126f, a[1] = 0.5f, b[0] = 0.1063f, b[1] = 0.5361f;
  for (int i = 0; i < 2; i++) yc.data[2 + i] = yr.data[2 + i] = 1.0f;
  double ssim;
  assert_int_equal(obs_metrics_ssim(&yc, &yr, "Y", "alpha", &ssim, &err), 0);
  assert_true(isnan(ssim) && isnan(m.ssim_luminance));
  /* Identical images: no error. */
  assert_int_equal(obs_metrics_compare_rgb(&r, &r, "rad", "alpha", &m, &err), 0);
  assert_true(m.rmse[0] == 0 && m.rmse_luminance == 0 && m.rel_mse == 0);
  obs_image_free(&c);
  obs_image_free(&r);
  obs_image_free(&yc);
  obs_image_free(&yr);
  obs_err_free(&err);
}

static void test_rgb_mask_and_errors(void **state) {
  (void)state;
  obs_image c, r;
  const float first[2] = {1.0f, 0.0f};
  make_rgb(&c, cand_v, both);
  make_rgb(&r, ref_v, first);
  obs_compare_rgb m;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_compare_rgb(&c, &r, "rad", "alpha", &m, &err), 0);
  assert_int_equal(m.pixels, 1);
  assert_true(fabs(m.rmse[0] - 0.5) < 1e-12);
  assert_true(m.rmse[2] == 0.0);
  /* A NaN in a selected pixel is never hidden. */
  obs_image_channel(&c, "rad.G")[0] = NAN;
  assert_int_equal(obs_metrics_compare_rgb(&c, &r, "rad", "alpha", &m, &err), 0);
  assert_true(isnan(m.rmse[0]) && isnan(m.rmse_luminance) && isnan(m.rel_mse));
  /* A missing output is named. */
  assert_int_equal(obs_metrics_compare_rgb(&c, &r, "radiance", "alpha", &m, &err), OBS_ENOTFOUND);
  assert_non_null(strstr(obs_err_message(&err), "radiance.R"));
  /* The luminance image carries the stderr bound and alpha. */
  const char *names[] = {"rad.R", "rad.G", "rad.B", "se.R", "se.G", "se.B"};
  obs_image s, y;
  assert_int_equal(obs_image_init(&s, 1, 1, 6, names, &err), 0);
  for (int k = 0; k < 6; k++) s.data[k] = k < 3 ? 1.0f : 0.1f;
  assert_int_equal(obs_metrics_luminance_image(&s, "rad", "se", &y, &err), 0);
  assert_true(fabs(obs_image_channel(&y, "rad")[0] - 1.0f) < 1e-6f);
  assert_true(fabs(obs_image_channel(&y, "rad_stderr")[0] - 0.1f) < 1e-6f);
  assert_null(obs_image_channel(&y, "alpha"));
  double mean;
  assert_int_equal(obs_metrics_luminance_mean(&s, "se", NULL, &mean, &err), 0);
  assert_true(fabs(mean - 0.1) < 1e-6);
  obs_image_free(&s);
  obs_image_free(&y);
  obs_image_free(&c);
  obs_image_free(&r);
  obs_err_free(&err);
}

static void make_patches(obs_patches *p, const float *v, const float *area, int n) {
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_patches_init(p, "w", n, 1, area != NULL, &err), 0);
  memcpy(p->values, v, (size_t)n * sizeof(float));
  if (area) memcpy(p->area, area, (size_t)n * sizeof(float));
}

static void test_patch_rmse(void **state) {
  (void)state;
  const float cv[3] = {1, 2, 3}, rv[3] = {1, 1, 1}, area[3] = {1, 3, 0};
  obs_patches c, r, ru;
  make_patches(&c, cv, NULL, 3);
  make_patches(&r, rv, area, 3);
  make_patches(&ru, rv, NULL, 3);
  obs_err err = OBS_ERR_INIT;
  double rmse;
  /* Weighted by area: (1 * 0 + 3 * 1^2) / (1 + 3); the zero-area patch does not count. */
  assert_int_equal(obs_metrics_patch_rmse(&c, &r, &rmse, &err), 0);
  assert_true(fabs(rmse - sqrt(0.75)) < 1e-12);
  /* Without areas on either side every patch weighs the same: (0 + 1 + 4) / 3. */
  assert_int_equal(obs_metrics_patch_rmse(&c, &ru, &rmse, &err), 0);
  assert_true(fabs(rmse - sqrt(5.0 / 3.0)) < 1e-12);
  obs_stats st;
  obs_metrics_patch_stats(&c, &st);
  assert_true(st.mean == 2.0 && st.min == 1.0 && st.max == 3.0 && st.count == 3);
  obs_patches_free(&c);
  make_patches(&c, cv, NULL, 2);
  assert_int_equal(obs_metrics_patch_rmse(&c, &r, &rmse, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "differ"));
  obs_patches_free(&c);
  obs_patches_free(&r);
  obs_patches_free(&ru);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_rgb_by_hand),
      cmocka_unit_test(test_rgb_mask_and_errors),
      cmocka_unit_test(test_patch_rmse),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
