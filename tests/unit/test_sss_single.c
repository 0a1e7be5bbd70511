/* sss_single against closed forms: Henyey-Greenstein's normalisation and mean cosine, Schlick's
 * transmittance at 0 and 90 degrees, the refracted light path of Eq. 6.5.6 against Snell's
 * geometry, the single-scattered radiance of a homogeneous slab lit and seen at normal incidence
 * (both methods), trace's standard error against a many-sample render, scale invariance through
 * unit_length, the adaptive refinement changing only the pixels near a shadow boundary, trace's
 * entry-point search on a sphere against Snell's law and a scan of the refracted rays, and the
 * loader's refusals. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "sss_job.h"
#include "stderr_check.h"
#include "testutil.h"

/* The slab's medium: coloured, anisotropic, every channel with its own sigma_t. */
static const double SA[3] = {0.2, 0.5, 1.0}, SS[3] = {1.0, 1.5, 0.5}, G = 0.3, ETA = 1.4;

static void test_hg_normalised(void **state) {
  (void)state;
  const double gs[] = {-0.9, -0.3, 0.0, 0.5, 0.9};
  for (size_t i = 0; i < sizeof gs / sizeof gs[0]; i++) {
    /* int p dw = 2 pi int_{-1}^{1} p(mu) dmu, and the mean cosine is g; midpoint rule */
    const int n = 200000;
    double sum = 0, mean = 0;
    for (int k = 0; k < n; k++) {
      double mu = -1 + (k + 0.5) * 2.0 / n, p = obs_sss_hg(mu, gs[i]) * 2 * M_PI * 2.0 / n;
      sum += p;
      mean += mu * p;
    }
    assert_true(fabs(sum - 1) < 1e-4);
    assert_true(fabs(mean - gs[i]) < 1e-4);
  }
  assert_true(fabs(obs_sss_hg(0.3, 0) - 1 / (4 * M_PI)) < 1e-15);
}

static void test_schlick_ends(void **state) {
  (void)state;
  for (double eta = 1.0; eta <= 3.0; eta += 0.25) {
    double r0 = (eta - 1) / (eta + 1) * (eta - 1) / (eta + 1);
    assert_true(fabs(obs_sss_schlick_t(1.0, eta) - (1 - r0)) < 1e-15); /* normal incidence */
    assert_true(fabs(obs_sss_schlick_t(0.0, eta)) < 1e-15);            /* grazing: all reflected */
    assert_true(obs_sss_schlick_t(0.5, eta) > 0 && obs_sss_schlick_t(0.5, eta) < 1 - r0);
  }
}

/* A flat surface at depth z above x_s, light at angle theta_i to the normal: the observed (straight)
 * distance is z / cos(theta_i), the refracted one z / cos(theta_t) with Snell's sin_t = sin_i /
 * eta; refraction bends toward the normal by exactly that angle. */
static void test_refracted_path(void **state) {
  (void)state;
  for (double th = 0; th < 1.5; th += 0.1) {
    double z = 0.7, ci = cos(th), st = sin(th) / ETA, ct = sqrt(1 - st * st);
    assert_true(fabs(obs_sss_refracted_length(z / ci, ci, ETA) - z / ct) < 1e-12);
    double d[3] = {sin(th), -ci, 0}, n[3] = {0, 1, 0}, t[3];
    obs_sss_refract(d, n, ETA, t);
    assert_true(fabs(t[0] - st) < 1e-12 && fabs(t[1] + ct) < 1e-12 && fabs(t[2]) < 1e-15);
  }
}

/* A slab [-4, 4] x [-depth, 0] x [-4, 4] of the medium, lit straight down by a directional light
 * of irradiance E and seen straight down by an orthographic camera, `extra` objects beside it;
 * lengths times `s`, unit_length s. */
static char *slab_doc(double depth, double s, const char *light_dir, const char *extra,
                      const char *params, int w, int h) {
  char *doc = malloc(4096);
  snprintf(doc, 4096,
           "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,%.17g,0],\"look_at\":[0,0,0],"
           "\"up\":[0,0,-1],\"height\":%.17g},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{\"name\":\"slab\",\"shape\":{\"type\":\"box\",\"min\":[%.17g,%.17g,"
           "%.17g],\"max\":[%.17g,0,%.17g]},\"material\":{\"reflectivity\":[0.5,0.5,0.5],"
           "\"medium\":{\"sigma_a\":[%g,%g,%g],\"sigma_s\":[%g,%g,%g],\"g\":%g,\"eta\":%g}}}%s],"
           "\"lights\":[{\"type\":\"directional\",\"direction\":%s,\"emission\":[2,2,2]}],"
           "\"technique\":{\"name\":\"sss_single\",\"backend\":\"cpu\",\"params\":{"
           "\"unit_length\":%.17g,%s}}}",
           5 * s, 2 * s, w, h, -4 * s, -depth * s, -4 * s, 4 * s, 4 * s, SA[0], SA[1], SA[2],
           SS[0], SS[1], SS[2], G, ETA, extra, light_dir, s, params);
  return doc;
}

/* The single-scattered radiance of a slab of optical thickness sigma_t d lit and seen along its
 * normal (Hanrahan and Krueger 1993, Eq. 17 at mu_i = mu_r = 1, with the article's Fresnel
 * factors): light entering with irradiance E F_t scatters back at depth z with weight
 * sigma_s p(-1) exp(-sigma_t z), and leaves through F_t after exp(-sigma_t z) more:
 *   L = F_t^2 E p(-1) sigma_s / (2 sigma_t) (1 - exp(-2 sigma_t d)). */
static double slab_closed(int c, double depth, double e) {
  double st = SA[c] + SS[c], r0 = (ETA - 1) / (ETA + 1) * (ETA - 1) / (ETA + 1);
  return (1 - r0) * (1 - r0) * e * obs_sss_hg(-1, G) * SS[c] / (2 * st) *
         (1 - exp(-2 * st * depth));
}

static void mean_channel(const obs_image *img, const char *name, double *mean, double *se) {
  const float *v = obs_image_channel(img, name);
  char sename[64];
  snprintf(sename, sizeof sename, "radiance_stderr.%s", name + strlen("radiance."));
  const float *e = obs_image_channel(img, sename);
  size_t n = (size_t)img->width * img->height;
  double m = 0, v2 = 0;
  for (size_t i = 0; i < n; i++) m += v[i], v2 += (double)e[i] * e[i];
  *mean = m / n;
  *se = sqrt(v2) / n; /* independent pixels */
}

static const char *const RGB[3] = {"radiance.R", "radiance.G", "radiance.B"};

static void test_slab_trace(void **state) {
  (void)state;
  obs_test_numeric_only();
  const double depths[2] = {0.5, 20}; /* optically thin and a half-space */
  for (int k = 0; k < 2; k++) {
    char *doc = slab_doc(depths[k], 1, "[0,-1,0]", "", "\"method\":\"trace\",\"samples\":256", 16,
                         16);
    obs_result r;
    obs_test_render(doc, 2, &r);
    for (int c = 0; c < 3; c++) {
      double m, se, want = slab_closed(c, depths[k], 2);
      mean_channel(&r.image, RGB[c], &m, &se);
      printf("trace slab depth %g %s: %.6g, closed form %.6g, 3 stderr %.3g\n", depths[k],
             RGB[c], m, want, 3 * se);
      assert_true(se > 0 && fabs(m - want) < 3 * se);
    }
    obs_result_free(&r);
    free(doc);
  }
}

/* The maps estimate the half-space (they do not know where the object ends below x_s); M = 10
 * deterministic samples integrate exp(-2 sigma_t s) to within the midpoint rule's error. */
static void test_slab_shadow_maps(void **state) {
  (void)state;
  obs_test_numeric_only();
  /* 6 deep: exp(-2 sigma_t 6) < 1e-6, a half-space to the test's precision */
  char *doc = slab_doc(6, 1, "[0,-1,0]", "",
                       "\"method\":\"shadow_maps\",\"samples\":10,\"map_size\":1024", 16, 16);
  obs_result r;
  obs_test_render(doc, 2, &r);
  for (int c = 0; c < 3; c++) {
    double m, se, want = slab_closed(c, 6, 2);
    mean_channel(&r.image, RGB[c], &m, &se);
    printf("shadow_maps half-space %s: %.6g, closed form %.6g (%.2f %%)\n", RGB[c], m, want,
           100 * (m / want - 1));
    assert_true(fabs(m / want - 1) < 0.01);
  }
  obs_result_free(&r);
  free(doc);
}

/* The same slab at scale 1e-3 and 1e3 with unit_length scaled alike: the same optical depths. */
static void test_scale_invariance(void **state) {
  (void)state;
  const char *methods[2] = {"\"method\":\"shadow_maps\"", "\"method\":\"trace\",\"samples\":4"};
  for (int m = 0; m < 2; m++) {
    obs_result r[3];
    const double s[3] = {1, 1e-3, 1e3};
    for (int k = 0; k < 3; k++) {
      char *doc = slab_doc(2, s[k], "[0.3,-1,0.2]", "", methods[m], 8, 8);
      obs_test_render(doc, 1, &r[k]);
      free(doc);
    }
    for (int k = 1; k < 3; k++)
      for (int c = 0; c < 3; c++) {
        const float *a = obs_image_channel(&r[0].image, RGB[c]);
        const float *b = obs_image_channel(&r[k].image, RGB[c]);
        for (int i = 0; i < 64; i++) assert_true(fabs(a[i] - b[i]) <= 1e-3 * fabs(a[i]) + 1e-7);
      }
    for (int k = 0; k < 3; k++) obs_result_free(&r[k]);
  }
}

/* trace's radiance_stderr against a render with 64 times the samples (stderr_check.h). */
static void test_trace_stderr(void **state) {
  (void)state;
  obs_test_numeric_only();
  static const obs_stderr_case c = {"sss_single trace", "scenes/sss_marble.json", "sss_single",
                                    "cpu", "{\"method\":\"trace\",\"samples\":$N,\"seed\":$S}",
                                    "radiance", "radiance_stderr", 0, 24};
  obs_test_stderr_check(&c, 16);
}

/* A grey medium (one sigma_t = 6) lit at 45 degrees, half of it in the shadow of a box whose
 * edge casts the shadow onto x = 0 of the slab's top. A pixel's samples read entry points at most
 * -ln(0.05 / M) / sigma_t deep, and so at most that far (tan 45 degrees) to the side: only pixels
 * within that band of the edge can see 20-85 % dim samples (the lit slab sees 10 %: the shallowest
 * sample alone; the shadow 100 %). Away from it refinement must change no bit; near it, some
 * pixels must change. */
static void test_adaptive_band(void **state) {
  (void)state;
  enum { W = 32 };
  obs_result r[2];
  for (int a = 0; a < 2; a++) {
    char doc[2048];
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,5,0],\"look_at\":[0,0,0],"
             "\"up\":[0,0,-1],\"height\":2},\"image\":{\"width\":%d,\"height\":%d},"
             "\"objects\":[{\"shape\":{\"type\":\"box\",\"min\":[-4,-3,-4],\"max\":[4,0,4]},"
             "\"material\":{\"reflectivity\":[0.5,0.5,0.5],\"medium\":{\"sigma_a\":[2,2,2],"
             "\"sigma_s\":[4,4,4],\"g\":0,\"eta\":1.3}}},{\"shape\":{\"type\":\"box\","
             "\"min\":[-6,1,-6],\"max\":[-1,1.2,6]}}],\"lights\":[{\"type\":\"directional\","
             "\"direction\":[1,-1,0],\"emission\":[2,2,2]}],\"technique\":{\"name\":"
             "\"sss_single\",\"params\":{\"samples\":10,\"jitter\":0,\"adaptive\":%s}}}",
             W, W, a ? "true" : "false");
    obs_test_render(doc, 1, &r[a]);
  }
  double band = -log(0.05 / 10) / 6 + 0.1; /* the deepest sample, plus a pixel and texels */
  int changed = 0;
  for (int y = 0; y < W; y++)
    for (int x = 0; x < W; x++) {
      double wx = -1 + (x + 0.5) * 2.0 / W;
      size_t i = (size_t)y * W + x;
      int same = 1;
      for (int c = 0; c < 3; c++)
        same &= obs_image_channel(&r[0].image, RGB[c])[i] ==
                obs_image_channel(&r[1].image, RGB[c])[i];
      if (!same) {
        changed++;
        if (fabs(wx) > band) printf("pixel (%d, %d) at x = %g changed, outside the band\n", x, y, wx);
        assert_true(fabs(wx) <= band);
      }
    }
  printf("adaptive refinement changed %d of %d pixels, all within %.3g of the shadow's edge\n",
         changed, W * W, band);
  assert_true(changed > 0);
  obs_result_free(&r[0]);
  obs_result_free(&r[1]);
}

/* In the meridian plane of a unit sphere lit straight down, whether light refracted at the entry
 * point at polar angle phi (from +y, signed) runs through (x, y): the signed distance of (x, y)
 * from that refracted ray, and the distance along it (negative: behind the entry point). */
static void meridian_ray(double phi, double x, double y, double *side, double *along) {
  double n[3] = {sin(phi), cos(phi), 0}, d[3] = {0, -1, 0}, wi[3];
  obs_sss_refract(d, n, ETA, wi);
  double rx = x - n[0], ry = y - n[1];
  *side = wi[0] * ry - wi[1] * rx;
  *along = wi[0] * rx + wi[1] * ry;
}

/* trace's entry-point search on a unit sphere lit straight down, at points of its meridian plane:
 * where a scan of the refracted rays (20000 entry angles, roots by bisection) finds a path, the
 * search converges to one of the roots with Snell's law holding at the hit (residual below 1e-5
 * of the radius); where none exists (the refraction shadow below the terminator) it reports none.
 * Off the axis the converged entry point moves away from the one-step estimate (the refraction at
 * the face the straight line to the light crosses), by more than half the radius at the deepest
 * points. */
static void test_entry_sphere(void **state) {
  (void)state;
  char doc[1024];
  snprintf(doc, sizeof doc,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,5],\"look_at\":[0,0,0],"
           "\"up\":[0,1,0],\"fov_y\":30},\"image\":{\"width\":8,\"height\":8,\"spp\":1},"
           "\"objects\":[{\"name\":\"ball\",\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
           "\"radius\":1},\"material\":{\"reflectivity\":[0.5,0.5,0.5],\"medium\":{\"sigma_a\":"
           "[%g,%g,%g],\"sigma_s\":[%g,%g,%g],\"g\":%g,\"eta\":%g}}}],\"lights\":[{\"type\":"
           "\"directional\",\"direction\":[0,-1,0],\"emission\":[1,1,1]}],\"technique\":{\"name\":"
           "\"sss_single\",\"backend\":\"cpu\"}}",
           SA[0], SA[1], SA[2], SS[0], SS[1], SS[2], G, ETA);
  obs_scene sc;
  obs_test_load(doc, "ball.json", &sc);
  obs_rt rt;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_rt_build_ex(&sc, &rt, 1, OBS_RT_FRAME_GEOMETRY, &err), 0);
  sss_medium md = {{0}, {0}, 1, G, ETA};
  sss_light light = {.point = 0, .dir = {0, -1, 0}};
  sss_job jb = {.rt = &rt, .media = &md, .nobjects = 1};
  const double *o = rt.geo.origin;
  int found = 0, none = 0, moved = 0;
  double max_move = 0;
  for (int i = 1; i <= 9; i++)
    for (int j = -9; j <= 9; j++) {
      double x = 0.1 * i, y = 0.1 * j;
      if (x * x + y * y > 0.95 * 0.95) continue;
      /* the scan: roots of the side where the ray runs forward through (x, y) */
      double roots[8];
      int nroots = 0;
      const int n = 20000;
      double a = -M_PI / 2, sa, al;
      meridian_ray(a, x, y, &sa, &al);
      for (int k = 1; k <= n; k++) {
        double b = -M_PI / 2 + M_PI * k / n, sb, bl;
        meridian_ray(b, x, y, &sb, &bl);
        if ((sa < 0) != (sb < 0) && al > 0 && bl > 0 && nroots < 8) {
          double lo = a, hi = b, slo = sa;
          for (int it = 0; it < 60; it++) {
            double m = 0.5 * (lo + hi), sm, ml;
            meridian_ray(m, x, y, &sm, &ml);
            if ((sm < 0) == (slo < 0)) lo = m, slo = sm;
            else hi = m;
          }
          roots[nroots++] = 0.5 * (lo + hi);
        }
        a = b, sa = sb, al = bl;
      }
      float xs[3] = {(float)(x - o[0]), (float)(y - o[1]), (float)(0 - o[2])};
      sss_entry e;
      uint64_t rays = 0;
      int ok = obs_sss_entry_solve(&jb, &light, 0, xs, OBS_SSS_ENTRY_STEPS, &e, &rays);
      if (!nroots) {
        assert_true(!ok || e.stalled);
        none++;
        continue;
      }
      assert_true(ok && e.converged);
      found++;
      /* Snell's law at the hit: the light refracted at the sphere's normal there runs to xs */
      double p[3], nrm[3], d[3] = {0, -1, 0}, wi[3], u[3], pl = 0, ul = 0;
      for (int k = 0; k < 3; k++) {
        p[k] = e.h.p[k] + o[k];
        pl += p[k] * p[k];
      }
      pl = sqrt(pl);
      for (int k = 0; k < 3; k++) nrm[k] = p[k] / pl;
      obs_sss_refract(d, nrm, ETA, wi);
      double xw[3] = {x, y, 0};
      for (int k = 0; k < 3; k++) {
        u[k] = xw[k] - p[k];
        ul += u[k] * u[k];
      }
      ul = sqrt(ul);
      double resid = 0;
      for (int k = 0; k < 3; k++) resid += (wi[k] - u[k] / ul) * (wi[k] - u[k] / ul);
      assert_true(fabs(pl - 1) < 1e-5);
      assert_true(sqrt(resid) * ul < 1e-5);
      assert_true(fabs(ul - e.h.t) < 1e-5);
      double best = INFINITY, phi = atan2(p[0], p[1]);
      for (int r = 0; r < nroots; r++) best = fmin(best, fabs(phi - roots[r]));
      assert_true(best < 1e-4);
      /* the one-step estimate: up to the sphere, refract, back from xs along the refracted light */
      double y0 = sqrt(1 - x * x), n0[3] = {x, y0, 0}, w0[3];
      obs_sss_refract(d, n0, ETA, w0);
      double bx = -w0[0], by = -w0[1], bq = bx * x + by * y, bc = x * x + y * y - 1;
      double t1 = -bq + sqrt(bq * bq - bc), p1[2] = {x + t1 * bx, y + t1 * by};
      double move = hypot(p[0] - p1[0], p[1] - p1[1]);
      max_move = fmax(max_move, move);
      moved += move > 1e-3;
    }
  printf("entry search on a sphere: %d points with a path (%d off the one-step estimate by more than "
         "1e-3, at most %.4f), %d in the refraction shadow\n", found, moved, max_move, none);
  assert_true(found > 50 && none > 5 && moved > 20 && max_move > 0.02);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void expect_refusal(const char *doc, const char *needle) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "t.json", NULL, NULL, 0, &err);
  if (!rc) obs_scene_free(&sc);
  printf("refused: %s\n", obs_err_message(&err));
  assert_int_not_equal(rc, 0);
  assert_non_null(strstr(obs_err_message(&err), needle));
  obs_err_free(&err);
}

static void test_refusals(void **state) {
  (void)state;
  char *doc = slab_doc(1, 1, "[0,-1,0]", "", "\"seed\":1", 8, 8);
  char *m = strstr(doc, "\"medium\"");
  char bad[4096];
  /* no medium anywhere */
  snprintf(bad, sizeof bad, "%.*s\"emission\":[0,0,0]%s", (int)(m - doc), doc,
           strstr(m, "}}") + 1);
  expect_refusal(bad, "/objects: technique \"sss_single\"");
  /* an unknown preset */
  snprintf(bad, sizeof bad, "%.*s\"medium\":\"jade\"%s", (int)(m - doc), doc,
           strstr(m, "}}") + 1);
  expect_refusal(bad, "/objects/0/material/medium");
  /* no punctual light */
  char *l = strstr(doc, "\"lights\"");
  snprintf(bad, sizeof bad, "%.*s\"lights\":[{\"type\":\"quad\",\"vertices\":[[-1,3,-1],[1,3,-1],"
           "[1,3,1],[-1,3,1]],\"emission\":[1,1,1]}]%s", (int)(l - doc), doc,
           strstr(l, "}]") + 2);
  expect_refusal(bad, "/lights");
  free(doc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_hg_normalised),    cmocka_unit_test(test_schlick_ends),
      cmocka_unit_test(test_refracted_path),   cmocka_unit_test(test_slab_trace),
      cmocka_unit_test(test_slab_shadow_maps), cmocka_unit_test(test_scale_invariance),
      cmocka_unit_test(test_trace_stderr),     cmocka_unit_test(test_adaptive_band),
      cmocka_unit_test(test_entry_sphere),     cmocka_unit_test(test_refusals),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
