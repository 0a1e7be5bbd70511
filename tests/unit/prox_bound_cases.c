/* proximity_ao's accessibility bound over several fields (prox_bound_cases.h): renders through
 * obs_render on one backend, the bound computed here from the `fields` output. */
#include "prox_bound_cases.h"

#include <math.h>
#include <stdio.h>

#include "testutil.h"

#define W 48
#define H 36

/* The bound on the accessibility of a point in k fields, each occluding at most s. */
static double bound(int multiplicative, int k, double s) {
  return multiplicative ? pow(1.0 - s, k) : fmax(0.0, 1.0 - k * s);
}

static const char *doc(obs_backend be, const char *combine, double s) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2.5,-3.5],\"look_at\":[0.2,0.3,0],"
      "\"up\":[0,1,0],\"fov_y\":45},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]}},{\"shape\":{\"type\":\"box\",\"min\":[-0.6,0,-0.4],\"max\":[0.2,0.8,0.4]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0.75,0.35,0],\"radius\":0.35}}],"
      "\"technique\":{\"name\":\"proximity_ao\",\"backend\":\"%s\",\"params\":{"
      "\"volume_res\":48,\"min_res\":8,\"propagation_fraction\":0.15,\"combine\":\"%s\","
      "\"scale_before\":1e6,\"scale_after\":%.9g}}}",
      W, H, obs_backend_name(be), combine, s);
}

int obs_prox_bound_cases(obs_backend be) {
  int bad = 0;
  const char *combines[2] = {"additive", "multiplicative"};
  const double scales[2] = {0.8, 0.3};
  for (int m = 0; m < 2; m++)
    for (int j = 0; j < 2; j++) {
      double s = (double)(float)scales[j]; /* the bound parameter is a float */
      obs_result res;
      obs_test_render(doc(be, combines[m], scales[j]), 2, &res);
      const float *ao = obs_image_channel(&res.image, "ao"),
                  *nf = obs_image_channel(&res.image, "fields"),
                  *al = obs_image_channel(&res.image, "alpha");
      double least[4] = {2, 2, 2, 2};
      int count[4] = {0, 0, 0, 0};
      for (int i = 0; i < W * H; i++) {
        if (!(al[i] > 0)) continue;
        int k = (int)nf[i];
        if (k < 0 || k > 3 || k != nf[i]) {
          printf("FAIL %s s %g: pixel %d in %g fields\n", combines[m], s, i, nf[i]);
          bad++;
          continue;
        }
        count[k]++;
        least[k] = fmin(least[k], ao[i]);
        if (ao[i] < bound(m, k, s) - 1e-6) {
          printf("FAIL %s s %g: pixel %d in %d fields reads %.7f < bound %.7f\n", combines[m], s,
                 i, k, ao[i], bound(m, k, s));
          bad++;
        }
      }
      for (int k = 1; k <= 3; k++) {
        printf("%s, scale_after %g, %d fields: %d pixels, least %.6f, bound %.6f\n",
               combines[m], s, k, count[k], least[k], bound(m, k, s));
        /* The scene puts ground points in two and three fields; there, with every field
         * saturated, the least pixel is the bound: the bound is the right one. */
        if (k >= 2 && (!count[k] || fabs(least[k] - bound(m, k, s)) > 1e-6)) {
          printf("FAIL %s s %g: %d fields: least %.7f, not the bound %.7f (%d pixels)\n",
                 combines[m], s, k, least[k], bound(m, k, s), count[k]);
          bad++;
        }
      }
      obs_result_free(&res);
    }
  return bad;
}
