/* Marching volumes (renderer/techniques/volume_ao/volume_march.h) against analytic spheres:
 * first-hit depth within a tenth of a voxel with and without macrocell skipping, gradient normals,
 * AO = 1 on a lone convex sphere, and the occlusion of a sphere by another, 1 - cos(alpha) (r/d)^2. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"
#include "simd.h"
#include "volume_march.h"

static void unit_dir(uint32_t *s, double d[3]) {
  double l;
  do {
    for (int a = 0; a < 3; a++) d[a] = obs_test_unit(s) * 2 - 1;
    l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  } while (!(l > 0.2 && l <= 1));
  for (int a = 0; a < 3; a++) d[a] /= l;
}

/* The procedural sphere (radius 0.6 about object-space (1, 1, 1)) hit from outside along random
 * rays through its centre: the hit lies on the sphere within a tenth of a voxel, the normal is
 * radial, and skipping empty macrocells finds the same point. */
static void test_first_hit_sphere(void **state) {
  (void)state;
  obs_volume v;
  obs_volume_cells c;
  obs_err err = OBS_ERR_INIT;
  const int n[3] = {64, 64, 64};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_SPHERE, 0, n, &v, &err), 0);
  assert_int_equal(obs_volume_cells_build(&v, 8, &c, &err), 0);
  obs_volume_sides sd;
  assert_int_equal(obs_volume_sides_build(&v, 0.5f, &sd, &err), 0);
  obs_volume_iso plain = {&v, NULL, 0.5f, NULL}, skip = {&v, &c, 0.5f, NULL},
                 sided = {&v, &c, 0.5f, &sd};
  double voxel = v.spacing[0];
  uint32_t seed = 9;
  for (int t = 0; t < 300; t++) {
    double out[3], o[3], d[3];
    unit_dir(&seed, out);
    for (int a = 0; a < 3; a++) o[a] = 1 + 3 * out[a], d[a] = -out[a];
    double t1, t2;
    assert_int_equal(obs_volume_first_hit(&plain, o, d, 0, 10, &t1), 1);
    assert_int_equal(obs_volume_first_hit(&skip, o, d, 0, 10, &t2), 1);
    double t3;
    assert_int_equal(obs_volume_first_hit(&sided, o, d, 0, 10, &t3), 1);
    assert_true(t3 == t2); /* cell sides change no sample's side: the same steps */
    assert_true(fabs(t1 - 2.4) < 0.1 * voxel);
    assert_true(fabs(t1 - t2) < 2e-3 * voxel);
    double p[3], nrm[3];
    for (int a = 0; a < 3; a++) p[a] = o[a] + t1 * d[a];
    obs_volume_normal(&v, p, nrm);
    assert_true(nrm[0] * out[0] + nrm[1] * out[1] + nrm[2] * out[2] > 0.999);
    /* A ray passing beside the sphere misses it, with and without skipping. */
    double side[3], perp[3] = {0, -d[2], d[1]}, pl = sqrt(perp[1] * perp[1] + perp[2] * perp[2]);
    if (pl < 0.3) continue;
    for (int a = 0; a < 3; a++) side[a] = o[a] + 0.7 * perp[a] / pl;
    assert_int_equal(obs_volume_first_hit(&plain, side, d, 0, 10, &t1), 0);
    assert_int_equal(obs_volume_first_hit(&skip, side, d, 0, 10, &t2), 0);
    assert_int_equal(obs_volume_first_hit(&sided, side, d, 0, 10, &t2), 0);
  }
  /* A ray starting inside the isosurface hits where it starts; one outside the box misses. */
  const double inside[3] = {1, 1, 1}, dir[3] = {1, 0, 0}, away[3] = {5, 5, 5};
  double th;
  assert_int_equal(obs_volume_first_hit(&skip, inside, dir, 0.25, 10, &th), 1);
  assert_true(th == 0.25);
  assert_int_equal(obs_volume_first_hit(&skip, away, dir, 0, 10, &th), 0);
  assert_int_equal(obs_volume_first_hit(&sided, inside, dir, 0.25, 10, &th), 1);
  assert_true(th == 0.25);
  obs_volume_sides_free(&sd);
  obs_volume_cells_free(&c);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* 64 x 64 jittered points of the unit square, the same every call. */
static float *strata(uint32_t *samples) {
  int k = 64;
  float *u = malloc(2 * (size_t)k * k * sizeof *u);
  uint32_t s = 21;
  for (int j = 0; j < k; j++)
    for (int i = 0; i < k; i++) {
      u[2 * (j * k + i)] = (float)((i + obs_test_unit(&s)) / k);
      u[2 * (j * k + i) + 1] = (float)((j + obs_test_unit(&s)) / k);
      if (u[2 * (j * k + i)] >= 1.0f) u[2 * (j * k + i)] = 0x1.fffffep-1f;
      if (u[2 * (j * k + i) + 1] >= 1.0f) u[2 * (j * k + i) + 1] = 0x1.fffffep-1f;
    }
  *samples = (uint32_t)(k * k);
  return u;
}

/* The union of two sphere fields (each 0.5 - distance / 2) sampled at n^3 voxel centres of
 * [-1, 1]^3, so object space is world + 1. */
static void two_spheres(const double a[3], double ra, const double b[3], double rb, int n,
                        obs_volume *v) {
  obs_err err = OBS_ERR_INIT;
  const int dims[3] = {n, n, n};
  const double s[3] = {2.0 / n, 2.0 / n, 2.0 / n};
  assert_int_equal(obs_volume_init(v, dims, s, &err), 0);
  for (int k = 0; k < n; k++)
    for (int j = 0; j < n; j++)
      for (int i = 0; i < n; i++) {
        double x[3] = {-1 + (i + 0.5) * s[0], -1 + (j + 0.5) * s[1], -1 + (k + 0.5) * s[2]};
        double da = 0, db = 0;
        for (int q = 0; q < 3; q++)
          da += (x[q] - a[q]) * (x[q] - a[q]), db += (x[q] - b[q]) * (x[q] - b[q]);
        double f = fmax(0.5 - (sqrt(da) - ra) / 2, 0.5 - (sqrt(db) - rb) / 2);
        v->data[((size_t)k * n + (size_t)j) * n + (size_t)i] = (float)fmin(1, fmax(0, f));
      }
  obs_err_free(&err);
}

/* AO on a lone sphere is 1 (it is convex: no direction re-enters it); with a second sphere of
 * radius r whose centre lies at distance d from the point, alpha from the normal, wholly above the
 * horizon and within max_distance, AO = 1 - cos(alpha) (r/d)^2 within discretisation and noise;
 * the bent normal leans away from the occluder. */
static void test_ao_spheres(void **state) {
  (void)state;
  uint32_t ns;
  float *u = strata(&ns);
  const double ca[3] = {-0.3, -0.3, 0}, ra = 0.4;
  const double alpha = 30 * 3.14159265358979 / 180, dist = 0.5, r = 0.15;
  double p[3] = {ca[0], ca[1] + ra, ca[2]}, nrm[3] = {0, 1, 0};
  double cb[3] = {p[0] + dist * sin(alpha), p[1] + dist * cos(alpha), p[2]};
  obs_volume v;
  two_spheres(ca, ra, cb, r, 128, &v);
  obs_volume_ao_params a = {ns, 0.01, 0.01, 0.9, OBS_VOLUME_CROSS_RISING, 0, 0};
  obs_volume_iso s = {&v, NULL, 0.5f, NULL};
  double po[3] = {p[0] + 1, p[1] + 1, p[2] + 1}, bent[3];
  double ao = obs_volume_ao(&s, po, nrm, &a, u, bent);
  double want = 1 - cos(alpha) * (r / dist) * (r / dist);
  printf("two spheres: AO %.5f, closed form %.5f\n", ao, want);
  assert_true(fabs(ao - want) < 0.01);
  assert_true(bent[0] < 0); /* away from the occluder, which lies toward +x */
  a.crossing = OBS_VOLUME_CROSS_ANY;
  assert_true(fabs(obs_volume_ao(&s, po, nrm, &a, u, bent) - want) < 0.01);
  obs_volume_free(&v);
  /* The lone sphere: every direction open, the bent normal the normal. */
  const double far[3] = {5, 5, 5};
  two_spheres(ca, ra, far, 0.01, 96, &v);
  a.crossing = OBS_VOLUME_CROSS_RISING;
  assert_true(obs_volume_ao(&s, po, nrm, &a, u, bent) == 1.0);
  assert_true(fabs(bent[1] - 1) < 1e-3);
  a.samples = 0;
  assert_true(obs_volume_ao(&s, po, nrm, &a, u, bent) == 1.0);
  obs_volume_free(&v);
  free(u);
}

static void grid_crossing_skip_exact(obs_volume_procedural kind, const int n[3], float iso0,
                                     int min_hits) {
  obs_volume v;
  obs_volume_cells c;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_volume_procedural_fill(kind, 5, n, &v, &err), 0);
  assert_int_equal(obs_volume_cells_build(&v, 8, &c, &err), 0);
  float lo = 1, hi = 0;
  for (size_t i = 0; i < (size_t)n[0] * n[1] * n[2]; i++)
    lo = fminf(lo, v.data[i]), hi = fmaxf(hi, v.data[i]);
  const float isos[] = {iso0, 0.55f, 0.7f, lo, hi};
  obs_volume_sides sides[5];
  for (int k = 0; k < 5; k++)
    assert_int_equal(obs_volume_sides_build(&v, isos[k], &sides[k], &err), 0);
  uint32_t seed = 4;
  int hits = 0, total = 0, isa = obs_simd_isa();
  static const double steps[] = {0.003, 0.02, 0.37, 0.05};
  for (int t = 0; t < 5000; t++) {
    double o[3], d[3];
    for (int a = 0; a < 3; a++) o[a] = obs_test_unit(&seed) * 2.4 - 0.2;
    unit_dir(&seed, d);
    obs_volume_ao_params p = {1, obs_test_unit(&seed) * 0.1, steps[t % 4], 0.5 + t % 7 * 0.3,
                              t % 2 ? OBS_VOLUME_CROSS_ANY : OBS_VOLUME_CROSS_RISING, 0, 0};
    int k = t % 5;
    obs_volume_iso plain = {&v, NULL, isos[k], NULL}, skip = {&v, &c, isos[k], NULL},
                   side = {&v, NULL, isos[k], &sides[k]}, both = {&v, &c, isos[k], &sides[k]};
    int a = obs_volume_grid_crossing(&plain, o, d, &p);
    assert_int_equal(obs_volume_grid_crossing(&skip, o, d, &p), a);
    assert_int_equal(obs_volume_grid_crossing(&side, o, d, &p), a);
    assert_int_equal(obs_volume_grid_crossing(&both, o, d, &p), a);
    /* Eight samples at a time (the best level here, its gathers both ways) answer the same. */
    for (int loads = 0; loads < 2; loads++) {
      obs_volume_ao_params q = p;
      q.isa = isa;
      q.gather_loads = loads;
      assert_int_equal(obs_volume_grid_crossing(&side, o, d, &q), a);
      assert_int_equal(obs_volume_grid_crossing(&both, o, d, &q), a);
    }
    hits += a;
    total++;
  }
  printf("grid crossings (%s %dx%dx%d): %d of %d segments cross, the same with and without "
         "skipping (%s)\n",
         obs_volume_procedural_names[kind], n[0], n[1], n[2], hits, total, obs_simd_isa_name(isa));
  assert_true(hits > min_hits && hits < total * 9 / 10);
  for (int k = 0; k < 5; k++) obs_volume_sides_free(&sides[k]);
  obs_volume_cells_free(&c);
  obs_volume_free(&v);
}

/* AO marches skip macrocells, settle samples from their voxel cell's side of the isovalue and
 * settle runs of samples in bricks far from it, and must answer exactly as without: random
 * segments through seeded noise and through a sphere (large bricks on either side), both
 * crossing tests, steps shorter and longer than a voxel (macrocells with sides inside, sides
 * alone), several isovalues, and the isovalue at the data's minimum and maximum. */
static void test_grid_crossing_skip_exact(void **state) {
  (void)state;
  const int noise[3] = {40, 32, 24}, sphere[3] = {90, 84, 77};
  grid_crossing_skip_exact(OBS_VOLUME_NOISE, noise, 0.3f, 500);
  grid_crossing_skip_exact(OBS_VOLUME_SPHERE, sphere, 0.5f, 100); /* most segments pass beside */
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_first_hit_sphere),
      cmocka_unit_test(test_ao_spheres),
      cmocka_unit_test(test_grid_crossing_skip_exact),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
