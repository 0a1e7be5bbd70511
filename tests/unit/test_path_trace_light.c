/* path_trace's emitters from first principles: an emitter of radiance Le that fills whole pixels
 * reads exactly Le in every one of them (a quad light and an emissive object, one and several
 * pixel samples, both samplers, both light strategies), and the light a quad light casts is the
 * power of a Lambertian emitter of that radiance, pi A Le: the radiance of a diffuse floor under
 * it is rho Le F, F the closed-form view factor of the rectangle (docs/techniques/path_trace.md,
 * "The light seen directly"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#define PI 3.14159265358979323846

static const char *const rad[3] = {"radiance.R", "radiance.G", "radiance.B"};
static const double LE[3] = {17, 12, 4}; /* the Cornell box's light */

/* A camera at the origin looking along +z at an emitter filling its view at z = 2: a quad light
 * facing it (`quad_light`), else an emissive quad object with reflectivity `rho`, in front of a
 * black wall at z = 3 that quad lights, which do not occlude, let camera rays reach. */
static const char *emitter_doc(int quad_light, double rho, int spp, const char *params) {
  static char e[512];
  if (quad_light)
    snprintf(e, sizeof e,
             "\"lights\":[{\"type\":\"quad\",\"vertices\":[[-5,-5,2],[-5,5,2],[5,5,2],[5,-5,2]],"
             "\"emission\":[%.17g,%.17g,%.17g]}],",
             LE[0], LE[1], LE[2]);
  else
    snprintf(e, sizeof e,
             "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-5,-5,2],[5,-5,2],[5,5,2],"
             "[-5,5,2]]},\"material\":{\"reflectivity\":[%.17g,%.17g,%.17g],"
             "\"emission\":[%.17g,%.17g,%.17g]}},",
             rho, rho, rho, LE[0], LE[1], LE[2]);
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
      "\"up\":[0,1,0],\"fov_y\":60},\"image\":{\"width\":12,\"height\":9,\"spp\":%d},%s%s"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-50,-50,3],[50,-50,3],[50,50,3],[-50,50,3]]},"
      "\"material\":{\"reflectivity\":[0,0,0]}}],"
      "\"technique\":{\"name\":\"path_trace\",\"params\":{%s}}}",
      spp, e, quad_light ? "\"objects\":[" : "", params);
}

/* Every pixel of an emitter seen directly, whole pixels covered, is exactly its radiance: the
 * camera ray's emission has weight 1 (no MIS: no other strategy finds it), whichever pixel
 * samples, paths, sampler or light strategy, and the light quad in front of a black wall adds
 * nothing else. */
static void test_emitter_reads_le(void **state) {
  (void)state;
  const char *params[] = {"\"samples\":1",
                          "\"samples\":16",
                          "\"samples\":16,\"sampler\":\"random\"",
                          "\"samples\":8,\"light_sampling\":\"bsdf\""};
  const int spps[] = {1, 4};
  const double rhos[] = {0, 0.5};
  for (int kind = 0; kind < 2; kind++)
    for (int r = 0; r < (kind ? 2 : 1); r++)
      for (int s = 0; s < 2; s++)
        for (size_t p = 0; p < sizeof params / sizeof params[0]; p++) {
          obs_result res;
          char doc[2048];
          snprintf(doc, sizeof doc, "%s", emitter_doc(!kind, rhos[r], spps[s], params[p]));
          obs_test_render(doc, 2, &res);
          size_t n = (size_t)res.image.width * (size_t)res.image.height, off = 0;
          for (int k = 0; k < 3; k++) {
            const float *v = obs_image_channel(&res.image, rad[k]);
            for (size_t i = 0; i < n; i++) off += v[i] != (float)LE[k];
          }
          printf("%s (rho %g), spp %d, %s: %zu of %zu values not exactly Le\n",
                 kind ? "emissive object" : "quad light", rhos[r], spps[s], params[p], off, 3 * n);
          assert_int_equal(off, 0);
          obs_result_free(&res);
        }
}

/* The view factor from a point to a parallel a x b rectangle centred h above it:
 * (2/pi) [X/sqrt(1+X^2) atan(Y/sqrt(1+X^2)) + Y/sqrt(1+Y^2) atan(X/sqrt(1+Y^2))], X = a/2h,
 * Y = b/2h (four corner rectangles of the standard corner formula). */
static double view_factor(double a, double b, double h) {
  double x = a / (2 * h), y = b / (2 * h), sx = sqrt(1 + x * x), sy = sqrt(1 + y * y);
  return 2 / PI * (x / sx * atan(y / sx) + y / sy * atan(x / sy));
}

/* A quad light a x b facing down h above a floor of reflectivity rho, seen straight down by an
 * orthographic camera between them over a patch 1 % of h wide: with nothing else in the scene
 * the floor's radiance is rho Le F (the irradiance pi Le F of a Lambertian emitter of radiance
 * Le, times rho / pi). The image mean against it within 3 standard errors (the spread of the
 * independent pixels) and 0.5 %, with MIS and with BSDF sampling alone. */
static void test_light_casts_pi_a_le(void **state) {
  (void)state;
  const double a = 1.3, b = 1.05, h = 1.0, rho = 0.5, F = view_factor(a, b, h);
  const char *strategies[2] = {"mis", "bsdf"};
  for (int st = 0; st < 2; st++) {
    char doc[2048];
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,0.5,0],\"look_at\":[0,0,0],"
             "\"up\":[0,0,1],\"height\":0.01},\"image\":{\"width\":8,\"height\":8,\"spp\":1},"
             "\"lights\":[{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,"
             "%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]],\"emission\":[%.17g,%.17g,%.17g]}],"
             "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-20,0,-20],[-20,0,20],"
             "[20,0,20],[20,0,-20]]},\"material\":{\"reflectivity\":[%.17g,%.17g,%.17g]}}],"
             "\"technique\":{\"name\":\"path_trace\",\"params\":{\"samples\":%d,"
             "\"sampler\":\"random\",\"max_bounces\":4,\"light_sampling\":\"%s\"}}}",
             a / 2, h, -b / 2, a / 2, h, b / 2, -a / 2, h, b / 2, -a / 2, h, -b / 2, LE[0], LE[1],
             LE[2], rho, rho, rho, st ? 4096 : 1024, strategies[st]);
    obs_result res;
    obs_test_render(doc, 2, &res);
    size_t n = (size_t)res.image.width * (size_t)res.image.height;
    for (int k = 0; k < 3; k++) {
      const float *v = obs_image_channel(&res.image, rad[k]);
      double sum = 0, sq = 0;
      for (size_t i = 0; i < n; i++) sum += v[i], sq += (double)v[i] * v[i];
      double mean = sum / n, se = sqrt((sq - sum * mean) / (n - 1) / n), want = rho * LE[k] * F;
      printf("%s, %s: floor %.5f (se %.2g), rho Le F = %.5f (F %.6f): ratio %.5f\n",
             strategies[st], rad[k], mean, se, want, F, mean / want);
      assert_true(se > 0);
      assert_true(fabs(mean - want) <= 3 * se);
      assert_true(fabs(mean - want) <= 0.005 * want);
    }
    obs_result_free(&res);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_emitter_reads_le),
      cmocka_unit_test(test_light_casts_pi_a_le),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
