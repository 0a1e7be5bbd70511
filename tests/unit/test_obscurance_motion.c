/* Moving objects in scenes and obscurance_map's frame updates: the scene format's rules, the
 * per-frame .patches output, `update: "exact"` equal to a full recompute bit for bit at every
 * scale, and the article's influenced list missing what it is known to miss. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/obscura.h"
#include "obscura/patches.h"
#include "testutil.h"

/* A floor, a wall behind it and a moving object at scale `s` (every length times s): a box
 * (`lid` 0), or a 1 x 1 quad at height 0.3 facing up (`lid` 1) or down (`lid` -1), which
 * starts beyond d_max of everything and ends beside the wall. */
static char *motion_doc(double s, int lid, const char *update, int extra_frames) {
  char obj[1024], motion[1024] = "";
  if (lid) {
    double a = lid > 0 ? -0.5 : 0.5; /* the winding picks the facing side */
    snprintf(obj, sizeof obj,
             "{\"name\":\"lid\",\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],"
             "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]},"
             "\"material\":{\"reflectivity\":[0.2,0.3,0.9]},"
             "\"transform\":{\"translate\":[%.17g,0,0]}",
             a * s, 0.3 * s, -0.5 * s, a * s, 0.3 * s, 0.5 * s, -a * s, 0.3 * s, 0.5 * s, -a * s,
             0.3 * s, -0.5 * s, -3.5 * s);
    snprintf(motion, sizeof motion, ",\"motion\":[{\"translate\":[0,0,%.17g]}]}", -1.45 * s);
  } else {
    snprintf(obj, sizeof obj,
             "{\"name\":\"box\",\"shape\":{\"type\":\"box\",\"min\":[%.17g,0,%.17g],"
             "\"max\":[%.17g,%.17g,%.17g]},\"material\":{\"reflectivity\":[0.3,0.8,0.3]},"
             "\"transform\":{\"translate\":[%.17g,0,0]}",
             -0.3 * s, -0.3 * s, 0.3 * s, 0.6 * s, 0.3 * s, -1.0 * s);
    size_t l = 0;
    l += (size_t)snprintf(motion + l, sizeof motion - l, ",\"motion\":[");
    for (int f = 1; f <= 2 + extra_frames; f++)
      l += (size_t)snprintf(motion + l, sizeof motion - l,
                            "%s{\"translate\":[%.17g,0,%.17g],\"rotate\":[0,%d,0]}",
                            f > 1 ? "," : "", (-1.0 + 0.6 * f) * s, -0.4 * s * f, 25 * f);
    snprintf(motion + l, sizeof motion - l, "]}");
  }
  return strdup(
      obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,%.17g,%.17g],"
                   "\"look_at\":[0,%.17g,0],\"fov_y\":50},\"image\":{\"width\":24,\"height\":18},"
                   "\"objects\":[{\"name\":\"floor\",\"shape\":{\"type\":\"quad\",\"vertices\":"
                   "[[%.17g,0,%.17g],[%.17g,0,%.17g],[%.17g,0,%.17g],[%.17g,0,%.17g]]},"
                   "\"material\":{\"reflectivity\":[0.7,0.7,0.7]}},"
                   "{\"name\":\"wall\",\"shape\":{\"type\":\"quad\",\"vertices\":"
                   "[[%.17g,0,%.17g],[%.17g,0,%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]},"
                   "\"material\":{\"reflectivity\":[0.8,0.3,0.3]}},%s%s],"
                   "\"technique\":{\"name\":\"obscurance_map\",\"params\":{\"method\":\"rays\","
                   "\"samples\":16,\"patch_size\":%.17g,\"d_max\":%.17g,\"update\":\"%s\"}}}",
                   1.5 * s, 4.0 * s, 0.4 * s, -2 * s, -2 * s, -2 * s, 2 * s, 2 * s, 2 * s, 2 * s,
                   -2 * s, -2 * s, -2 * s, 2 * s, -2 * s, 2 * s, 2 * s, -2 * s, -2 * s, 2 * s,
                   -2 * s, obj, motion, 0.25 * s, 0.8 * s, update));
}

static void render(const char *doc, int threads, obs_result *r) {
  obs_test_render(doc, threads, r);
}

/* The frames' figures of a result: frame f's member `key`. */
static double frame_fig(const obs_result *r, int f, const char *key) {
  json_t *fr = json_array_get(r->frames, (size_t)f);
  json_t *v = json_object_get(fr, key);
  assert_non_null(v);
  return json_number_value(v);
}

/* exact equals full, every frame, every bit, at both ends of the guaranteed scale range and for
 * any thread count; and it samples fewer patches than a full recompute. */
static void test_exact_equals_full(void **state) {
  (void)state;
  const double scales[] = {1e-4, 1.0, 1e4};
  for (int k = 0; k < 3; k++) {
    char *exact = motion_doc(scales[k], 0, "exact", 0), *full = motion_doc(scales[k], 0, "full", 0);
    obs_result a, b, c;
    render(exact, 2, &a);
    render(full, 2, &b);
    render(exact, 1, &c);
    const obs_patches *pa = &a.patches[0], *pb = &b.patches[0], *pc = &c.patches[0];
    assert_int_equal(pa->frames, 3);
    assert_int_equal(pb->frames, 3);
    assert_int_equal(pa->count, pb->count);
    size_t n = obs_patches_values(pa);
    assert_memory_equal(pa->values, pb->values, n * sizeof(float));
    assert_memory_equal(pa->values, pc->values, n * sizeof(float));
    for (size_t i = 0; i < n; i++) assert_true(pa->values[i] >= 0.0f && pa->values[i] <= 1.0f);
    /* The frames differ: the box moved. */
    assert_true(memcmp(pa->values, pa->values + 3 * (size_t)pa->count,
                       3 * (size_t)pa->count * sizeof(float)) != 0);
    assert_int_equal((int)json_array_size(a.frames), 3);
    assert_true(frame_fig(&a, 0, "patches_updated") == (double)pa->count);
    for (int f = 1; f < 3; f++) {
      assert_true(frame_fig(&a, f, "patches_differing") == 0);
      assert_true(frame_fig(&a, f, "max_abs_vs_full") == 0);
      double upd = frame_fig(&a, f, "patches_updated");
      assert_true(upd > 0 && upd < 0.8 * (double)pa->count);
      assert_true(frame_fig(&b, f, "patches_updated") == (double)pb->count);
    }
    obs_test_assert_finite(&a.image);
    obs_result_free(&a);
    obs_result_free(&b);
    obs_result_free(&c);
    free(exact);
    free(full);
  }
}

/* A lid facing up moves from beyond d_max to just above the floor by the wall. Floor patches
 * under it and wall patches below it now meet its back; no sample of theirs met it before, and
 * its own samples go up, so the article's list never holds them: they keep frame 0's values while
 * a full recompute changes them. Facing down, its samples find them, and the error falls. */
static void test_article_misses(void **state) {
  (void)state;
  double rmse[2];
  for (int side = 0; side < 2; side++) {
    char *doc = motion_doc(1.0, side ? -1 : 1, "article", 0);
    obs_result r;
    render(doc, 2, &r);
    assert_int_equal((int)json_array_size(r.frames), 2);
    assert_true(frame_fig(&r, 0, "patches_updated") == (double)r.patches[0].count);
    rmse[side] = frame_fig(&r, 1, "rmse_vs_full");
    assert_true(isfinite(rmse[side]));
    if (side == 0) assert_true(frame_fig(&r, 1, "patches_differing") > 0);
    obs_result_free(&r);
    free(doc);
  }
  printf("article rmse vs full: lid facing up %.5f, facing down %.5f\n", rmse[0], rmse[1]);
  assert_true(rmse[0] > 0);
  assert_true(rmse[1] < 0.5 * rmse[0]);
  /* exact on the same move: nothing differs. */
  char *doc = motion_doc(1.0, 1, "exact", 0);
  obs_result r;
  render(doc, 2, &r);
  assert_true(frame_fig(&r, 1, "patches_differing") == 0);
  obs_result_free(&r);
  free(doc);
}

/* The .patches file of a moving scene: every frame, read back as written. */
static void test_patches_file(void **state) {
  (void)state;
  char *doc = motion_doc(1.0, 0, "exact", 1);
  obs_scene sc;
  obs_test_load(doc, "motion.json", &sc);
  assert_int_equal(sc.frames, 4);
  /* Backend auto never lands on one that renders no frames; the work counts frame 0 and, per
   * later frame, the update (at most a map) and the full recompute measure_full adds. */
  assert_int_equal(obs_technique_motion_backend(sc.technique, &sc, OBS_BACKEND_VULKAN),
                   OBS_BACKEND_CPU);
  assert_int_equal(obs_technique_motion_backend(sc.technique, &sc, OBS_BACKEND_CPU),
                   OBS_BACKEND_CPU);
  assert_true(obs_scene_work(&sc) == 24.0 * 18 * 16 * (1 + 3 * 2));
  obs_result r;
  obs_err err = OBS_ERR_INIT;
  render(doc, 2, &r);
  const char *dir = obs_test_tmpdir("motion-out");
  assert_int_equal(obs_result_write(&r, &sc, dir, &err), 0);
  obs_patches p;
  assert_int_equal(obs_patches_read(&p, obs_test_path(dir, "obscurance.patches"), &err), 0);
  assert_int_equal(p.frames, 4);
  assert_int_equal(p.count, r.patches[0].count);
  assert_memory_equal(p.values, r.patches[0].values, obs_patches_values(&p) * sizeof(float));
  double rmse = 1;
  assert_int_equal(obs_metrics_patch_rmse(&p, &r.patches[0], &rmse, &err), 0);
  assert_true(rmse == 0);
  /* Frames must match to compare. */
  p.frames = 2;
  assert_int_equal(obs_metrics_patch_rmse(&p, &r.patches[0], &rmse, &err), OBS_EINVAL);
  obs_patches_free(&p);
  obs_result_free(&r);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free(doc);
}

static void expect_refused(const char *doc, const char *needle) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "m.json", NULL, NULL, 0, &err);
  if (rc == 0 || !strstr(obs_err_message(&err), needle))
    print_error("wanted \"%s\", got rc %d: %s\n", needle, rc, obs_err_message(&err));
  assert_int_equal(rc, OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), needle));
  obs_err_free(&err);
}

/* Each rule of `motion`, refused with the pointer it breaks. */
static void test_scene_rules(void **state) {
  (void)state;
  char *doc = motion_doc(1.0, 0, "exact", 0);
  json_t *d = json_loads(doc, 0, NULL);
  json_t *objs = json_object_get(d, "objects");
  json_t *box = json_array_get(objs, 2);
  char *text;
  /* Not rigid. */
  json_t *m0 = json_array_get(json_object_get(box, "motion"), 1);
  json_object_set_new(m0, "scale", json_pack("[f,f,f]", 1.0, 2.0, 1.0));
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/2/motion/1/scale: must equal the object's transform scale");
  free(text);
  json_object_del(m0, "scale");
  /* Moving objects of different lengths. */
  json_t *wall = json_array_get(objs, 1);
  json_object_set_new(wall, "motion", json_pack("[{s:[f,f,f]}]", "translate", 0.0, 0.1, 0.0));
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/2/motion: lists 2 transforms but /objects/1/motion lists 1");
  free(text);
  json_object_del(wall, "motion");
  /* An empty list, an unknown key. */
  json_object_set_new(wall, "motion", json_array());
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/1/motion: must list 1 to 1024 transforms");
  free(text);
  json_object_set_new(wall, "motion", json_pack("[{s:i}]", "spin", 1));
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/1/motion/0/spin");
  free(text);
  json_object_del(wall, "motion");
  /* An analytic sphere. */
  json_array_append_new(objs, json_pack("{s:{s:s,s:[i,i,i],s:f},s:{s:[f,f,f]},s:[{s:[i,i,i]},"
                                        "{s:[i,i,i]}]}",
                                        "shape", "type", "sphere", "center", 0, 1, 0, "radius", 0.2,
                                        "material", "reflectivity", 0.5, 0.5, 0.5, "motion",
                                        "translate", 0, 1, 0, "translate", 0, 2, 0));
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/3/motion: an analytic sphere cannot move");
  free(text);
  json_array_remove(objs, 3);
  /* A technique that renders one frame; a line estimator updating patch by patch; Vulkan. */
  json_t *tech = json_object_get(d, "technique");
  json_object_set_new(tech, "name", json_string("rt_ao"));
  json_object_del(tech, "params");
  text = json_dumps(d, 0);
  expect_refused(text, "/objects/2/motion: technique \"rt_ao\" renders one frame");
  free(text);
  json_object_set_new(tech, "name", json_string("obscurance_map"));
  json_object_set_new(tech, "params", json_pack("{s:s}", "method", "bundles"));
  text = json_dumps(d, 0);
  expect_refused(text, "/technique/params/update: \"exact\" recomputes patch by patch");
  free(text);
  json_object_set_new(tech, "params", json_pack("{s:s}", "method", "depth_peeling"));
  json_object_set_new(tech, "backend", json_string("vulkan"));
  text = json_dumps(d, 0);
  expect_refused(text, "/technique/backend: moving objects (motion) render on the cpu backend");
  free(text);
  json_decref(d);
  free(doc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_exact_equals_full),
      cmocka_unit_test(test_article_misses),
      cmocka_unit_test(test_patches_file),
      cmocka_unit_test(test_scene_rules),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
