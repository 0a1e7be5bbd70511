/* Sample streams: ranges, determinism, and the net property of scrambled Sobol. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "normalize.h"
#include "sampling.h"
#include "simd.h"
#include "testutil.h"

/* The first 2^m points of a (scrambled) 2D Sobol sequence form a (0,m,2)-net: every elementary
 * box of area 2^-m (2^a x 2^(m-a) grid, any a) holds exactly one point. A wrong direction number
 * or a broken scramble breaks this. */
static void test_sobol_is_a_net(void **state) {
  (void)state;
  for (uint32_t seed = 0; seed < 4; seed++) {
    obs_sampler2d s;
    obs_sampler2d_init(&s, OBS_SAMPLER_SOBOL, 17 + seed, 5, 0, 1, seed);
    for (int m = 1; m <= 10; m++) {
      uint32_t n = 1u << m;
      float *u = malloc(n * sizeof *u), *v = malloc(n * sizeof *v);
      for (uint32_t i = 0; i < n; i++) obs_sampler2d_get(&s, i, &u[i], &v[i]);
      for (int a = 0; a <= m; a++) {
        uint32_t nx = 1u << a, ny = 1u << (m - a);
        unsigned char *seen = calloc(n, 1);
        for (uint32_t i = 0; i < n; i++) {
          assert_true(u[i] >= 0.0f && u[i] < 1.0f && v[i] >= 0.0f && v[i] < 1.0f);
          uint32_t cell = (uint32_t)(u[i] * nx) * ny + (uint32_t)(v[i] * ny);
          assert_int_equal(seen[cell], 0);
          seen[cell] = 1;
        }
        free(seen);
      }
      free(u);
      free(v);
    }
  }
}

static void test_streams_deterministic_and_distinct(void **state) {
  (void)state;
  const obs_sampler_kind kinds[] = {OBS_SAMPLER_SOBOL, OBS_SAMPLER_HALTON, OBS_SAMPLER_RANDOM};
  for (int k = 0; k < 3; k++) {
    obs_sampler2d a, b, c;
    obs_sampler2d_init(&a, kinds[k], 3, 4, 0, 1, 9);
    obs_sampler2d_init(&b, kinds[k], 3, 4, 0, 1, 9);
    obs_sampler2d_init(&c, kinds[k], 4, 3, 0, 1, 9); /* swapped pixel: a different stream */
    int differ = 0;
    double mean = 0;
    for (uint32_t i = 0; i < 4096; i++) {
      float ua, va, ub, vb, uc, vc;
      obs_sampler2d_get(&a, i, &ua, &va);
      obs_sampler2d_get(&b, i, &ub, &vb);
      obs_sampler2d_get(&c, i, &uc, &vc);
      assert_true(ua == ub && va == vb);
      assert_true(ua >= 0.0f && ua < 1.0f && va >= 0.0f && va < 1.0f);
      differ += ua != uc;
      mean += ua + va;
    }
    assert_true(differ > 4000);
    mean /= 8192;
    assert_true(mean > 0.48 && mean < 0.52);
  }
}

static void test_hemisphere_maps(void **state) {
  (void)state;
  /* Extreme inputs stay on the unit hemisphere. */
  const float us[] = {0.0f, 0x1p-24f, 0.5f, 0x1.fffffep-1f};
  for (int i = 0; i < 4; i++)
    for (int j = 0; j < 4; j++) {
      float d[3], e[3];
      obs_sample_cosine(us[i], us[j], d);
      obs_sample_uniform(us[i], us[j], e);
      float ld = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      float le = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
      assert_true(fabsf(ld - 1.0f) < 1e-5f && d[2] >= 0.0f);
      assert_true(fabsf(le - 1.0f) < 1e-5f && e[2] >= 0.0f);
    }
  /* The basis is orthonormal for normals near both poles and in between. */
  const float ns[][3] = {{0, 0, 1}, {0, 0, -1}, {0, 1, 0}, {1e-8f, 0, -1}, {0.6f, 0, 0.8f}};
  for (int i = 0; i < 5; i++) {
    float t[3], b[3];
    obs_onb(ns[i], t, b);
    float tb = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
    float tn = t[0] * ns[i][0] + t[1] * ns[i][1] + t[2] * ns[i][2];
    float tt = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    assert_true(fabsf(tb) < 1e-5f && fabsf(tn) < 1e-5f && fabsf(tt - 1.0f) < 1e-5f);
  }
}

/* Scale-safe normalisation: vectors from 1e-45 to 1e38 in float (1e-320 to 1e308 in double) come
 * out unit length and in the right direction; zero and non-finite vectors are refused; in the
 * ordinary range the result is that of plain v / |v|. */
static void test_normalize_extremes(void **state) {
  (void)state;
  const float fs[] = {1e-45f, 1e-40f, 1e-30f, 1e-20f, 1.0f, 1e20f, 1e30f, 3e38f};
  for (int i = 0; i < 8; i++) {
    float v[3] = {fs[i], -fs[i], fs[i] / 2};
    assert_int_equal(obs_normalize3f(v), 0);
    float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    assert_true(fabsf(l - 1.0f) < 1e-6f);
    assert_true(v[0] > 0 && v[1] < 0);
    /* The frame about a normal that came from a huge or tiny vector is orthonormal. */
    float w[3] = {fs[i], 0.0f, -fs[i]}, t[3], b[3];
    assert_int_equal(obs_normalize3f(w), 0);
    obs_onb(w, t, b);
    float tb = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
    float tn = t[0] * w[0] + t[1] * w[1] + t[2] * w[2];
    float bn = b[0] * w[0] + b[1] * w[1] + b[2] * w[2];
    float tt = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    float bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
    assert_true(fabsf(tb) < 1e-6f && fabsf(tn) < 1e-6f && fabsf(bn) < 1e-6f);
    assert_true(fabsf(tt - 1.0f) < 1e-6f && fabsf(bb - 1.0f) < 1e-6f);
  }
  const double ds[] = {4.9e-324, 1e-310, 1e-200, 1e-150, 1.0, 1e150, 1e200, 1.7e308};
  for (int i = 0; i < 8; i++) {
    double v[3] = {ds[i], ds[i], 0};
    assert_int_equal(obs_normalize3d(v), 0);
    assert_true(fabs(v[0] - sqrt(0.5)) < 1e-15 && v[1] == v[0] && v[2] == 0);
  }
  float z[3] = {0, 0, 0}, inf[3] = {INFINITY, 0, 0}, nan[3] = {NAN, 1, 0};
  assert_int_equal(obs_normalize3f(z), -1);
  assert_int_equal(obs_normalize3f(inf), -1);
  assert_int_equal(obs_normalize3f(nan), -1);
  double dz[3] = {0, 0, 0};
  assert_int_equal(obs_normalize3d(dz), -1);
  /* Ordinary vectors: bit-identical to the plain formula. */
  float o[3] = {0.3f, -1.7f, 2.9f}, p[3];
  float l = sqrtf(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
  for (int k = 0; k < 3; k++) p[k] = o[k] / l;
  assert_int_equal(obs_normalize3f(o), 0);
  assert_memory_equal(o, p, sizeof o);
  /* Power-of-two pre-scaling is exact: a tiny or huge copy gives the same bits. */
  double a[3] = {0.3, -1.7, 2.9}, b[3];
  for (int k = 0; k < 3; k++) b[k] = ldexp(a[k], -1000);
  assert_int_equal(obs_normalize3d(a), 0);
  assert_int_equal(obs_normalize3d(b), 0);
  assert_memory_equal(a, b, sizeof a);
}

/* A run of points equals the points one by one, bit for bit, for every kind, at the baseline and
 * at this CPU's best level, from any start and of any length (vector bodies and remainders). */
static void test_points_in_runs(void **state) {
  (void)state;
  const obs_sampler_kind kinds[] = {OBS_SAMPLER_SOBOL, OBS_SAMPLER_HALTON, OBS_SAMPLER_RANDOM};
  const int isas[] = {OBS_ISA_SSE2, obs_simd_isa()};
  static const uint32_t starts[] = {0, 1, 7, 16, 255, 65531, 0x7ffffff9u, 0xfffffff0u};
  for (int k = 0; k < 3; k++)
    for (int l = 0; l < 2; l++)
      for (int st = 0; st < 8; st++)
        for (uint32_t n = 0; n <= 37; n += 1 + n / 4) {
          obs_sampler2d s;
          obs_sampler2d_init(&s, kinds[k], 3 + st, 11 * st, st, 1, 77);
          float u[40], v[40];
          obs_sampler2d_get_n(&s, starts[st], n, u, v, isas[l]);
          for (uint32_t i = 0; i < n; i++) {
            float a, b;
            obs_sampler2d_get(&s, starts[st] + i, &a, &b);
            assert_memory_equal(&a, &u[i], sizeof a);
            assert_memory_equal(&b, &v[i], sizeof b);
          }
        }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_sobol_is_a_net),
      cmocka_unit_test(test_points_in_runs),
      cmocka_unit_test(test_streams_deterministic_and_distinct),
      cmocka_unit_test(test_hemisphere_maps),
      cmocka_unit_test(test_normalize_extremes),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
