/* Unit tests for the metric table and obs_metrics_compare_all: every entry complete and unique,
 * the figures compare_all gives equal to the single metrics' functions, what applies to which
 * kind of channel, the mean angle of directions by hand, and the JSON placement. */
#include "testutil.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "obscura/metric_table.h"

static void test_table_complete(void **state) {
  (void)state;
  const obs_metric *t = obs_metric_table();
  for (int i = 0; i < OBS_METRIC_COUNT; i++) {
    assert_non_null(t[i].name);
    assert_non_null(t[i].label);
    assert_non_null(t[i].unit);
    assert_non_null(t[i].json_key);
    assert_true(t[i].definition && strlen(t[i].definition) > 5);
    assert_true(t[i].min < t[i].max);
    assert_true(t[i].digits >= 2 && t[i].digits <= 6);
    assert_string_not_equal(obs_metric_direction_name(t[i].direction), "?");
    assert_string_not_equal(obs_metric_needs_name(t[i].needs), "?");
    assert_ptr_equal(obs_metric_find(t[i].name), &t[i]);
    for (int j = 0; j < i; j++) assert_string_not_equal(t[i].name, t[j].name);
  }
  assert_null(obs_metric_find("nope"));
  for (int i = 0; i < OBS_METRIC_COUNT; i++)
    if (t[i].same_as) assert_non_null(obs_metric_find(t[i].same_as));
  assert_true(t[OBS_METRIC_PSNR].max == OBS_METRICS_PSNR_MAX);
}

static void image(obs_image *img, int w, int h, const char *const *names, int n, uint32_t seed,
                  double scale) {
  assert_int_equal(obs_image_init(img, w, h, n, names, NULL), 0);
  uint32_t s = seed;
  for (size_t i = 0; i < (size_t)n * w * h; i++) img->data[i] = (float)(scale * obs_test_unit(&s));
  float *a = obs_image_channel(img, "alpha");
  for (int i = 0; a && i < w * h; i++) a[i] = (i % w) < w / 2 ? 1.0f : 0.0f;
}

/* A scalar [0, 1] channel: the scalar figures are obs_metrics_compare's, flip is
 * obs_metrics_flip's (LDR); no RGB or vector entries. */
static void test_scalar(void **state) {
  (void)state;
  const char *names[] = {"ao", "alpha", "ao_stderr"};
  obs_image c, r;
  image(&c, 24, 18, names, 2, 3, 1.0);
  image(&r, 24, 18, names, 3, 4, 1.0);
  obs_metric_opts op = {.channel = "ao", .mask = "alpha"};
  obs_metric_values v;
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, NULL), 0);
  obs_compare m;
  assert_int_equal(obs_metrics_compare(&c, &r, "ao", "alpha", &m, NULL), 0);
  double flip;
  assert_int_equal(obs_metrics_flip(&c, &r, "ao", "alpha", 0, NULL, &flip, NULL), 0);
  assert_true(v.v[OBS_METRIC_RMSE] == m.rmse && v.v[OBS_METRIC_BIAS] == m.bias);
  assert_true(v.v[OBS_METRIC_MAX_ABS] == m.max_abs && v.v[OBS_METRIC_PSNR] == m.psnr);
  assert_true(v.v[OBS_METRIC_SSIM] == m.ssim && v.v[OBS_METRIC_REF_NOISE] == m.ref_noise);
  assert_true(v.v[OBS_METRIC_FLIP] == flip && flip > 0 && flip < 1);
  assert_int_equal(v.pixels, 12 * 18);
  for (int i = 0; i < OBS_METRIC_COUNT; i++)
    assert_int_equal(v.has[i], i <= OBS_METRIC_FLIP || i == OBS_METRIC_REF_NOISE);
  /* Values beyond [0, 1] (depth, radiance luminance) are no display values: no FLIP. */
  r.data[5] = 3.0f;
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, NULL), 0);
  assert_int_equal(v.has[OBS_METRIC_FLIP], 0);
  assert_true(isnan(v.v[OBS_METRIC_FLIP]));
  obs_image_free(&c);
  obs_image_free(&r);
}

/* An RGB output: the RGB figures, the scalar ones on the luminance, HDR-FLIP. */
static void test_rgb(void **state) {
  (void)state;
  const char *names[] = {"radiance.R", "radiance.G", "radiance.B", "alpha"};
  obs_image c, r;
  image(&c, 20, 16, names, 4, 7, 4.0);
  image(&r, 20, 16, names, 4, 8, 4.0);
  obs_metric_opts op = {.channel = "radiance", .mask = "alpha"};
  obs_metric_values v;
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, NULL), 0);
  obs_compare_rgb m;
  assert_int_equal(obs_metrics_compare_rgb(&c, &r, "radiance", "alpha", &m, NULL), 0);
  assert_true(v.v[OBS_METRIC_RMSE_R] == m.rmse[0] && v.v[OBS_METRIC_RMSE_B] == m.rmse[2]);
  assert_true(v.v[OBS_METRIC_REL_MSE] == m.rel_mse);
  assert_true(fabs(v.v[OBS_METRIC_RMSE] - m.rmse_luminance) <= 1e-6 * m.rmse_luminance);
  assert_true(v.v[OBS_METRIC_SSIM] == m.ssim_luminance);
  double flip;
  assert_int_equal(obs_metrics_flip(&c, &r, "radiance", "alpha", 1, NULL, &flip, NULL), 0);
  assert_true(v.v[OBS_METRIC_FLIP] == flip);
  assert_int_equal(v.has[OBS_METRIC_ANGLE_DEG], 0);
  assert_int_equal(v.has[OBS_METRIC_SSIM_LUMINANCE], 1);
  /* same_as: equal where both apply (the RMSEs up to the float luminance plane's rounding). */
  const obs_metric *t = obs_metric_table();
  for (int i = 0; i < OBS_METRIC_COUNT; i++) {
    if (!t[i].same_as) continue;
    double other = v.v[obs_metric_find(t[i].same_as) - t];
    assert_true(fabs(v.v[i] - other) <= 1e-6 * fabs(other));
  }
  /* JSON: the RGB entries in "rgb", the per-channel RMSE as an array. */
  json_t *j = json_object();
  assert_int_equal(obs_metric_values_json(&v, j), 0);
  json_t *rgb = json_object_get(j, "rgb");
  assert_int_equal(json_array_size(json_object_get(rgb, "rmse")), 3);
  assert_true(json_real_value(json_array_get(json_object_get(rgb, "rmse"), 1)) == m.rmse[1]);
  assert_true(json_real_value(json_object_get(rgb, "rel_mse")) == m.rel_mse);
  assert_true(json_real_value(json_object_get(j, "flip")) == flip);
  assert_true(json_is_null(json_object_get(j, "angle_deg")) == 0); /* absent, not null */
  assert_null(json_object_get(j, "angle_deg"));
  assert_int_equal(json_integer_value(json_object_get(j, "pixels")), 10 * 16);
  json_decref(j);
  obs_image_free(&c);
  obs_image_free(&r);
}

/* Directions: 0, 90, 180 and 30 degrees by hand, lengths ignored, zero vectors left out. */
static void test_angle(void **state) {
  (void)state;
  const char *names[] = {"bent.X", "bent.Y", "bent.Z"};
  obs_image c, r;
  assert_int_equal(obs_image_init(&c, 5, 1, 3, names, NULL), 0);
  assert_int_equal(obs_image_init(&r, 5, 1, 3, names, NULL), 0);
  const float cv[5][3] = {{0, 0, 1}, {1, 0, 0}, {0, 0, -2}, {0.5f, 0, 0.8660254f}, {0, 0, 0}};
  const float rv[5][3] = {{0, 0, 3}, {0, 1, 0}, {0, 0, 1}, {0, 0, 1}, {0, 1, 0}};
  for (int i = 0; i < 5; i++)
    for (int k = 0; k < 3; k++) c.data[k * 5 + i] = cv[i][k], r.data[k * 5 + i] = rv[i][k];
  obs_metric_opts op = {.channel = "bent"};
  obs_metric_values v;
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, NULL), 0);
  assert_int_equal(v.pixels, 4);
  assert_true(fabs(v.v[OBS_METRIC_ANGLE_DEG] - (0 + 90 + 180 + 30) / 4.0) < 1e-5);
  assert_int_equal(v.has[OBS_METRIC_RMSE], 0);
  c.data[0] = NAN;
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, NULL), 0);
  assert_true(isnan(v.v[OBS_METRIC_ANGLE_DEG]));
  obs_err err = OBS_ERR_INIT;
  op.channel = "nothing";
  assert_int_equal(obs_metrics_compare_all(&c, &r, &op, &v, &err), OBS_ENOTFOUND);
  assert_non_null(strstr(obs_err_message(&err), "\"nothing\""));
  obs_err_free(&err);
  obs_image_free(&c);
  obs_image_free(&r);
}

/* The table as JSON carries every entry, open ends as null. */
static void test_table_json(void **state) {
  (void)state;
  json_t *a = obs_metric_table_json();
  assert_int_equal(json_array_size(a), OBS_METRIC_COUNT);
  json_t *psnr = json_array_get(a, OBS_METRIC_PSNR);
  assert_string_equal(json_string_value(json_object_get(psnr, "name")), "psnr");
  assert_string_equal(json_string_value(json_object_get(psnr, "direction")), "higher");
  assert_string_equal(json_string_value(json_object_get(psnr, "unit")), "dB");
  assert_true(json_is_null(json_object_get(psnr, "min")));
  assert_true(json_real_value(json_object_get(psnr, "max")) == 100.0);
  json_t *r = json_array_get(a, OBS_METRIC_RMSE_G);
  assert_string_equal(json_string_value(json_object_get(r, "json_group")), "rgb");
  assert_int_equal(json_integer_value(json_object_get(r, "json_index")), 1);
  json_decref(a);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_table_complete), cmocka_unit_test(test_scalar),
      cmocka_unit_test(test_rgb),            cmocka_unit_test(test_angle),
      cmocka_unit_test(test_table_json),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
