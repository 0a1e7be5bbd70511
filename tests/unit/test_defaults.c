/* The params a technique starts from on a scene (obs_technique_defaults_for): the scene's own for
 * its technique, lengths derived from the scene's size for another, and the render warning of a
 * length that is tiny or huge for the scene (obs_range_check). */
#include <jansson.h>
#include <math.h>
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
    obs_range_check(&obs_technique_find("rt_ao")->range[OBS_BACKEND_CPU], "rt_ao", OBS_BACKEND_CPU, &sc,
                    &ex, &ctx);
    assert_int_equal(count_with(&ctx, "max_distance ="), warns[i]);
    if (warns[i])
      assert_non_null(strstr(ctx.warnings[0], values[i] < 1 ? "unoccluded" : "saturated"));
  }
  obs_scene_free(&sc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_same_technique_keeps_scene),
      cmocka_unit_test(test_other_technique_derives_lengths),
      cmocka_unit_test(test_size_defaults_are_lengths),
      cmocka_unit_test(test_length_warning),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
