/* The obscurance model's scene terms (renderer/core/obscurance.h) against hand-computed values:
 * the falloffs, R_ave and the closed-environment ambient intensity I_A of a small box. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "geometry.h"
#include "obscurance.h"
#include "testutil.h"

static void test_falloffs(void **state) {
  (void)state;
  obs_falloff b = {OBS_FALLOFF_BINARY, 2.0, 0}, s = {OBS_FALLOFF_SQRT, 4.0, 0},
              e = {OBS_FALLOFF_EXP, INFINITY, 0.5};
  assert_true(obs_falloff_rho(&b, 1.9) == 0.0);
  assert_true(obs_falloff_rho(&b, 2.0) == 1.0);
  assert_true(obs_falloff_rho(&b, INFINITY) == 1.0);
  assert_true(fabs(obs_falloff_rho(&s, 1.0) - 0.5) < 1e-15);
  assert_true(obs_falloff_rho(&s, 4.0) == 1.0);
  assert_true(obs_falloff_rho(&s, 0.0) == 0.0);
  assert_true(fabs(obs_falloff_rho(&e, 2.0) - (1.0 - exp(-1.0))) < 1e-15);
  assert_true(obs_falloff_rho(&e, INFINITY) == 1.0);
}

/* A closed unit cube of six quads: floor R = 0.2, ceiling R = 0.8 emitting (1, 2, 3), four walls
 * R = (0.5, 0.4, 0.3); a quad light of area 0.25 emitting 4 under the ceiling; a sphere of radius
 * 0.1 with R = 0.6 inside. Every figure below is the formula of obscurance.h done by hand. */
static void test_closed_box(void **state) {
  (void)state;
  const char *doc =
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0.5,0.5,0.1],\"look_at\":[0.5,0.5,1],"
      "\"fov_y\":60},\"image\":{\"width\":4,\"height\":4},\"objects\":["
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,0,1],[0,0,1]]},"
      "\"material\":{\"reflectivity\":[0.2,0.2,0.2]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,1,0],[0,1,1],[1,1,1],[1,1,0]]},"
      "\"material\":{\"reflectivity\":[0.8,0.8,0.8],\"emission\":[1,2,3]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,1,0],[1,1,0],[1,0,0]]},"
      "\"material\":{\"reflectivity\":[0.5,0.4,0.3]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,1],[1,0,1],[1,1,1],[0,1,1]]},"
      "\"material\":{\"reflectivity\":[0.5,0.4,0.3]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,0,1],[0,1,1],[0,1,0]]},"
      "\"material\":{\"reflectivity\":[0.5,0.4,0.3]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[1,0,0],[1,1,0],[1,1,1],[1,0,1]]},"
      "\"material\":{\"reflectivity\":[0.5,0.4,0.3]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0.5,0.3,0.5],\"radius\":0.1},"
      "\"material\":{\"reflectivity\":[0.6,0.6,0.6]}}],"
      "\"lights\":[{\"type\":\"quad\",\"vertices\":[[0.25,0.99,0.25],[0.75,0.99,0.25],"
      "[0.75,0.99,0.75],[0.25,0.99,0.75]],\"emission\":[4,4,4]}],"
      "\"technique\":{\"name\":\"path_trace\"}}";
  obs_scene sc;
  obs_test_load(doc, "box.json", &sc);
  obs_geometry g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &g, &err), 0);
  obs_obscurance_env env;
  int rc = obs_obscurance_env_compute(&sc, &g, &env, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  const double as = 4.0 * M_PI * 0.01, at = 6.0 + as;
  assert_true(fabs(env.area - at) < 1e-9);
  const double wall[3] = {0.5, 0.4, 0.3}, emit[3] = {1, 2, 3};
  double ia[3], ib[3];
  obs_obscurance_ambient(&env, 0, ia);
  obs_obscurance_ambient(&env, 1, ib);
  for (int c = 0; c < 3; c++) {
    double r = (0.2 + 0.8 + 4 * wall[c] + 0.6 * as) / at;
    double e = (emit[c] + 0.25 * 4.0) / at;
    assert_true(fabs(env.r_ave[c] - r) < 1e-9);
    assert_true(fabs(env.emitted[c] - e) < 1e-9);
    assert_true(fabs(ia[c] - r / (1 - r) * e) < 1e-9);
    assert_true(fabs(ib[c] - e / (1 - r)) < 1e-9);
  }
  obs_geometry_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* R_ave = 1 makes I_A diverge: refused with the scene named. */
static void test_white_refused(void **state) {
  (void)state;
  const char *doc =
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,-5],\"look_at\":[0,0,0],"
      "\"fov_y\":40},\"image\":{\"width\":4,\"height\":4},\"objects\":["
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]},"
      "\"material\":{\"reflectivity\":[1,0.5,0.5],\"emission\":[1,1,1]}}],\"technique\":{\"name\":\"path_trace\"}}";
  obs_scene sc;
  obs_test_load(doc, "white.json", &sc);
  obs_geometry g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &g, &err), 0);
  obs_obscurance_env env;
  assert_int_equal(obs_obscurance_env_compute(&sc, &g, &env, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "white.json"));
  assert_non_null(strstr(obs_err_message(&err), "channel 0"));
  obs_geometry_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_falloffs),
      cmocka_unit_test(test_closed_box),
      cmocka_unit_test(test_white_refused),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
