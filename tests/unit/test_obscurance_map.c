/* obscurance_map's estimators against closed forms (an open plane, two parallel plates), against
 * each other on the Cornell box, and at the extremes: subdivision, degenerate patches, scale,
 * d_max, reflectivity, seeds and thread counts. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurance_map_cpu.h"
#include "patch_mesh.h"
#include "raytrace.h"
#include "testutil.h"

static const char *const method_names[3] = {"rays", "global_lines", "bundles"};

static obs_obscurance_map_params defaults(int method) {
  obs_obscurance_map_params p;
  memset(&p, 0, sizeof p);
  p.method = method;
  p.d_max = 1;
  p.falloff = OBS_FALLOFF_SQRT;
  p.tau = 1;
  p.color_bleeding = 1;
  p.samples = 64;
  p.directions = 64;
  p.bundle_resolution = 64;
  p.patch_size = INFINITY;
  p.seed = 1;
  return p;
}

/* The map of `p` on the scene `doc` with `threads` threads (asserting success). */
static void map_of(const char *doc, const obs_obscurance_map_params *p, int threads, obs_omap *m) {
  obs_scene sc;
  obs_test_load(doc, "omap.json", &sc);
  obs_rt rt;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_rt_build_ex(&sc, &rt, threads, OBS_RT_FRAME_GEOMETRY, &err);
  if (!rc) rc = obs_omap_compute(&rt, &sc, p, threads, NULL, NULL, NULL, m, &err);
  if (rc) printf("omap: %s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  for (int64_t i = 0; i < m->pm.count; i++) {
    for (int c = 0; c < 3; c++) assert_true(m->w[3 * i + c] >= 0.0f && m->w[3 * i + c] <= 1.0f);
    assert_true(isfinite(m->se[i]) && m->se[i] >= 0.0f);
  }
}

/* ---- an open plane: nothing within d_max ---- */

static const char *plane_doc(double refl) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]},\"material\":{\"reflectivity\":[%g,%g,%g]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}",
      refl, refl * 0.5, refl * 0.25);
}

static void test_open_plane(void **state) {
  (void)state;
  for (int method = 0; method < 3; method++)
    for (int bleed = 0; bleed < 2; bleed++) {
      obs_obscurance_map_params p = defaults(method);
      p.color_bleeding = bleed;
      p.patch_size = 0.5;
      obs_omap m;
      map_of(plane_doc(0.8), &p, 2, &m);
      assert_int_equal(m.pm.count, 2 * 12 * 12); /* diagonal 5.66 / 0.5: n = 12 */
      const double r[3] = {0.8, 0.4, 0.2};
      for (int64_t i = 0; i < m.pm.count; i++)
        for (int c = 0; c < 3; c++) {
          if (!bleed) assert_true(m.w[3 * i + c] == 1.0f);
          else assert_true(fabs(m.w[3 * i + c] - r[c]) < 1e-6);
        }
      obs_omap_free(&m);
    }
}

/* ---- two parallel plates ---- */

/* Plates of half-width L at y = 0 (facing up) and y = h (facing down). */
static const char *plates_doc(double h, double L) {
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

/* W at a plate facing another at distance h < d_max, sqrt falloff, mu = cos theta:
 *   W = 2 int_0^1 rho(h / mu) mu dmu, rho = 1 ("nothing", R_ave with bleeding) for mu < m0 = h/d_max
 *   and sqrt(h / (mu d_max)) (times R of the other plate) above:
 *   W = R_ave m0^2 + R_other 4/3 sqrt(m0) (1 - m0^(3/2)). */
static double plates_w(double m0, double r_ave, double r_other) {
  return r_ave * m0 * m0 + r_other * 4.0 / 3.0 * sqrt(m0) * (1 - pow(m0, 1.5));
}

/* The centroid of a patch (its triangle's sub-triangle). */
static void patch_centroid(const obs_scene *sc, const obs_omap *m, int64_t patch, double c[3]) {
  (void)sc;
  (void)m;
  (void)patch;
  c[0] = c[1] = c[2] = 0;
}

static void check_plates(int method, int bleed) {
  const double h = 0.5, L = 2.5, dmax = 1.0;
  obs_obscurance_map_params p = defaults(method);
  p.color_bleeding = bleed;
  p.patch_size = 0.25;
  p.samples = 256;
  /* Bundles share their directions between all patches: their error over the direction set is
   * common to the pooled patches, so many directions keep it well below the pooled noise. */
  p.directions = method == OBS_OMAP_BUNDLES ? 1024 : 128;
  p.bundle_resolution = method == OBS_OMAP_BUNDLES ? 45 : 128;
  obs_omap m;
  const char *doc = plates_doc(h, L);
  obs_scene sc;
  obs_test_load(doc, "plates.json", &sc);
  obs_geometry geo;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &geo, &err), 0);
  map_of(doc, &p, 2, &m);
  const double r_bot[3] = {0.2, 0.5, 0.8}, r_top[3] = {0.6, 0.4, 0.3};
  /* The central patches: centroid within 0.6 of the axis, so everything within d_max of them
   * horizontally (sqrt(d_max^2 - h^2) = 0.87) lies on the other plate. */
  double sum[2][3] = {{0}}, var[2] = {0}, wsum[2] = {0};
  int npatch[2] = {0, 0};
  size_t tri = 0;
  for (size_t mi = 0; mi < geo.nmeshes; mi++) {
    const obs_mesh *me = &geo.meshes[mi];
    for (size_t t = 0; t < me->ntris; t++, tri++) {
      const float *v[3];
      for (int k = 0; k < 3; k++) v[k] = me->pos + 3 * (size_t)me->idx[3 * t + (size_t)k];
      int n = m.pm.split[tri];
      for (int64_t s = 0; s < (int64_t)n * n; s++) {
        double uv[3][2], c[3] = {0, 0, 0};
        obs_patch_sub_corners(n, s, uv);
        for (int q = 0; q < 3; q++)
          for (int k = 0; k < 3; k++)
            c[k] += (v[0][k] + uv[q][0] * (v[1][k] - v[0][k]) + uv[q][1] * (v[2][k] - v[0][k])) / 3;
        if (c[0] * c[0] + c[2] * c[2] > 0.36) continue;
        int top = c[1] > h / 2;
        int64_t id = m.pm.first[tri] + s;
        double a = m.pm.area[id];
        for (int k = 0; k < 3; k++) sum[top][k] += a * m.w[3 * id + k];
        var[top] += a * a * (double)m.se[id] * m.se[id];
        wsum[top] += a;
        npatch[top]++;
        /* Each patch alone within 5 sigma (one in 10^6 fails by chance). */
        const double *ro = top ? r_bot : r_top;
        for (int k = 0; k < 3; k++) {
          double ra = bleed ? (r_bot[k] + r_top[k]) / 2 : 1, rt = bleed ? ro[k] : 1;
          double want = plates_w(h / dmax, ra, rt);
          if (!(fabs(m.w[3 * id + k] - want) <= 5 * m.se[id] + 1e-6))
            printf("%s bleed %d: patch %lld channel %d: %g, want %g (se %g, n %llu)\n",
                   method_names[method], bleed, (long long)id, k, m.w[3 * id + k], want,
                   m.se[id], (unsigned long long)m.n[id]);
          assert_true(fabs(m.w[3 * id + k] - want) <= 5 * m.se[id] + 1e-6);
        }
      }
    }
  }
  /* The area-weighted mean of each plate's central patches within 3 sigma. */
  for (int top = 0; top < 2; top++) {
    assert_true(npatch[top] >= 20);
    const double *ro = top ? r_bot : r_top;
    double sigma = sqrt(var[top]) / wsum[top];
    for (int k = 0; k < 3; k++) {
      double ra = bleed ? (r_bot[k] + r_top[k]) / 2 : 1, rt = bleed ? ro[k] : 1;
      double want = plates_w(h / dmax, ra, rt), got = sum[top][k] / wsum[top];
      printf("%-12s bleed %d plate %d ch %d: W %.5f want %.5f (3 sigma %.5f, %d patches)\n",
             method_names[method], bleed, top, k, got, want, 3 * sigma, npatch[top]);
      assert_true(fabs(got - want) <= 3 * sigma);
    }
  }
  (void)patch_centroid;
  obs_omap_free(&m);
  obs_geometry_free(&geo);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_plates_rays(void **state) {
  (void)state;
  check_plates(OBS_OMAP_RAYS, 0);
  check_plates(OBS_OMAP_RAYS, 1);
}
static void test_plates_global_lines(void **state) {
  (void)state;
  check_plates(OBS_OMAP_GLOBAL_LINES, 0);
  check_plates(OBS_OMAP_GLOBAL_LINES, 1);
}
static void test_plates_bundles(void **state) {
  (void)state;
  check_plates(OBS_OMAP_BUNDLES, 0);
  check_plates(OBS_OMAP_BUNDLES, 1);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_open_plane),
      cmocka_unit_test(test_plates_rays),
      cmocka_unit_test(test_plates_global_lines),
      cmocka_unit_test(test_plates_bundles),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
