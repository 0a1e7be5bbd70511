/* Unit tests for obs_metrics: statistics, RMSE, SSIM, comparisons and error images, each against
 * hand-computed small images, and the Pareto set on a synthetic table. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

/* SSIM: identical images give 1; constant images reduce to the luminance term, computed by hand
 * (the mirrored borders keep them constant); noise lowers it; the mask picks the pixels. */
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
  /* Images smaller than the 11x11 window have no SSIM (skimage refuses them): NaN. */
  obs_image t1, t2;
  make_image(&t1, 10, 1, va, NULL);
  make_image(&t2, 10, 1, vb, NULL);
  assert_int_equal(obs_metrics_ssim(&t1, &t2, "v", NULL, &r, &err), 0);
  assert_true(isnan(r));
  assert_int_equal(obs_metrics_ssim(&t1, &a, "v", NULL, &r, &err), OBS_EINVAL);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_image_free(&n);
  obs_image_free(&nm);
  obs_image_free(&t1);
  obs_image_free(&t2);
  obs_err_free(&err);
}

/* A reference with channels "v", "alpha" and "v_stderr" (the noise channel obs_metrics_compare
 * looks for when comparing channel "v"). */
static void make_ref(obs_image *img, int w, int h, const float *v, const float *alpha,
                     const float *se) {
  const char *names[] = {"v", "alpha", "v_stderr"};
  assert_int_equal(obs_image_init(img, w, h, 3, names, NULL), 0);
  size_t n = (size_t)w * (size_t)h;
  memcpy(obs_image_channel(img, "v"), v, n * sizeof(float));
  float *a = obs_image_channel(img, "alpha");
  for (size_t i = 0; i < n; i++) a[i] = alpha ? alpha[i] : 1.0f;
  memcpy(obs_image_channel(img, "v_stderr"), se, n * sizeof(float));
}

static int near(double got, double want, double tol) {
  if (fabs(got - want) <= tol) return 1;
  fprintf(stderr, "got %.17g, want %.17g (tol %g)\n", got, want, tol);
  return 0;
}

/* d = candidate - reference = {+0.25, 0, -0.25, +0.5}: sum 0.5, sum d^2 0.375 over 4 pixels. */
static void test_compare_hand_computed(void **state) {
  (void)state;
  const float ref[] = {0.5f, 0.5f, 0.5f, 0.5f};
  const float cand[] = {0.75f, 0.5f, 0.25f, 1.0f};
  obs_image r, c;
  make_image(&r, 4, 1, ref, NULL);
  make_image(&c, 4, 1, cand, NULL);
  obs_err err = OBS_ERR_INIT;
  obs_compare m;
  memset(&m, 0x7f, sizeof m);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, &err), 0);
  assert_int_equal(m.pixels, 4);
  assert_true(near(m.rmse, sqrt(0.375 / 4), 1e-15));
  assert_true(m.bias == 0.125); /* candidate brighter on average: positive */
  assert_true(m.max_abs == 0.5);
  assert_true(near(m.psnr, 10.0 * log10(4 / 0.375), 1e-12)); /* 10.2803 dB */
  assert_true(near(m.psnr, 10.280287236002437, 1e-12));
  assert_true(m.ref_noise == 0.0); /* no v_stderr channel */
  assert_int_equal(m.at_reference_accuracy, 0);
  double ssim;
  assert_int_equal(obs_metrics_ssim(&c, &r, "v", NULL, &ssim, &err), 0);
  assert_true(isnan(m.ssim) && isnan(ssim)); /* 4x1: smaller than SSIM's window */

  /* Swapped roles: the bias changes sign, everything else is symmetric. */
  obs_compare s;
  assert_int_equal(obs_metrics_compare(&r, &c, "v", NULL, &s, &err), 0);
  assert_true(s.bias == -0.125);
  assert_true(s.rmse == m.rmse && s.max_abs == m.max_abs && s.psnr == m.psnr);
  /* A darker-everywhere candidate: bias is minus the (uniform) error, max_abs its size. */
  const float dark[] = {0.375f, 0.375f, 0.375f, 0.375f};
  obs_image d;
  make_image(&d, 4, 1, dark, NULL);
  assert_int_equal(obs_metrics_compare(&d, &r, "v", NULL, &s, &err), 0);
  assert_true(s.bias == -0.125 && s.max_abs == 0.125 && s.rmse == 0.125);
  assert_true(near(s.psnr, 10.0 * log10(64.0), 1e-12)); /* MSE 2^-6: 18.0618 dB */
  assert_int_equal(err.count, 0);
  obs_image_free(&d);
  obs_image_free(&r);
  obs_image_free(&c);
  obs_err_free(&err);
}

/* SSIM by hand on an 11x11 pair: after the 5-pixel border crop only the centre pixel counts, and
 * its window covers the image exactly (no mirroring), so the weighted moments are plain sums with
 * the Gaussian weights exp(-(x^2 + y^2) / 4.5) / sum. a is a checkerboard of 0 and 1, b = a/2 + a
 * ramp in x. */
static void test_compare_ssim_hand_computed(void **state) {
  (void)state;
  enum { N = 11 };
  float va[N * N], vb[N * N];
  double g[N * N], gs = 0;
  for (int y = 0; y < N; y++)
    for (int x = 0; x < N; x++) {
      va[y * N + x] = (float)((x + y) % 2);
      vb[y * N + x] = 0.5f * va[y * N + x] + 0.03125f * (float)x;
      gs += g[y * N + x] = exp(-((x - 5) * (x - 5) + (y - 5) * (y - 5)) / 4.5);
    }
  double ma = 0, mb = 0, saa = 0, sbb = 0, sab = 0;
  for (int i = 0; i < N * N; i++) {
    double w = g[i] / gs;
    ma += w * va[i], mb += w * vb[i];
    saa += w * va[i] * va[i], sbb += w * vb[i] * vb[i], sab += w * va[i] * vb[i];
  }
  double vaa = saa - ma * ma, vbb = sbb - mb * mb, cov = sab - ma * mb;
  obs_image a, b;
  make_image(&a, N, N, va, NULL);
  make_image(&b, N, N, vb, NULL);
  obs_compare m;
  assert_int_equal(obs_metrics_compare(&a, &b, "v", NULL, &m, NULL), 0);
  const double c1 = 1e-4, c2 = 9e-4;
  double want = (2 * ma * mb + c1) * (2 * cov + c2) / ((ma * ma + mb * mb + c1) * (vaa + vbb + c2));
  assert_true(near(m.ssim, want, 1e-12));
  assert_true(m.ssim > 0.5 && m.ssim < 1.0);
  obs_image_free(&a);
  obs_image_free(&b);
}

/* Only the reference's mask counts; the candidate's alpha is ignored. */
static void test_compare_masked(void **state) {
  (void)state;
  const float ref[] = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  const float cand[] = {0.625f, 0.0f, 0.25f, NAN, 1.0f, 0.5f};
  const float ref_alpha[] = {1.0f, 0.0f, 0.5f, 0.0f, -1.0f, NAN};
  const float cand_alpha[] = {0.0f, 1.0f, 0.0f, 1.0f, 1.0f, 1.0f};
  const float se[] = {0.5f, 9.0f, 0.25f, 9.0f, 9.0f, 9.0f};
  obs_image r, c;
  make_ref(&r, 6, 1, ref, ref_alpha, se);
  make_image(&c, 6, 1, cand, cand_alpha);
  obs_compare m;
  assert_int_equal(obs_metrics_compare(&c, &r, "v", "alpha", &m, NULL), 0);
  /* selected: pixels 0 and 2, d = {+0.125, -0.25} */
  assert_int_equal(m.pixels, 2);
  assert_true(m.bias == -0.0625);
  assert_true(m.max_abs == 0.25);
  assert_true(near(m.rmse, sqrt((0.015625 + 0.0625) / 2), 1e-15));
  assert_true(m.ref_noise == 0.375);            /* mean of 0.5 and 0.25; the 9s are masked out */
  assert_int_equal(m.at_reference_accuracy, 1); /* 0.1976 < 0.75 */
  double rm;
  assert_int_equal(obs_metrics_rmse(&c, &r, "v", "alpha", &rm, NULL), 0);
  assert_true(m.rmse == rm);

  /* Without the mask the NaN and the 9s count. */
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_int_equal(m.pixels, 6);
  assert_true(isnan(m.rmse) && isnan(m.bias) && isnan(m.max_abs) && isnan(m.psnr));
  assert_true(isnan(m.ssim));                   /* 6x1: smaller than SSIM's window */
  assert_int_equal(m.at_reference_accuracy, 0); /* NaN never passes */

  /* A mask selecting nothing: no error by convention, and pixels says so. */
  const float none[] = {0, 0, 0, 0, 0, 0};
  obs_image z;
  make_ref(&z, 6, 1, ref, none, se);
  assert_int_equal(obs_metrics_compare(&c, &z, "v", "alpha", &m, NULL), 0);
  assert_int_equal(m.pixels, 0);
  assert_true(m.rmse == 0.0 && m.bias == 0.0 && m.max_abs == 0.0);
  assert_true(m.psnr == OBS_METRICS_PSNR_MAX && isnan(m.ssim)); /* 6x1: no SSIM */
  assert_true(m.ref_noise == 0.0); /* obs_stats' empty-set mean */
  obs_image_free(&z);
  obs_image_free(&r);
  obs_image_free(&c);
}

/* PSNR = 10 log10(1/MSE), capped at OBS_METRICS_PSNR_MAX: identical images report the cap. */
static void test_compare_psnr_cap(void **state) {
  (void)state;
  const float ref[] = {0.5f, 0.25f, 1.0f, 0.0f};
  const float tiny[] = {0.5f + 0x1p-20f, 0.25f, 1.0f, 0.0f}; /* MSE 2^-42: 126.4 dB uncapped */
  const float tenth[] = {0.5f, 0.25f, 1.0f, 0.2f};           /* MSE 0.04/4 = 0.01: 20 dB */
  obs_image r, t, u;
  make_image(&r, 2, 2, ref, NULL);
  make_image(&t, 2, 2, tiny, NULL);
  make_image(&u, 2, 2, tenth, NULL);
  obs_compare m;
  assert_int_equal(obs_metrics_compare(&r, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.rmse == 0.0 && m.psnr == 100.0 && m.max_abs == 0.0 && m.bias == 0.0);
  assert_true(isnan(m.ssim)); /* 2x2: smaller than SSIM's window */
  assert_int_equal(obs_metrics_compare(&t, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.rmse > 0 && m.psnr == 100.0);
  assert_int_equal(obs_metrics_compare(&u, &r, "v", NULL, &m, NULL), 0);
  double mse = (double)0.2f * (double)0.2f / 4;
  assert_true(near(m.psnr, 10.0 * log10(1.0 / mse), 1e-12));
  assert_true(near(m.psnr, 20.0, 1e-6)); /* 0.2f is not exactly 0.2 */
  assert_true(near(m.psnr, -20.0 * log10(m.rmse), 1e-12));
  obs_image_free(&r);
  obs_image_free(&t);
  obs_image_free(&u);
}

/* at_reference_accuracy = rmse < 2 * ref_noise, strictly. */
static void test_compare_reference_accuracy(void **state) {
  (void)state;
  const float ref[] = {0.5f, 0.5f, 0.5f, 0.5f};
  const float cand[] = {0.75f, 0.25f, 0.75f, 0.25f};          /* rmse exactly 0.25 */
  const float se_edge[] = {0.125f, 0.125f, 0.0625f, 0.1875f}; /* mean 0.125: 2x = 0.25 */
  const float se_above[] = {0.125f, 0.125f, 0.125f, 0.1875f}; /* mean 0.140625 */
  const float se_nan[] = {NAN, 0.25f, 0.25f, INFINITY};       /* finite values: mean 0.25 */
  obs_image r, c;
  make_image(&c, 4, 1, cand, NULL);
  obs_compare m;
  make_ref(&r, 4, 1, ref, NULL, se_edge);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.rmse == 0.25 && m.ref_noise == 0.125);
  assert_int_equal(m.at_reference_accuracy, 0); /* 0.25 is not < 0.25 */
  obs_image_free(&r);
  make_ref(&r, 4, 1, ref, NULL, se_above);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.ref_noise == 0.140625);
  assert_int_equal(m.at_reference_accuracy, 1);
  obs_image_free(&r);
  make_ref(&r, 4, 1, ref, NULL, se_nan);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.ref_noise == 0.25);
  assert_int_equal(m.at_reference_accuracy, 1);
  /* Identical to a noisy reference: within its noise. */
  assert_int_equal(obs_metrics_compare(&r, &r, "v", NULL, &m, NULL), 0);
  assert_int_equal(m.at_reference_accuracy, 1);
  obs_image_free(&r);
  /* No noise channel: never flagged, even when identical. */
  make_image(&r, 4, 1, ref, NULL);
  assert_int_equal(obs_metrics_compare(&r, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.ref_noise == 0.0);
  assert_int_equal(m.at_reference_accuracy, 0);
  obs_image_free(&r);
  obs_image_free(&c);
}

static void test_compare_non_finite(void **state) {
  (void)state;
  const float ref[] = {0.5f, INFINITY, 0.5f, 0.5f};
  const float pos[] = {INFINITY, INFINITY, 0.5f, 0.25f}; /* +Inf difference; equal infinities */
  const float both[] = {INFINITY, INFINITY, -INFINITY, 0.5f};
  const float same[] = {0.5f, INFINITY, 0.5f, 0.75f};
  obs_image r, c;
  make_image(&r, 4, 1, ref, NULL);
  obs_compare m;
  make_image(&c, 4, 1, pos, NULL);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(isinf(m.rmse) && m.rmse > 0);
  assert_true(isinf(m.max_abs) && m.max_abs > 0);
  assert_true(isinf(m.bias) && m.bias > 0);
  assert_true(isinf(m.psnr) && m.psnr < 0);
  assert_int_equal(m.at_reference_accuracy, 0);
  obs_image_free(&c);
  make_image(&c, 4, 1, both, NULL);
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(isinf(m.rmse) && isnan(m.bias));
  obs_image_free(&c);
  make_image(&c, 4, 1, same, NULL); /* the shared infinity is no error */
  assert_int_equal(obs_metrics_compare(&c, &r, "v", NULL, &m, NULL), 0);
  assert_true(m.rmse == 0.125 && m.bias == 0.0625 && m.max_abs == 0.25);
  obs_image_free(&c);
  obs_image_free(&r);
}

/* Same pass as obs_metrics_rmse and the same SSIM, to the bit, on a larger noisy masked image. */
static void test_compare_matches_rmse_ssim(void **state) {
  (void)state;
  enum { W = 37, H = 29 };
  float va[W * H], vb[W * H], mask[W * H];
  uint32_t s = 777;
  for (int i = 0; i < W * H; i++) {
    s = s * 1664525u + 1013904223u;
    va[i] = (float)(s >> 8) / 16777216.0f;
    s = s * 1664525u + 1013904223u;
    vb[i] = va[i] * 0.9f + 0.1f * (float)(s >> 8) / 16777216.0f;
    mask[i] = (i % W) * (i / W) % 3 ? 1.0f : 0.0f;
  }
  obs_image a, b;
  make_image(&a, W, H, va, NULL);
  make_image(&b, W, H, vb, mask);
  obs_compare m;
  double rmse, ssim;
  assert_int_equal(obs_metrics_compare(&a, &b, "v", "alpha", &m, NULL), 0);
  assert_int_equal(obs_metrics_rmse(&a, &b, "v", "alpha", &rmse, NULL), 0);
  assert_int_equal(obs_metrics_ssim(&a, &b, "v", "alpha", &ssim, NULL), 0);
  assert_true(m.rmse == rmse && m.ssim == ssim);
  assert_true(m.rmse > 0.01 && m.ssim < 1.0 && m.ssim > 0.5);
  assert_true(m.max_abs >= m.rmse && fabs(m.bias) <= m.rmse);
  obs_image_free(&a);
  obs_image_free(&b);
}

static void test_compare_errors(void **state) {
  (void)state;
  const float v6[] = {0, 1, 2, 3, 4, 5};
  obs_image a, b, c;
  make_image(&a, 2, 2, v6, NULL);
  make_image(&b, 3, 2, v6, NULL);
  const char *other[] = {"ao"};
  assert_int_equal(obs_image_init(&c, 2, 2, 1, other, NULL), 0);
  obs_err err = OBS_ERR_INIT;
  obs_compare m;
  obs_image e;
  assert_int_equal(obs_metrics_compare(&a, &b, "v", NULL, &m, &err), OBS_EINVAL);
  assert_msg_has(&err, "2x2");
  assert_msg_has(&err, "3x2");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_compare(&c, &a, "v", NULL, &m, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "candidate");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_compare(&a, &c, "v", NULL, &m, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "reference");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_compare(&a, &a, "v", "coverage", &m, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "coverage");
  obs_err_clear(&err);
  assert_int_equal(obs_metrics_compare(&a, &a, "v", NULL, NULL, &err), OBS_EINVAL);
  assert_int_equal(obs_metrics_compare(&a, NULL, "v", NULL, &m, &err), OBS_EINVAL);
  obs_err_clear(&err);
  memset(&e, 0x55, sizeof e);
  assert_int_equal(obs_metrics_error_image(&a, &b, "v", NULL, &e, &err), OBS_EINVAL);
  assert_true(e.data == NULL); /* zeroed on failure: obs_image_free is safe */
  obs_image_free(&e);
  assert_int_equal(obs_metrics_error_image(&a, &c, "v", NULL, &e, &err), OBS_ENOTFOUND);
  assert_int_equal(obs_metrics_error_image(&a, &a, "v", "coverage", &e, &err), OBS_ENOTFOUND);
  assert_int_equal(obs_metrics_error_image(&a, &a, NULL, NULL, &e, &err), OBS_EINVAL);
  obs_err_clear(&err);
  /* Writing needs an error image's channels. */
  assert_int_equal(obs_metrics_write_error_files(&a, obs_test_tmpdir("metrics-bad"), &err),
                   OBS_ENOTFOUND);
  assert_msg_has(&err, "\"error\"");
  assert_int_equal(obs_metrics_write_error_files(&a, "", &err), OBS_EINVAL);
  obs_image_free(&c);
  obs_image_free(&a);
  obs_image_free(&b);
  obs_err_free(&err);
}

static void assert_rgb(const obs_image *img, int i, double r, double g, double b, double tol) {
  const float *R = obs_image_channel(img, "R"), *G = obs_image_channel(img, "G"),
              *B = obs_image_channel(img, "B");
  if (fabs(R[i] - r) > tol || fabs(G[i] - g) > tol || fabs(B[i] - b) > tol) {
    fprintf(stderr, "pixel %d: (%g, %g, %g), want (%g, %g, %g)\n", i, R[i], G[i], B[i], r, g, b);
    fail();
  }
}

/* Error image: signed values inside the mask, 0 outside; colours at -scale, 0, +scale, halfway,
 * clamped beyond, grey outside the mask, green for NaN; then the files on disk. */
static void test_error_image(void **state) {
  (void)state;
  const float ref[] = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  const float cand[] = {0.25f, 0.5f, 0.75f, 0.375f, 0.625f, 0.0f, 0.9f, NAN};
  const float alpha[] = {1, 1, 1, 1, 1, 1, 0, 1};
  obs_image r, c, e;
  make_image(&r, 4, 2, ref, alpha);
  make_image(&c, 4, 2, cand, NULL);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_error_image(&c, &r, "v", "alpha", &e, &err), 0);
  assert_int_equal(e.width, 4);
  assert_int_equal(e.height, 2);
  assert_int_equal(e.nchannels, 4);
  const float *ev = obs_image_channel(&e, "error");
  const float want[] = {-0.25f, 0.0f, 0.25f, -0.125f, 0.125f, -0.5f, 0.0f};
  for (int i = 0; i < 7; i++) assert_true(ev[i] == want[i]);
  assert_true(isnan(ev[7]));
  const double tol = 1e-6;
  const double br = 0x21 / 255.0, bg = 0x66 / 255.0, bb = 0xAC / 255.0; /* #2166AC */
  const double rr = 0xB2 / 255.0, rg = 0x18 / 255.0, rb = 0x2B / 255.0; /* #B2182B */
  assert_rgb(&e, 0, br, bg, bb, tol);                                   /* -scale: full blue */
  assert_rgb(&e, 1, 1, 1, 1, tol);                                      /* 0: white */
  assert_rgb(&e, 2, rr, rg, rb, tol);                                   /* +scale: full red */
  assert_rgb(&e, 3, (1 + br) / 2, (1 + bg) / 2, (1 + bb) / 2, tol);     /* -scale/2 */
  assert_rgb(&e, 4, (1 + rr) / 2, (1 + rg) / 2, (1 + rb) / 2, tol);     /* +scale/2 */
  assert_rgb(&e, 5, br, bg, bb, tol);    /* -2 scale clamps to blue */
  assert_rgb(&e, 6, 0.5, 0.5, 0.5, tol); /* outside the mask: grey */
  assert_rgb(&e, 7, 0, 1, 0, tol);       /* NaN: green */

  /* Files: a nested directory that does not exist yet. */
  char dir[1200], path[1300];
  snprintf(dir, sizeof dir, "%s/a/b", obs_test_tmpdir("metrics-err"));
  assert_int_equal(obs_metrics_write_error_files(&e, dir, &err), 0);
  obs_image x;
  snprintf(path, sizeof path, "%s/error.exr", dir);
  assert_int_equal(obs_image_read_exr(&x, path, &err), 0);
  assert_int_equal(x.nchannels, 1);
  assert_string_equal(x.names[0], "error");
  for (int i = 0; i < 7; i++) assert_true(x.data[i] == want[i]);
  assert_true(isnan(x.data[7]));
  obs_image_free(&x);
  snprintf(path, sizeof path, "%s/error.png", dir);
  assert_int_equal(obs_image_read_png(&x, path, &err), 0);
  assert_int_equal(x.nchannels, 3);
  const double q = 0.5 / 255 + 1e-6;   /* 8-bit rounding */
  assert_rgb(&x, 0, br, bg, bb, 1e-6); /* the ramp ends are exact 8-bit values */
  assert_rgb(&x, 1, 1, 1, 1, 1e-6);
  assert_rgb(&x, 2, rr, rg, rb, 1e-6);
  assert_rgb(&x, 3, (1 + br) / 2, (1 + bg) / 2, (1 + bb) / 2, q);
  assert_rgb(&x, 6, 128 / 255.0, 128 / 255.0, 128 / 255.0, 1e-6);
  assert_rgb(&x, 7, 0, 1, 0, 1e-6);
  obs_image_free(&x);
  snprintf(path, sizeof path, "%s/.error.exr.new", dir);
  assert_int_equal(access(path, F_OK), -1); /* no staging file left behind */
  snprintf(path, sizeof path, "%s/.error.png.new", dir);
  assert_int_equal(access(path, F_OK), -1);

  /* A directory that cannot be created (a file is in the way) fails with a message. */
  snprintf(path, sizeof path, "%s/error.png/sub", dir);
  assert_int_equal(obs_metrics_write_error_files(&e, path, &err), OBS_EIO);
  assert_msg_has(&err, "error.png");

  /* Unmasked: the grey pixel gets its real (red, clamped) colour. */
  obs_image u;
  assert_int_equal(obs_metrics_error_image(&c, &r, "v", NULL, &u, &err), 0);
  assert_true(obs_image_channel(&u, "error")[6] == 0.9f - 0.5f);
  assert_rgb(&u, 6, rr, rg, rb, tol);
  obs_image_free(&u);
  obs_image_free(&e);
  obs_image_free(&r);
  obs_image_free(&c);
  obs_err_free(&err);
}

/* Pareto set on a synthetic table: dominated points, exact ties, NaN time or error (no part),
 * +Inf error, and the at-reference-accuracy group (equal accuracy: only its fastest counts). */
static void test_pareto(void **state) {
  (void)state;
  const obs_pareto_point p[] = {
      {10.0, 0.50, 0, 0, 0, 0}, /* 0: fastest: optimal */
      {20.0, 0.30, 0, 0, 0, 0}, /* 1: optimal */
      {20.0, 0.30, 0, 0, 0, 0}, /* 2: exact tie with 1: optimal too */
      {25.0, 0.40, 0, 0, 0, 0}, /* 3: dominated by 1 */
      {30.0, 0.30, 0, 0, 0, 0}, /* 4: same error as 1, slower: dominated */
      {40.0, 0.10, 1, 0, 0, 0}, /* 5: at reference accuracy, fastest of them: optimal */
      {50.0, 0.01, 1, 0, 0, 0}, /* 6: at reference accuracy too: its lower RMSE is noise, dominated */
      {NAN, 0.001, 0, 0, 0, 0}, /* 7: no time: takes no part */
      {5.0, NAN, 0, 0, 0, 0},   /* 8: no error: takes no part (does not dominate 0) */
      {35.0, 0.2, 0, 0, 0, 0},  /* 9: optimal (between 1 and 5) */
      {9.0, INFINITY, 0, 0, 0, 0}, /* 10: fastest but worst: optimal */
      {45.0, 0.05, 0, 0, 0, 0}, /* 11: more accurate than 5 by RMSE but not at reference accuracy: dominated */
  };
  const size_t n = sizeof p / sizeof p[0];
  unsigned char opt[sizeof p / sizeof p[0]];
  const unsigned char want[] = {1, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0};
  assert_int_equal(obs_metrics_pareto(p, n, opt, NULL), 6);
  for (size_t i = 0; i < n; i++) {
    if (opt[i] != want[i]) fprintf(stderr, "point %zu: optimal %d, want %d\n", i, opt[i], want[i]);
    assert_int_equal(opt[i], want[i]);
  }
  /* Two at-reference points with the same time are both optimal (an exact tie). */
  const obs_pareto_point q[] = {{3.0, 0.2, 1, 0, 0, 0}, {3.0, 0.1, 1, 0, 0, 0}, {1.0, 0.9, 0, 0, 0, 0}};
  unsigned char o2[3];
  assert_int_equal(obs_metrics_pareto(q, 3, o2, NULL), 3);
  /* Margins. hbao on the CPU 2.7x faster than on Vulkan, RMSEs 2e-9 apart against a reference
   * noise of 0.004: Vulkan's lower RMSE is noise, the CPU is faster beyond both spreads, so only
   * the CPU is optimal (exactly, Vulkan's lower RMSE would have kept it). */
  const obs_pareto_point h[] = {
      {27.0, 0.080000000, 0, 25.0, 30.0, 0.004}, /* 0: hbao/vulkan */
      {10.0, 0.080000002, 0, 9.0, 11.0, 0.004},  /* 1: hbao/cpu */
  };
  unsigned char oh[2];
  assert_int_equal(obs_metrics_pareto(h, 2, oh, NULL), 1);
  assert_int_equal(oh[0], 0);
  assert_int_equal(oh[1], 1);
  const obs_pareto_point hx[] = {{27.0, 0.080000000, 0, 0, 0, 0}, {10.0, 0.080000002, 0, 0, 0, 0}};
  assert_int_equal(obs_metrics_pareto(hx, 2, oh, NULL), 2);
  /* Overlapping spreads: neither is faster, and equal within the noise: both optimal. A clearly
   * lower error (beyond the noise) still dominates within overlapping spreads. */
  const obs_pareto_point ov[] = {
      {10.0, 0.050, 0, 8.0, 12.0, 0.004},  /* 0: optimal */
      {11.0, 0.052, 0, 9.0, 13.0, 0.004},  /* 1: slower by median, within spread: optimal */
      {10.5, 0.090, 0, 9.5, 11.5, 0.004},  /* 2: less accurate beyond the noise: dominated */
      {30.0, 0.010, 0, 29.0, 31.0, 0.004}, /* 3: slower but more accurate: optimal */
      {31.0, 0.012, 0, 30.5, 40.0, 0.0},   /* 4: ties 3 on time, within 3's noise: optimal */
  };
  unsigned char oo[5];
  const unsigned char want_ov[] = {1, 1, 0, 1, 1};
  assert_int_equal(obs_metrics_pareto(ov, 5, oo, NULL), 4);
  for (size_t i = 0; i < 5; i++) assert_int_equal(oo[i], want_ov[i]);
  /* At reference accuracy: the faster one wins only beyond the spreads. */
  const obs_pareto_point ar[] = {{40.0, 0.01, 1, 35.0, 45.0, 0.01}, {42.0, 0.005, 1, 41.0, 43.0, 0.01},
                                 {60.0, 0.004, 1, 58.0, 62.0, 0.01}};
  unsigned char oa[3];
  const unsigned char want_ar[] = {1, 1, 0};
  assert_int_equal(obs_metrics_pareto(ar, 3, oa, NULL), 2);
  for (size_t i = 0; i < 3; i++) assert_int_equal(oa[i], want_ar[i]);
  /* Empty input, and bad arguments. */
  assert_int_equal(obs_metrics_pareto(NULL, 0, NULL, NULL), 0);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_pareto(NULL, 2, o2, &err), OBS_EINVAL);
  assert_msg_has(&err, "pareto");
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
      cmocka_unit_test(test_compare_hand_computed),
      cmocka_unit_test(test_compare_ssim_hand_computed),
      cmocka_unit_test(test_compare_masked),
      cmocka_unit_test(test_compare_psnr_cap),
      cmocka_unit_test(test_compare_reference_accuracy),
      cmocka_unit_test(test_compare_non_finite),
      cmocka_unit_test(test_compare_matches_rmse_ssim),
      cmocka_unit_test(test_compare_errors),
      cmocka_unit_test(test_error_image),
      cmocka_unit_test(test_pareto),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
