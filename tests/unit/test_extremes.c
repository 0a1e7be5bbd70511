/* Guaranteed ranges on the CPU: the scene extent the range check measures, and every registered
 * technique with a CPU backend holding its declared range at both ends (tests/unit/extremes.c)
 * and warning just outside it. */
#include "extremes.h"
#include "testutil.h"

#include <math.h>
#include <stdio.h>

#include "extent.h"

static void load(const char *objects, const char *camera_pos, obs_scene *sc) {
  char doc[2048];
  snprintf(doc, sizeof doc,
           "{\"camera\":{\"type\":\"perspective\",\"position\":%s,\"look_at\":[0,0,1e30],"
           "\"up\":[0,1,0],\"fov_y\":40},\"image\":{\"width\":4,\"height\":4},"
           "\"objects\":%s,\"technique\":{\"name\":\"rt_ao\"}}",
           camera_pos, objects);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(sc, doc, "extent.json", NULL, NULL, 0, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

/* Size and translation as declared: the transformed bounding box's diagonal, and the farther of
 * the camera and the box centre from the origin in sizes. */
static void test_scene_extent(void **state) {
  (void)state;
  obs_scene sc;
  obs_extent ex;
  obs_err err = OBS_ERR_INIT;
  /* A 2x4x6 box turned 90 degrees about Y (x becomes z, z becomes -x), moved by 97 along x;
   * a sphere of radius 1 at (50, 0, 0) scaled by -2: radius 2 at (-100, 0, 0). Bounds: x
   * -102..103, y -2..4, z -2..2; the camera (3 from the origin) is farther out than the box
   * centre (0.5, 1, 0). */
  load("[{\"shape\":{\"type\":\"box\",\"min\":[0,0,0],\"max\":[2,4,6]},"
       "\"transform\":{\"rotate\":[0,90,0],\"translate\":[97,0,0]}},"
       "{\"shape\":{\"type\":\"sphere\",\"center\":[50,0,0],\"radius\":1},"
       "\"transform\":{\"scale\":[-2,-2,-2]}}]",
       "[0,0,-3]", &sc);
  assert_int_equal(obs_scene_extent(&sc, &ex, &err), 0);
  assert_false(ex.empty);
  const double want[2][3] = {{-102, -2, -2}, {103, 4, 2}};
  for (int b = 0; b < 2; b++)
    for (int k = 0; k < 3; k++) assert_true(fabs(ex.bounds[b][k] - want[b][k]) < 1e-9);
  double size = sqrt(205.0 * 205 + 6 * 6 + 4 * 4);
  assert_true(fabs(ex.size - size) < 1e-9 * size);
  assert_true(fabs(ex.translation - 3 / size) < 1e-12);
  obs_scene_free(&sc);
  /* A camera far away sets the translation; no objects: empty. */
  load("[{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}}]",
       "[0,0,-1e12]", &sc);
  assert_int_equal(obs_scene_extent(&sc, &ex, &err), 0);
  assert_true(fabs(ex.size - sqrt(2.0)) < 1e-12);
  assert_true(fabs(ex.translation - 1e12 / sqrt(2.0)) < 1e-3);
  obs_scene_free(&sc);
  load("[]", "[0,0,-1]", &sc);
  assert_int_equal(obs_scene_extent(&sc, &ex, &err), 0);
  assert_true(ex.empty);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_cpu_ranges_hold(void **state) {
  (void)state;
  int ran = 0;
  int bad = obs_extremes_check_backend(OBS_BACKEND_CPU, &ran);
  assert_true(ran >= 1);
  assert_int_equal(bad, 0);
}

static void test_cpu_warns_outside(void **state) {
  (void)state;
  assert_int_equal(obs_extremes_check_warnings(OBS_BACKEND_CPU), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_scene_extent),
      cmocka_unit_test(test_cpu_ranges_hold),
      cmocka_unit_test(test_cpu_warns_outside),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
