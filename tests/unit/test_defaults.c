/* The params a technique starts from on a scene (obs_technique_defaults_for): the scene's own for
 * its technique, lengths derived from the scene's size for another, and the render warning of a
 * length that is tiny or huge for the scene (obs_range_check). */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "extent.h"
#include "testutil.h"

static void load_cornell(obs_scene *sc) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(sc, obs_test_src("scenes/cornell_box.json"), NULL, 0, &err);
  if (rc) print_error("%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

static double size_of(const obs_scene *sc) {
  obs_extent ex;
  assert_int_equal(obs_scene_extent(sc, &ex, NULL), 0);
  return ex.size;
}

/* The scene's technique keeps the scene's params, and notes nothing. */
static void test_same_technique_keeps_scene(void **state) {
  (void)state;
  obs_scene sc;
  load_cornell(&sc);
  json_t *notes = json_array();
  json_t *p = obs_technique_defaults_for(obs_technique_find("rt_ao"), &sc, NULL, notes, NULL);
  assert_non_null(p);
  assert_true(json_equal(p, sc.params));
  assert_float_equal(json_number_value(json_object_get(p, "max_distance")), 200, 0);
  assert_int_equal(json_array_size(notes), 0);
  json_decref(p);
  /* Given values win over the scene's. */
  json_t *given = json_pack("{si}", "samples", 8);
  p = obs_technique_defaults_for(obs_technique_find("rt_ao"), &sc, given, notes, NULL);
  assert_int_equal(json_integer_value(json_object_get(p, "samples")), 8);
  assert_float_equal(json_number_value(json_object_get(p, "max_distance")), 200, 0);
  json_decref(p);
  json_decref(given);
  json_decref(notes);
  obs_scene_free(&sc);
}

/* Another technique: its lengths are fractions of the scene's size, each with a note; what is
 * given is kept and not noted; parameters without a size_default keep the registry's default. */
static void test_other_technique_derives_lengths(void **state) {
  (void)state;
  obs_scene sc;
  load_cornell(&sc);
  double size = size_of(&sc);
  assert_true(size > 500 && size < 2000);
  json_t *notes = json_array();
  json_t *p = obs_technique_defaults_for(obs_technique_find("hbao"), &sc, NULL, notes, NULL);
  assert_non_null(p);
  double r = json_number_value(json_object_get(p, "radius"));
  assert_float_equal(r, 0.3 * size, 1e-3 * size);
  assert_int_equal(json_integer_value(json_object_get(p, "directions")), 8);
  assert_int_equal(json_array_size(notes), 1);
  const char *note = json_string_value(json_array_get(notes, 0));
  assert_non_null(strstr(note, "hbao radius"));
  assert_non_null(strstr(note, "scene's size"));
  json_decref(p);
  /* ssao's radius is a fraction of the image: nothing to derive. */
  json_array_clear(notes);
  p = obs_technique_defaults_for(obs_technique_find("ssao"), &sc, NULL, notes, NULL);
  assert_float_equal(json_number_value(json_object_get(p, "radius")), 0.01, 1e-7);
  assert_int_equal(json_array_size(notes), 0);
  json_decref(p);
  /* A radius given is kept, and nothing is noted. */
  json_t *given = json_pack("{sf}", "radius", 30.0);
  p = obs_technique_defaults_for(obs_technique_find("hbao"), &sc, given, notes, NULL);
  assert_float_equal(json_number_value(json_object_get(p, "radius")), 30, 0);
  assert_int_equal(json_array_size(notes), 0);
  json_decref(p);
  json_decref(given);
  json_decref(notes);
  obs_scene_free(&sc);
}

/* Every declared size_default is on a length (size_power 1), as the self-check demands. */
static void test_size_defaults_are_lengths(void **state) {
  (void)state;
  int found = 0;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    for (size_t k = 0; k < t->params_size; k++)
      if (t->params[k].size_default > 0) {
        assert_int_equal(obs_technique_param_size_power(t, t->params[k].name), 1);
        found++;
      }
  }
  assert_true(found >= 2); /* hbao radius, rt_ao max_distance */
}

static int count_with(const obs_render_ctx *ctx, const char *what) {
  int n = 0;
  for (int i = 0; i < ctx->nwarnings; i++) n += strstr(ctx->warnings[i], what) != NULL;
  return n;
}

/* A length below 1e-3 or above 10 scene sizes warns; one in between does not. */
static void test_length_warning(void **state) {
  (void)state;
  obs_scene sc;
  load_cornell(&sc);
  obs_extent ex;
  assert_int_equal(obs_scene_extent(&sc, &ex, NULL), 0);
  const double values[] = {0.5, 200, 1e5};
  const int warns[] = {1, 0, 1};
  for (int i = 0; i < 3; i++) {
    json_object_set_new(sc.params, "max_distance", json_real(values[i]));
    obs_render_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    obs_range_check(&obs_technique_find("rt_ao")->range[OBS_BACKEND_CPU], "rt_ao", "cpu", &sc, &ex,
                    &ctx);
    assert_int_equal(count_with(&ctx, "max_distance ="), warns[i]);
    if (warns[i])
      assert_non_null(strstr(ctx.warnings[0], values[i] < 1 ? "unoccluded" : "saturated"));
  }
  obs_scene_free(&sc);
}

/* A derived default never trips a range check: for every technique with scene-size defaults,
 * on scenes of 241 sizes from 1e-6 to 1e6 (each decade cut in 40, mantissas between the 4-digit
 * roundings included) and on the bundled scenes' sizes, every backend's range check of the
 * derived params names none of them. obscurance_map's patch_size (0.05 scene sizes, Vulkan's
 * minimum) used to round under it: 0.05 x 56.59 to 2.829 on sphere_on_plane. */
static int derived_warnings(const obs_scene *sc, double size) {
  int bad = 0;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    json_t *p = obs_technique_defaults_for(t, sc, NULL, NULL, NULL);
    assert_non_null(p);
    obs_scene s = *sc; /* the same scene with the derived params, for the check only */
    s.params = p;
    obs_extent ex;
    assert_int_equal(obs_scene_extent(&s, &ex, NULL), 0);
    for (int be = OBS_BACKEND_CPU; be < OBS_BACKEND_COUNT; be++) {
      if (!t->run[be]) continue;
      obs_render_ctx ctx;
      memset(&ctx, 0, sizeof ctx);
      obs_range_check(&t->range[be], t->name, obs_backend_name((obs_backend)be), &s, &ex, &ctx);
      for (size_t k = 0; k < t->params_size; k++) {
        if (!(t->params[k].size_default > 0)) continue;
        char key[64];
        snprintf(key, sizeof key, "%s = ", t->params[k].name);
        for (int w = 0; w < ctx.nwarnings; w++)
          if (strstr(ctx.warnings[w], key)) {
            printf("size %.17g, %s on %s: %s\n", size, t->name,
                   obs_backend_name((obs_backend)be), ctx.warnings[w]);
            bad++;
          }
      }
    }
    json_decref(p);
  }
  return bad;
}

static void test_derived_defaults_in_range(void **state) {
  (void)state;
  int bad = 0, n = 0;
  for (int k = 0; k <= 480; k += 2, n++) {
    /* A quad of side L has the diagonal sqrt(2) L. */
    double size = pow(10.0, -6.0 + k / 40.0), L = size / sqrt(2.0);
    obs_scene sc;
    obs_test_load(obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,%.17g],"
                               "\"look_at\":[0,0,0],\"fov_y\":40},\"image\":{\"width\":8,"
                               "\"height\":8},\"objects\":[{\"shape\":{\"type\":\"quad\","
                               "\"vertices\":[[0,0,0],[%.17g,0,0],[%.17g,%.17g,0],[0,%.17g,0]]}}],"
                               "\"technique\":{\"name\":\"ssao\"}}",
                               -3 * L, L, L, L, L),
                  "sizes.json", &sc);
    bad += derived_warnings(&sc, size_of(&sc));
    obs_scene_free(&sc);
  }
  const char *files[] = {"scenes/sphere_on_plane.json", "scenes/teapot.json",
                         "scenes/cornell_box.json"};
  for (int f = 0; f < 3; f++) {
    obs_scene sc;
    obs_err err = OBS_ERR_INIT;
    int rc = obs_scene_load_file(&sc, obs_test_src(files[f]), NULL, 0, &err);
    if (rc) print_error("%s\n", obs_err_message(&err));
    assert_int_equal(rc, 0);
    obs_err_free(&err);
    bad += derived_warnings(&sc, size_of(&sc));
    obs_scene_free(&sc);
  }
  printf("%d sizes and 3 scenes: %d derived defaults outside a range\n", n, bad);
  assert_int_equal(bad, 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_same_technique_keeps_scene),
      cmocka_unit_test(test_other_technique_derives_lengths),
      cmocka_unit_test(test_size_defaults_are_lengths),
      cmocka_unit_test(test_length_warning),
      cmocka_unit_test(test_derived_defaults_in_range),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
