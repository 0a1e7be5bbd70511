/* obscurance_map's depth_peeling estimator on lavapipe: an open plane exactly, parallel plates
 * against the closed form, agreement with the CPU's bundles (same directions and grids) on the
 * Cornell box, the same bits for the same seed, scale and d_max extremes, the technique's run,
 * the refusal of a method on a backend that lacks it, and no range warning from the lengths
 * derived for the bundled scenes. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurance_map_cpu.h"
#include "omap_peel.h"
#include "omap_scenes.h"
#include "raytrace.h"
#include "stderr_check.h"
#include "vktest.h"

/* The shared test parameters with 32 directions: a rendered direction costs more than a traced
 * bundle. */
static obs_obscurance_map_params defaults(int method) {
  obs_obscurance_map_params p = obs_test_omap_defaults(method);
  p.directions = 32;
  return p;
}

/* The depth-peeled map of `p` on `doc` (asserting success, values finite and in [0, 1]). */
static void peel_of(const char *doc, const obs_obscurance_map_params *p, obs_omap_peel *m) {
  obs_vk *vk = vktest_need_vk();
  obs_scene sc;
  obs_test_load(doc, "peel.json", &sc);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, sc.width, sc.height, &rig);
  obs_geometry geo;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_geometry_build_at(&sc, rig.origin, &geo, &err);
  if (!rc) rc = obs_omap_peel_compute(vk, &sc, &geo, p, NULL, NULL, NULL, NULL, m, NULL, &err);
  vktest_check_rc(rc, &err);
  obs_err_free(&err);
  obs_geometry_free(&geo);
  obs_scene_free(&sc);
  for (int64_t i = 0; i < m->pm.count; i++) {
    for (int c = 0; c < 3; c++) assert_true(m->w[3 * i + c] >= 0.0f && m->w[3 * i + c] <= 1.0f);
    for (int c = 0; c < 3; c++)
      assert_true(isfinite(m->se[3 * i + c]) && m->se[3 * i + c] >= 0.0f);
  }
}

/* The CPU map of `p` on `doc`. */
static void cpu_of(const char *doc, const obs_obscurance_map_params *p, obs_omap *m) {
  obs_scene sc;
  obs_test_load(doc, "peel.json", &sc);
  obs_rt rt;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_rt_build_ex(&sc, &rt, 2, OBS_RT_FRAME_GEOMETRY, &err);
  if (!rc) rc = obs_omap_compute(&rt, &sc, p, 2, NULL, NULL, NULL, m, &err);
  vktest_check_rc(rc, &err);
  obs_err_free(&err);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
}

static void test_open_plane(void **state) {
  (void)state;
  for (int bleed = 0; bleed < 2; bleed++) {
    obs_obscurance_map_params p = defaults(OBS_OMAP_DEPTH_PEELING);
    p.color_bleeding = bleed;
    p.patch_size = 0.5;
    obs_omap_peel m;
    peel_of(obs_test_omap_plane_doc(0.8), &p, &m);
    assert_int_equal(m.pm.count, 2 * 12 * 12);
    assert_int_equal(m.unsampled, 0);
    const double r[3] = {0.8, 0.4, 0.2};
    for (int64_t i = 0; i < m.pm.count; i++)
      for (int c = 0; c < 3; c++) {
        if (!bleed)
          assert_true(m.w[3 * i + c] == 1.0f);
        else
          assert_true(fabs(m.w[3 * i + c] - r[c]) < 1e-6);
      }
    obs_omap_peel_free(&m);
  }
}

/* The central patches of each plate (centroid within 0.6 of the axis, so everything within d_max
 * of them lies on the other plate) against the closed form: the area-weighted mean per plate and
 * channel within 3 sigma, every patch within 5. */
static void check_plates(int bleed) {
  const double h = 0.5, L = 2.5, dmax = 1.0;
  obs_obscurance_map_params p = defaults(OBS_OMAP_DEPTH_PEELING);
  p.color_bleeding = bleed;
  p.patch_size = 0.25;
  /* As for the CPU bundles: many directions keep the error common to all patches (that of the
   * direction set) well below the pooled noise. */
  p.directions = 1024;
  p.bundle_resolution = 45;
  const char *doc = obs_test_omap_plates_doc(h, L);
  obs_omap_peel m;
  peel_of(doc, &p, &m);
  obs_test_omap_check_plates("depth_peeling", obs_test_omap_plates_doc(h, L), h, dmax, bleed,
                             &m.pm, m.w, m.se);
  obs_omap_peel_free(&m);
}

static void test_plates(void **state) {
  (void)state;
  check_plates(0);
  check_plates(1);
}

/* bundles (CPU) and depth_peeling (Vulkan) cast the same lines: their per-patch RMSE must stay
 * within the per-patch noise of either. */
static void test_cornell_bundles(void **state) {
  (void)state;
  char *doc = obs_test_omap_cornell_doc();
  obs_obscurance_map_params p = defaults(OBS_OMAP_BUNDLES);
  p.d_max = 200;
  p.patch_size = 100;
  obs_omap cpu;
  cpu_of(doc, &p, &cpu);
  p.method = OBS_OMAP_DEPTH_PEELING;
  obs_omap_peel gpu;
  peel_of(doc, &p, &gpu);
  assert_int_equal(gpu.pm.count, cpu.pm.count);
  double d2 = 0, se_cpu = 0, se_gpu = 0;
  size_t k = 0;
  for (int64_t i = 0; i < cpu.pm.count; i++) {
    /* As on the CPU: patches with few samples (under the blocks) have no usable noise estimate. */
    if (cpu.n[i] < 32 || gpu.n[i] < 32) continue;
    for (int c = 0; c < 3; c++) {
      double d = (double)cpu.w[3 * i + c] - gpu.w[3 * i + c];
      d2 += d * d;
    }
    for (int c = 0; c < 3; c++) {
      se_cpu += (double)cpu.se[3 * i + c] * cpu.se[3 * i + c] / 3;
      se_gpu += (double)gpu.se[3 * i + c] * gpu.se[3 * i + c] / 3;
    }
    k++;
  }
  double rmse = sqrt(d2 / (3.0 * k)), n_cpu = sqrt(se_cpu / k), n_gpu = sqrt(se_gpu / k);
  printf(
      "bundles vs depth_peeling: per-patch RMSE %.5f, noise %.5f (bundles) %.5f "
      "(depth_peeling) over %zu of %lld patches, %llu layers\n",
      rmse, n_cpu, n_gpu, k, (long long)cpu.pm.count, (unsigned long long)gpu.layers);
  assert_true(k > (size_t)cpu.pm.count * 8 / 10);
  assert_true(rmse <= n_cpu && rmse <= n_gpu);
  obs_omap_free(&cpu);
  obs_omap_peel_free(&gpu);
  free(doc);
}

static void test_same_seed_same_bits(void **state) {
  (void)state;
  char *doc = obs_test_omap_cornell_doc();
  obs_obscurance_map_params p = defaults(OBS_OMAP_DEPTH_PEELING);
  p.d_max = 200;
  p.patch_size = 150;
  p.directions = 8;
  obs_omap_peel m[3];
  peel_of(doc, &p, &m[0]);
  peel_of(doc, &p, &m[1]);
  p.seed = 2;
  peel_of(doc, &p, &m[2]);
  size_t bytes = (size_t)m[0].pm.count * 3 * sizeof(float);
  assert_memory_equal(m[0].w, m[1].w, bytes);
  assert_memory_equal(m[0].n, m[1].n, (size_t)m[0].pm.count * sizeof(uint64_t));
  assert_true(memcmp(m[0].w, m[2].w, bytes) != 0);
  for (int i = 0; i < 3; i++) obs_omap_peel_free(&m[i]);
  free(doc);
}

/* The Cornell box scaled by s about the origin (its coordinates and camera as text). */
static char *scaled_cornell(double s) {
  char *doc = obs_test_omap_cornell_doc();
  /* The box and its light are quads: scaling the "vertices", "position" and "look_at" arrays
   * scales the geometry and the camera alike. */
  char *out = calloc(1, 1 << 17);
  assert_non_null(out);
  const char *p = doc;
  char *o = out;
  while (*p) {
    int scale = !strncmp(p, "\"vertices\"", 10) || !strncmp(p, "\"position\"", 10) ||
                !strncmp(p, "\"look_at\"", 9);
    if (!scale) {
      *o++ = *p++;
      continue;
    }
    const char *colon = strchr(p, ':');
    memcpy(o, p, (size_t)(colon - p + 1));
    o += colon - p + 1;
    p = colon + 1;
    while (*p == ' ') *o++ = *p++;
    int depth = 0;
    do {
      if (*p == '[') depth++;
      if (*p == ']') depth--;
      if ((*p >= '0' && *p <= '9') || *p == '-' || *p == '.') {
        char *end;
        double v = strtod(p, &end);
        o += sprintf(o, "%.17g", v * s);
        p = end;
        continue;
      }
      *o++ = *p++;
    } while (depth > 0);
  }
  free(doc);
  return out;
}

/* Scaled by 1e-4 and 1e4, and with d_max at its range's ends: finite, in range, and the same
 * map up to the rounding of the normalised coordinates (a few samples' worth per patch). */
static void test_extremes(void **state) {
  (void)state;
  obs_obscurance_map_params p = defaults(OBS_OMAP_DEPTH_PEELING);
  p.d_max = 200;
  p.patch_size = 150;
  p.directions = 8;
  obs_omap_peel base;
  char *doc = scaled_cornell(1);
  peel_of(doc, &p, &base);
  free(doc);
  const double scales[2] = {1e-4, 1e4};
  for (int k = 0; k < 2; k++) {
    obs_obscurance_map_params q = p;
    q.d_max = p.d_max * scales[k];
    q.patch_size = p.patch_size * scales[k];
    obs_omap_peel m;
    doc = scaled_cornell(scales[k]);
    peel_of(doc, &q, &m);
    free(doc);
    assert_int_equal(m.pm.count, base.pm.count);
    double worst = 0;
    for (int64_t i = 0; i < m.pm.count; i++)
      for (int c = 0; c < 3; c++)
        worst = fmax(worst, fabs((double)m.w[3 * i + c] - base.w[3 * i + c]));
    printf("scale %g: largest per-patch change %.2e\n", scales[k], worst);
    assert_true(worst < 0.02);
    obs_omap_peel_free(&m);
  }
  /* d_max at the lower end: every surface is farther, every sample is "nothing" (R_ave). */
  doc = obs_test_omap_cornell_doc();
  obs_obscurance_map_params q = p;
  q.d_max = 1e-6 * 559;
  obs_omap_peel m;
  peel_of(doc, &q, &m);
  for (int64_t i = 0; i < m.pm.count; i++)
    for (int c = 0; c < 3; c++) assert_true(fabs(m.w[3 * i + c] - m.r_ave[c]) < 1e-6);
  obs_omap_peel_free(&m);
  /* At the upper end rho is ~0 for everything seen: with the same lines, no sample's value can
   * exceed its value at the base d_max (without bleeding: rho, or 1 for nothing seen). */
  q.color_bleeding = 0;
  q.d_max = 1e6 * 559;
  obs_omap_peel lo;
  peel_of(doc, &q, &m);
  q.d_max = p.d_max;
  peel_of(doc, &q, &lo);
  double mean = 0;
  for (int64_t i = 0; i < m.pm.count; i++) {
    assert_true(m.w[3 * i] <= lo.w[3 * i] + 1e-6);
    mean += m.w[3 * i] - lo.w[3 * i];
  }
  printf("d_max 1e6 scene sizes: mean W change %.3e against d_max 200\n",
         mean / (double)m.pm.count);
  obs_omap_peel_free(&m);
  obs_omap_peel_free(&lo);
  free(doc);
  obs_omap_peel_free(&base);
}

/* A document of the Cornell box at 32 x 32 with `params` on `backend`. */
static char *cornell_render_doc(const char *backend, const char *params) {
  char *doc = obs_test_omap_cornell_doc();
  char *t = strstr(doc, "\"technique\"");
  assert_non_null(t);
  snprintf(t, 4096, "\"technique\":{\"name\":\"obscurance_map\",\"backend\":\"%s\",\"params\":%s}}",
           backend, params);
  char *img = strstr(doc, "\"width\": 256, \"height\": 256");
  assert_non_null(img);
  memcpy(img, "\"width\": 32 , \"height\": 32 ", 27);
  return doc;
}

/* The technique's run: a per-patch output and an image of the patch each pixel sees. */
static void test_render(void **state) {
  (void)state;
  vktest_need_vk();
  char *doc =
      cornell_render_doc("vulkan",
                         "{\"method\":\"depth_peeling\",\"directions\":8,\"bundle_resolution\":48,"
                         "\"d_max\":200,\"patch_size\":150}");
  obs_scene sc;
  obs_test_load(doc, "cornell.json", &sc);
  obs_result res;
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  int rc = obs_render(&sc, &o, &res, &err);
  vktest_check_rc(rc, &err);
  assert_int_equal(res.backend, OBS_BACKEND_VULKAN);
  assert_int_equal(res.npatches, 2); /* obscurance and obscurance_stderr */
  assert_true(res.patches[0].count > 0);
  assert_int_equal(res.patches[1].count, res.patches[0].count);
  const obs_image *im = &res.image;
  size_t npx = (size_t)im->width * (size_t)im->height, covered = 0;
  const float *alpha = obs_image_channel(im, "alpha");
  assert_non_null(alpha);
  for (size_t i = 0; i < npx; i++) {
    float a = alpha[i];
    covered += a == 1.0f;
    for (int c = 0; c < 5; c++) { /* W, its error, RGB */
      float v = im->data[(size_t)c * npx + i];
      assert_true(isfinite(v) && v >= 0 && v <= 1);
      if (a == 0.0f) assert_true(v == 0.0f);
    }
  }
  /* The box fills most of the view. */
  assert_true(covered > npx / 2);
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free(doc);
}

/* A method on a backend that lacks it is refused, naming the parameter. */
static void test_refusals(void **state) {
  (void)state;
  static const char *const cases[3][2] = {{"vulkan", "{\"method\":\"rays\"}"},
                                          {"cpu", "{\"method\":\"depth_peeling\"}"},
                                          {"auto", "{\"method\":\"depth_peeling\"}"}};
  for (int k = 0; k < 3; k++) {
    char *doc = cornell_render_doc(cases[k][0], cases[k][1]);
    obs_scene sc;
    obs_err err = OBS_ERR_INIT;
    int rc = obs_scene_load_string(&sc, doc, "cornell.json", NULL, NULL, 0, &err);
    assert_int_equal(rc, OBS_EINVAL);
    printf("%s %s: %s\n", cases[k][0], cases[k][1], obs_err_message(&err));
    assert_non_null(strstr(obs_err_message(&err), "/technique/params/method"));
    assert_non_null(strstr(obs_err_message(&err), "backend"));
    obs_err_free(&err);
    free(doc);
  }
}

/* The bundled sphere_on_plane and teapot (grey materials added), switched to obscurance_map on
 * Vulkan with the lengths derived from their size (obs_technique_defaults_for, as `obscura render
 * --technique` and the server do): no range warning. patch_size's share, 0.05 scene sizes, is
 * Vulkan's minimum, and it used to round under it (2.829 and 4.247). */
static void test_derived_defaults(void **state) {
  (void)state;
  vktest_need_vk();
  const char *names[2] = {"sphere_on_plane", "teapot"};
  for (int k = 0; k < 2; k++) {
    char rel[64];
    snprintf(rel, sizeof rel, "scenes/%s.json", names[k]);
    json_error_t je;
    json_t *doc = json_load_file(obs_test_src(rel), 0, &je);
    assert_non_null(doc);
    size_t i;
    json_t *o;
    json_array_foreach(json_object_get(doc, "objects"), i, o)
        json_object_set_new(o, "material", json_pack("{s[fff]}", "reflectivity", 0.5, 0.5, 0.5));
    json_object_set_new(json_object_get(doc, "image"), "width", json_integer(48));
    json_object_set_new(json_object_get(doc, "image"), "height", json_integer(36));
    char dir[512];
    snprintf(dir, sizeof dir, "%s", obs_test_src("scenes"));
    obs_scene old, sc;
    obs_err err = OBS_ERR_INIT;
    vktest_check_rc(obs_scene_load_json(&old, doc, rel, dir, NULL, 0, &err), &err);
    const obs_technique *t = obs_technique_find("obscurance_map");
    json_t *params = obs_technique_defaults_for(t, &old, NULL, NULL, &err);
    assert_non_null(params);
    obs_scene_free(&old);
    printf("%s: patch_size %.17g, d_max %.17g\n", names[k],
           json_number_value(json_object_get(params, "patch_size")),
           json_number_value(json_object_get(params, "d_max")));
    /* Cheap directions: the range check does not depend on them. */
    json_object_set_new(params, "directions", json_integer(8));
    json_t *tech = json_pack("{s:s, s:s, s:o}", "name", t->name, "backend", "vulkan", "params",
                             params);
    assert_non_null(tech);
    json_object_set_new(doc, "technique", tech);
    vktest_check_rc(obs_scene_load_json(&sc, doc, rel, dir, NULL, 0, &err), &err);
    assert_int_equal(sc.backend, OBS_BACKEND_VULKAN);
    obs_result res;
    obs_render_opts opts = {.threads = 2};
    vktest_check_rc(obs_render(&sc, &opts, &res, &err), &err);
    for (int w = 0; w < res.nwarnings; w++) {
      printf("  warned: %s\n", res.warnings[w]);
      assert_null(strstr(res.warnings[w], "Guaranteed ranges"));
    }
    obs_result_free(&res);
    obs_scene_free(&sc);
    obs_err_free(&err);
    json_decref(doc);
  }
}

/* depth_peeling's per-patch standard errors, held to the CPU's check (stderr_check.h): groups of
 * directions with their own rotations, pooled over each triangle's patches. */
static void test_stderr_calibrated(void **state) {
  (void)state;
  vktest_need_vk();
  static const obs_stderr_case c = {
      "obscurance_map depth_peeling (vulkan)", "scenes/cornell_box.json", "obscurance_map",
      "vulkan",
      "{\"method\":\"depth_peeling\",\"directions\":$N,\"bundle_resolution\":64,"
      "\"patch_size\":100,\"d_max\":150,\"seed\":$S}",
      "obscurance", "obscurance_stderr", 1, 8};
  obs_test_stderr_check(&c, 16);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_open_plane, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_plates, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cornell_bundles, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_same_seed_same_bits, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_extremes, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_render, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_refusals, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_derived_defaults, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_stderr_calibrated, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
