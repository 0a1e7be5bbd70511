/* Scenes and closed forms shared by the per-patch obscurance tests (omap_scenes.h). */
#include "omap_scenes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "obscurance.h"
#include "patch_mesh.h"
#include "testutil.h"

obs_obscurance_map_params obs_test_omap_defaults(int method) {
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

const char *obs_test_omap_plane_doc(double refl) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]},\"material\":{\"reflectivity\":[%g,%g,%g]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}",
      refl, refl * 0.5, refl * 0.25);
}

const char *obs_test_omap_plates_doc(double h, double L) {
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

/* mu = cos theta: W = 2 int_0^1 rho(h / mu) mu dmu, rho = 1 ("nothing", R_ave with bleeding) for
 * mu < m0 = h / d_max and sqrt(h / (mu d_max)) (times R of the other plate) above:
 *   W = R_ave m0^2 + R_other 4/3 sqrt(m0) (1 - m0^(3/2)). */
double obs_test_omap_plates_w(double m0, double r_ave, double r_other) {
  return r_ave * m0 * m0 + r_other * 4.0 / 3.0 * sqrt(m0) * (1 - pow(m0, 1.5));
}

char *obs_test_omap_cornell_doc(void) {
  FILE *f = fopen(obs_test_src("scenes/cornell_box.json"), "rb");
  assert_non_null(f);
  char *buf = calloc(1, 1 << 16);
  assert_non_null(buf);
  size_t n = fread(buf, 1, (1 << 16) - 1, f);
  fclose(f);
  assert_true(n > 0);
  return buf;
}

/* The centroid of sub-triangle s of triangle v split n times. */
static void sub_centroid(const float *v[3], int n, int64_t s, double c[3]) {
  double uv[3][2];
  obs_patch_sub_corners(n, s, uv);
  for (int k = 0; k < 3; k++) c[k] = 0;
  for (int q = 0; q < 3; q++)
    for (int k = 0; k < 3; k++)
      c[k] += (v[0][k] + uv[q][0] * (v[1][k] - v[0][k]) + uv[q][1] * (v[2][k] - v[0][k])) / 3;
}

void obs_test_omap_check_plates(const char *what, const char *doc, double h, double dmax,
                                int bleed, const obs_patch_mesh *pm, const float *w,
                                const float *se) {
  obs_scene sc;
  obs_test_load(doc, "plates.json", &sc);
  obs_geometry geo;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &geo, &err), 0);
  const double r_bot[3] = {0.2, 0.5, 0.8}, r_top[3] = {0.6, 0.4, 0.3};
  double sum[2][3] = {{0}}, var[2] = {0}, wsum[2] = {0};
  int npatch[2] = {0, 0};
  size_t tri = 0;
  for (size_t mi = 0; mi < geo.nmeshes; mi++) {
    const obs_mesh *me = &geo.meshes[mi];
    for (size_t t = 0; t < me->ntris; t++, tri++) {
      const float *v[3];
      for (int k = 0; k < 3; k++) v[k] = me->pos + 3 * (size_t)me->idx[3 * t + (size_t)k];
      int n = pm->split[tri];
      for (int64_t s = 0; s < (int64_t)n * n; s++) {
        double c[3];
        sub_centroid(v, n, s, c);
        if (c[0] * c[0] + c[2] * c[2] > 0.36) continue;
        int top = c[1] > h / 2;
        int64_t id = pm->first[tri] + s;
        double a = pm->area[id];
        const double *ro = top ? r_bot : r_top;
        double se2 = 0; /* the largest of the channels' */
        for (int k = 0; k < 3; k++) {
          se2 = fmax(se2, (double)se[3 * id + k] * se[3 * id + k]);
          double want = obs_test_omap_plates_w(h / dmax, bleed ? (r_bot[k] + r_top[k]) / 2 : 1,
                                               bleed ? ro[k] : 1);
          sum[top][k] += a * w[3 * id + k];
          /* Each patch alone within 5 sigma (one in 10^6 fails by chance). */
          if (!(fabs(w[3 * id + k] - want) <= 5 * se[3 * id + k] + 1e-6))
            printf("%s bleed %d: patch %lld channel %d: %g, want %g (se %g)\n", what, bleed,
                   (long long)id, k, w[3 * id + k], want, se[3 * id + k]);
          assert_true(fabs(w[3 * id + k] - want) <= 5 * se[3 * id + k] + 1e-6);
        }
        var[top] += a * a * se2;
        wsum[top] += a;
        npatch[top]++;
      }
    }
  }
  for (int top = 0; top < 2; top++) {
    assert_true(npatch[top] >= 20);
    const double *ro = top ? r_bot : r_top;
    double sigma = sqrt(var[top]) / wsum[top];
    for (int k = 0; k < 3; k++) {
      double want = obs_test_omap_plates_w(h / dmax, bleed ? (r_bot[k] + r_top[k]) / 2 : 1,
                                           bleed ? ro[k] : 1);
      double got = sum[top][k] / wsum[top];
      printf("%-13s bleed %d plate %d ch %d: W %.5f want %.5f (3 sigma %.5f, %d patches)\n", what,
             bleed, top, k, got, want, 3 * sigma, npatch[top]);
      assert_true(fabs(got - want) <= 3 * sigma);
    }
  }
  obs_geometry_free(&geo);
  obs_scene_free(&sc);
  obs_err_free(&err);
}
