/* The screen-space rule's cases (screen_rule_cases.h): an open plane seen at an angle, rendered
 * through obs_render on one backend, its warnings read back and their figures checked against
 * what the test computes itself from the definition and the depth output. */
#include "screen_rule_cases.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#define W 64
#define H 48
#define PIXEL_WARNING "pixels across the screen (under one)"
#define DEPTH_WARNING "depth steps along the view axis (under one)"

/* An open plane (40 x 40 around the origin) seen from (0, h, -4/3 h) through fov_y degrees. */
static const char *plane_doc(const char *technique, obs_backend be, double fov, double h,
                             const char *params) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,%.17g,%.17g],\"look_at\":[0,0,0],"
      "\"up\":[0,1,0],\"fov_y\":%.17g},\"image\":{\"width\":%d,\"height\":%d},\"objects\":[{"
      "\"shape\":{\"type\":\"quad\",\"vertices\":[[-20,0,-20],[-20,0,20],[20,0,20],[20,0,-20]]}}],"
      "\"technique\":{\"name\":\"%s\",\"backend\":\"%s\",\"params\":%s}}",
      h, -4.0 / 3.0 * h, fov, W, H, technique, obs_backend_name(be), params);
}

static int render(const char *doc, obs_result *res) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "screen_rule.json", NULL, NULL, 0, &err);
  if (!rc) {
    obs_render_opts o = {.threads = 2};
    rc = obs_render(&sc, &o, res, &err);
    obs_scene_free(&sc);
  }
  if (rc) printf("FAIL render: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

static const char *warning_with(const obs_result *res, const char *what) {
  for (int i = 0; i < res->nwarnings; i++)
    if (strstr(res->warnings[i], what)) return res->warnings[i];
  return NULL;
}

/* The number after `key` in `text`, NaN when absent. */
static double number_after(const char *text, const char *key) {
  const char *p = text ? strstr(text, key) : NULL;
  return p ? strtod(p + strlen(key), NULL) : NAN;
}

/* One check: prints FAIL and counts when `ok` is false. */
#define CHECK(ok, ...)                                                                         \
  do {                                                                                         \
    if (!(ok)) {                                                                               \
      printf("FAIL " __VA_ARGS__);                                                             \
      printf("\n");                                                                            \
      bad++;                                                                                   \
    }                                                                                          \
  } while (0)

/* Renders `params` and checks which of the two warnings it carries, adding failures to *bad.
 * Returns 1 when `res` holds the render (the caller frees it), 0 when it failed. */
static int expect(const char *technique, obs_backend be, double fov, double h, const char *params,
                  int pixel, int depth, obs_result *res, int *bad_out) {
  int bad = 0;
  char p[256];
  snprintf(p, sizeof p, "%s", params); /* params may be obs_test_fmt's buffer, reused below */
  if (render(plane_doc(technique, be, fov, h, p), res)) return ++*bad_out, 0;
  const char *wp = warning_with(res, PIXEL_WARNING), *wd = warning_with(res, DEPTH_WARNING);
  CHECK(!wp == !pixel, "%s %s: pixel warning %s (%s)", technique, p,
        pixel ? "missing" : "unexpected", wp ? wp : "");
  CHECK(!wd == !depth, "%s %s: depth warning %s (%s)", technique, p,
        depth ? "missing" : "unexpected", wd ? wd : "");
  for (int i = 0; i < res->nwarnings; i++) printf("  warned: %s\n", res->warnings[i]);
  *bad_out += bad;
  return 1;
}

int obs_screen_rule_ssao_cases(obs_backend be) {
  int bad = 0;
  /* The longest of N = 16 offsets is r (1 + 2.4/16)^16; a pixel is 1/64 of the image. */
  double reach = pow(1.0 + 2.4 / 16.0, 16.0), r_pixel = 1.0 / (reach * W),
         r_depth = FLT_EPSILON / (2.0 * reach);
  obs_result res;
  /* A few pixels: no warning, and the open plane reads 0.75 on average. */
  if (expect("ssao", be, 45, 3, obs_test_fmt("{\"radius\":%.17g}", 4 * r_pixel), 0, 0, &res,
             &bad)) {
    const float *ao = obs_image_channel(&res.image, "ao");
    double s = 0;
    for (int i = 0; i < W * H; i++) s += ao[i];
    CHECK(fabs(s / (W * H) - 0.75) < 0.03, "ssao at 4 pixels: open plane mean %.4f, not 0.75",
          s / (W * H));
    obs_result_free(&res);
  }
  /* Either side of one pixel. */
  if (expect("ssao", be, 45, 3, obs_test_fmt("{\"radius\":%.17g}", 1.02 * r_pixel), 0, 0, &res,
             &bad))
    obs_result_free(&res);
  const double radii[] = {0.98 * r_pixel, 1e-6, 1e-8, 0.5 * r_depth, 1e-12};
  for (size_t k = 0; k < sizeof radii / sizeof radii[0]; k++) {
    int below_depth = radii[k] < r_depth;
    const char *params = obs_test_fmt("{\"radius\":%.17g}", radii[k]);
    char copy[128];
    snprintf(copy, sizeof copy, "%s", params);
    if (!expect("ssao", be, 45, 3, copy, 1, below_depth, &res, &bad)) continue;
    const char *wp = warning_with(&res, PIXEL_WARNING);
    double share = number_after(wp, "(under one) at "), need = number_after(wp, "radius >= ");
    CHECK(share == 100, "ssao %s: share %g%%, not every covered pixel", copy, share);
    CHECK(fabs(need / r_pixel - 1) < 1e-3, "ssao %s: suggests radius >= %g, not %g", copy, need,
          r_pixel);
    if (below_depth) {
      need = number_after(warning_with(&res, DEPTH_WARNING), "radius >= ");
      CHECK(fabs(need / r_depth - 1) < 1e-3, "ssao %s: suggests radius >= %g for depth, not %g",
            copy, need, r_depth);
    }
    bad += obs_test_check_sane(copy, obs_technique_find("ssao"), &res.image);
    obs_result_free(&res);
  }
  return bad;
}

/* The share of covered pixels (percent) where R projects under one pixel, from the depth output:
 * R (W/2) / (tan(fov/2) (W/H) z) < 1; and whether every such pixel's ao_raw is 1. */
static double hbao_short_share(const obs_result *res, double R, double fov, int *ones) {
  const float *z = obs_image_channel(&res->image, "depth.Z"),
              *a = obs_image_channel(&res->image, "alpha"),
              *raw = obs_image_channel(&res->image, "ao_raw");
  double half_w = tan(0.5 * fov * 3.14159265358979323846 / 180.0) * W / H;
  int covered = 0, missed = 0;
  *ones = 1;
  for (int i = 0; i < W * H; i++) {
    if (!(a[i] > 0)) continue;
    covered++;
    double px = R * 0.5 * W / (half_w * z[i]);
    missed += px < 1;
    if (px < 0.999 && raw[i] != 1.0f) *ones = 0;
  }
  return covered ? 100.0 * missed / covered : 0;
}

int obs_screen_rule_hbao_cases(obs_backend be) {
  int bad = 0;
  obs_result res;
  /* The covered depths, from a render whose radius reaches every pixel. */
  if (!expect("hbao", be, 45, 3, "{\"radius\":5}", 0, 0, &res, &bad)) return bad;
  const float *z = obs_image_channel(&res.image, "depth.Z"),
              *a = obs_image_channel(&res.image, "alpha");
  double zmin = INFINITY, zmax = 0;
  for (int i = 0; i < W * H; i++)
    if (a[i] > 0) zmin = fmin(zmin, z[i]), zmax = fmax(zmax, z[i]);
  obs_result_free(&res);
  double half_w = tan(22.5 * 3.14159265358979323846 / 180.0) * W / H;
  /* Under a pixel everywhere, and at the depths between the nearest and the farthest. */
  const double radii[2] = {0.5 * 2 * half_w * zmin / W, 2 * half_w * sqrt(zmin * zmax) / W};
  for (int k = 0; k < 2; k++) {
    const char *params = obs_test_fmt("{\"radius\":%.17g,\"blur_radius\":0}", radii[k]);
    char copy[128];
    snprintf(copy, sizeof copy, "%s", params);
    if (!expect("hbao", be, 45, 3, copy, 1, 0, &res, &bad)) continue;
    int ones;
    double want = hbao_short_share(&res, radii[k], 45, &ones);
    double share = number_after(warning_with(&res, PIXEL_WARNING), "(under one) at ");
    CHECK(fabs(share - want) < 1.0, "hbao %s: warned of %g%% of the pixels, measured %g%%", copy,
          share, want);
    CHECK(k == 1 || want == 100, "hbao %s: %g%% under a pixel, not all", copy, want);
    CHECK(k == 0 || (want > 10 && want < 90), "hbao %s: %g%% under a pixel, not some", copy, want);
    CHECK(ones, "hbao %s: a pixel under one texel does not read 1", copy);
    obs_result_free(&res);
  }
  /* fov_y 1e-4 degrees from 5e5 units away: a pixel spans ~3.6e-8 of the depth, the depth's
   * uncertainty (2 OBS_HBAO_DEPTH_EPS z) ~4.8e-7 of it. A radius of 4 pixels is within it. */
  double h = 3e5, zc = h * 5.0 / 3.0, pixel = 2 * tan(0.5e-4 * 3.14159265358979323846 / 180.0) *
                                                (double)W / H * zc / W;
  if (expect("hbao", be, 1e-4, h, obs_test_fmt("{\"radius\":%.17g}", 4 * pixel), 0, 1, &res,
             &bad))
    obs_result_free(&res);
  return bad;
}
