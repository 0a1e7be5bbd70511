/* obscurance against closed forms (open plane, two parallel plates), rt_ao and path_trace within
 * noise, its convergence rate, determinism, and the extremes of its range. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

static const char *const rgb[3] = {"R", "G", "B"};

static const float *chan(const obs_result *r, const char *out, int k) {
  char name[64];
  snprintf(name, sizeof name, "%s.%s", out, rgb[k]);
  const float *p = obs_image_channel(&r->image, name);
  assert_non_null(p);
  return p;
}

/* Every channel finite, the radiances and W non-negative. */
static void assert_sane(const obs_result *r) {
  obs_test_assert_finite(&r->image);
  static const char *const outs[] = {"final", "obscurance", "indirect", "direct",
                                     "constant_ambient", "final_stderr", "obscurance_stderr"};
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  for (size_t o = 0; o < sizeof outs / sizeof outs[0]; o++)
    for (int k = 0; k < 3; k++) {
      const float *v = chan(r, outs[o], k);
      for (size_t i = 0; i < n; i++) assert_true(v[i] >= 0.0f);
    }
}

/* A plane of reflectivity `refl` seen from above, `params` for the technique. */
static const char *open_plane(const char *refl, const char *params_in) {
  char params[512]; /* params_in may be obs_test_fmt's buffer, which the call below overwrites */
  snprintf(params, sizeof params, "%s", params_in);
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":16,\"height\":12},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,0,-100],[-100,0,100],"
      "[100,0,100],[100,0,-100]]},\"material\":{\"reflectivity\":%s}}],"
      "\"technique\":{\"name\":\"obscurance\",\"params\":%s}}",
      refl, params);
}

/* Nothing within d_max: W = 1 without bleeding, R_ave with it, exactly; the indirect term is
 * then R(P) times the ambient given. */
static void test_open_plane(void **state) {
  (void)state;
  const double refl[3] = {0.2, 0.5, 0.8}, amb[3] = {0.5, 1, 2};
  for (int bleed = 0; bleed < 2; bleed++) {
    obs_result r;
    obs_test_render(open_plane("[0.2,0.5,0.8]",
                               obs_test_fmt("{\"samples\":32,\"d_max\":5,\"ambient\":[0.5,1,2],"
                                            "\"color_bleeding\":%s}",
                                            bleed ? "true" : "false")),
                    2, &r);
    assert_sane(&r);
    const float *al = obs_image_channel(&r.image, "alpha");
    size_t n = (size_t)r.image.width * (size_t)r.image.height, covered = 0;
    for (size_t i = 0; i < n; i++) {
      if (al[i] == 0.0f) continue;
      covered++;
      for (int k = 0; k < 3; k++) {
        assert_true(chan(&r, "obscurance", k)[i] == (bleed ? (float)refl[k] : 1.0f));
        assert_true(fabs(chan(&r, "indirect", k)[i] - refl[k] * amb[k]) < 1e-6);
        /* No emitter: the final image is the indirect term, the constant ambient the same. */
        assert_true(chan(&r, "direct", k)[i] == 0.0f);
        assert_true(fabs(chan(&r, "constant_ambient", k)[i] - refl[k] * amb[k]) < 1e-6);
      }
    }
    assert_true(covered > n / 3);
    obs_result_free(&r);
  }
}

/* Under a sky and without `ambient`, I_A is the sky's radiance: an open point receives
 * R(P) L_sky per channel, with bleeding too (I_A = L_sky / R_ave there, W = R_ave). */
static void test_sky_ambient(void **state) {
  (void)state;
  const double refl[3] = {0.2, 0.5, 0.8}, sky[3] = {0.3, 0.6, 0.9};
  for (int bleed = 0; bleed < 2; bleed++) {
    char doc[2048];
    snprintf(doc, sizeof doc, "%s", open_plane("[0.2,0.5,0.8]", bleed ? "{\"samples\":8}"
                                                                    : "{\"samples\":8,"
                                                                      "\"color_bleeding\":false}"));
    char *at = strstr(doc, "\"technique\"");
    assert_non_null(at);
    char tail[512];
    snprintf(tail, sizeof tail, "%s", at);
    snprintf(at, sizeof doc - (size_t)(at - doc), "\"environment\":{\"color\":[0.3,0.6,0.9]},%s",
             tail);
    obs_result r;
    obs_test_render(doc, 2, &r);
    assert_sane(&r);
    const float *al = obs_image_channel(&r.image, "alpha");
    size_t n = (size_t)r.image.width * (size_t)r.image.height;
    for (size_t i = 0; i < n; i++)
      for (int k = 0; al[i] > 0 && k < 3; k++)
        assert_true(fabs(chan(&r, "indirect", k)[i] - refl[k] * sky[k]) < 1e-6);
    obs_result_free(&r);
  }
}

/* A scene without emitter, sky or ambient is refused at /lights. */
static void test_needs_light(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, open_plane("[0.5,0.5,0.5]", "{}"), "t.json", NULL, NULL, 0,
                                 &err);
  assert_int_not_equal(rc, 0);
  assert_non_null(strstr(obs_err_message(&err), "/lights"));
  assert_non_null(strstr(obs_err_message(&err), "ambient"));
  obs_err_free(&err);
}

/* Two parallel plates at distance h (y = 0: reflectivity 0.5, y = h: 0.8 0.4 0.1), each reaching
 * at least d_max beyond the measured points, which the camera sees from between them; everything
 * scaled by s and moved by `off`. */
static const char *plates(double s, double off, double h, double dmax, const char *params_in,
                          int size) {
  char params[512]; /* params_in may be obs_test_fmt's buffer, which the call below overwrites */
  snprintf(params, sizeof params, "%s", params_in);
  double L = (dmax + 2 * h) * s, y1 = h * s + off;
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[%.17g,%.17g,%.17g],"
      "\"look_at\":[%.17g,%.17g,%.17g],\"up\":[0,0,1],\"fov_y\":10},"
      "\"image\":{\"width\":%d,\"height\":%d},\"objects\":["
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
      "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
      "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]},\"material\":{\"reflectivity\":[0.8,0.4,0.1]}}],"
      "\"technique\":{\"name\":\"obscurance\",\"params\":{\"ambient\":[1,1,1],\"d_max\":%.17g,%s}}}",
      off, 0.5 * h * s + off, off, off, off, off, size, size, off - L, off, off - L, off - L, off,
      off + L, off + L, off, off + L, off + L, off, off - L, off - L, y1, off - L, off - L, y1,
      off + L, off + L, y1, off + L, off + L, y1, off - L, dmax * s, params);
}

/* The closed forms for plates at distance h, a = h / d_max <= 1, sqrt falloff (mu = cos theta):
 * W = 2 int_0^1 rho(h / mu) mu dmu with rho = 1 for mu < a, sqrt(a / mu) above:
 *   without bleeding  W = a^2 + (4/3)(sqrt(a) - a^2) = (4/3) sqrt(a) - a^2 / 3,
 *   with bleeding     W = R_ave a^2 + R_Q (4/3)(sqrt(a) - a^2). */
static double plates_w(double a, int bleed, int k) {
  const double rq[3] = {0.8, 0.4, 0.1}, rave[3] = {0.65, 0.45, 0.3};
  if (a >= 1) return bleed ? rave[k] : 1.0;
  double cross = 4.0 / 3.0 * (sqrt(a) - a * a);
  return bleed ? rave[k] * a * a + rq[k] * cross : a * a + cross;
}

/* Mean and standard error of the mean of channel k of `out` over the image's pixels (each pixel
 * an independent estimate: its own scrambled sequence). */
static void pixel_mean(const obs_result *r, const char *out, int k, double *mean, double *sem) {
  const float *v = chan(r, out, k);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  double s = 0, s2 = 0;
  for (size_t i = 0; i < n; i++) s += v[i], s2 += (double)v[i] * v[i];
  *mean = s / n;
  *sem = sqrt(fmax(0.0, s2 / n - *mean * *mean) / (n - 1));
}

static void test_plates_closed_form(void **state) {
  (void)state;
  const double h = 1, dmaxs[] = {4, 1.5};
  for (size_t d = 0; d < 2; d++)
    for (int bleed = 0; bleed < 2; bleed++)
      for (int seq = 0; seq < 2; seq++) {
        obs_result r;
        obs_test_render(plates(1, 0, h, dmaxs[d],
                               obs_test_fmt("\"samples\":64,\"color_bleeding\":%s,"
                                            "\"sequence\":\"%s\"",
                                            bleed ? "true" : "false", seq ? "sobol" : "halton"),
                               16),
                        2, &r);
        assert_sane(&r);
        for (int k = 0; k < 3; k++) {
          double m, sem, want = plates_w(h / dmaxs[d], bleed, k);
          pixel_mean(&r, "obscurance", k, &m, &sem);
          printf("plates d_max %g bleed %d %s %s: W %.5f want %.5f (sem %.2g)\n", dmaxs[d], bleed,
                 seq ? "sobol" : "halton", rgb[k], m, want, sem);
          assert_true(fabs(m - want) <= 3 * sem + 1e-6);
        }
        obs_result_free(&r);
      }
}

/* RMS error of the obscurance over the plates' pixels against the closed form. */
static double plates_rmse(int samples, const char *seq) {
  obs_result r;
  obs_test_render(plates(1, 0, 1, 4,
                         obs_test_fmt("\"samples\":%d,\"color_bleeding\":false,\"sequence\":\"%s\"",
                                      samples, seq),
                         16),
                  2, &r);
  double want = plates_w(0.25, 0, 0), s = 0;
  const float *v = chan(&r, "obscurance", 0);
  size_t n = (size_t)r.image.width * (size_t)r.image.height;
  for (size_t i = 0; i < n; i++) s += (v[i] - want) * (v[i] - want);
  obs_result_free(&r);
  return sqrt(s / n);
}

/* Four times the rays at least halve the error: the Monte-Carlo rate, which the scrambled
 * low-discrepancy sequences may beat but must not miss. 256 pixels estimate each RMSE to about
 * 1 / sqrt(2 * 256) = 4.4 %, the ratio to 6.3 %: 3 sigma allows 2 x 0.81. */
static void test_error_halves(void **state) {
  (void)state;
  static const char *const seqs[] = {"halton", "sobol"};
  for (int q = 0; q < 2; q++) {
    double e16 = plates_rmse(16, seqs[q]), e64 = plates_rmse(64, seqs[q]),
           e256 = plates_rmse(256, seqs[q]);
    printf("%s: RMSE 16 %.4g, 64 %.4g, 256 %.4g (ratios %.2f, %.2f)\n", seqs[q], e16, e64, e256,
           e16 / e64, e64 / e256);
    assert_true(e16 / e64 >= 2 * 0.81);
    assert_true(e64 / e256 >= 2 * 0.81);
  }
}

/* Without bleeding W is rt_ao's obscurance with the same falloff and distance: their difference
 * over the image is within 3 sigma of their reported errors, and per pixel within noise. */
static void test_matches_rt_ao(void **state) {
  (void)state;
  static const char *const falloffs[] = {"sqrt", "exp", "binary"};
  for (int f = 0; f < 3; f++) {
    const char *scene =
        "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2.5,-4],\"look_at\":[0,0.3,0],"
        "\"fov_y\":45},\"image\":{\"width\":24,\"height\":16},\"objects\":["
        "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]]},"
        "\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},{\"shape\":{\"type\":\"sphere\","
        "\"center\":[0,0.6,0],\"radius\":0.5},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
        "\"environment\":{\"color\":[1,1,1]},\"technique\":";
    obs_result a, b;
    obs_test_render(obs_test_fmt("%s{\"name\":\"obscurance\",\"params\":{\"samples\":128,"
                                 "\"d_max\":1.5,\"tau\":2,\"falloff\":\"%s\","
                                 "\"color_bleeding\":false}}}",
                                 scene, falloffs[f]),
                    2, &a);
    obs_test_render(obs_test_fmt("%s{\"name\":\"rt_ao\",\"params\":{\"samples\":128,"
                                 "\"max_distance\":1.5,\"tau\":2,\"falloff\":\"%s\","
                                 "\"seed\":7}}}",
                                 scene, falloffs[f]),
                    2, &b);
    const float *w = chan(&a, "obscurance", 0), *ws = chan(&a, "obscurance_stderr", 0);
    const float *ao = obs_image_channel(&b.image, "ao"), *as = obs_image_channel(&b.image,
                                                                                  "ao_stderr");
    const float *al = obs_image_channel(&a.image, "alpha");
    size_t n = (size_t)a.image.width * (size_t)a.image.height, cov = 0;
    double diff = 0, var = 0, chi = 0;
    size_t exact = 0;
    for (size_t i = 0; i < n; i++) {
      if (al[i] == 0.0f) continue;
      double v = (double)ws[i] * ws[i] + (double)as[i] * as[i];
      cov++;
      diff += w[i] - ao[i];
      var += v;
      if (v == 0) { /* both exact: nothing within d_max above the point */
        assert_true(w[i] == ao[i]);
        exact++;
        continue;
      }
      chi += (w[i] - ao[i]) * (w[i] - ao[i]) / v;
      assert_true(chan(&a, "obscurance", 1)[i] == w[i] && chan(&a, "obscurance", 2)[i] == w[i]);
    }
    double mchi = chi / (double)(cov - exact);
    printf("%s: mean W - AO %.3g, 3 sigma %.3g, mean chi^2 %.3f over %zu pixels (%zu exact)\n",
           falloffs[f], diff / cov, 3 * sqrt(var) / cov, mchi, cov - exact, exact);
    assert_true(cov > n / 2);
    assert_true(fabs(diff) <= 3 * sqrt(var));
    /* The reported errors are honest standard errors: chi^2 per pixel averages about 1 (0.95,
     * 1.15 and 1.52 for the three falloffs here), within what docs/accuracy.md's calibration band
     * (RMS stderr / RMSE in [0.67, 1.5]) allows: [1 / 1.5^2, 1 / 0.67^2]. */
    assert_true(mchi > 0.44 && mchi < 2.2);
    obs_result_free(&a);
    obs_result_free(&b);
  }
}

/* A render of the Cornell box, small, with `technique` and `params`. */
static void cornell(const char *technique, const char *params, obs_result *r) {
  char name[64];
  snprintf(name, sizeof name, "\"%s\"", technique);
  const obs_override ov[] = {{"/image/width", "24"},
                             {"/image/height", "24"},
                             {"/technique/name", name},
                             {"/technique/params", params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src("scenes/cornell_box.json"), ov, 4, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_render_opts o = {.threads = 2};
  rc = obs_render(&sc, &o, r, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The direct term is path_trace with one bounce (the emitters seen and light reflected once):
 * their image means agree within 3 sigma of the reported errors. */
static void test_direct_is_one_bounce(void **state) {
  (void)state;
  obs_result a, b;
  /* ambient 0: no indirect term, so final_stderr is the direct term's. */
  cornell("obscurance", "{\"samples\":1,\"light_samples\":256,\"d_max\":100,\"ambient\":[0,0,0]}", &a);
  cornell("path_trace", "{\"samples\":256,\"max_bounces\":1,\"seed\":3}", &b);
  size_t n = (size_t)a.image.width * (size_t)a.image.height;
  for (int k = 0; k < 3; k++) {
    const float *d = chan(&a, "direct", k), *ds = chan(&a, "final_stderr", k);
    const float *p = chan(&b, "radiance", k), *ps = chan(&b, "radiance_stderr", k);
    double diff = 0, var = 0, mean = 0;
    for (size_t i = 0; i < n; i++) {
      diff += d[i] - p[i];
      var += (double)ds[i] * ds[i] + (double)ps[i] * ps[i];
      mean += p[i];
    }
    printf("direct %s: mean %.5f, path_trace %.5f, diff %.3g, 3 sigma %.3g\n", rgb[k],
           (mean + diff) / n, mean / n, diff / n, 3 * sqrt(var) / n);
    assert_true(fabs(diff) <= 3 * sqrt(var));
  }
  obs_result_free(&a);
  obs_result_free(&b);
}

static int same_bits(const obs_result *a, const obs_result *b) {
  size_t n = (size_t)a->image.width * (size_t)a->image.height * (size_t)a->image.nchannels;
  return a->image.nchannels == b->image.nchannels &&
         !memcmp(a->image.data, b->image.data, n * sizeof *a->image.data);
}

/* The same seed gives the same bits, another seed other bits; 1, 2 and 3 threads the same bits. */
static void test_determinism(void **state) {
  (void)state;
  obs_result a, b, c, d;
  cornell("obscurance", "{\"samples\":8,\"d_max\":150,\"seed\":5}", &a);
  cornell("obscurance", "{\"samples\":8,\"d_max\":150,\"seed\":5}", &b);
  cornell("obscurance", "{\"samples\":8,\"d_max\":150,\"seed\":6}", &c);
  assert_true(same_bits(&a, &b));
  assert_false(same_bits(&a, &c));
  const char *doc = plates(1, 0, 1, 3, "\"samples\":16,\"light_samples\":2", 12);
  obs_result_free(&b);
  obs_result_free(&c);
  obs_test_render(doc, 1, &b);
  obs_test_render(doc, 2, &c);
  obs_test_render(doc, 3, &d);
  assert_true(same_bits(&b, &c));
  assert_true(same_bits(&b, &d));
  obs_result_free(&a);
  obs_result_free(&b);
  obs_result_free(&c);
  obs_result_free(&d);
}

/* The plates across the guaranteed range: scaled by 1e-4 and 1e4 and moved by 1e6 they give the
 * closed form still (and W as at scale 1 up to grazing rays); d_max far below and far above h
 * gives the open limit and the (4/3) sqrt(a) one. */
static void test_extremes(void **state) {
  (void)state;
  obs_result base;
  obs_test_render(plates(1, 0, 1, 4, "\"samples\":64", 8), 2, &base);
  const double scales[] = {1e-4, 1e4, 1}, offs[] = {0, 0, 1e6};
  for (int i = 0; i < 3; i++) {
    obs_result r;
    obs_test_render(plates(scales[i], offs[i] * (i == 2), 1, 4, "\"samples\":64", 8), 2, &r);
    assert_sane(&r);
    size_t n = (size_t)r.image.width * (size_t)r.image.height;
    double worst = 0;
    for (int k = 0; k < 3; k++)
      for (size_t j = 0; j < n; j++)
        worst = fmax(worst, fabs(chan(&r, "obscurance", k)[j] - chan(&base, "obscurance", k)[j]));
    printf("plates at scale %g moved by %g: W differs by at most %.3g\n", scales[i],
           offs[i] * (i == 2), worst);
    assert_true(worst < 1e-4);
    obs_result_free(&r);
  }
  obs_result_free(&base);
  const double dmaxs[] = {1e-6, 1e6};
  for (int i = 0; i < 2; i++)
    for (int bleed = 0; bleed < 2; bleed++) {
      obs_result r;
      obs_test_render(plates(1, 0, 1, dmaxs[i],
                             obs_test_fmt("\"samples\":64,\"color_bleeding\":%s",
                                          bleed ? "true" : "false"),
                             8),
                      2, &r);
      assert_sane(&r);
      for (int k = 0; k < 3; k++) {
        double m, sem, want = plates_w(1 / dmaxs[i], bleed, k);
        pixel_mean(&r, "obscurance", k, &m, &sem);
        printf("plates d_max %g bleed %d %s: W %.6g want %.6g (sem %.2g)\n", dmaxs[i], bleed,
               rgb[k], m, want, sem);
        if (i == 0) assert_true(fabs(m - want) < 1e-6);
        else assert_true(fabs(m - want) <= 3 * sem + 1e-6);
      }
      obs_result_free(&r);
    }
}

/* Reflectivity 0 and 0.99 everywhere in a closed box lit inside: finite, non-negative; I_A of the
 * closed environment grows as 1 / (1 - R_ave) and stays finite at 0.99. */
static void test_reflectivity_extremes(void **state) {
  (void)state;
  static const char *const refl[] = {"0", "0.99"};
  for (int i = 0; i < 2; i++)
    for (int bleed = 0; bleed < 2; bleed++) {
      const char *doc = obs_test_fmt(
          "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,-0.8],\"look_at\":[0,0,0],"
          "\"fov_y\":60},\"image\":{\"width\":12,\"height\":12},\"objects\":[{\"shape\":"
          "{\"type\":\"box\",\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"material\":{\"reflectivity\":"
          "[%s,%s,%s]}}],\"lights\":[{\"type\":\"quad\",\"vertices\":[[-0.2,0.99,-0.2],"
          "[0.2,0.99,-0.2],[0.2,0.99,0.2],[-0.2,0.99,0.2]],\"emission\":[5,5,5]}],"
          "\"technique\":{\"name\":\"obscurance\",\"params\":{\"samples\":16,\"d_max\":1,"
          "\"color_bleeding\":%s}}}",
          refl[i], refl[i], refl[i], bleed ? "true" : "false");
      obs_result r;
      obs_test_render(doc, 2, &r);
      assert_sane(&r);
      double m, sem;
      pixel_mean(&r, "final", 0, &m, &sem);
      printf("closed box, reflectivity %s, bleed %d: final mean %.4g\n", refl[i], bleed, m);
      if (i == 0) assert_true(m == 0.0); /* black walls; the light is out of the camera's view */
      else assert_true(m > 0.0);
      obs_result_free(&r);
    }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_open_plane),
      cmocka_unit_test(test_sky_ambient),
      cmocka_unit_test(test_needs_light),
      cmocka_unit_test(test_plates_closed_form),
      cmocka_unit_test(test_error_halves),
      cmocka_unit_test(test_matches_rt_ao),
      cmocka_unit_test(test_direct_is_one_bounce),
      cmocka_unit_test(test_determinism),
      cmocka_unit_test(test_extremes),
      cmocka_unit_test(test_reflectivity_extremes),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
