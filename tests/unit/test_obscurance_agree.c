/* The two obscurance estimators of one quantity agree: per-pixel `obscurance` (W at each pixel's
 * point) averaged over the pixels of a patch equals `obscurance_map`'s value of that patch (W
 * averaged over the patch's area) within their noise. An orthographic camera looks straight down
 * at a floor beside a wall, so the pixel centres of a patch sample its area uniformly. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

/* Fine enough that the pixel centres' average over a patch is its area average: at 96 the
 * grid's quadrature error (7e-4 in the mean) exceeds the honest noise. */
#define RES 192

static const char *scene_doc(const char *technique, const char *params) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,5,0],\"look_at\":[0,0,0],"
      "\"up\":[0,0,1],\"height\":2},\"image\":{\"width\":%d,\"height\":%d},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,-1],[-1,0,1],[1,0,1],"
      "[1,0,-1]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,0,1],[-1,1,1],[1,1,1],[1,0,1]]},"
      "\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
      "\"technique\":{\"name\":\"%s\",\"params\":{%s}}}",
      RES, RES, technique, params);
}

/* The map's image plane (the value of the patch each pixel sees) of a map with `seed`, and in
 * *se_out that of its standard error. */
static float *map_plane(int seed, float **se_out) {
  char params[256];
  snprintf(params, sizeof params,
           "\"method\":\"rays\",\"samples\":2048,\"d_max\":1,\"falloff\":\"sqrt\","
           "\"color_bleeding\":false,\"patch_size\":0.35,\"seed\":%d",
           seed);
  char doc[2048];
  snprintf(doc, sizeof doc, "%s", scene_doc("obscurance_map", params));
  obs_result r;
  obs_test_render(doc, 2, &r);
  const float *ch = obs_image_channel(&r.image, "obscurance_rgb.R");
  const float *se = obs_image_channel(&r.image, "obscurance_stderr");
  assert_non_null(ch);
  assert_non_null(se);
  float *out = malloc(RES * RES * sizeof *out);
  *se_out = malloc(RES * RES * sizeof **se_out);
  assert_non_null(out);
  assert_non_null(*se_out);
  memcpy(out, ch, RES * RES * sizeof *out);
  memcpy(*se_out, se, RES * RES * sizeof **se_out);
  obs_result_free(&r);
  return out;
}

static void test_pixels_average_to_patches(void **state) {
  (void)state;
  obs_result px;
  char doc[2048];
  snprintf(doc, sizeof doc, "%s",
           scene_doc("obscurance", "\"samples\":64,\"d_max\":1,\"falloff\":\"sqrt\","
                                   "\"color_bleeding\":false,\"ambient\":[1,1,1]"));
  obs_test_render(doc, 2, &px);
  const float *w = obs_image_channel(&px.image, "obscurance.R");
  const float *se = obs_image_channel(&px.image, "obscurance_stderr.R");
  assert_non_null(w);
  assert_non_null(se);
  float *s1, *s2, *v1 = map_plane(1, &s1), *v2 = map_plane(2, &s2);
  /* Pixels grouped by the patch they see: one map value per patch, so equal values mark a group. */
  enum { MAXG = 4096 };
  static double val[MAXG], val2[MAXG], mse[MAXG], mse2[MAXG], sum[MAXG], var[MAXG];
  static int cnt[MAXG];
  int ng = 0;
  for (int i = 0; i < RES * RES; i++) {
    int g = 0;
    while (g < ng && val[g] != v1[i]) g++;
    if (g == ng) {
      assert_true(ng < MAXG);
      val[g] = v1[i], val2[g] = v2[i], mse[g] = s1[i], mse2[g] = s2[i];
      sum[g] = var[g] = 0, cnt[g] = 0;
      ng++;
    }
    sum[g] += w[i];
    var[g] += (double)se[i] * se[i];
    cnt[g]++;
  }
  /* The map's noise from its own standard error (the two seeds' difference checks it); each
   * pixel's from its own. */
  double d2 = 0, zm2 = 0;
  int nbig = 0;
  for (int g = 0; g < ng; g++)
    if (cnt[g] >= 20) {
      d2 += (val[g] - val2[g]) * (val[g] - val2[g]), nbig++;
      zm2 += (val[g] - val2[g]) * (val[g] - val2[g]) / (mse[g] * mse[g] + mse2[g] * mse2[g]);
    }
  assert_true(nbig >= 30);
  double map_noise = sqrt(d2 / nbig / 2), rms_zm = sqrt(zm2 / nbig);
  double z2 = 0, dmean = 0, dvar = 0;
  for (int g = 0; g < ng; g++) {
    if (cnt[g] < 20) continue; /* patches cut by the image's edge or seen by a few pixels */
    double m = sum[g] / cnt[g], pv = var[g] / cnt[g] / cnt[g], mv = mse[g] * mse[g];
    double z = (m - val[g]) / sqrt(pv + mv);
    z2 += z * z;
    dmean += m - val[g];
    dvar += pv + mv;
  }
  double rms_z = sqrt(z2 / nbig);
  printf("patches %d (of %d groups): rms z %.3f, mean difference %.5f (3 sigma %.5f), map noise "
         "%.5f, the two maps' rms z %.3f\n",
         nbig, ng, rms_z, dmean / nbig, 3 * sqrt(dvar) / nbig, map_noise, rms_zm);
  /* The map's reported errors describe the difference of two of its seeds (0.86 here: pooled over
   * each triangle's patches, they lean conservative). */
  assert_true(rms_zm > 0.7 && rms_zm < 1.3);
  /* Under agreement z is standard normal per patch (both standard errors are honest: RMS 1.05
   * here; over 90 patches its own spread is 0.075, so 1.3 is 4 of those), and the mean difference
   * lies within 3 sigma. A map with d_max 1.1 instead of 1 gives RMS 4.6 and a mean difference of
   * 38 sigma. */
  assert_true(rms_z < 1.3);
  assert_true(fabs(dmean / nbig) <= 3 * sqrt(dvar) / nbig);
  /* The wall makes W vary: the test is not of a constant. */
  double lo = 1, hi = 0;
  for (int g = 0; g < ng; g++)
    if (cnt[g] >= 20) lo = fmin(lo, val[g]), hi = fmax(hi, val[g]);
  assert_true(hi - lo > 0.2);
  free(v1);
  free(v2);
  free(s1);
  free(s2);
  obs_result_free(&px);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_pixels_average_to_patches),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
