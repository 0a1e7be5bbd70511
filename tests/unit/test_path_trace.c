/* path_trace against closed forms (white furnace, open plane under a sky, emission only), its
 * statistics (reported standard error, its 1/sqrt(spp) law, MIS against BSDF sampling),
 * thread-count invariance and the scenes it refuses. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"


static const char *const rad[3] = {"radiance.R", "radiance.G", "radiance.B"};
static const char *const err3[3] = {"radiance_stderr.R", "radiance_stderr.G", "radiance_stderr.B"};

static size_t npix(const obs_result *r) { return (size_t)r->image.width * (size_t)r->image.height; }

/* The image mean of channel k's radiance and the standard error of that mean (pixels are
 * independent, so their variances add). */
static void image_mean(const obs_result *r, int k, double *mean, double *se) {
  const float *v = obs_image_channel(&r->image, rad[k]), *s = obs_image_channel(&r->image, err3[k]);
  assert_non_null(v);
  assert_non_null(s);
  double sum = 0, var = 0;
  size_t n = npix(r);
  for (size_t i = 0; i < n; i++) {
    sum += v[i];
    var += (double)s[i] * s[i];
  }
  *mean = sum / (double)n;
  *se = sqrt(var) / (double)n;
}

/* Finite everywhere, radiance and its error non-negative, alpha in [0, 1]. */
static void assert_sane(const obs_result *r) {
  obs_test_assert_finite(&r->image);
  size_t n = npix(r);
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(&r->image, rad[k]),
                *s = obs_image_channel(&r->image, err3[k]);
    for (size_t i = 0; i < n; i++) assert_true(v[i] >= 0.0f && s[i] >= 0.0f);
  }
  const float *a = obs_image_channel(&r->image, "alpha");
  for (size_t i = 0; i < n; i++) assert_true(a[i] >= 0.0f && a[i] <= 1.0f);
}

/* Inside a closed sphere of reflectivity rho emitting E: camera at its centre; n paths per pixel
 * through its centre. */
static const char *furnace(const double rho[3], const double e[3], int n, const char *params) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
      "\"fov_y\":120},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
      "\"material\":{\"reflectivity\":[%.17g,%.17g,%.17g],\"emission\":[%.17g,%.17g,%.17g]}}],"
      "\"technique\":{\"name\":\"path_trace\",\"params\":{\"samples\":%d%s%s}}}",
      rho[0], rho[1], rho[2], e[0], e[1], e[2], n, *params ? "," : "", params);
}

/* L = E + rho L everywhere: E / (1 - rho), summed over bounces 0..max_bounces. */
static void test_white_furnace(void **state) {
  (void)state;
  const double rho[3] = {0.5, 0.3, 0.8}, e[3] = {1, 2, 0.5};
  obs_result r;
  obs_test_render(furnace(rho, e, 128, "\"max_bounces\":200"), 2, &r);
  assert_sane(&r);
  for (int k = 0; k < 3; k++) {
    double want = e[k] * (1 - pow(rho[k], 201)) / (1 - rho[k]), mean, se;
    image_mean(&r, k, &mean, &se);
    printf("furnace %s: %.5f (stderr %.2g), closed form %.5f\n", rad[k], mean, se, want);
    assert_true(se > 0);
    assert_true(fabs(mean - want) <= 3 * se);
    assert_true(fabs(mean - want) <= 0.02 * want);
  }
  obs_result_free(&r);
}

/* rho -> 1: long paths, ended by Russian roulette or max_bounces, stay finite and unbiased. */
static void test_furnace_near_one(void **state) {
  (void)state;
  const double rho[3] = {0.999, 0.999, 0.999}, e[3] = {1, 1, 1};
  const int m = 1024;
  obs_result r;
  obs_test_render(furnace(rho, e, 16, "\"max_bounces\":1024,\"rr_depth\":3"), 2, &r);
  assert_sane(&r);
  double want = (1 - pow(rho[0], m + 1)) / (1 - rho[0]), mean, se;
  image_mean(&r, 0, &mean, &se);
  printf("furnace rho 0.999: %.2f (stderr %.2g), closed form %.2f\n", mean, se, want);
  assert_true(fabs(mean - want) <= 3 * se);
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(&r.image, rad[k]);
    for (size_t i = 0; i < npix(&r); i++) assert_true(v[i] <= 2.0 * (m + 1));
  }
  obs_result_free(&r);
}

/* An open plane under a constant sky L reflects rho L: every path gives exactly that. */
static void test_open_plane_under_sky(void **state) {
  (void)state;
  const double rho[3] = {0.2, 0.5, 0.8}, sky[3] = {1, 2, 3};
  obs_result r;
  obs_test_render(
      obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
          "\"fov_y\":60},\"image\":{\"width\":16,\"height\":12,\"spp\":8},"
          "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-100,0,-100],[-100,0,100],"
          "[100,0,100],[100,0,-100]]},\"material\":{\"reflectivity\":[%g,%g,%g]}}],"
          "\"environment\":{\"color\":[%g,%g,%g]},\"technique\":{\"name\":\"path_trace\"}}",
          rho[0], rho[1], rho[2], sky[0], sky[1], sky[2]),
      2, &r);
  assert_sane(&r);
  const float *a = obs_image_channel(&r.image, "alpha");
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(&r.image, rad[k]), *s = obs_image_channel(&r.image, err3[k]);
    const float *al = obs_image_channel(&r.image, k == 0   ? "albedo.R"
                                                  : k == 1 ? "albedo.G"
                                                           : "albedo.B");
    for (size_t i = 0; i < npix(&r); i++) {
      assert_true(a[i] == 1.0f);
      double want = rho[k] * sky[k];
      assert_true(fabs(v[i] - want) <= 3 * s[i] + 1e-6 * want);
      assert_true(fabs(al[i] - rho[k]) < 1e-6);
    }
  }
  obs_result_free(&r);
}

/* rho = 0 everywhere: radiance is the emission seen directly, nothing else. */
static void test_black_surfaces_emission_only(void **state) {
  (void)state;
  obs_result r;
  obs_test_render(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0.5,0],"
      "\"fov_y\":60},\"image\":{\"width\":16,\"height\":12},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-9,0,-9],[-9,0,9],[9,0,9],"
      "[9,0,-9]]},\"material\":{\"reflectivity\":[0,0,0]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0,0.6,0],\"radius\":0.6},"
      "\"material\":{\"reflectivity\":[0,0,0],\"emission\":[3,2,1]}}],"
      "\"technique\":{\"name\":\"path_trace\"}}",
      1, &r);
  assert_sane(&r);
  const double e[3] = {3, 2, 1};
  size_t lit = 0, dark = 0;
  const float *v[3];
  for (int k = 0; k < 3; k++) v[k] = obs_image_channel(&r.image, rad[k]);
  for (size_t i = 0; i < npix(&r); i++) {
    int is_lit = v[0][i] != 0.0f;
    for (int k = 0; k < 3; k++) assert_true(v[k][i] == (is_lit ? (float)e[k] : 0.0f));
    lit += is_lit;
    dark += !is_lit;
  }
  assert_true(lit > 0 && dark > 0);
  obs_result_free(&r);
}

/* A plane and a sphere casting a shadow, lit from 2 units above by a quad light facing down
 * (EMIT_LIGHT) or up (EMIT_LIGHT_UP), or by an emissive quad object (EMIT_OBJECT, two-sided). */
enum { EMIT_LIGHT, EMIT_LIGHT_UP, EMIT_OBJECT };
static const char *lit_scene_by(int w, int h, int n, const char *params, int emitter) {
  static const char *const emitters[] = {
      "],\"lights\":[{\"type\":\"quad\",\"vertices\":[[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]],"
      "\"emission\":[4,4,4]}]",
      "],\"lights\":[{\"type\":\"quad\",\"vertices\":[[-1,2,1],[1,2,1],[1,2,-1],[-1,2,-1]],"
      "\"emission\":[4,4,4]}]",
      ",{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]]},"
      "\"material\":{\"reflectivity\":[0.3,0.3,0.3],\"emission\":[4,3,2]}}]"};
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,1.5,-2.5],"
      "\"look_at\":[0,0,0],\"fov_y\":60},\"image\":{\"width\":%d,\"height\":%d},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],"
      "[3,0,-3]]},\"material\":{\"reflectivity\":[0.7,0.6,0.5]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0.3,0.5,0.2],\"radius\":0.5},"
      "\"material\":{\"reflectivity\":[0.2,0.5,0.8]}}%s,"
      "\"technique\":{\"name\":\"path_trace\",\"params\":{\"samples\":%d%s%s}}}",
      w, h, emitters[emitter], n, *params ? "," : "", params);
}

static const char *lit_scene(int w, int h, int n, const char *params) {
  return lit_scene_by(w, h, n, params, EMIT_LIGHT);
}

/* A quad light emits from the side its vertices turn counter-clockwise on only: facing up, it
 * lights nothing the camera sees. */
static void test_quad_light_one_sided(void **state) {
  (void)state;
  obs_result r;
  obs_test_render(lit_scene_by(8, 8, 4, "", EMIT_LIGHT_UP), 2, &r);
  assert_sane(&r);
  for (int k = 0; k < 3; k++) {
    const float *v = obs_image_channel(&r.image, rad[k]);
    for (size_t i = 0; i < npix(&r); i++) assert_true(v[i] == 0.0f);
  }
  obs_result_free(&r);
}

/* Quadrupling the samples halves the standard error (i.i.d. samples: random sampler). */
static void test_stderr_halves(void **state) {
  (void)state;
  obs_result a, b;
  obs_test_render(lit_scene(8, 8, 16, "\"sampler\":\"random\""), 2, &a);
  obs_test_render(lit_scene(8, 8, 64, "\"sampler\":\"random\""), 2, &b);
  assert_sane(&a);
  assert_sane(&b);
  for (int k = 0; k < 3; k++) {
    const float *sa = obs_image_channel(&a.image, err3[k]),
                *sb = obs_image_channel(&b.image, err3[k]);
    double ta = 0, tb = 0;
    for (size_t i = 0; i < npix(&a); i++) ta += sa[i], tb += sb[i];
    printf("%s: mean stderr %.4g at 16 spp, %.4g at 64 spp, ratio %.3f\n", err3[k],
           ta / (double)npix(&a), tb / (double)npix(&b), ta / tb);
    assert_true(tb > 0);
    assert_true(ta / tb > 1.7 && ta / tb < 2.3);
  }
  obs_result_free(&a);
  obs_result_free(&b);
}

/* The same bits for any thread count. */
static void test_thread_invariant(void **state) {
  (void)state;
  obs_result a, b;
  obs_test_render(lit_scene(40, 36, 4, ""), 1, &a);
  obs_test_render(lit_scene(40, 36, 4, ""), 2, &b);
  assert_int_equal(a.image.nchannels, b.image.nchannels);
  assert_memory_equal(a.image.data, b.image.data,
                      npix(&a) * (size_t)a.image.nchannels * sizeof(float));
  obs_result_free(&a);
  obs_result_free(&b);
}

/* Next-event estimation with MIS and BSDF sampling alone estimate the same image, with a quad
 * light and with an emissive object (whose triangles are light-sampled and occlude). */
static void test_mis_agrees_with_bsdf(void **state) {
  (void)state;
  for (int e = 0; e < 2; e++) {
    int emitter = e ? EMIT_OBJECT : EMIT_LIGHT;
    obs_result m, b;
    obs_test_render(lit_scene_by(12, 12, 64, "\"light_sampling\":\"mis\"", emitter), 2, &m);
    obs_test_render(lit_scene_by(12, 12, 64, "\"light_sampling\":\"bsdf\",\"seed\":7", emitter), 2,
                    &b);
    assert_sane(&m);
    assert_sane(&b);
    for (int k = 0; k < 3; k++) {
      double mm, sm, mb, sb;
      image_mean(&m, k, &mm, &sm);
      image_mean(&b, k, &mb, &sb);
      printf("%s, %s: mis %.5f (stderr %.2g), bsdf %.5f (stderr %.2g)\n",
             e ? "emissive object" : "quad light", rad[k], mm, sm, mb, sb);
      assert_true(sm < sb); /* the point of light sampling */
      assert_true(fabs(mm - mb) <= 3 * sqrt(sm * sm + sb * sb));
    }
    obs_result_free(&m);
    obs_result_free(&b);
  }
}

/* Loads `doc` expecting a refusal whose message holds every one of `words`. */
static void expect_refused(const char *doc, const char *w1, const char *w2) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "pt.json", NULL, NULL, 0, &err);
  assert_int_equal(rc, OBS_EINVAL);
  const char *msg = obs_err_message(&err);
  printf("refused: %s\n", msg);
  assert_non_null(strstr(msg, w1));
  assert_non_null(strstr(msg, w2));
  obs_err_free(&err);
}

/* No emitter at all, an object without a material, and a negative emission are refused. */
static void test_refusals(void **state) {
  (void)state;
  const char *head =
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],"
      "\"look_at\":[0,0,0],\"fov_y\":60},\"image\":{\"width\":4,\"height\":4},";
  char doc[1024];
  snprintf(doc, sizeof doc,
           "%s\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
           "\"material\":{\"reflectivity\":[1,1,1]}}],\"environment\":{\"color\":[0,0,0]},"
           "\"technique\":{\"name\":\"path_trace\"}}",
           head);
  expect_refused(doc, "/lights", "needs an emitter");
  snprintf(doc, sizeof doc,
           "%s\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1}}],"
           "\"environment\":{\"color\":[1,1,1]},\"technique\":{\"name\":\"path_trace\"}}",
           head);
  expect_refused(doc, "/objects/0/material", "needs a material");
  snprintf(doc, sizeof doc,
           "%s\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1},"
           "\"material\":{\"reflectivity\":[1,1,1],\"emission\":[1,-1,1]}}],"
           "\"technique\":{\"name\":\"path_trace\"}}",
           head);
  expect_refused(doc, "/objects/0/material/emission", "");
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_white_furnace),
      cmocka_unit_test(test_furnace_near_one),
      cmocka_unit_test(test_open_plane_under_sky),
      cmocka_unit_test(test_black_surfaces_emission_only),
      cmocka_unit_test(test_stderr_halves),
      cmocka_unit_test(test_thread_invariant),
      cmocka_unit_test(test_mis_agrees_with_bsdf),
      cmocka_unit_test(test_quad_light_one_sided),
      cmocka_unit_test(test_refusals),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
