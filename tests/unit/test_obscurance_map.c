/* obscurance_map's estimators against closed forms (an open plane, two parallel plates), against
 * each other on the Cornell box, and at the extremes: subdivision, degenerate patches, scale,
 * d_max, reflectivity, seeds and thread counts. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurance_map_cpu.h"
#include "patch_mesh.h"
#include "raytrace.h"
#include "omap_scenes.h"
#include "obscurance_map.h"
#include "testutil.h"

static const char *const method_names[3] = {"rays", "global_lines", "bundles"};

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
    for (int c = 0; c < 3; c++)
      assert_true(isfinite(m->se[3 * i + c]) && m->se[3 * i + c] >= 0.0f);
  }
}

/* ---- an open plane: nothing within d_max ---- */

static void test_open_plane(void **state) {
  (void)state;
  for (int method = 0; method < 3; method++)
    for (int bleed = 0; bleed < 2; bleed++) {
      obs_obscurance_map_params p = obs_test_omap_defaults(method);
      p.color_bleeding = bleed;
      p.patch_size = 0.5;
      obs_omap m;
      map_of(obs_test_omap_plane_doc(0.8), &p, 2, &m);
      assert_int_equal(m.pm.count, 2 * 12 * 12); /* diagonal 5.66 / 0.5: n = 12 */
      const double r[3] = {0.8, 0.4, 0.2};
      for (int64_t i = 0; i < m.pm.count; i++)
        for (int c = 0; c < 3; c++) {
          if (!bleed)
            assert_true(m.w[3 * i + c] == 1.0f);
          else
            assert_true(fabs(m.w[3 * i + c] - r[c]) < 1e-6);
        }
      obs_omap_free(&m);
    }
}

/* ---- two parallel plates ---- */

static void check_plates(int method, int bleed) {
  const double h = 0.5, L = 2.5, dmax = 1.0;
  obs_obscurance_map_params p = obs_test_omap_defaults(method);
  p.color_bleeding = bleed;
  p.patch_size = 0.25;
  p.samples = 256;
  /* Bundles share their directions between all patches: their error over the direction set is
   * common to the pooled patches, so many directions keep it well below the pooled noise. */
  p.directions = method == OBS_OMAP_BUNDLES ? 1024 : 128;
  p.bundle_resolution = method == OBS_OMAP_BUNDLES ? 45 : 128;
  obs_omap m;
  const char *doc = obs_test_omap_plates_doc(h, L);
  map_of(doc, &p, 2, &m);
  obs_test_omap_check_plates(method_names[method], obs_test_omap_plates_doc(h, L), h, dmax, bleed,
                             &m.pm, m.w, m.se);
  obs_omap_free(&m);
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

/* ---- the estimators agree on the Cornell box ---- */

static void test_cornell_agree(void **state) {
  (void)state;
  char *doc = obs_test_omap_cornell_doc();
  obs_omap m[3];
  for (int method = 0; method < 3; method++) {
    obs_obscurance_map_params p = obs_test_omap_defaults(method);
    p.d_max = 200;
    p.patch_size = 100;
    p.samples = 256;
    p.directions = 128;
    p.bundle_resolution = 128;
    map_of(doc, &p, 2, &m[method]);
  }
  for (int a = 0; a < 3; a++)
    for (int b = a + 1; b < 3; b++) {
      double se2 = 0, d2 = 0;
      size_t k = 0;
      for (int64_t i = 0; i < m[a].pm.count; i++) {
        /* Patches with few samples (some lie under the blocks, which have no bottom: they see the
         * back of the block's top and every sample is eliminated) have no usable noise estimate. */
        if (m[a].n[i] < 32 || m[b].n[i] < 32) continue;
        for (int c = 0; c < 3; c++) {
          double d = (double)m[a].w[3 * i + c] - m[b].w[3 * i + c];
          d2 += d * d;
        }
        for (int c = 0; c < 3; c++)
          se2 += (double)m[a].se[3 * i + c] * m[a].se[3 * i + c] +
                 (double)m[b].se[3 * i + c] * m[b].se[3 * i + c];
        k++;
      }
      double rmse = sqrt(d2 / (3.0 * k)), noise = sqrt(se2 / (3.0 * k));
      printf("%s vs %s: per-patch RMSE %.5f, noise %.5f over %zu of %lld patches\n",
             method_names[a], method_names[b], rmse, noise, k, (long long)m[a].pm.count);
      assert_true(k > (size_t)m[a].pm.count * 8 / 10);
      /* The RMSE of two unbiased estimates of one quantity is the root of their summed
       * variances. The line estimators (global lines, bundles) do estimate one quantity. The rays
       * estimator's differs from theirs by 0.012 RMS per patch here (measured at 8192 rays per
       * patch against 16M global lines, where the noise is 0.0013: a difference of the estimators,
       * not of their noise), which the honest standard errors no longer hide: its pairs allow it. */
      double sys = a == OBS_OMAP_RAYS ? 0.013 : 0.0;
      assert_true(rmse <= sqrt(1.2 * 1.2 * noise * noise + sys * sys));
    }
  for (int i = 0; i < 3; i++) obs_omap_free(&m[i]);
  free(doc);
}

/* ---- subdivision ---- */

static void test_subdivision(void **state) {
  (void)state;
  for (int n = 1; n <= 9; n++) {
    int64_t total = (int64_t)n * n;
    int *seen = calloc((size_t)total, sizeof *seen);
    for (int64_t k = 0; k < total; k++) {
      double uv[3][2];
      obs_patch_sub_corners(n, k, uv);
      /* Inside the triangle, same winding, area 1/n^2 of it. */
      double cross = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1]) -
                     (uv[1][1] - uv[0][1]) * (uv[2][0] - uv[0][0]);
      assert_true(fabs(cross - 1.0 / total) < 1e-12);
      for (int q = 0; q < 3; q++)
        assert_true(uv[q][0] >= 0 && uv[q][1] >= 0 && uv[q][0] + uv[q][1] <= 1 + 1e-12);
      /* Points inside sub-triangle k map back to k. */
      for (int t = 0; t < 4; t++) {
        double w[3] = {0.2 + 0.2 * (t == 1), 0.3 + 0.2 * (t == 2),
                       0.5 - 0.2 * (t == 1) - 0.2 * (t == 2)};
        if (t == 3) w[0] = w[1] = w[2] = 1.0 / 3;
        double u = w[0] * uv[0][0] + w[1] * uv[1][0] + w[2] * uv[2][0];
        double v = w[0] * uv[0][1] + w[1] * uv[1][1] + w[2] * uv[2][1];
        assert_int_equal(obs_patch_sub_index(n, u, v), k);
      }
      seen[k]++;
    }
    for (int64_t k = 0; k < total; k++) assert_int_equal(seen[k], 1);
    /* Points on the boundary and outside clamp into the triangle. */
    assert_true(obs_patch_sub_index(n, 1.0, 0.0) >= 0 && obs_patch_sub_index(n, 1.0, 0.0) < total);
    assert_true(obs_patch_sub_index(n, 0.7, 0.7) >= 0 && obs_patch_sub_index(n, 0.7, 0.7) < total);
    assert_true(obs_patch_sub_index(n, -0.1, NAN) >= 0 &&
                obs_patch_sub_index(n, -0.1, NAN) < total);
    free(seen);
  }
  /* Areas of a scene's patches add up to their triangles'; ids map back to their triangles. */
  obs_scene sc;
  obs_test_load(obs_test_omap_plates_doc(0.5, 2.5), "plates.json", &sc);
  obs_geometry geo;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &geo, &err), 0);
  obs_patch_mesh pm;
  assert_int_equal(obs_patch_mesh_build(&geo, 0.3, "/x", &pm, &err), 0);
  assert_int_equal(pm.count, 4 * 24 * 24); /* diagonal 7.07 / 0.3: n = 24 */
  for (size_t t = 0; t < pm.ntris; t++) {
    double a = 0;
    for (int64_t i = pm.first[t]; i < pm.first[t + 1]; i++) {
      a += pm.area[i];
      int64_t sub;
      assert_int_equal(obs_patch_mesh_owner(&pm, i, &sub), t);
      assert_int_equal(sub, i - pm.first[t]);
    }
    assert_true(fabs(a - 12.5) < 1e-4 * 12.5);
  }
  obs_patch_mesh_free(&pm);
  /* A split finer than OBS_PATCH_SPLIT_MAX is capped, and counted. */
  assert_int_equal(obs_patch_mesh_build(&geo, 1e-30, "/x", &pm, &err), 0);
  assert_int_equal(pm.capped, 4);
  assert_int_equal(pm.count, 4 * OBS_PATCH_SPLIT_MAX * OBS_PATCH_SPLIT_MAX);
  obs_patch_mesh_free(&pm);
  obs_geometry_free(&geo);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* A zero-area triangle beside a plate: one patch of area 0, never sampled, "nothing" (no NaN). */
static void test_degenerate(void **state) {
  (void)state;
  const char *doc =
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},"
      "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0,0.1,0],[1,0.1,0],[2,0.1,0]]},"
      "\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}";
  for (int method = 0; method < 3; method++) {
    obs_obscurance_map_params p = obs_test_omap_defaults(method);
    p.patch_size = 0.5;
    obs_omap m;
    map_of(doc, &p, 2, &m);
    assert_int_equal(m.pm.degenerate, 1);
    int64_t last = m.pm.count - 1;
    assert_true(m.pm.area[last] == 0.0f);
    assert_int_equal(m.n[last], 0);
    assert_true(m.w[3 * last] == (float)m.r_ave[0]);
    assert_int_equal(m.unsampled, 0);
    obs_omap_free(&m);
  }
}

/* ---- extremes ---- */

/* A floor with a block standing just above it (a bottom face coincident with the floor would
 * make the order of the two along a line a matter of rounding), every length times s. */
static const char *room_doc(double s, double refl) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,%g,%g],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":8,\"height\":8},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[%g,0,%g],[%g,0,%g],[%g,0,%g],"
      "[%g,0,%g]]},\"material\":{\"reflectivity\":[%g,%g,%g]}},"
      "{\"shape\":{\"type\":\"box\",\"min\":[%g,%g,%g],\"max\":[%g,%g,%g]},"
      "\"material\":{\"reflectivity\":[%g,%g,%g]}}],"
      "\"technique\":{\"name\":\"obscurance_map\"}}",
      2 * s, -3 * s, -2 * s, -2 * s, -2 * s, 2 * s, 2 * s, 2 * s, 2 * s, -2 * s, refl, refl, refl,
      -0.5 * s, 0.05 * s, -0.5 * s, 0.5 * s, 0.7 * s, 0.5 * s, refl, refl * 0.5, refl);
}

static void test_scale_invariance(void **state) {
  (void)state;
  for (int method = 0; method < 3; method++) {
    obs_omap ref;
    obs_obscurance_map_params p = obs_test_omap_defaults(method);
    p.patch_size = 0.5;
    p.d_max = 1;
    map_of(room_doc(1, 0.6), &p, 2, &ref);
    const double scales[2] = {1e-4, 1e4};
    for (int k = 0; k < 2; k++) {
      obs_obscurance_map_params q = p;
      q.patch_size *= scales[k];
      q.d_max *= scales[k];
      q.tau /= scales[k];
      obs_omap m;
      map_of(room_doc(scales[k], 0.6), &q, 2, &m);
      assert_int_equal(m.pm.count, ref.pm.count);
      double sum = 0, worst = 0;
      for (int64_t i = 0; i < m.pm.count; i++) {
        assert_true(fabs(m.pm.area[i] / (scales[k] * scales[k]) - ref.pm.area[i]) <=
                    1e-5 * ref.pm.area[i]);
        for (int c = 0; c < 3; c++) {
          double d = fabs((double)m.w[3 * i + c] - ref.w[3 * i + c]);
          sum += d, worst = fmax(worst, d);
        }
      }
      printf("%s scale %g: mean |d| %.2g, max %.2g\n", method_names[method], scales[k],
             sum / (3.0 * m.pm.count), worst);
      /* The same lines and rays relative to the scene: only samples grazing an edge may change. */
      assert_true(sum / (3.0 * m.pm.count) < 1e-5);
      assert_true(worst < 1e-3);
      obs_omap_free(&m);
    }
    obs_omap_free(&ref);
  }
}

static void test_dmax_and_reflectivity_ends(void **state) {
  (void)state;
  for (int method = 0; method < 3; method++) {
    obs_obscurance_map_params p = obs_test_omap_defaults(method);
    p.patch_size = 0.5;
    p.color_bleeding = 0;
    obs_omap m;
    /* d_max tiny: nothing is within reach but contact. */
    p.d_max = 1e-9;
    map_of(room_doc(1, 0.5), &p, 2, &m);
    for (int64_t i = 0; i < m.pm.count; i++) assert_true(m.w[3 * i] >= 0.99f || m.n[i] == 0);
    obs_omap_free(&m);
    /* d_max huge: every surface seen is as good as in contact, open directions stay 1. */
    p.d_max = 1e30;
    map_of(room_doc(1, 0.5), &p, 2, &m);
    obs_omap_free(&m);
    p.falloff = OBS_FALLOFF_EXP;
    p.tau = 1e-30;
    map_of(room_doc(1, 0.5), &p, 2, &m);
    obs_omap_free(&m);
    /* Reflectivity 0 with bleeding: every sample is 0 (R_ave = 0 too). */
    p = obs_test_omap_defaults(method);
    p.patch_size = 0.5;
    map_of(room_doc(1, 0.0), &p, 2, &m);
    for (int64_t i = 0; i < 3 * m.pm.count; i++) assert_true(m.w[i] == 0.0f);
    obs_omap_free(&m);
    map_of(room_doc(1, 0.99), &p, 2, &m); /* in range: map_of checks [0, 1] and finite */
    obs_omap_free(&m);
  }
}

static void test_seed_and_threads(void **state) {
  (void)state;
  for (int method = 0; method < 3; method++) {
    obs_obscurance_map_params p = obs_test_omap_defaults(method);
    p.patch_size = 0.5;
    p.samples = 16;
    p.directions = 16;
    p.bundle_resolution = 32;
    obs_omap m[4];
    for (int t = 0; t < 3; t++) map_of(room_doc(1, 0.6), &p, t + 1, &m[t]);
    p.seed = 2;
    map_of(room_doc(1, 0.6), &p, 2, &m[3]);
    size_t bytes = (size_t)m[0].pm.count * 3 * sizeof(float);
    assert_memory_equal(m[0].w, m[1].w, bytes);
    assert_memory_equal(m[0].w, m[2].w, bytes);
    assert_memory_equal(m[0].se, m[2].se, 3 * (size_t)m[0].pm.count * sizeof(float));
    assert_true(memcmp(m[0].w, m[3].w, bytes) != 0);
    for (int t = 0; t < 4; t++) obs_omap_free(&m[t]);
  }
}

/* The reference is the same map by the rays estimator, with the defining parameters copied; on
 * request, rt_ao with the same falloff for W without colour bleeding. */
static void test_reference_hook(void **state) {
  (void)state;
  const obs_technique *t = obs_technique_find("obscurance_map");
  assert_non_null(t);
  obs_scene sc;
  obs_test_load(obs_test_omap_plane_doc(0.5), "plane.json", &sc);
  json_t *params =
      json_pack("{s:s, s:f, s:s, s:b, s:f, s:i}", "method", "bundles", "d_max", 2.5, "falloff",
                "exp", "color_bleeding", 0, "patch_size", 0.25, "directions", 32);
  obs_reference_def def;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_technique_reference(t, &sc, params, NULL, &def, &err), 0);
  assert_ptr_equal(def.technique, t);
  assert_int_equal(def.response, OBS_RESPONSE_IDENTITY);
  assert_string_equal(json_string_value(json_object_get(def.params, "method")), "rays");
  assert_true(json_real_value(json_object_get(def.params, "d_max")) == 2.5);
  assert_string_equal(json_string_value(json_object_get(def.params, "falloff")), "exp");
  assert_true(json_is_false(json_object_get(def.params, "color_bleeding")));
  assert_true(json_real_value(json_object_get(def.params, "patch_size")) == 0.25);
  assert_null(json_object_get(def.params, "directions"));
  assert_string_equal(t->reference_quality, "samples");
  assert_null(def.output);
  assert_ptr_equal(obs_technique_compared_output(t, t), obs_technique_primary(t));
  obs_reference_def_free(&def);
  /* Against rt_ao: W without bleeding, the falloff's parameters under rt_ao's names. */
  const obs_technique *rt = obs_technique_find("rt_ao");
  assert_int_equal(obs_technique_reference_against(t, &sc, params, "rt_ao", NULL, &def, &err), 0);
  assert_ptr_equal(def.technique, rt);
  assert_string_equal(def.output, "obscurance");
  assert_true(json_real_value(json_object_get(def.params, "max_distance")) == 2.5);
  assert_string_equal(json_string_value(json_object_get(def.params, "falloff")), "exp");
  assert_int_equal((int)json_object_size(def.params), 2); /* these params have no tau */
  assert_string_equal(obs_technique_compared_output(t, rt)->name, "obscurance");
  obs_reference_def_free(&def);
  json_object_set_new(params, "color_bleeding", json_true());
  assert_int_equal(obs_technique_reference_against(t, &sc, params, "rt_ao", NULL, &def, &err),
                   OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "/technique/params/color_bleeding"));
  obs_err_clear(&err);
  assert_int_equal(obs_technique_reference_against(t, &sc, params, "ssao", NULL, &def, &err),
                   OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "cannot be compared against \"ssao\""));
  json_decref(params);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* A whole render: the .patches output (RGB, with areas adding up to the scene's), the image of
 * the patch each pixel sees, and the coverage. */
static void test_render(void **state) {
  (void)state;
  obs_result r;
  obs_test_render(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
      "\"fov_y\":60},\"image\":{\"width\":16,\"height\":12},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],"
      "[2,0,-2]]},\"material\":{\"reflectivity\":[0.8,0.4,0.2]}}],"
      "\"technique\":{\"name\":\"obscurance_map\",\"params\":{\"patch_size\":1,"
      "\"samples\":8}}}",
      2, &r);
  obs_test_assert_finite(&r.image);
  assert_int_equal(r.npatches, 2);
  const obs_patches *p = &r.patches[0], *pse = &r.patches[1];
  assert_string_equal(p->name, "obscurance");
  assert_string_equal(pse->name, "obscurance_stderr");
  assert_int_equal(p->components, 3);
  assert_int_equal(pse->components, 3);
  assert_int_equal(p->count, 2 * 6 * 6); /* diagonal 5.66: n = 6 */
  assert_int_equal(pse->count, p->count);
  double area = 0;
  for (int64_t i = 0; i < p->count; i++) {
    area += p->area[i];
    /* Nothing within d_max over an open plane: R_ave in each channel, exactly (no surface lies
     * above a patch: its standard error is 0). */
    assert_true(fabsf(p->values[3 * i] - 0.8f) < 1e-6f);
    assert_true(fabsf(p->values[3 * i + 2] - 0.2f) < 1e-6f);
    for (int c = 0; c < 3; c++) assert_true(pse->values[3 * i + c] == 0.0f);
  }
  assert_true(fabs(area - 16.0) < 1e-4);
  size_t n = (size_t)r.image.width * (size_t)r.image.height, seen = 0;
  const float *w = obs_image_channel(&r.image, "obscurance");
  const float *g = obs_image_channel(&r.image, "obscurance_rgb.G");
  const float *al = obs_image_channel(&r.image, "alpha");
  assert_non_null(w);
  assert_non_null(g);
  assert_non_null(al);
  for (size_t i = 0; i < n; i++) {
    if (al[i] == 0.0f) {
      assert_true(w[i] == 0.0f && g[i] == 0.0f);
      continue;
    }
    seen++;
    assert_true(fabsf(w[i] - (0.8f + 0.4f + 0.2f) / 3) < 1e-6f);
    assert_true(fabsf(g[i] - 0.4f) < 1e-6f);
  }
  assert_true(seen > n / 4 && seen < n);
  obs_result_free(&r);
}

/* bundles below OBS_OMAP_STDERR_MIN_DIRECTIONS directions: the render says its standard errors
 * are not calibrated there (too few groups of directions); from that count on it does not. */
static void test_bundles_stderr_warning(void **state) {
  (void)state;
  const unsigned dirs[2] = {OBS_OMAP_STDERR_MIN_DIRECTIONS - 1, OBS_OMAP_STDERR_MIN_DIRECTIONS};
  for (int k = 0; k < 2; k++) {
    obs_result r;
    obs_test_render(
        obs_test_fmt(
            "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],"
            "\"fov_y\":60},\"image\":{\"width\":8,\"height\":6},"
            "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],"
            "[2,0,2],[2,0,-2]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
            "\"technique\":{\"name\":\"obscurance_map\",\"params\":{\"method\":\"bundles\","
            "\"directions\":%u,\"bundle_resolution\":8}}}",
            dirs[k]),
        2, &r);
    int warned = 0;
    for (int w = 0; w < r.nwarnings; w++)
      warned |= strstr(r.warnings[w], "obscurance_stderr is calibrated from 16 directions") != NULL;
    assert_int_equal(warned, k == 0);
    obs_result_free(&r);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_open_plane),
      cmocka_unit_test(test_plates_rays),
      cmocka_unit_test(test_plates_global_lines),
      cmocka_unit_test(test_plates_bundles),
      cmocka_unit_test(test_cornell_agree),
      cmocka_unit_test(test_subdivision),
      cmocka_unit_test(test_degenerate),
      cmocka_unit_test(test_scale_invariance),
      cmocka_unit_test(test_dmax_and_reflectivity_ends),
      cmocka_unit_test(test_seed_and_threads),
      cmocka_unit_test(test_reference_hook),
      cmocka_unit_test(test_render),
      cmocka_unit_test(test_bundles_stderr_warning),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
