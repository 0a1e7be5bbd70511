/* Scalar volumes (renderer/core/volume.h): trilinear reconstruction against linear fields and at
 * the extremes of shape, the procedural volumes against their formulas, and the macrocell grid's
 * bounds against the field they bound. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"
#include "volume.h"

/* A linear field a + b.x sampled at the voxel centres is reconstructed exactly (to float) between
 * them, and held constant beyond them. */
static void test_trilinear_linear(void **state) {
  (void)state;
  const int n[3] = {7, 5, 4};
  const double s[3] = {0.5, 2.0, 0.25};
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_volume_init(&v, n, s, &err), 0);
  const double b[3] = {0.03, 0.02, 0.1};
  for (int k = 0; k < n[2]; k++)
    for (int j = 0; j < n[1]; j++)
      for (int i = 0; i < n[0]; i++)
        v.data[(k * n[1] + j) * n[0] + i] =
            (float)(0.1 + b[0] * (i + 0.5) * s[0] + b[1] * (j + 0.5) * s[1] +
                    b[2] * (k + 0.5) * s[2]);
  uint32_t seed = 7;
  for (int t = 0; t < 2000; t++) {
    double p[3], q[3];
    for (int a = 0; a < 3; a++) {
      /* Anywhere in the box and a little beyond it. */
      p[a] = (obs_test_unit(&seed) * 1.4 - 0.2) * n[a] * s[a];
      q[a] = fmin(fmax(p[a], 0.5 * s[a]), (n[a] - 0.5) * s[a]); /* held beyond the centres */
    }
    double want = 0.1 + b[0] * q[0] + b[1] * q[1] + b[2] * q[2];
    assert_true(fabs(obs_volume_sample(&v, p) - want) < 1e-6);
  }
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* Degenerate shapes: one voxel, a 4096 x 1 x 1 line, extreme spacings; and refused shapes. */
static void test_shapes_and_refusals(void **state) {
  (void)state;
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  const int one[3] = {1, 1, 1};
  const double s1[3] = {1e-4, 1e-4, 1e-4};
  assert_int_equal(obs_volume_init(&v, one, s1, &err), 0);
  v.data[0] = 0.25f;
  const double far[3] = {-1e30, 5, NAN};
  assert_true(obs_volume_sample(&v, far) == 0.25f);
  obs_volume_free(&v);
  const int line[3] = {4096, 1, 1};
  const double s4[3] = {1e4, 1e4, 1e4};
  assert_int_equal(obs_volume_init(&v, line, s4, &err), 0);
  for (int i = 0; i < 4096; i++) v.data[i] = (float)i / 4095;
  const double mid[3] = {2048.0 * 1e4, 0, 3e4};
  assert_true(fabs(obs_volume_sample(&v, mid) - 2047.5 / 4095) < 1e-6);
  obs_volume_cells c;
  assert_int_equal(obs_volume_cells_build(&v, 8, &c, &err), 0);
  assert_int_equal(c.n[0], 512);
  assert_int_equal(c.n[1], 1);
  assert_true(c.min[0] == 0.0f && c.max[0] == 8.0f / 4095);
  obs_volume_cells_free(&c);
  obs_volume_free(&v);
  const int zero[3] = {4, 0, 4}, huge[3] = {2048, 2048, 1024};
  const double bad[3] = {1, 0, 1}, nan[3] = {1, NAN, 1};
  assert_int_equal(obs_volume_init(&v, zero, s1, &err), OBS_EINVAL);
  assert_int_equal(obs_volume_init(&v, one, bad, &err), OBS_EINVAL);
  assert_int_equal(obs_volume_init(&v, one, nan, &err), OBS_EINVAL);
  assert_int_equal(obs_volume_init(&v, huge, s1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "more than"));
  obs_err_free(&err);
}

/* The procedural formulas at points where they are known, and the sphere's isosurface where the
 * sphere is. */
static void test_procedural(void **state) {
  (void)state;
  const double o[3] = {0, 0, 0}, top[3] = {0, 0, 1}, rim[3] = {0.6, 0, 0};
  /* Marschner-Lobb: (1 - sin(pi z/2) + a (1 + cos(2 pi 6 cos(pi r/2)))) / (2 (1 + a)), a = 0.25. */
  assert_true(fabs(obs_volume_procedural_value(OBS_VOLUME_MARSCHNER_LOBB, 0, o) - 0.6) < 1e-12);
  assert_true(fabs(obs_volume_procedural_value(OBS_VOLUME_MARSCHNER_LOBB, 0, top) - 0.2) < 1e-12);
  assert_true(fabs(obs_volume_procedural_value(OBS_VOLUME_SPHERE, 0, rim) - 0.5) < 1e-12);
  const double tor[3] = {0.85, 0, 0};
  assert_true(fabs(obs_volume_procedural_value(OBS_VOLUME_TORUS, 0, tor) - 0.5) < 1e-12);
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  const int n[3] = {32, 32, 32};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_SPHERE, 0, n, &v, &err), 0);
  /* Along random directions from the centre (object space (1, 1, 1)), the field crosses 0.5 at
   * radius 0.6 within a tenth of a voxel. */
  uint32_t seed = 3;
  for (int t = 0; t < 200; t++) {
    double d[3], l = 0;
    for (int a = 0; a < 3; a++) d[a] = obs_test_unit(&seed) * 2 - 1, l += d[a] * d[a];
    l = sqrt(l);
    if (!(l > 0.1)) continue;
    double lo = 0.3, hi = 0.9;
    for (int it = 0; it < 50; it++) {
      double r = 0.5 * (lo + hi), p[3];
      for (int a = 0; a < 3; a++) p[a] = 1 + r * d[a] / l;
      if (obs_volume_sample(&v, p) > 0.5f)
        lo = r;
      else
        hi = r;
    }
    assert_true(fabs(lo - 0.6) < 0.1 * v.spacing[0]);
  }
  obs_volume_free(&v);
  /* Noise: in [0, 1], the same for a seed, another for another seed. */
  obs_volume a, b, c;
  const int m[3] = {16, 12, 8};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_NOISE, 5, m, &a, &err), 0);
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_NOISE, 5, m, &b, &err), 0);
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_NOISE, 6, m, &c, &err), 0);
  size_t count = 16 * 12 * 8;
  assert_memory_equal(a.data, b.data, count * sizeof(float));
  assert_true(memcmp(a.data, c.data, count * sizeof(float)) != 0);
  float lo = 1, hi = 0;
  for (size_t i = 0; i < count; i++) lo = fminf(lo, a.data[i]), hi = fmaxf(hi, a.data[i]);
  assert_true(lo >= 0 && hi <= 1 && hi - lo > 0.3f);
  obs_volume_free(&a);
  obs_volume_free(&b);
  obs_volume_free(&c);
  obs_err_free(&err);
}

/* A random object-space point p in and a little around v's box, and its continuous voxel index u
 * clamped to the voxel centres (where the field is held beyond them). */
static void random_point(uint32_t *seed, const obs_volume *v, double p[3], double u[3]) {
  for (int a = 0; a < 3; a++) {
    p[a] = (obs_test_unit(seed) * 1.2 - 0.1) * v->n[a] * v->spacing[a];
    u[a] = fmin(fmax(p[a] / v->spacing[a] - 0.5, 0), v->n[a] - 1);
  }
}

/* Every value of the field in a cell lies within the cell's [min, max]. */
static void test_cells_bound_the_field(void **state) {
  (void)state;
  obs_volume v;
  obs_volume_cells c;
  obs_err err = OBS_ERR_INIT;
  const int n[3] = {37, 20, 9};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_MARSCHNER_LOBB, 0, n, &v, &err), 0);
  assert_int_equal(obs_volume_cells_build(&v, 8, &c, &err), 0);
  assert_int_equal(c.n[0], 5);
  assert_int_equal(c.n[1], 3);
  assert_int_equal(c.n[2], 1);
  uint32_t seed = 11;
  for (int t = 0; t < 20000; t++) {
    double p[3], u[3];
    int ci[3];
    random_point(&seed, &v, p, u);
    for (int a = 0; a < 3; a++) {
      ci[a] = (int)(u[a] / c.cell);
      if (ci[a] >= c.n[a]) ci[a] = c.n[a] - 1;
    }
    size_t at = ((size_t)ci[2] * (size_t)c.n[1] + (size_t)ci[1]) * (size_t)c.n[0] + (size_t)ci[0];
    float x = obs_volume_sample(&v, p);
    assert_true(x >= c.min[at] - 1e-6f && x <= c.max[at] + 1e-6f);
  }
  obs_volume_cells_free(&c);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* A voxel cell said to lie below (above) the isovalue holds no sample at or above (below) it, and
 * the sides are those of its corners: each side is seen, and a cell whose corners straddle the
 * isovalue is never settled. Thin axes (1 voxel) have one cell. */
static void test_sides_bound_the_field(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  const int dims[2][3] = {{37, 20, 9}, {12, 1, 5}};
  for (int vi = 0; vi < 2; vi++) {
    obs_volume v;
    obs_volume_sides s;
    const int *n = dims[vi];
    assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_MARSCHNER_LOBB, 0, n, &v, &err), 0);
    assert_int_equal(obs_volume_sides_build(&v, 0.5f, &s, &err), 0);
    for (int a = 0; a < 3; a++) assert_int_equal(s.n[a], n[a] > 1 ? n[a] - 1 : 1);
    int seen[3] = {0, 0, 0};
    uint32_t seed = 12;
    for (int t = 0; t < 20000; t++) {
      double p[3], u[3];
      int ci[3];
      random_point(&seed, &v, p, u);
      for (int a = 0; a < 3; a++) {
        ci[a] = (int)u[a];
        if (ci[a] >= s.n[a]) ci[a] = s.n[a] - 1;
      }
      int side = obs_volume_side(&s, ci[0], ci[1], ci[2]);
      float x = obs_volume_sample(&v, p);
      seen[side]++;
      if (side == OBS_VOLUME_BELOW) assert_true(x < 0.5f);
      if (side == OBS_VOLUME_ABOVE) assert_true(x > 0.5f);
      float lo = 1, hi = 0;
      for (int c = 0; c < 8; c++) {
        int q[3];
        for (int a = 0; a < 3; a++) q[a] = n[a] > 1 ? ci[a] + (c >> a & 1) : 0;
        float y = obs_volume_at(&v, q[0], q[1], q[2]);
        lo = fminf(lo, y), hi = fmaxf(hi, y);
      }
      if (lo <= 0.5f && hi >= 0.5f) assert_int_equal(side, 0);
      if (hi < 0.49f) assert_int_equal(side, OBS_VOLUME_BELOW);
      if (lo > 0.51f) assert_int_equal(side, OBS_VOLUME_ABOVE);
    }
    printf("cell sides (%dx%dx%d): %d open, %d below, %d above of 20000 samples\n", n[0], n[1],
           n[2], seen[0], seen[1], seen[2]);
    for (int k = 0; k < 3; k++) assert_true(seen[k] > 0);
    obs_volume_sides_free(&s);
    obs_volume_free(&v);
  }
  obs_err_free(&err);
}

/* Each brick's far distance is the Chebyshev distance (in bricks, capped) to the nearest brick not
 * wholly on its side, by brute force over the brick grid, and a brick's side is that of all its
 * cells; a sphere volume has bricks far from its surface, inside and out. */
static void test_sides_far_bricks(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  obs_volume v;
  obs_volume_sides s;
  const int n[3] = {97, 81, 66};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_SPHERE, 0, n, &v, &err), 0);
  assert_int_equal(obs_volume_sides_build(&v, 0.5f, &s, &err), 0);
  const int *b = s.bricks;
  int far_seen = 0, sides_seen[3] = {0, 0, 0};
  for (int z = 0; z < b[2]; z++)
    for (int y = 0; y < b[1]; y++)
      for (int x = 0; x < b[0]; x++) {
        int far = s.far[((size_t)z * b[1] + y) * b[0] + x], side = far & 3, dist = far >> 2;
        sides_seen[side]++;
        int all = 3;
        for (int k = z * 8; k < z * 8 + 8 && k < s.n[2]; k++)
          for (int j = y * 8; j < y * 8 + 8 && j < s.n[1]; j++)
            for (int i = x * 8; i < x * 8 + 8 && i < s.n[0]; i++)
              all &= obs_volume_side(&s, i, j, k);
        assert_int_equal(side, all);
        if (!side) {
          assert_int_equal(dist, 0);
          continue;
        }
        int want = OBS_VOLUME_FAR_MAX;
        for (int zz = 0; zz < b[2]; zz++)
          for (int yy = 0; yy < b[1]; yy++)
            for (int xx = 0; xx < b[0]; xx++) {
              if ((s.far[((size_t)zz * b[1] + yy) * b[0] + xx] & 3) == side) continue;
              int d = abs(xx - x);
              d = abs(yy - y) > d ? abs(yy - y) : d;
              d = abs(zz - z) > d ? abs(zz - z) : d;
              want = d < want ? d : want;
            }
        assert_int_equal(dist, want);
        far_seen += dist >= 2;
      }
  printf("far bricks (%dx%dx%d bricks): %d mixed, %d below, %d above, %d at 2 or more\n", b[0],
         b[1], b[2], sides_seen[0], sides_seen[1], sides_seen[2], far_seen);
  assert_true(sides_seen[0] > 0 && sides_seen[1] > 0 && sides_seen[2] > 0 && far_seen > 0);
  obs_volume_sides_free(&s);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* A fill's samples are the formula's, bit for bit, for every kind (Marschner-Lobb is filled by its
 * separable terms), and a part of the lattice holds the whole fill's samples. */
static void test_fill_parts_are_the_formula(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  const int full[3] = {19, 14, 11}, off[3] = {3, 0, 5}, n[3] = {9, 14, 4};
  for (int kind = 0; kind < OBS_VOLUME_PROCEDURAL_COUNT; kind++) {
    obs_volume whole, part;
    assert_int_equal(obs_volume_procedural_fill(kind, 3, full, &whole, &err), 0);
    assert_int_equal(obs_volume_procedural_fill_part(kind, 3, full, off, n, &part, &err), 0);
    for (int k = 0; k < full[2]; k++)
      for (int j = 0; j < full[1]; j++)
        for (int i = 0; i < full[0]; i++) {
          double x[3] = {-1 + (i + 0.5) * (2.0 / full[0]), -1 + (j + 0.5) * (2.0 / full[1]),
                         -1 + (k + 0.5) * (2.0 / full[2])};
          float want = (float)obs_volume_procedural_value(kind, 3, x);
          assert_true(obs_volume_at(&whole, i, j, k) == want);
          int in = i >= off[0] && i < off[0] + n[0] && j >= off[1] && j < off[1] + n[1] &&
                   k >= off[2] && k < off[2] + n[2];
          if (in) assert_true(obs_volume_at(&part, i - off[0], j - off[1], k - off[2]) == want);
        }
    assert_true(part.spacing[0] == whole.spacing[0] && part.spacing[2] == whole.spacing[2]);
    obs_volume_free(&whole);
    obs_volume_free(&part);
  }
  const int outside[3] = {3, 0, 8};
  obs_volume v;
  assert_int_equal(obs_volume_procedural_fill_part(OBS_VOLUME_SPHERE, 0, full, outside, n, &v, &err),
                   OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "[8, 12) of 11 voxels on axis 2"));
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_trilinear_linear),
      cmocka_unit_test(test_shapes_and_refusals),
      cmocka_unit_test(test_procedural),
      cmocka_unit_test(test_cells_bound_the_field),
      cmocka_unit_test(test_sides_bound_the_field),
      cmocka_unit_test(test_sides_far_bricks),
      cmocka_unit_test(test_fill_parts_are_the_formula),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
