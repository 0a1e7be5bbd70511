/* ibl_shadows and the environment sampling it shares with path_trace, against closed forms: the
 * SH basis orthonormal, the SH projection of a constant environment (only L00 = c 2 sqrt(pi)) and
 * of a single-texel one (its Y_lm times power), the luminance x sin theta PMF (sums to 1, the
 * stated ratios, sample densities consistent and a histogram within its binomial error), the
 * regularised pseudo-inverse recovering band-limited functions, an open plane under a constant
 * sky (visibility 1 and radiance albedo x L up to the order-4 fit's computed error), and
 * path_trace's environment-map path unbiased: a white furnace under a constant map and MIS
 * against BSDF sampling under the sun; and the reference hook (path_trace, one bounce). */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "environment.h"
#include "testutil.h"
#include "../../renderer/techniques/ibl_shadows/ibl_shadows.h"

#define PI 3.14159265358979323846

/* Midpoint quadrature in (theta, phi): int Y_i Y_j = delta_ij. */
static void test_sh_orthonormal(void **state) {
  (void)state;
  enum { NT = 200, NP = 400 };
  double g[16][16];
  memset(g, 0, sizeof g);
  for (int a = 0; a < NT; a++)
    for (int b = 0; b < NP; b++) {
      double th = (a + 0.5) * PI / NT, ph = (b + 0.5) * 2 * PI / NP, y[16];
      double d[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
      double w = sin(th) * (PI / NT) * (2 * PI / NP);
      obs_sh_basis(4, d, y);
      for (int i = 0; i < 16; i++)
        for (int j = 0; j < 16; j++) g[i][j] += y[i] * y[j] * w;
    }
  for (int i = 0; i < 16; i++)
    for (int j = 0; j < 16; j++) assert_true(fabs(g[i][j] - (i == j)) < 1e-4);
}

static float *zero_faces(int res, const float *faces[6]) {
  float *buf = calloc((size_t)6 * res * res * 3, sizeof *buf);
  for (int f = 0; f < 6; f++) faces[f] = buf + (size_t)f * res * res * 3;
  return buf;
}

/* A constant environment projects onto the DC term alone; one lit texel onto its Y_lm. */
static void test_sh_projection(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  obs_env e;
  const double c[3] = {0.25, 1.5, 3};
  assert_int_equal(obs_env_constant(&e, c, &err), 0);
  double k[16][3];
  obs_env_sh(&e, 4, k);
  for (int ch = 0; ch < 3; ch++) {
    assert_true(fabs(k[0][ch] - c[ch] * 2 * sqrt(PI)) < 1e-12 * c[ch]);
    for (int i = 1; i < 16; i++) assert_true(fabs(k[i][ch]) < 1e-12);
  }
  obs_env_free(&e);
  /* A res-8 map, every texel the same: still the DC term alone (texel solid angles sum to 4 pi). */
  const int res = 8, fi = 2, ti = 5, tj = 1;
  const float *faces[6];
  float *buf = zero_faces(res, faces);
  for (size_t i = 0; i < (size_t)6 * res * res * 3; i++) buf[i] = 2.0f;
  assert_int_equal(obs_env_from_faces(&e, faces, res, &err), 0);
  obs_env_sh(&e, 4, k);
  assert_true(fabs(k[0][1] - 4 * sqrt(PI)) < 1e-9);
  for (int i = 1; i < 16; i++) assert_true(fabs(k[i][1]) < 1e-9);
  obs_env_free(&e);
  /* One texel of radiance L: coefficients L omega Y_i(centre), the single direction's values. */
  memset(buf, 0, (size_t)6 * res * res * 3 * sizeof *buf);
  float *t = buf + (((size_t)fi * res + tj) * res + ti) * 3;
  t[0] = t[1] = t[2] = 10.0f;
  assert_int_equal(obs_env_from_faces(&e, faces, res, &err), 0);
  obs_env_sh(&e, 4, k);
  double d[3], y[16], om = obs_env_texel_solid_angle(res, ti, tj);
  obs_env_face_dir(fi, (ti + 0.5) / res, (tj + 0.5) / res, d);
  obs_sh_basis(4, d, y);
  for (int i = 0; i < 16; i++) assert_true(fabs(k[i][2] - 10 * om * y[i]) < 1e-12);
  obs_env_free(&e);
  free(buf);
  obs_err_free(&err);
}

static void sky(obs_env *e, int res) {
  obs_env_sky_params sp;
  obs_env_sky_default(&sp);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_sky(e, &sp, res, &err), 0);
  obs_err_free(&err);
}

/* The PMF over the lat-long grid: sums to 1, pixel ratios luminance x sin theta, densities the
 * sampler returns equal obs_env_dist_pdf's, the density integrates to 1 over the sphere, and the
 * share of samples per band of rows matches its mass within 4 binomial sigmas. */
static void test_pmf(void **state) {
  (void)state;
  obs_env e;
  sky(&e, 32);
  obs_env_dist d;
  obs_err err = OBS_ERR_INIT;
  int w, h;
  obs_env_dist_grid(e.res, &w, &h);
  assert_int_equal(w, 128);
  assert_int_equal(obs_env_dist_build(&d, &e, w, h, &err), 0);
  double sum = 0;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) sum += obs_env_dist_pmf(&d, x, y);
  assert_true(fabs(sum - 1) < 1e-12);
  const int px[4][2] = {{3, 5}, {70, 20}, {100, 40}, {17, 63}};
  double ratio0 = 0;
  for (int i = 0; i < 4; i++) {
    double u = (px[i][0] + 0.5) / w, v = (px[i][1] + 0.5) / h, dir[3];
    obs_env_latlong_dir(u, v, dir);
    float fd[3] = {(float)dir[0], (float)dir[1], (float)dir[2]}, rgb[3];
    obs_env_lookup(&e, fd, rgb);
    double want = (0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]) * sin(PI * v);
    double ratio = obs_env_dist_pmf(&d, px[i][0], px[i][1]) / want;
    if (i == 0) ratio0 = ratio;
    assert_true(fabs(ratio / ratio0 - 1) < 1e-12);
  }
  /* Density against the sampler's own and its integral (midpoint over a finer grid). */
  uint32_t seed = 7;
  for (int i = 0; i < 2000; i++) {
    double dir[3], p = obs_env_dist_sample(&d, obs_test_unit(&seed), obs_test_unit(&seed), dir);
    assert_true(p > 0 && fabs(obs_env_dist_pdf(&d, dir) / p - 1) < 1e-6);
  }
  double integ = 0;
  for (int a = 0; a < 4 * h; a++)
    for (int b = 0; b < 4 * w; b++) {
      double v = (a + 0.5) / (4 * h), u = (b + 0.5) / (4 * w), dir[3];
      obs_env_latlong_dir(u, v, dir);
      integ += obs_env_dist_pdf(&d, dir) * sin(PI * v) * (PI / (4 * h)) * (2 * PI / (4 * w));
    }
  assert_true(fabs(integ - 1) < 1e-3);
  /* The upper 8 rows (the zenith cap): the share of 20000 samples against their mass. */
  enum { N = 20000 };
  int in = 0;
  for (int i = 0; i < N; i++) {
    double dir[3];
    obs_env_dist_sample(&d, obs_test_unit(&seed), obs_test_unit(&seed), dir);
    in += acos(dir[1]) < PI * 8 / h;
  }
  double mass = d.row[8] / d.total, sd = sqrt(mass * (1 - mass) / N);
  assert_true(fabs((double)in / N - mass) < 4 * sd);
  obs_env_dist_free(&d);
  obs_env_free(&e);
  obs_err_free(&err);
}

/* With alpha 0 and enough spread directions Y+ recovers any band-limited function's coefficients;
 * alpha > 0 shrinks them. */
static void test_pinv(void **state) {
  (void)state;
  enum { M = 48 };
  double dir[M][3], c[16], f[M];
  uint32_t seed = 3;
  for (int j = 0; j < M; j++) {
    double z = 2 * obs_test_unit(&seed) - 1, ph = 2 * PI * obs_test_unit(&seed);
    double r = sqrt(1 - z * z);
    dir[j][0] = r * cos(ph), dir[j][1] = r * sin(ph), dir[j][2] = z;
  }
  for (int i = 0; i < 16; i++) c[i] = obs_test_unit(&seed) - 0.5;
  for (int j = 0; j < M; j++) {
    double y[16];
    obs_sh_basis(4, dir[j], y);
    f[j] = 0;
    for (int i = 0; i < 16; i++) f[j] += c[i] * y[i];
  }
  static float yp[OBS_SH_MAX_COEFFS][OBS_IBL_MAX_MAPS];
  obs_err err = OBS_ERR_INIT;
  double norm0 = 0, norm1 = 0;
  for (int pass = 0; pass < 2; pass++) {
    assert_int_equal(obs_ibl_pinv((const double(*)[3])dir, M, 4, pass ? 0.5 : 0, yp, &err), 0);
    for (int i = 0; i < 16; i++) {
      double w = 0;
      for (int j = 0; j < M; j++) w += yp[i][j] * f[j];
      if (!pass) assert_true(fabs(w - c[i]) < 1e-4);
      *(pass ? &norm1 : &norm0) += w * w;
    }
  }
  assert_true(norm1 < norm0);
  assert_true(obs_ibl_pinv((const double(*)[3])dir, 0, 4, 0, yp, &err) != 0);
  obs_err_free(&err);
}

static const char *const PLANE_DOC =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0.3,3,-0.2],\"look_at\":[0,0,0],"
    "\"up\":[0,0,1],\"fov_y\":40},\"image\":{\"width\":32,\"height\":24,\"spp\":1},"
    "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-4,0,-4],[-4,0,4],[4,0,4],[4,0,"
    "-4]]},\"material\":{\"reflectivity\":[0.8,0.5,0.2]}}],"
    "\"environment\":{\"color\":[1.5,1.5,1.5]},"
    "\"technique\":{\"name\":\"ibl_shadows\",\"backend\":\"cpu\",\"params\":{%s}}}";

/* An open plane under a constant sky: every direction above is visible, so every pixel's fit is
 * that of the clamped cosine alone, w = Y+ max(0, n . w_j), and radiance = albedo L 2 w_0 /
 * sqrt(pi) exactly (the rest is the order-4 fit's error on these directions, computed here). */
static void plane_case(const char *params, int maps, int order, double alpha) {
  obs_result res;
  obs_test_render(obs_test_fmt(PLANE_DOC, params), 2, &res);
  const obs_image *img = &res.image;
  const float *r = obs_image_channel(img, "radiance.R"), *b = obs_image_channel(img, "radiance.B");
  const float *ao = obs_image_channel(img, "ao"), *a = obs_image_channel(img, "alpha");
  assert_non_null(r);
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  const double L[3] = {1.5, 1.5, 1.5};
  assert_int_equal(obs_env_constant(&e, L, &err), 0);
  obs_ibl_shadows_params p = {.shadow_maps = maps, .sh_order = order, .tikhonov = (float)alpha};
  obs_ibl_setup s;
  assert_int_equal(obs_ibl_setup_make(&e, &p, &s, &err), 0);
  double w0 = 0;
  for (int j = 0; j < s.m; j++) w0 += (double)s.yplus[0][j] * fmax(0, s.dir[j][1]);
  double factor = 2 * w0 / sqrt(PI);
  printf("plane, %d maps, order %d, alpha %g: fit factor 2 w0 / sqrt(pi) = %.6f (error %.2f%%)\n",
         maps, order, alpha, factor, 100 * fabs(factor - 1));
  assert_true(fabs(factor - 1) < 0.05);
  size_t n = (size_t)img->width * img->height, covered = 0;
  for (size_t i = 0; i < n; i++) {
    if (a[i] < 1) continue;
    covered++;
    assert_true(fabs(r[i] - 0.8 * 1.5 * factor) < 2e-4);
    assert_true(fabs(b[i] - 0.2 * 1.5 * factor) < 1e-4);
    assert_true(fabs(ao[i] - fmin(1, factor)) < 2e-4);
  }
  assert_true(covered == n);
  obs_env_free(&e);
  obs_err_free(&err);
  obs_result_free(&res);
}

static void test_open_plane(void **state) {
  (void)state;
  plane_case("\"map_size\":64", 32, 4, 0.2);
  plane_case("\"map_size\":64,\"shadow_maps\":16,\"tikhonov\":0.05", 16, 4, 0.05);
  plane_case("\"map_size\":64,\"sh_order\":2", 32, 2, 0.2);
}

/* The reference is path_trace with one bounce (direct light, exact visibility) and the exposure
 * copied; rendered on the plane it gives albedo x L exactly, which ibl_shadows matches up to its
 * fit factor. */
static void test_reference(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(obs_test_fmt(PLANE_DOC, "\"map_size\":64,\"exposure\":1.5"), "p.json", &sc);
  obs_reference_def def;
  memset(&def, 0, sizeof def);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_technique_reference(sc.technique, &sc, sc.params, NULL, &def, &err), 0);
  assert_ptr_equal(def.technique, obs_technique_find("path_trace"));
  assert_int_equal(def.response, OBS_RESPONSE_IDENTITY);
  assert_int_equal(json_integer_value(json_object_get(def.params, "max_bounces")), 1);
  assert_true(json_number_value(json_object_get(def.params, "exposure")) == 1.5);
  char *params = json_dumps(def.params, JSON_COMPACT);
  char *doc = strdup(obs_test_fmt(PLANE_DOC, "\"map_size\":64"));
  char *t = strstr(doc, "\"technique\"");
  snprintf(t, strlen(t) + 1, "\"technique\":{\"name\":\"path_trace\",\"params\":%s}}", params);
  obs_result res;
  obs_test_render(doc, 2, &res);
  const float *r = obs_image_channel(&res.image, "radiance.R");
  for (size_t i = 0; i < (size_t)res.image.width * res.image.height; i++)
    assert_true(fabs(r[i] - 0.8 * 1.5) < 1e-5);
  obs_result_free(&res);
  free(doc);
  free(params);
  obs_reference_def_free(&def);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The mean of a radiance channel over covered pixels and its standard error from the per-pixel
 * errors (independent pixels). */
static void channel_mean(const obs_image *img, const char *ch, const char *se, double *mean,
                         double *sem) {
  const float *v = obs_image_channel(img, ch), *s = obs_image_channel(img, se);
  const float *a = obs_image_channel(img, "alpha");
  double sum = 0, var = 0;
  size_t n = 0;
  for (size_t i = 0; i < (size_t)img->width * img->height; i++) {
    if (a[i] < 1) continue;
    sum += v[i];
    var += (double)s[i] * s[i];
    n++;
  }
  assert_true(n > 0);
  *mean = sum / n;
  *sem = sqrt(var) / n;
}

static const char *const FURNACE_DOC =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,-3],\"look_at\":[0,0,0],"
    "\"fov_y\":30},\"image\":{\"width\":12,\"height\":12,\"spp\":1},"
    "\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":0.7},"
    "\"material\":{\"reflectivity\":[0.8,0.8,0.8]}}],"
    "\"environment\":{\"map\":\"sky\",\"zenith\":[1,1,1],\"horizon\":[1,1,1],\"ground\":[1,1,1],"
    "\"resolution\":8},"
    "\"technique\":{\"name\":\"path_trace\",\"backend\":\"cpu\",\"params\":{\"samples\":32,"
    "\"max_bounces\":4}}}";

/* A convex sphere of albedo 0.8 under a constant map of radiance 1 reflects exactly 0.8. */
static void test_furnace(void **state) {
  (void)state;
  obs_result res;
  obs_test_render(FURNACE_DOC, 2, &res);
  double m, se;
  channel_mean(&res.image, "radiance.G", "radiance_stderr.G", &m, &se);
  printf("furnace: %.5f +- %.5f (want 0.8)\n", m, se);
  assert_true(fabs(m - 0.8) < 5 * se + 1e-6);
  obs_result_free(&res);
}

static const char *const SUN_DOC =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,0.01],\"look_at\":[0,0,0],"
    "\"fov_y\":30},\"image\":{\"width\":8,\"height\":8,\"spp\":1},"
    "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-4,0,-4],[-4,0,4],[4,0,4],[4,0,"
    "-4]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},{\"shape\":{\"type\":\"sphere\","
    "\"center\":[0.3,0.5,0],\"radius\":0.3},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
    "\"environment\":{\"map\":\"sky\",\"sun_radius\":8,\"resolution\":16},"
    "\"technique\":{\"name\":\"path_trace\",\"backend\":\"cpu\",\"params\":{\"samples\":%d,"
    "\"max_bounces\":1,\"light_sampling\":\"%s\"}}}";

/* Map sampling with MIS and BSDF sampling alone estimate the same direct light under a sun. */
static void test_mis_agrees(void **state) {
  (void)state;
  obs_result a, b;
  obs_test_render(obs_test_fmt(SUN_DOC, 64, "mis"), 2, &a);
  obs_test_render(obs_test_fmt(SUN_DOC, 256, "bsdf"), 2, &b);
  double ma, sa, mb, sb;
  channel_mean(&a.image, "radiance.R", "radiance_stderr.R", &ma, &sa);
  channel_mean(&b.image, "radiance.R", "radiance_stderr.R", &mb, &sb);
  printf("sun: mis %.5f +- %.5f, bsdf %.5f +- %.5f\n", ma, sa, mb, sb);
  assert_true(fabs(ma - mb) < 5 * sqrt(sa * sa + sb * sb));
  assert_true(sa < sb);
  obs_result_free(&a);
  obs_result_free(&b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_sh_orthonormal), cmocka_unit_test(test_sh_projection),
      cmocka_unit_test(test_pmf),            cmocka_unit_test(test_pinv),
      cmocka_unit_test(test_open_plane),     cmocka_unit_test(test_furnace),
      cmocka_unit_test(test_mis_agrees),     cmocka_unit_test(test_reference),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
