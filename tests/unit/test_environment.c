/* Environment cube maps (renderer/core/environment.h) against analytic ground truth: the Vulkan
 * face table by hand, texel solid angles against 4 pi and a direct quadrature, lat-long conversion
 * of known functions and of spots at known places, spherical-harmonic irradiance against the
 * closed form for linear environments and against the brute-force reference for the sky, EXR
 * round trips and the refusals of bad input. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "environment.h"
#include "testutil.h"

#define PI 3.14159265358979323846

static void random_dir(uint32_t *seed, float d[3]) {
  double z = 2 * obs_test_unit(seed) - 1, phi = 2 * PI * obs_test_unit(seed);
  double r = sqrt(fmax(0, 1 - z * z));
  d[0] = (float)(r * cos(phi));
  d[1] = (float)(r * sin(phi));
  d[2] = (float)z;
}

static int rel_close(double got, double want, double tol) {
  return fabs(got - want) <= tol * fmax(fabs(want), 1e-30);
}

/* Six res x res faces from fn(dir, channel) at the texel centres, in obs_env_from_faces layout. */
typedef double (*dir_fn)(const double d[3], int c);
static float *faces_of(int res, dir_fn fn, const float *faces[6]) {
  float *all = malloc(sizeof(float) * 6 * res * res * 3);
  assert_non_null(all);
  for (int f = 0; f < 6; f++) {
    faces[f] = all + (size_t)f * res * res * 3;
    for (int j = 0; j < res; j++)
      for (int i = 0; i < res; i++) {
        double d[3];
        obs_env_face_dir(f, (i + 0.5) / res, (j + 0.5) / res, d);
        for (int c = 0; c < 3; c++)
          all[((size_t)(f * res + j) * res + i) * 3 + c] = (float)fn(d, c);
      }
  }
  return all;
}

/* A w x h lat-long image of fn, each pixel at the direction the header's convention gives it. */
static float *latlong_of(int w, int h, dir_fn fn) {
  float *img = malloc(sizeof(float) * w * h * 3);
  assert_non_null(img);
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      double theta = PI * (y + 0.5) / h, phi = 2 * PI * ((x + 0.5) / w - 0.5);
      double d[3] = {sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi)};
      for (int c = 0; c < 3; c++) img[((size_t)y * w + x) * 3 + c] = (float)fn(d, c);
    }
  return img;
}

/* Texel (3, 0) of every face at res 4 (s = 0.875, t = 0.125: sc = 0.75, tc = -0.75) is looked up
 * exactly at the direction the Vulkan table gives it, written out by hand here; the faces hold
 * (face, i, j) so a wrong face or a flipped axis shows. */
static void test_face_table(void **state) {
  (void)state;
  const int res = 4;
  float *all = malloc(sizeof(float) * 6 * res * res * 3);
  const float *faces[6];
  for (int f = 0; f < 6; f++) {
    faces[f] = all + f * res * res * 3;
    for (int j = 0; j < res; j++)
      for (int i = 0; i < res; i++) {
        float *p = all + ((f * res + j) * res + i) * 3;
        p[0] = (float)f, p[1] = (float)i, p[2] = (float)j;
      }
  }
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_from_faces(&e, faces, res, &err), 0);
  const float dirs[6][3] = {{1, 0.75f, -0.75f}, {-1, 0.75f, 0.75f}, {0.75f, 1, -0.75f},
                            {0.75f, -1, 0.75f}, {0.75f, 0.75f, 1},  {-0.75f, 0.75f, -1}};
  for (int f = 0; f < 6; f++) {
    float rgb[3], scaled[3] = {3 * dirs[f][0], 3 * dirs[f][1], 3 * dirs[f][2]};
    obs_env_lookup(&e, scaled, rgb);
    assert_true(rgb[0] == f && rgb[1] == 3 && rgb[2] == 0);
    double d[3], s, t, dd[3] = {dirs[f][0], dirs[f][1], dirs[f][2]};
    assert_int_equal(obs_env_face_coords(dd, &s, &t), f);
    assert_true(fabs(s - 0.875) < 1e-15 && fabs(t - 0.125) < 1e-15);
    obs_env_face_dir(f, 0.875, 0.125, d);
    double l = sqrt(dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]);
    for (int a = 0; a < 3; a++) assert_true(fabs(d[a] - dd[a] / l) < 1e-15);
  }
  /* Face and coordinates round-trip for random directions. */
  uint32_t seed = 11;
  for (int k = 0; k < 1000; k++) {
    float r[3];
    random_dir(&seed, r);
    double d[3] = {r[0], r[1], r[2]}, back[3], s, t;
    int f = obs_env_face_coords(d, &s, &t);
    assert_true(f >= 0 && f < 6);
    obs_env_face_dir(f, s, t, back);
    for (int a = 0; a < 3; a++) assert_true(fabs(back[a] - d[a]) < 1e-6);
  }
  const double zero[3] = {0, 0, 0}, nan3[3] = {NAN, 0, 1};
  double s, t;
  assert_int_equal(obs_env_face_coords(zero, &s, &t), -1);
  assert_int_equal(obs_env_face_coords(nan3, &s, &t), -1);
  obs_env_free(&e);
  free(all);
  obs_err_free(&err);
}

/* The integrand of the solid angle over a face at distance 1: dA / (1 + x^2 + y^2)^(3/2). */
static double solid_angle_midpoint(double x0, double x1, double y0, double y1, int n) {
  double sum = 0, hx = (x1 - x0) / n, hy = (y1 - y0) / n;
  for (int b = 0; b < n; b++)
    for (int a = 0; a < n; a++) {
      double x = x0 + (a + 0.5) * hx, y = y0 + (b + 0.5) * hy;
      sum += hx * hy / pow(1 + x * x + y * y, 1.5);
    }
  return sum;
}

static void test_solid_angles(void **state) {
  (void)state;
  const int sizes[3] = {1, 7, 64};
  for (int k = 0; k < 3; k++) {
    int r = sizes[k];
    double sum = 0;
    for (int j = 0; j < r; j++)
      for (int i = 0; i < r; i++) {
        double o = obs_env_texel_solid_angle(r, i, j);
        assert_true(o > 0);
        /* Symmetric under the face's mirror images and its transpose. */
        assert_true(fabs(o - obs_env_texel_solid_angle(r, r - 1 - i, j)) < 1e-15);
        assert_true(fabs(o - obs_env_texel_solid_angle(r, j, i)) < 1e-15);
        sum += 6 * o;
      }
    assert_true(rel_close(sum, 4 * PI, 1e-9));
  }
  assert_true(rel_close(obs_env_texel_solid_angle(1, 0, 0), 4 * PI / 6, 1e-14));
  /* A corner texel and an inner one against a midpoint rule (error ~1e-7 at 400^2 points). */
  assert_true(rel_close(obs_env_texel_solid_angle(7, 0, 0),
                        solid_angle_midpoint(-1, -1 + 2.0 / 7, -1, -1 + 2.0 / 7, 400), 1e-6));
  assert_true(rel_close(
      obs_env_texel_solid_angle(7, 4, 2),
      solid_angle_midpoint(-1 + 8.0 / 7, -1 + 10.0 / 7, -1 + 4.0 / 7, -1 + 6.0 / 7, 400), 1e-6));
  assert_true(obs_env_texel_solid_angle(7, 7, 0) == 0 && obs_env_texel_solid_angle(0, 0, 0) == 0);
}

static const double L_const[3] = {0.3, 1.5, 7.0};
static double constant_fn(const double d[3], int c) {
  (void)d;
  return L_const[c];
}

/* A constant environment is L everywhere: lookups, mean, SH and reference irradiance; at res 1
 * and, from faces, at res 16. */
static void test_constant(void **state) {
  (void)state;
  obs_env envs[2];
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_constant(&envs[0], L_const, &err), 0);
  assert_int_equal(envs[0].res, 1);
  const float *faces[6];
  float *all = faces_of(16, constant_fn, faces);
  assert_int_equal(obs_env_from_faces(&envs[1], faces, 16, &err), 0);
  free(all);
  uint32_t seed = 3;
  for (int k = 0; k < 2; k++) {
    const obs_env *e = &envs[k];
    double mean[3], sh[9][3];
    obs_env_mean(e, mean);
    obs_env_sh9(e, sh);
    for (int c = 0; c < 3; c++) assert_true(rel_close(mean[c], (float)L_const[c], 1e-12));
    for (int t = 0; t < 200; t++) {
      float d[3], rgb[3], irr[3], ref[3];
      random_dir(&seed, d);
      obs_env_lookup(e, d, rgb);
      obs_env_sh_irradiance((const double(*)[3])sh, d, irr);
      obs_env_irradiance_ref(e, d, ref);
      for (int c = 0; c < 3; c++) {
        assert_true(rel_close(rgb[c], L_const[c], 1e-6));
        assert_true(rel_close(irr[c], L_const[c], 1e-4));
        assert_true(rel_close(ref[c], L_const[c], 1e-4));
      }
    }
    /* Degenerate directions give the mean. */
    const float bad[4][3] = {{0, 0, 0}, {NAN, 1, 0}, {INFINITY, 0, 0}, {0, -INFINITY, NAN}};
    for (int b = 0; b < 4; b++) {
      float rgb[3], irr[3], ref[3];
      obs_env_lookup(e, bad[b], rgb);
      obs_env_sh_irradiance((const double(*)[3])sh, bad[b], irr);
      obs_env_irradiance_ref(e, bad[b], ref);
      for (int c = 0; c < 3; c++)
        assert_true(rel_close(rgb[c], L_const[c], 1e-6) && rel_close(irr[c], L_const[c], 1e-6) &&
                    rel_close(ref[c], L_const[c], 1e-6));
    }
    obs_env_free(&envs[k]);
  }
  assert_null(envs[0].data);
  obs_err_free(&err);
}

/* Linear in the direction, a different axis per channel, so both elevation and azimuth show. */
static double linear_fn(const double d[3], int c) {
  static const double a[3][3] = {{0, 1, 0}, {0.8, 0, 0}, {0.3, -0.4, 0.5}};
  return 1 + a[c][0] * d[0] + a[c][1] * d[1] + a[c][2] * d[2];
}

/* A lat-long image of known functions converts so that lookups follow the functions. In a face's
 * interior the error is second order (bilinear, box filter: well under 2e-3 at res 32); within
 * half a texel of an edge the lookup holds the edge texels' value, off by at most the angular
 * distance to their centres (<= sqrt(2) / res radians) times the gradient (<= 1 per radian). */
static void test_latlong_function(void **state) {
  (void)state;
  const int w = 512, h = 256, res = 32;
  float *img = latlong_of(w, h, linear_fn);
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_from_latlong(&e, img, w, h, res, &err), 0);
  uint32_t seed = 5;
  double worst_in = 0, worst_edge = 0;
  for (int k = 0; k < 5000; k++) {
    float d[3], rgb[3];
    random_dir(&seed, d);
    obs_env_lookup(&e, d, rgb);
    double dd[3] = {d[0], d[1], d[2]}, s, t;
    obs_env_face_coords(dd, &s, &t);
    double u = s * res, v = t * res;
    int edge = u < 0.5 || u > res - 0.5 || v < 0.5 || v > res - 0.5;
    double l = sqrt(dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]);
    for (int a = 0; a < 3; a++) dd[a] /= l;
    for (int c = 0; c < 3; c++) {
      double e_abs = fabs(rgb[c] - linear_fn(dd, c));
      if (edge)
        worst_edge = fmax(worst_edge, e_abs);
      else
        worst_in = fmax(worst_in, e_abs);
    }
  }
  print_message("lat-long linear: worst interior error %.2e, worst edge error %.2e\n", worst_in,
                worst_edge);
  assert_true(worst_in < 2e-3);
  assert_true(worst_edge < sqrt(2.0) / res + 2e-3);
  obs_env_free(&e);
  free(img);
  obs_err_free(&err);
}

/* A spot placed by hand in the image (by pixel, not through the convention's formula) appears
 * where the header says: u = 0.75 is +X, the centre -Z, the left and right edges +Z (wrapping),
 * the top row +Y, the bottom row -Y. */
static void test_latlong_spots(void **state) {
  (void)state;
  const int w = 64, h = 32, res = 8;
  const struct {
    int x0, x1, y0, y1; /* the lit pixels, inclusive */
    float dir[3];
  } spots[] = {{47, 48, 15, 16, {1, 0, 0}},  {15, 16, 15, 16, {-1, 0, 0}},
               {31, 32, 15, 16, {0, 0, -1}}, {63, 64, 15, 16, {0, 0, 1}},
               {0, 63, 0, 0, {0, 1, 0}},     {0, 63, 31, 31, {0, -1, 0}}};
  const float axes[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  float *img = malloc(sizeof(float) * w * h * 3);
  for (size_t k = 0; k < sizeof spots / sizeof spots[0]; k++) {
    memset(img, 0, sizeof(float) * w * h * 3);
    for (int y = spots[k].y0; y <= spots[k].y1; y++)
      for (int x = spots[k].x0; x <= spots[k].x1; x++)
        for (int c = 0; c < 3; c++) img[((size_t)y * w + (x % w)) * 3 + c] = 1;
    obs_env e;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_env_from_latlong(&e, img, w, h, res, &err), 0);
    float at[3], rgb[3], anti[3] = {-spots[k].dir[0], -spots[k].dir[1], -spots[k].dir[2]};
    obs_env_lookup(&e, spots[k].dir, at);
    assert_true(at[0] > 0.1f);
    for (int a = 0; a < 6; a++) {
      obs_env_lookup(&e, axes[a], rgb);
      assert_true(rgb[0] <= at[0]);
    }
    obs_env_lookup(&e, anti, rgb);
    assert_true(rgb[0] == 0);
    obs_env_free(&e);
    obs_err_free(&err);
  }
  free(img);
}

/* A source much smaller than a cube texel keeps its power: a 3 x 3 block of a 2048 x 1024 image
 * (0.5 degrees across) in a res 16 cube map (texels of ~7 degrees). The pixels' solid angles are
 * (2 pi / w) (pi / h) sin(theta); the bilinear tents sampled at the pixel spacing sum to one
 * whatever their phase, so what remains is the sampling of the block's rim: well under 1%. */
static void test_latlong_power(void **state) {
  (void)state;
  const int w = 2048, h = 1024, res = 16;
  float *img = calloc((size_t)w * h * 3, sizeof(float));
  assert_non_null(img);
  double power = 0;
  for (int y = 300; y < 303; y++)
    for (int x = 1500; x < 1503; x++) {
      for (int c = 0; c < 3; c++) img[((size_t)y * w + x) * 3 + c] = 1000.0f * (c + 1);
      power += 1000 * (2 * PI / w) * (PI / h) * sin(PI * (y + 0.5) / h);
    }
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_from_latlong(&e, img, w, h, res, &err), 0);
  double mean[3];
  obs_env_mean(&e, mean);
  print_message("lat-long spot power: %.6g, cube map %.6g\n", power, 4 * PI * mean[0]);
  for (int c = 0; c < 3; c++) assert_true(rel_close(4 * PI * mean[c], power * (c + 1), 0.01));
  obs_env_free(&e);
  free(img);
  obs_err_free(&err);
}

/* SH of L = 1 + a . w: the irradiance is exact for bands <= 1, and
 * (1/pi) int (1 + a . w) max(0, n . w) dw = 1 + (a . n) (1/pi) int_hemisphere cos^2 = 1 + (2/3)
 * a.n. At res 64 the texel-centre projection is within ~1e-4 of it; the reference, which holds each
 * texel constant, within ~1e-4 too. */
static void test_sh_linear(void **state) {
  (void)state;
  const int res = 64;
  const float *faces[6];
  float *all = faces_of(res, linear_fn, faces);
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_from_faces(&e, faces, res, &err), 0);
  free(all);
  double sh[9][3];
  obs_env_sh9(&e, sh);
  /* c00 = sqrt(4 pi); c1m = sqrt(4 pi / 3) a_m; band 2 vanishes. */
  static const double a[3][3] = {{0, 1, 0}, {0.8, 0, 0}, {0.3, -0.4, 0.5}};
  for (int c = 0; c < 3; c++) {
    assert_true(fabs(sh[0][c] - sqrt(4 * PI)) < 1e-6);
    assert_true(fabs(sh[1][c] - sqrt(4 * PI / 3) * a[c][1]) < 1e-3);
    assert_true(fabs(sh[2][c] - sqrt(4 * PI / 3) * a[c][2]) < 1e-3);
    assert_true(fabs(sh[3][c] - sqrt(4 * PI / 3) * a[c][0]) < 1e-3);
    for (int k = 4; k < 9; k++) assert_true(fabs(sh[k][c]) < 1e-6);
  }
  uint32_t seed = 9;
  double worst_sh = 0, worst_ref = 0;
  for (int t = 0; t < 100; t++) {
    float n[3], irr[3], ref[3];
    random_dir(&seed, n);
    obs_env_sh_irradiance((const double(*)[3])sh, n, irr);
    obs_env_irradiance_ref(&e, n, ref);
    for (int c = 0; c < 3; c++) {
      double want = 1 + (2.0 / 3) * (a[c][0] * n[0] + a[c][1] * n[1] + a[c][2] * n[2]);
      worst_sh = fmax(worst_sh, fabs(irr[c] - want));
      worst_ref = fmax(worst_ref, fabs(ref[c] - want));
    }
  }
  print_message("linear environment: worst SH error %.2e, worst reference error %.2e\n", worst_sh,
                worst_ref);
  assert_true(worst_sh < 1e-3);
  assert_true(worst_ref < 1e-3);
  obs_env_free(&e);
  obs_err_free(&err);
}

/* The sky's formula at known directions, and its continuity across the horizon and the rim. */
static void test_sky_radiance(void **state) {
  (void)state;
  obs_env_sky_params p;
  obs_env_sky_default(&p);
  double rgb[3];
  const double up[3] = {0, 5, 0}, side[3] = {0.6, 0, 0.8}, down[3] = {0.1, -1, 0};
  obs_env_sky_radiance(&p, up, rgb);
  for (int c = 0; c < 3; c++) assert_true(fabs(rgb[c] - p.zenith[c]) < 1e-12);
  obs_env_sky_radiance(&p, side, rgb);
  for (int c = 0; c < 3; c++) assert_true(fabs(rgb[c] - p.horizon[c]) < 1e-12);
  obs_env_sky_radiance(&p, down, rgb);
  for (int c = 0; c < 3; c++) assert_true(fabs(rgb[c] - p.ground[c]) < 1e-12);
  double h = sqrt(0.5); /* the sun is 45 degrees up */
  obs_env_sky_radiance(&p, p.sun_dir, rgb);
  for (int c = 0; c < 3; c++)
    assert_true(fabs(rgb[c] -
                     (p.horizon[c] + (p.zenith[c] - p.horizon[c]) * h + p.sun_radiance[c])) < 1e-9);
  const double a1[3] = {1, 1e-9, 0}, a2[3] = {1, -1e-9, 0};
  double r1[3], r2[3];
  obs_env_sky_radiance(&p, a1, r1);
  obs_env_sky_radiance(&p, a2, r2);
  for (int c = 0; c < 3; c++) assert_true(fabs(r1[c] - r2[c]) < 1e-6);
}

/* (1/pi) int L max(0, n . w) dw for the sun alone facing it: int w(a) cos a 2 pi sin a da / pi,
 * by Simpson's rule. */
static double sun_irradiance(double radius_deg) {
  double r = radius_deg * PI / 180, hi = 1.1 * r, sum = 0;
  const int n = 2000;
  for (int k = 0; k <= n; k++) {
    double a = hi * k / n, x = (a - 0.9 * r) / (0.2 * r);
    double s = x <= 0 ? 0 : x >= 1 ? 1 : x * x * (3 - 2 * x);
    double f = (1 - s) * cos(a) * 2 * PI * sin(a);
    sum += f * (k == 0 || k == n ? 1 : k % 2 ? 4 : 2);
  }
  return sum * hi / n / 3 / PI;
}

/* SH irradiance against the reference on the sky, and the sun's power through the cube map.
 * Tolerances: both paths sum the same texels, with the clamped-cosine kernel max(0, c) replaced
 * in the SH path by its band-2 truncation 1/4 + c/2 + (5/16)(3c^2 - 1)/2, which is off by at most
 * 3/32 (at c = 0). So |SH - ref| <= (3/32) (1/pi) int L dw = (3/8) mean for any environment; the
 * reference's own discretisation (texels held constant) adds well under 1% of the mean. Without
 * the sun the sky is smooth and Ramamoorthi and Hanrahan's average error (< 3%) applies. */
static void test_sky_irradiance(void **state) {
  (void)state;
  obs_env_sky_params p;
  obs_env_sky_default(&p);
  obs_env sky, clear;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_sky(&sky, &p, 32, &err), 0);
  p.sun_radius_deg = 0;
  assert_int_equal(obs_env_sky(&clear, &p, 32, &err), 0);
  obs_env_sky_default(&p);
  double sh[9][3], sh_clear[9][3], mean[3];
  obs_env_sh9(&sky, sh);
  obs_env_sh9(&clear, sh_clear);
  obs_env_mean(&sky, mean);
  uint32_t seed = 21;
  double worst = 0, rel_clear = 0;
  const int trials = 200;
  for (int t = 0; t < trials; t++) {
    float n[3], irr[3], ref[3];
    random_dir(&seed, n);
    obs_env_sh_irradiance((const double(*)[3])sh, n, irr);
    obs_env_irradiance_ref(&sky, n, ref);
    for (int c = 0; c < 3; c++) {
      assert_true(fabs(irr[c] - ref[c]) <= (3.0 / 8 + 0.01) * mean[c]);
      worst = fmax(worst, fabs(irr[c] - ref[c]) / mean[c]);
    }
    obs_env_sh_irradiance((const double(*)[3])sh_clear, n, irr);
    obs_env_irradiance_ref(&clear, n, ref);
    for (int c = 0; c < 3; c++) rel_clear += fabs(irr[c] - ref[c]) / ref[c] / (3 * trials);
  }
  print_message(
      "sky: worst |SH - ref| / mean %.3f (bound 0.385); clear sky mean relative "
      "error %.4f\n",
      worst, rel_clear);
  assert_true(rel_clear < 0.03);
  /* Facing the sun, the sun adds its analytic irradiance, about twice the sky's. The texels'
   * solid-angle-weighted supersampling keeps its power even at res 8, where it is smaller than one
   * texel; the reference holds that texel constant while the cosine varies over it: 1% at most. */
  float sun[3] = {(float)p.sun_dir[0], (float)p.sun_dir[1], (float)p.sun_dir[2]}, with[3],
        without[3];
  obs_env_irradiance_ref(&clear, sun, without);
  const int sizes[3] = {8, 32, 128};
  const double rec709[3] = {0.2126, 0.7152, 0.0722};
  for (int k = 0; k < 3; k++) {
    obs_env e;
    assert_int_equal(obs_env_sky(&e, &p, sizes[k], &err), 0);
    obs_env_irradiance_ref(&e, sun, with);
    double y_sun = 0, y_sky = 0;
    for (int c = 0; c < 3; c++) {
      double want = p.sun_radiance[c] * sun_irradiance(p.sun_radius_deg);
      assert_true(rel_close(with[c] - without[c], want, 0.01));
      y_sun += rec709[c] * want;
      y_sky += rec709[c] * without[c];
    }
    assert_true(y_sun > 1.5 * y_sky && y_sun < 2.5 * y_sky);
    obs_env_free(&e);
  }
  obs_env_free(&sky);
  obs_env_free(&clear);
  obs_err_free(&err);
}

static int write_rgb_exr(const char *path, const float *rgb, int w, int h, int extra) {
  const char *names[4] = {"R", "G", "B", "A"};
  obs_image img;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(&img, w, h, extra ? 4 : 3, names, &err), 0);
  for (size_t k = 0; k < (size_t)w * h; k++)
    for (int c = 0; c < 3; c++) obs_image_channel(&img, names[c])[k] = rgb[k * 3 + c];
  int rc = obs_image_write_exr(&img, path, &err);
  obs_image_free(&img);
  obs_err_free(&err);
  return rc;
}

/* Files read back to exactly the cube maps the same pixels give in memory. */
static void test_exr_round_trip(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("environment");
  char ll_path[512], face_paths[6][512];
  const int w = 40, h = 20, res = 8;
  float *img = latlong_of(w, h, linear_fn);
  snprintf(ll_path, sizeof ll_path, "%s", obs_test_path(dir, "sky.exr"));
  assert_int_equal(write_rgb_exr(ll_path, img, w, h, 1), 0);
  obs_env a, b;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_from_latlong(&a, img, w, h, res, &err), 0);
  assert_int_equal(obs_env_from_latlong_file(&b, ll_path, res, &err), 0);
  assert_int_equal(b.res, res);
  assert_memory_equal(a.data, b.data, sizeof(float) * 6 * res * res * 3);
  obs_env_free(&b);

  const float *faces[6];
  const char *paths[6];
  for (int f = 0; f < 6; f++) {
    faces[f] = obs_env_texel(&a, f, 0, 0);
    snprintf(face_paths[f], sizeof face_paths[f], "%s",
             obs_test_path(dir, obs_test_fmt("face%d.exr", f)));
    paths[f] = face_paths[f];
    assert_int_equal(write_rgb_exr(paths[f], faces[f], res, res, 0), 0);
  }
  assert_int_equal(obs_env_from_face_files(&b, paths, &err), 0);
  assert_memory_equal(a.data, b.data, sizeof(float) * 6 * res * res * 3);
  for (int c = 0; c < 3; c++) assert_true(a.mean[c] == b.mean[c]);
  obs_env_free(&b);

  /* A face of the wrong size, a missing file, a file without B. */
  assert_int_equal(write_rgb_exr(paths[3], faces[3], 4, 4, 0), 0);
  assert_int_equal(obs_env_from_face_files(&b, paths, &err), OBS_EINVAL);
  assert_null(b.data);
  assert_non_null(strstr(obs_err_message(&err), paths[3]));
  assert_non_null(strstr(obs_err_message(&err), "face -Y is 4 x 4 pixels, but face +X"));
  obs_err_clear(&err);
  assert_int_equal(write_rgb_exr(paths[3], faces[3], 8, 4, 0), 0);
  assert_int_equal(obs_env_from_face_files(&b, paths, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "not square"));
  obs_err_clear(&err);
  const char *missing = obs_test_path(dir, "no-such.exr");
  assert_true(obs_env_from_latlong_file(&b, missing, res, &err) < 0);
  assert_null(b.data);
  assert_non_null(strstr(obs_err_message(&err), "no-such.exr"));
  obs_err_clear(&err);
  const char *two[2] = {"R", "G"};
  obs_image rg;
  assert_int_equal(obs_image_init(&rg, 4, 2, 2, two, &err), 0);
  assert_int_equal(obs_image_write_exr(&rg, ll_path, &err), 0);
  obs_image_free(&rg);
  assert_int_equal(obs_env_from_latlong_file(&b, ll_path, res, &err), OBS_ENOTFOUND);
  assert_non_null(strstr(obs_err_message(&err), "sky.exr: EXR has no channel \"B\""));
  obs_env_free(&a);
  free(img);
  obs_err_free(&err);
}

/* Bad values, shapes and parameters are refused with the culprit named, and leave nothing. */
static void test_refusals(void **state) {
  (void)state;
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  float img[4 * 3 * 3];
  for (int k = 0; k < 36; k++) img[k] = 0.5f;
  img[(2 * 4 + 3) * 3 + 1] = -1; /* pixel (3, 2), G */
  assert_int_equal(obs_env_from_latlong(&e, img, 4, 3, 8, &err), OBS_EINVAL);
  assert_null(e.data);
  assert_non_null(strstr(obs_err_message(&err), "pixel (3, 2) channel G is -1"));
  obs_err_clear(&err);
  img[(2 * 4 + 3) * 3 + 1] = 0.5f;
  assert_int_equal(obs_env_from_latlong(&e, img, 1, 12, 8, &err), OBS_EINVAL);
  assert_int_equal(obs_env_from_latlong(&e, img, 4, 0, 8, &err), OBS_EINVAL);
  assert_int_equal(obs_env_from_latlong(&e, img, 4, 3, 0, &err), OBS_EINVAL);
  assert_int_equal(obs_env_from_latlong(&e, img, 4, 3, OBS_ENV_MAX_RES + 1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "resolution 2049 is outside [1, 2048]"));
  obs_err_clear(&err);

  const float *faces[6];
  float *all = faces_of(2, constant_fn, faces);
  all[(4 * 4 + 1 * 2 + 0) * 3 + 2] = NAN; /* face 4 (+Z), texel (0, 1), B */
  assert_int_equal(obs_env_from_faces(&e, faces, 2, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "face +Z texel (0, 1) channel B is nan"));
  faces[2] = NULL;
  assert_int_equal(obs_env_from_faces(&e, faces, 2, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "face +Y is missing"));
  free(all);
  obs_err_clear(&err);

  const double neg[3] = {1, -0.5, 1}, inf[3] = {INFINITY, 0, 0};
  assert_int_equal(obs_env_constant(&e, neg, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "rgb[1] is -0.5"));
  assert_int_equal(obs_env_constant(&e, inf, &err), OBS_EINVAL);
  obs_err_clear(&err);

  obs_env_sky_params p;
  obs_env_sky_default(&p);
  p.ground[2] = -1;
  assert_int_equal(obs_env_sky(&e, &p, 8, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "ground[2] is -1"));
  obs_env_sky_default(&p);
  p.sun_radius_deg = 50;
  assert_int_equal(obs_env_sky(&e, &p, 8, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "sun_radius_deg is 50"));
  obs_env_sky_default(&p);
  p.sun_dir[0] = p.sun_dir[1] = p.sun_dir[2] = 0;
  assert_int_equal(obs_env_sky(&e, &p, 8, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "sun_dir"));
  p.sun_radius_deg = 0; /* without a sun its direction does not matter */
  assert_int_equal(obs_env_sky(&e, &p, 8, &err), 0);
  obs_env_free(&e);
  obs_err_free(&err);
}

/* Lookups stay finite and within the texel range for extreme directions. */
static void test_lookup_extremes(void **state) {
  (void)state;
  obs_env_sky_params p;
  obs_env_sky_default(&p);
  obs_env e;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_env_sky(&e, &p, 16, &err), 0);
  const float dirs[][3] = {{3e38f, 3e38f, -3e38f},    {1e-45f, 0, 0},
                           {-1e-45f, 1e-45f, 1e-45f}, {1, 1, 1},
                           {0, -1e30f, 1e-30f},       {-0.0f, 0, 1}};
  float hi = 0;
  for (size_t k = 0; k < 6 * 16 * 16 * 3; k++) hi = fmaxf(hi, e.data[k]);
  for (size_t k = 0; k < sizeof dirs / sizeof dirs[0]; k++) {
    float rgb[3];
    obs_env_lookup(&e, dirs[k], rgb);
    for (int c = 0; c < 3; c++) assert_true(isfinite(rgb[c]) && rgb[c] >= 0 && rgb[c] <= hi);
  }
  obs_env_free(&e);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_face_table),     cmocka_unit_test(test_solid_angles),
      cmocka_unit_test(test_constant),       cmocka_unit_test(test_latlong_function),
      cmocka_unit_test(test_latlong_spots),  cmocka_unit_test(test_latlong_power),
      cmocka_unit_test(test_sh_linear),      cmocka_unit_test(test_sky_radiance),
      cmocka_unit_test(test_sky_irradiance), cmocka_unit_test(test_exr_round_trip),
      cmocka_unit_test(test_refusals),       cmocka_unit_test(test_lookup_extremes),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
