/* Unit tests for FLIP (obs_metrics_flip): the paper's properties (identical images give 0, values
 * in [0, 1], LDR-FLIP symmetric, the error confined to the filters' reach, HDR-FLIP's exposures
 * following the reference so a common scale changes nothing), uniform colour differences against
 * the colour pipeline derived by hand, masks, non-finite values, bad input and the map's files. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/metrics.h"

static int near(double got, double want, double tol) {
  if (fabs(got - want) <= tol) return 1;
  fprintf(stderr, "got %.17g, want %.17g (tol %g)\n", got, want, tol);
  return 0;
}

/* A w x h image with channel "ao" = f(x, y) and "alpha" = 1. */
static void grey(obs_image *img, int w, int h, double (*f)(int, int, void *), void *ctx) {
  const char *names[] = {"ao", "alpha"};
  assert_int_equal(obs_image_init(img, w, h, 2, names, NULL), 0);
  float *v = obs_image_channel(img, "ao"), *a = obs_image_channel(img, "alpha");
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      v[y * w + x] = (float)f(x, y, ctx);
      a[y * w + x] = 1.0f;
    }
}

static double constant(int x, int y, void *ctx) {
  (void)x, (void)y;
  return *(const double *)ctx;
}

static double noise(int x, int y, void *ctx) {
  uint32_t s = (uint32_t)(x * 7919 + y * 104729) ^ *(const uint32_t *)ctx;
  s = s ? s : 1;
  for (int i = 0; i < 3; i++) obs_test_rand(&s);
  return 0.2 + 0.6 * obs_test_unit(&s);
}

/* ---- the colour pipeline by hand (IEC 61966-2-1 sRGB, CIE L*a*b*, D65) ----------------------- */

static double lin(double v) { return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4); }
static double f_lab(double t) {
  return t > pow(6.0 / 29, 3) ? cbrt(t) : t / (3 * pow(6.0 / 29, 2)) + 4.0 / 29;
}
/* Hunt-adjusted L*a*b* of linear sRGB (r, g, b). */
static void hunt_lab(double r, double g, double b, double o[3]) {
  double X = 0.4124 * r + 0.3576 * g + 0.1805 * b, Y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
  double Z = 0.0193 * r + 0.1192 * g + 0.9505 * b;
  double fx = f_lab(X / 0.95047), fy = f_lab(Y), fz = f_lab(Z / 1.08883);
  o[0] = 116 * fy - 16;
  o[1] = 0.01 * o[0] * 500 * (fx - fy);
  o[2] = 0.01 * o[0] * 200 * (fy - fz);
}
/* LDR-FLIP of two uniform greys (display values): no features, the CSFs leave a uniform image
 * as it is, so the error is the redistributed HyAB distance |L*1 - L*2|^0.7. */
static double uniform_grey_flip(double v1, double v2) {
  double g[3], b[3];
  hunt_lab(0, 1, 0, g);
  hunt_lab(0, 0, 1, b);
  double cmax = pow(fabs(g[0] - b[0]) + hypot(g[1] - b[1], g[2] - b[2]), 0.7);
  double l1 = 116 * f_lab(lin(v1)) - 16, l2 = 116 * f_lab(lin(v2)) - 16;
  double e = pow(fabs(l1 - l2), 0.7);
  return e < 0.4 * cmax ? 0.95 / (0.4 * cmax) * e : 0.95 + (e - 0.4 * cmax) / (0.6 * cmax) * 0.05;
}

static void flip_map(const obs_image *t, const obs_image *r, const char *ch, const char *mask,
                     int hdr, obs_image *map, double *mean) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_metrics_flip(t, r, ch, mask, hdr, map, mean, &err);
  if (rc) fprintf(stderr, "flip: %s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

static void test_identical_and_range(void **state) {
  (void)state;
  uint32_t s1 = 11, s2 = 977;
  obs_image a, b, map;
  grey(&a, 40, 30, noise, &s1);
  grey(&b, 40, 30, noise, &s2);
  double mean;
  flip_map(&a, &a, "ao", NULL, 0, &map, &mean);
  assert_true(mean == 0.0);
  for (int i = 0; i < 40 * 30; i++) assert_true(map.data[i] == 0.0f);
  obs_image_free(&map);
  flip_map(&a, &b, "ao", NULL, 0, &map, &mean);
  double s = 0;
  for (int i = 0; i < 40 * 30; i++) {
    assert_true(map.data[i] >= 0.0f && map.data[i] <= 1.0f);
    s += map.data[i];
  }
  assert_true(near(mean, s / (40 * 30), 1e-6));
  assert_true(mean > 0.05 && mean < 1.0);
  /* LDR-FLIP is symmetric (HyAB and the feature differences are), to the bit. */
  obs_image swapped;
  double mean2;
  flip_map(&b, &a, "ao", NULL, 0, &swapped, &mean2);
  assert_memory_equal(map.data, swapped.data, 40 * 30 * sizeof(float));
  obs_image_free(&swapped);
  obs_image_free(&map);
  obs_image_free(&a);
  obs_image_free(&b);
}

/* Uniform greys: black against white (the largest grey difference: 100 L*, 0.968 not 1, since
 * only colour differences beyond the green-blue one reach 1), a large and a small difference
 * (either side of pc cmax), each pixel equal to the hand derivation. */
static void test_uniform_by_hand(void **state) {
  (void)state;
  const double pairs[][2] = {{0.0, 1.0}, {0.25, 0.75}, {0.5, 0.52}, {0.9, 0.1}};
  for (size_t k = 0; k < sizeof pairs / sizeof *pairs; k++) {
    obs_image a, b, map;
    grey(&a, 24, 20, constant, (void *)&pairs[k][0]);
    grey(&b, 24, 20, constant, (void *)&pairs[k][1]);
    double mean, want = uniform_grey_flip(pairs[k][0], pairs[k][1]);
    flip_map(&a, &b, "ao", NULL, 0, &map, &mean);
    for (int i = 0; i < 24 * 20; i++) assert_true(near(map.data[i], want, 2e-4));
    assert_true(near(mean, want, 2e-4));
    if (k == 0) assert_true(near(mean, 0.9676, 1e-3));
    obs_image_free(&a);
    obs_image_free(&b);
    obs_image_free(&map);
  }
}

/* A scalar display value enters as the grey sRGB colour (v, v, v): the same error as an RGB image
 * whose linear channels are the sRGB decoding of v. */
static void test_scalar_is_grey_srgb(void **state) {
  (void)state;
  uint32_t s1 = 5, s2 = 6;
  obs_image a, b;
  grey(&a, 30, 22, noise, &s1);
  grey(&b, 30, 22, noise, &s2);
  const char *names[] = {"c.R", "c.G", "c.B"};
  obs_image ra, rb;
  assert_int_equal(obs_image_init(&ra, 30, 22, 3, names, NULL), 0);
  assert_int_equal(obs_image_init(&rb, 30, 22, 3, names, NULL), 0);
  for (int k = 0; k < 3; k++)
    for (int i = 0; i < 30 * 22; i++) {
      ra.data[k * 30 * 22 + i] = (float)lin(a.data[i]);
      rb.data[k * 30 * 22 + i] = (float)lin(b.data[i]);
    }
  double m1, m2;
  flip_map(&a, &b, "ao", NULL, 0, NULL, &m1);
  flip_map(&ra, &rb, "c", NULL, 0, NULL, &m2);
  assert_true(near(m1, m2, 1e-5));
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&ra);
  obs_image_free(&rb);
}

/* One brighter pixel on a uniform grey: the error is largest there and exactly 0 beyond the
 * filters' reach (the colour CSFs' 10-pixel radius at 67 ppd, the feature detectors' 9). */
static void test_error_support(void **state) {
  (void)state;
  double g = 0.5;
  obs_image a, b, map;
  grey(&a, 41, 41, constant, &g);
  grey(&b, 41, 41, constant, &g);
  b.data[20 * 41 + 20] = 0.9f;
  double mean;
  flip_map(&a, &b, "ao", NULL, 0, &map, &mean);
  float peak = map.data[20 * 41 + 20];
  assert_true(peak > 0.1f);
  for (int y = 0; y < 41; y++)
    for (int x = 0; x < 41; x++) {
      float e = map.data[y * 41 + x];
      assert_true(e <= peak);
      if (abs(x - 20) > 10 || abs(y - 20) > 10) assert_true(e == 0.0f);
    }
  assert_true(map.data[20 * 41 + 25] > 0.0f);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&map);
}

/* The mask chooses the pixels averaged; the map covers every pixel. A NaN makes its pixel NaN
 * (and the mean, when selected). */
static void test_mask_and_nan(void **state) {
  (void)state;
  uint32_t s1 = 21, s2 = 22;
  obs_image a, b, map;
  grey(&a, 32, 24, noise, &s1);
  grey(&b, 32, 24, noise, &s2);
  float *alpha = obs_image_channel(&b, "alpha");
  for (int i = 0; i < 32 * 24; i++) alpha[i] = (i % 32) < 12 ? 1.0f : 0.0f;
  double mean;
  flip_map(&a, &b, "ao", "alpha", 0, &map, &mean);
  double s = 0;
  int n = 0;
  for (int i = 0; i < 32 * 24; i++)
    if (alpha[i] > 0) s += map.data[i], n++;
  assert_true(near(mean, s / n, 1e-6));
  obs_image_free(&map);
  a.data[5 * 32 + 20] = NAN; /* unselected column */
  flip_map(&a, &b, "ao", "alpha", 0, &map, &mean);
  assert_true(isnan(map.data[5 * 32 + 20]) && isfinite(mean));
  obs_image_free(&map);
  a.data[5 * 32 + 3] = NAN; /* selected */
  flip_map(&a, &b, "ao", "alpha", 0, NULL, &mean);
  assert_true(isnan(mean));
  obs_image_free(&a);
  obs_image_free(&b);
}

static void rgb_image(obs_image *img, int w, int h, uint32_t seed, double scale) {
  const char *names[] = {"radiance.R", "radiance.G", "radiance.B"};
  assert_int_equal(obs_image_init(img, w, h, 3, names, NULL), 0);
  uint32_t s = seed;
  for (int i = 0; i < 3 * w * h; i++) {
    int x = (i % (w * h)) % w;
    /* a gradient over 6 stops with noise: radiance-like */
    img->data[i] = (float)(scale * exp2(6.0 * x / w - 3) * (0.8 + 0.4 * obs_test_unit(&s)));
  }
}

/* HDR-FLIP: identical images 0, values in [0, 1]; the exposures follow the reference's maximum
 * and median, so scaling both images by 2^3 leaves every pixel's error as it was. */
static void test_hdr(void **state) {
  (void)state;
  obs_image a, b, a8, b8, map, map8;
  rgb_image(&a, 36, 20, 3, 1.0);
  rgb_image(&b, 36, 20, 4, 1.0);
  rgb_image(&a8, 36, 20, 3, 8.0);
  rgb_image(&b8, 36, 20, 4, 8.0);
  double mean, mean8;
  flip_map(&a, &a, "radiance", NULL, 1, &map, &mean);
  assert_true(mean == 0.0);
  obs_image_free(&map);
  flip_map(&a, &b, "radiance", NULL, 1, &map, &mean);
  flip_map(&a8, &b8, "radiance", NULL, 1, &map8, &mean8);
  assert_true(mean > 0.01 && mean < 1.0);
  for (int i = 0; i < 36 * 20; i++) {
    assert_true(map.data[i] >= 0.0f && map.data[i] <= 1.0f);
    assert_true(near(map.data[i], map8.data[i], 1e-4));
  }
  /* The maximum over exposures is at least the error at any single one: HDR-FLIP >= LDR-FLIP of
   * the values as they are wherever those lie in [0, 1] (exposure 0 lies in the range here). */
  double ldr;
  flip_map(&a, &b, "radiance", NULL, 0, NULL, &ldr);
  assert_true(mean > 0.5 * ldr);
  obs_image_free(&map);
  obs_image_free(&map8);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&a8);
  obs_image_free(&b8);
}

static void test_bad_input(void **state) {
  (void)state;
  double g = 0.5, mean;
  obs_image a, small, rgb;
  grey(&a, 16, 16, constant, &g);
  grey(&small, 15, 16, constant, &g);
  rgb_image(&rgb, 16, 16, 1, 1.0);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_flip(&a, &small, "ao", NULL, 0, NULL, &mean, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "sizes differ"));
  obs_err_free(&err);
  assert_int_equal(obs_metrics_flip(&a, &a, "nope", NULL, 0, NULL, &mean, &err), OBS_ENOTFOUND);
  assert_non_null(strstr(obs_err_message(&err), "\"nope\""));
  obs_err_free(&err);
  assert_int_equal(obs_metrics_flip(&a, &a, "ao", NULL, 1, NULL, &mean, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "HDR-FLIP needs an RGB output"));
  obs_err_free(&err);
  assert_int_equal(obs_metrics_flip(&a, &a, "ao", "mask", 0, NULL, &mean, &err), OBS_ENOTFOUND);
  obs_err_free(&err);
  assert_int_equal(obs_metrics_flip_ppd(&a, &a, "ao", NULL, 0, 0.0, NULL, &mean, &err),
                   OBS_EINVAL);
  obs_err_free(&err);
  assert_int_equal(obs_metrics_flip(&rgb, &a, "radiance", NULL, 1, NULL, &mean, &err),
                   OBS_ENOTFOUND);
  obs_err_free(&err);
  obs_image_free(&a);
  obs_image_free(&small);
  obs_image_free(&rgb);
}

/* flip.exr holds the map; flip.png is the magma ramp: black-purple at 0, light yellow at 1. */
static void test_files(void **state) {
  (void)state;
  double lo = 0.0, hi = 1.0, mean;
  obs_image a, b, map, back, png;
  grey(&a, 24, 20, constant, &lo);
  grey(&b, 24, 20, constant, &hi);
  flip_map(&a, &b, "ao", NULL, 0, &map, &mean);
  map.data[0] = 0.0f; /* one pixel at each end of the ramp */
  map.data[1] = 1.0f;
  const char *dir = obs_test_tmpdir("flip_files");
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_write_flip_files(&map, dir, &err), 0);
  assert_int_equal(obs_image_read_exr(&back, obs_test_path(dir, "flip.exr"), &err), 0);
  assert_int_equal(back.nchannels, 1);
  assert_memory_equal(obs_image_channel(&back, "flip"), map.data, 24 * 20 * sizeof(float));
  assert_int_equal(obs_image_read_png(&png, obs_test_path(dir, "flip.png"), &err), 0);
  const float *r = obs_image_channel(&png, "R"), *g = obs_image_channel(&png, "G"),
              *bl = obs_image_channel(&png, "B");
  assert_true(r[0] < 0.01f && g[0] < 0.01f && bl[0] < 0.03f);
  assert_true(r[1] > 0.98f && g[1] > 0.98f && bl[1] > 0.74f && bl[1] < 0.76f);
  assert_true(r[2] > 0.9f && g[2] > 0.6f && g[2] < 0.98f); /* 0.968: orange-yellow */
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&map);
  obs_image_free(&back);
  obs_image_free(&png);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_identical_and_range), cmocka_unit_test(test_uniform_by_hand),
      cmocka_unit_test(test_scalar_is_grey_srgb), cmocka_unit_test(test_error_support),
      cmocka_unit_test(test_mask_and_nan),        cmocka_unit_test(test_hdr),
      cmocka_unit_test(test_bad_input),           cmocka_unit_test(test_files),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
