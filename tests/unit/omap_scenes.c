/* Scenes and closed forms shared by the per-patch obscurance tests (omap_scenes.h). */
#include "omap_scenes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "testutil.h"

const char *obs_test_omap_plane_doc(double refl) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]},\"material\":{\"reflectivity\":[%g,%g,%g]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}",
      refl, refl * 0.5, refl * 0.25);
}

const char *obs_test_omap_plates_doc(double h, double L) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,%g,-9],\"look_at\":[0,%g,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-%g,0,-%g],[-%g,0,%g],[%g,0,%g],"
      "[%g,0,-%g]]},\"material\":{\"reflectivity\":[0.2,0.5,0.8]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-%g,%g,-%g],[%g,%g,-%g],[%g,%g,%g],"
      "[-%g,%g,%g]]},\"material\":{\"reflectivity\":[0.6,0.4,0.3]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}",
      h / 2, h / 2, L, L, L, L, L, L, L, L, L, h, L, L, h, L, L, h, L, L, h, L);
}

/* mu = cos theta: W = 2 int_0^1 rho(h / mu) mu dmu, rho = 1 ("nothing", R_ave with bleeding) for
 * mu < m0 = h / d_max and sqrt(h / (mu d_max)) (times R of the other plate) above:
 *   W = R_ave m0^2 + R_other 4/3 sqrt(m0) (1 - m0^(3/2)). */
double obs_test_omap_plates_w(double m0, double r_ave, double r_other) {
  return r_ave * m0 * m0 + r_other * 4.0 / 3.0 * sqrt(m0) * (1 - pow(m0, 1.5));
}

char *obs_test_omap_cornell_doc(void) {
  FILE *f = fopen(obs_test_src("scenes/cornell_box.json"), "rb");
  assert_non_null(f);
  char *buf = calloc(1, 1 << 16);
  assert_non_null(buf);
  size_t n = fread(buf, 1, (1 << 16) - 1, f);
  fclose(f);
  assert_true(n > 0);
  return buf;
}
