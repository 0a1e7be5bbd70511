/* Scene loading: strict validation messages with JSON pointers, overrides, defaults, registry. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "testutil.h"

#define BASE                                                                                      \
  "\"camera\":{\"type\":\"perspective\",\"position\":[0,1,-3],\"look_at\":[0,0,0],\"fov_y\":40}," \
  "\"image\":{\"width\":8,\"height\":8}"

static int load(const char *json, obs_scene *sc, obs_err *err) {
  return obs_scene_load_string(sc, json, "t.json", obs_test_src("tests/data"), NULL, 0, err);
}

static void expect_error(const char *json, const char *needle) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = load(json, &sc, &err);
  if (rc == 0 || !strstr(obs_err_message(&err), needle))
    fprintf(stderr, "expected \"%s\", got rc=%d: %s\n", needle, rc, obs_err_message(&err));
  assert_int_equal(rc, OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), needle));
  /* A failed load leaves nothing behind. */
  assert_null(sc.doc);
  assert_null(sc.objects);
  obs_err_free(&err);
}

static void test_valid_scene_defaults(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(load("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
                        "\"radius\":1}}],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  assert_string_equal(sc.technique->name, "rt_ao");
  assert_int_equal(sc.backend, OBS_BACKEND_AUTO);
  assert_int_equal(sc.spp, 1);
  assert_int_equal(json_integer_value(json_object_get(sc.params, "samples")), 64);
  assert_true(json_is_null(json_object_get(sc.params, "max_distance")));
  assert_string_equal(json_string_value(json_object_get(sc.params, "falloff")), "binary");
  assert_string_equal(sc.objects[0].name, "object0");
  assert_true(sc.camera.up.y == 1.0);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_error_names_pointer_and_value(void **state) {
  (void)state;
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],"
               "[1,1,0],[0,1,0]]}},{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":"
               "-1}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "t.json: /objects/1/shape/radius: must be > 0 (got -1)");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "0}}}",
               "t.json: /technique/params/samples: must be >= 1 (got 0)");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"nope\"}}",
               "t.json: /technique/name: must be one of \"");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"nope\"}}", "\"rt_ao\"");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"nope\"}}", "(got \"nope\")");
  expect_error("{" BASE ",\"objects\":[],\"extra\":1,\"technique\":{\"name\":\"rt_ao\"}}",
               "t.json: /extra: unknown field");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"backend\":\"vulkan\"}}",
               "t.json: /technique/backend: technique \"rt_ao\" has no vulkan backend; available: "
               "\"cpu\"");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"falloff\":"
               "\"sqrt\"}}}",
               "/technique/params/max_distance: falloff \"sqrt\" needs a finite max_distance");
  expect_error("{\"camera\":{\"type\":\"perspective\",\"position\":[1,2,3],\"look_at\":[1,2,3],"
               "\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":[],\"technique\":"
               "{\"name\":\"rt_ao\"}}",
               "/camera/look_at: must differ from /camera/position");
  expect_error("{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,5,0],"
               "\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":[],\"technique\":"
               "{\"name\":\"rt_ao\"}}",
               "/camera/up: must not be zero or parallel to the view direction");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":"
               "1},\"transform\":{\"scale\":[1,2,1]}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/transform/scale: must be uniform for a sphere");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,-1,1]}"
               "}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/shape/max: must be >= /min in every component");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],"
               "[1,1,\"NaN\"],[0,1,0]]}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/shape/vertices/2/2: must be a number (got \"NaN\")");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "1.5}}}",
               "/technique/params/samples: must be an integer (got 1.5)");
  expect_error("{" BASE ",\"objects\":[], \"objects\":[],\"technique\":{\"name\":\"rt_ao\"}}",
               "invalid JSON");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\"}} trailing",
               "invalid JSON");
  expect_error("[1,2]", "t.json: /: the document must be a JSON object");
}

static void test_all_problems_reported(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = load("{\"camera\":{\"type\":\"fisheye\",\"position\":[0,0]},\"image\":{\"width\":0,"
                "\"height\":99999,\"spp\":0},\"objects\":[{\"shape\":{\"type\":\"sphere\",\"radius\":0}"
                ",\"colour\":1}],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":0,"
                "\"seed\":-1,\"wat\":true}}}",
                &sc, &err);
  assert_int_equal(rc, OBS_EINVAL);
  printf("%s\n", obs_err_message(&err));
  const char *expected[] = {"/camera/type", "/camera/position", "/camera/look_at: is required",
                            "/image/width", "/image/height", "/image/spp",
                            "/objects/0/colour: unknown field", "/objects/0/shape/center: is required",
                            "/objects/0/shape/radius", "/technique/params/samples",
                            "/technique/params/seed", "/technique/params/wat: unknown parameter"};
  for (size_t i = 0; i < sizeof expected / sizeof expected[0]; i++)
    assert_non_null(strstr(obs_err_message(&err), expected[i]));
  assert_true(err.count >= 12);
  obs_err_free(&err);
}

static void test_integral_reals_are_integers(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(load("{\"camera\":{\"type\":\"orthographic\",\"position\":[0,1,0],\"look_at\":"
                        "[0,0,0],\"up\":[0,0,1],\"height\":2},\"image\":{\"width\":8.0,\"height\":"
                        "4},\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
                        "64.0}}}",
                        &sc, &err),
                   0);
  assert_int_equal(sc.width, 8);
  /* Stored as a true integer, so the technique reads 64 (not 0) and renders finite values. */
  assert_true(json_is_integer(json_object_get(sc.params, "samples")));
  assert_int_equal(json_integer_value(json_object_get(sc.params, "samples")), 64);
  obs_result r;
  obs_render_opts o = {.threads = 1};
  assert_int_equal(obs_render(&sc, &o, &r, &err), 0);
  obs_test_assert_finite(&r.image);
  obs_result_free(&r);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_ranges_and_utf8(void **state) {
  (void)state;
  /* Geometry beyond what the ray tracer can hold is refused by validation, naming the object. */
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
               "\"radius\":1e25}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "t.json: /objects/0: once transformed, object \"object0\" reaches 1e+25 scene units "
               "from the camera, beyond the renderer's range of +-1e+18");
  expect_error("{\"camera\":{\"type\":\"orthographic\",\"position\":[0,1,0],\"look_at\":[0,0,0],"
               "\"up\":[0,0,1],\"height\":1e25},\"image\":{\"width\":8,\"height\":8},\"objects\":[],"
               "\"technique\":{\"name\":\"rt_ao\"}}",
               "/camera/height: must be <= 1e+18");
  /* Tiny but distinct camera points are not degenerate. */
  assert_int_equal(load("{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,1e-300],"
                        "\"look_at\":[0,0,2e-300],\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},"
                        "\"objects\":[],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  obs_scene_free(&sc);
  /* A pointer with invalid UTF-8 is refused without touching the document. */
  json_t *j = json_loads("{\"a\":{}}", 0, NULL);
  assert_int_equal(obs_json_pointer_set(j, "/a/\xff/x", "1", &err), OBS_EINVAL);
  assert_int_equal(obs_json_pointer_set(j, "/a/\xff", "1", &err), OBS_EINVAL);
  assert_int_equal(json_object_size(json_object_get(j, "a")), 0);
  json_decref(j);
  /* Cross-field technique rules are reported alongside other problems. */
  assert_int_equal(load("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
                        "\"radius\":-1}}],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"falloff\":"
                        "\"sqrt\"}}}",
                        &sc, &err),
                   OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "/objects/0/shape/radius"));
  assert_non_null(strstr(obs_err_message(&err), "/technique/params/max_distance"));
  obs_err_free(&err);
}

/* What lies beyond +-1e18 of the camera once transformed: validation and every geometry build run
 * the same per-object check and name the object; its reach is measured from the camera. */
static void test_geometry_reach(void **state) {
  (void)state;
  const char *shapes[] = {
      "{\"name\":\"far\",\"shape\":{\"type\":\"box\",\"min\":[0,0,0],\"max\":[1,1,1]},"
      "\"transform\":{\"translate\":[2e18,0,0]}}",
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,-1.5e18]]}}",
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,9e17],\"radius\":2e17}}",
      "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":2},\"transform\":{\"scale\":"
      "[1e18,1,1]}}",
      "{\"shape\":{\"type\":\"mesh\",\"file\":\"tetra.obj\"},\"transform\":{\"scale\":[1,1,1e20],"
      "\"rotate\":[0,30,0]}}",
      "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0,0,0],[1,0,0],[0,1,0]]},\"transform\":{"
      "\"scale\":[1e30,1e30,1e30]}}",
  };
  char doc[2048], needle[64];
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
    snprintf(doc, sizeof doc,
             "{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":"
             "1}},%s],\"technique\":{\"name\":\"rt_ao\"}}",
             shapes[i]);
    expect_error(doc, "t.json: /objects/1: once transformed, object ");
    snprintf(needle, sizeof needle, "beyond the renderer's range of +-1e+18");
    expect_error(doc, needle);
  }
  /* Exactly at the limit, and far from the world origin but near the camera: accepted. */
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(load("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
                        "\"radius\":1e18}}],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  obs_scene_free(&sc);
  assert_int_equal(load("{\"camera\":{\"type\":\"perspective\",\"position\":[1e20,1,-3],\"look_at\":"
                        "[1e20,0,0],\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":"
                        "[{\"shape\":{\"type\":\"box\",\"min\":[1e20,0,0],\"max\":[1.0000000001e20,"
                        "1,1]}}],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  obs_scene_free(&sc);
  /* The build runs the same check: a scene changed after validation fails there alike, with the
   * reach it measured (not a value read after the geometry was freed). */
  assert_int_equal(load("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
                        "\"radius\":1}},{\"name\":\"ball\",\"shape\":{\"type\":\"sphere\",\"center\":"
                        "[0,0,0],\"radius\":1}}],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  sc.objects[1].shape.sphere.radius = 3e18;
  obs_result r;
  obs_render_opts o = {.threads = 1};
  assert_int_equal(obs_render(&sc, &o, &r, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "/objects/1: once transformed, object \"ball\" "
                                                "reaches 3e+18 scene units"));
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Camera bases: any direction and up that are distinct and not parallel in double are accepted,
 * however small or large; the others are refused at their pointer. */
static void test_camera_basis_validation(void **state) {
  (void)state;
  const char *ok[][3] = {{"0,0,0", "0,-1e-200,3e-200", "0,1,0"},
                         {"0,1,-3", "0,0,0", "0,1e-300,0"},
                         {"0,1,-3", "0,0,0", "0,4.9e-324,0"},
                         {"0,1,-3", "0,0,0", "0,1e30,0"},
                         {"-1e30,0,0", "1e30,1,0", "0,1,0"},
                         {"1e30,0,0", "1e30,1e-200,0", "0,0,1"}};
  char doc[1024];
  for (int i = 0; i < 6; i++) {
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"perspective\",\"position\":[%s],\"look_at\":[%s],\"up\":[%s],"
             "\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":[],\"technique\":{"
             "\"name\":\"rt_ao\"}}",
             ok[i][0], ok[i][1], ok[i][2]);
    obs_scene sc;
    obs_err err = OBS_ERR_INIT;
    int rc = load(doc, &sc, &err);
    if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
    assert_int_equal(rc, 0);
    obs_scene_free(&sc);
    obs_err_free(&err);
  }
  const char *bad[][4] = {
      /* equal once in double, though written differently */
      {"1.5,2,3", "1.50000000000000000001,2,3", "0,1,0", "/camera/look_at: must differ"},
      {"1e30,0,0", "1.00000000000000001e30,0,0", "0,1,0", "/camera/look_at: must differ"},
      {"0,0,0", "0,1e-200,0", "0,1,0", "/camera/up: must not be zero or parallel"},
      {"0,0,0", "0,0,1", "0,0,-1e-300", "/camera/up: must not be zero or parallel"},
      {"0,0,0", "0,0,1", "0,0,0", "/camera/up: must not be zero or parallel"},
  };
  for (int i = 0; i < 5; i++) {
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"perspective\",\"position\":[%s],\"look_at\":[%s],\"up\":[%s],"
             "\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":[],\"technique\":{"
             "\"name\":\"rt_ao\"}}",
             bad[i][0], bad[i][1], bad[i][2]);
    expect_error(doc, bad[i][3]);
  }
}

/* Numbers the parser cannot hold are refused with the pointer of the value, like every other
 * problem, before jansson parses the document. */
static void test_number_range_pointers(void **state) {
  (void)state;
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,1e400,0],"
               "\"radius\":1}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "t.json: /objects/0/shape/center/1: number too large for a double");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "18446744073709551616}}}",
               "t.json: /technique/params/samples: integer outside the 64-bit range");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"seed\":"
               "9223372036854775808}}}",
               "t.json: /technique/params/seed: integer outside the 64-bit range");
  /* In range for the parser and exact as a double: the ordinary range rules answer. */
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "9007199254740992}}}",
               "t.json: /technique/params/samples: must be <=");
  /* Numbers the parser stores as another value. */
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "9223372036854775807}}}",
               "t.json: /technique/params/samples: integer a double cannot hold exactly");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
               "\"radius\":1e-99999}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "t.json: /objects/0/shape/radius: nonzero number too small for a double (below "
               "4.9e-324 in magnitude it becomes 0) (got 1e-99999; it would be read as 0)");
  expect_error("{" BASE ",\"objects\":[],\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":"
               "63.99999999999999999}}}",
               "t.json: /technique/params/samples: fraction that a double rounds to a whole number");
}

/* displaced_sphere at level 1 is a closed, displaced tetrahedron of 4 triangles (2^(2s)), wound
 * like every level: its signed volume has the grid's sign. */
static void test_displaced_sphere_levels(void **state) {
  (void)state;
  double vol[3];
  for (int s = 1; s <= 3; s++) {
    obs_mesh m;
    assert_int_equal(obs_geometry_displaced_sphere(s, &m), 0);
    assert_int_equal(m.ntris, (size_t)1 << (2 * s));
    double v = 0;
    for (size_t t = 0; t < m.ntris; t++) {
      const float *a = m.pos + 3 * m.idx[3 * t], *b = m.pos + 3 * m.idx[3 * t + 1],
                  *c = m.pos + 3 * m.idx[3 * t + 2];
      assert_true(m.idx[3 * t] < m.nverts && m.idx[3 * t + 1] < m.nverts &&
                  m.idx[3 * t + 2] < m.nverts);
      v += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
            a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
            a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) /
           6.0;
    }
    vol[s - 1] = v;
    obs_geometry_mesh_free(&m);
  }
  printf("signed volumes: level 1 %.4f, 2 %.4f, 3 %.4f\n", vol[0], vol[1], vol[2]);
  assert_true(fabs(vol[0]) > 0.2);
  assert_true(vol[0] * vol[1] > 0 && vol[1] * vol[2] > 0);
}

static void test_mesh_contents_validated(void **state) {
  (void)state;
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"garbage.obj\"}"
               "}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/shape/file: ");
}

static void test_mesh_paths(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(load("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"tetra.obj\"}"
                        "}],\"technique\":{\"name\":\"rt_ao\"}}",
                        &sc, &err),
                   0);
  assert_non_null(strstr(sc.objects[0].shape.mesh.path, "tests/data/tetra.obj"));
  obs_scene_free(&sc);
  obs_err_free(&err);
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"tetra.mtl\"}"
               "}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/shape/file: must name a .obj");
  /* A ".." path is refused before the file system is asked: an existing and a missing file
   * outside the tree get the same answer, so the message reveals nothing about either. */
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":"
               "\"../no/such/file.obj\"}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "must stay inside the scene's directory tree");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"missing.obj\"}"
               "}],\"technique\":{\"name\":\"rt_ao\"}}",
               "/objects/0/shape/file: file not found");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":\"/etc/x.obj\"}"
               "}],\"technique\":{\"name\":\"rt_ao\"}}",
               "must be relative to the scene file");
  expect_error("{" BASE ",\"objects\":[{\"shape\":{\"type\":\"mesh\",\"file\":"
               "\"../corpus/scene_good/data/tri.obj\"}}],\"technique\":{\"name\":\"rt_ao\"}}",
               "must stay inside the scene's directory tree");
}

static void test_overrides(void **state) {
  (void)state;
  const char *doc = "{" BASE ",\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],"
                    "\"radius\":1}}],\"technique\":{\"name\":\"rt_ao\"}}";
  obs_override ov[] = {{"/technique/params/samples", "256"},
                       {"/objects/0/shape/radius", "2.5"},
                       {"/technique/params/falloff", "\"exp\""}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_scene_load_string(&sc, doc, "o.json", NULL, ov, 3, &err), 0);
  assert_int_equal(json_integer_value(json_object_get(sc.params, "samples")), 256);
  assert_true(sc.objects[0].shape.sphere.radius == 2.5);
  obs_scene_free(&sc);
  obs_override bad[] = {{"/objects/7/shape", "{}"}};
  assert_int_equal(obs_scene_load_string(&sc, doc, "o.json", NULL, bad, 1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "--set /objects/7/shape: array index"));
  obs_err_clear(&err);
  obs_override bad2[] = {{"/technique/params/samples", "not json"}};
  assert_int_equal(obs_scene_load_string(&sc, doc, "o.json", NULL, bad2, 1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "value is not valid JSON"));
  obs_err_clear(&err);
  /* Overrides are validated like the document. */
  obs_override bad3[] = {{"/technique/params/samples", "70000"}};
  assert_int_equal(obs_scene_load_string(&sc, doc, "o.json", NULL, bad3, 1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "/technique/params/samples: must be <= 65536"));
  obs_err_free(&err);
  /* RFC 6901 escapes. */
  json_t *j = json_loads("{\"a/b\":{\"c~d\":1}}", 0, NULL);
  assert_int_equal(obs_json_pointer_set(j, "/a~1b/c~0d", "2", NULL), 0);
  assert_int_equal(json_integer_value(json_object_get(json_object_get(j, "a/b"), "c~d")), 2);
  json_decref(j);
}

static void test_registry(void **state) {
  (void)state;
  assert_true(obs_technique_count() >= 1);
  const obs_technique *t = obs_technique_find("rt_ao");
  assert_non_null(t);
  assert_true(obs_technique_has_backend(t, OBS_BACKEND_CPU));
  assert_false(obs_technique_has_backend(t, OBS_BACKEND_VULKAN));
  obs_backend b;
  assert_int_equal(obs_technique_pick_backend(t, OBS_BACKEND_AUTO, &b, NULL), 0);
  assert_int_equal(b, OBS_BACKEND_CPU);
  json_t *reg = obs_technique_registry_json(), *e = NULL;
  /* The registry lists its techniques in the order of their names (the folders it is generated
   * from), each once, as obs_technique_at does. */
  assert_int_equal(json_array_size(reg), obs_technique_count());
  for (size_t i = 0; i < json_array_size(reg); i++) {
    const char *name = json_string_value(json_object_get(json_array_get(reg, i), "name"));
    assert_string_equal(name, obs_technique_at(i)->name);
    if (i) assert_true(strcmp(obs_technique_at(i - 1)->name, name) < 0);
    if (!strcmp(name, "rt_ao")) e = json_array_get(reg, i);
  }
  assert_non_null(e);
  json_t *props = json_object_get(json_object_get(e, "params_schema"), "properties");
  assert_non_null(json_object_get(props, "samples"));
  assert_int_equal(json_integer_value(json_object_get(json_object_get(props, "samples"), "maximum")),
                   65536);
  assert_string_equal(json_string_value(json_array_get(json_object_get(e, "backends"), 0)), "cpu");
  json_decref(reg);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_valid_scene_defaults),
      cmocka_unit_test(test_error_names_pointer_and_value),
      cmocka_unit_test(test_all_problems_reported),
      cmocka_unit_test(test_integral_reals_are_integers),
      cmocka_unit_test(test_ranges_and_utf8),
      cmocka_unit_test(test_mesh_contents_validated),
      cmocka_unit_test(test_mesh_paths),
      cmocka_unit_test(test_overrides),
      cmocka_unit_test(test_registry),
      cmocka_unit_test(test_geometry_reach),
      cmocka_unit_test(test_camera_basis_validation),
      cmocka_unit_test(test_number_range_pointers),
      cmocka_unit_test(test_displaced_sphere_levels),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
