/* Technique parameter tables: the binder (each type, bounds, enums, null, defaults, offsets), the
 * generated JSON Schema, the cost hook, and the self-check of every registered technique. */
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "params.h"
#include "testutil.h"

typedef struct demo {
  int flag;
  int32_t count;
  char pad; /* a member the table does not name: zeroed by the binder */
  uint32_t seed;
  float radius;
  double dist;
  int mode;
  float angle;
  int32_t taps;
} demo;

static const char *const modes[] = {"near", "far", NULL};
static const int tap_counts[] = {8, 16, 24};

#define P(m) offsetof(demo, m)
static const obs_param demo_params[] = {
    {.name = "flag",
     .type = OBS_PARAM_BOOL,
     .def = 1,
     .description = "a switch",
     .offset = P(flag)},
    {.name = "count",
     .type = OBS_PARAM_INT,
     .min = -3,
     .max = 7,
     .def = 2,
     .description = "an integer",
     .offset = P(count)},
    {.name = "seed",
     .type = OBS_PARAM_UINT,
     .min = 0,
     .max = 4294967295.0,
     .def = 5,
     .description = "all 32 bits",
     .offset = P(seed)},
    {.name = "radius",
     .type = OBS_PARAM_FLOAT,
     .flags = OBS_PARAM_MIN_EXCLUSIVE,
     .min = 0,
     .max = 10,
     .def = 0.25,
     .description = "a float",
     .offset = P(radius)},
    {.name = "dist",
     .type = OBS_PARAM_DOUBLE,
     .flags = OBS_PARAM_NULLABLE | OBS_PARAM_DEFAULT_NULL | OBS_PARAM_MIN_EXCLUSIVE,
     .min = 0,
     .max = 1e30,
     .null_value = INFINITY,
     .description = "null = unbounded",
     .offset = P(dist)},
    {.name = "mode",
     .type = OBS_PARAM_ENUM,
     .choices = modes,
     .def = 1,
     .description = "an enum",
     .offset = P(mode)},
    {.name = "angle",
     .type = OBS_PARAM_FLOAT,
     .flags = OBS_PARAM_MAX_EXCLUSIVE,
     .min = 0,
     .max = 1.5707963267948966,
     .def = 0.5,
     .description = "below pi/2",
     .offset = P(angle)},
    {.name = "taps",
     .type = OBS_PARAM_INT,
     .values = tap_counts,
     .nvalues = 3,
     .def = 16,
     .description = "one of three",
     .offset = P(taps)},
};
#undef P

static double demo_cost(const void *bound) {
  const demo *d = bound;
  return (double)d->taps * (d->flag ? 2 : 1);
}

static obs_technique demo_technique(void) {
  obs_technique t;
  memset(&t, 0, sizeof t);
  t.name = "demo";
  t.params = demo_params;
  t.params_size = sizeof demo_params / sizeof demo_params[0];
  t.bound_size = sizeof(demo);
  t.cost = demo_cost;
  return t;
}

/* Binds `text` (NULL: no params); returns the rc and leaves the message in `msg`. */
static int bind_text(const obs_technique *t, const char *text, demo *out, char *msg, size_t n) {
  json_t *j = text ? json_loads(text, 0, NULL) : NULL;
  if (text) assert_non_null(j);
  obs_err err = OBS_ERR_INIT;
  memset(out, 0x5a, sizeof *out);
  int rc = obs_params_bind(t, j, out, &err);
  snprintf(msg, n, "%s", obs_err_message(&err));
  obs_err_free(&err);
  json_decref(j);
  return rc;
}

static void expect_bad(const obs_technique *t, const char *text, const char *message) {
  demo d;
  char msg[512];
  assert_int_equal(bind_text(t, text, &d, msg, sizeof msg), OBS_EINVAL);
  if (!strstr(msg, message))
    fprintf(stderr, "%s: expected \"%s\", got \"%s\"\n", text, message, msg);
  assert_non_null(strstr(msg, message));
}

static void test_defaults_and_offsets(void **state) {
  (void)state;
  obs_technique t = demo_technique();
  demo d;
  char msg[256];
  assert_int_equal(bind_text(&t, NULL, &d, msg, sizeof msg), 0);
  assert_int_equal(d.flag, 1);
  assert_int_equal(d.count, 2);
  assert_int_equal(d.pad, 0);
  assert_true(d.seed == 5u);
  assert_true(d.radius == 0.25f);
  assert_true(isinf(d.dist) && d.dist > 0);
  assert_int_equal(d.mode, 1);
  assert_true(d.angle == 0.5f);
  assert_int_equal(d.taps, 16);
  demo e;
  assert_int_equal(bind_text(&t, "{}", &e, msg, sizeof msg), 0);
  assert_memory_equal(&d, &e, sizeof d);
  /* Every member lands at its own offset. */
  assert_int_equal(bind_text(&t,
                             "{\"flag\":false,\"count\":-3,\"seed\":4294967295,\"radius\":10,"
                             "\"dist\":2.5,\"mode\":\"near\",\"angle\":0,\"taps\":24}",
                             &d, msg, sizeof msg),
                   0);
  assert_int_equal(d.flag, 0);
  assert_int_equal(d.count, -3);
  assert_true(d.seed == 4294967295u);
  assert_true(d.radius == 10.0f);
  assert_true(d.dist == 2.5);
  assert_int_equal(d.mode, 0);
  assert_true(d.angle == 0.0f);
  assert_int_equal(d.taps, 24);
  /* Integral reals count as integers; null binds as null_value. */
  assert_int_equal(bind_text(&t, "{\"count\":7.0,\"taps\":8.0,\"dist\":null}", &d, msg, sizeof msg),
                   0);
  assert_int_equal(d.count, 7);
  assert_int_equal(d.taps, 8);
  assert_true(isinf(d.dist));
  /* bind_new gives the same bytes. */
  void *b = NULL;
  assert_int_equal(obs_params_bind_new(&t, NULL, &b, NULL), 0);
  assert_int_equal(bind_text(&t, NULL, &d, msg, sizeof msg), 0);
  assert_memory_equal(b, &d, sizeof d);
  free(b);
}

static void test_bounds_types_messages(void **state) {
  (void)state;
  obs_technique t = demo_technique();
  demo d;
  char msg[256];
  /* Inclusive bounds accept their ends; exclusive ones refuse them. */
  assert_int_equal(bind_text(&t, "{\"count\":7,\"radius\":10,\"angle\":0}", &d, msg, sizeof msg),
                   0);
  expect_bad(&t, "{\"count\":8}", "demo params: /count: must be <= 7 (got 8)");
  expect_bad(&t, "{\"count\":-4}", "demo params: /count: must be >= -3 (got -4)");
  expect_bad(&t, "{\"radius\":0}", "demo params: /radius: must be > 0 (got 0)");
  expect_bad(&t, "{\"radius\":10.5}", "/radius: must be <= 10 (got 10.5)");
  expect_bad(&t, "{\"angle\":1.5707963267948966}",
             "/angle: must be < 1.570796327 (got 1.570796327)");
  expect_bad(&t, "{\"seed\":-1}", "/seed: must be >= 0 (got -1)");
  expect_bad(&t, "{\"seed\":4294967296}", "/seed: must be <= 4294967295 (got 4294967296)");
  /* Types. */
  expect_bad(&t, "{\"flag\":1}", "/flag: must be boolean (got 1)");
  expect_bad(&t, "{\"count\":1.5}", "/count: must be an integer (got 1.5)");
  expect_bad(&t, "{\"radius\":\"big\"}", "/radius: must be a number (got \"big\")");
  expect_bad(&t, "{\"radius\":null}", "/radius: must be a number (got null)");
  expect_bad(&t, "{\"dist\":\"far\"}", "/dist: must be a number or null (got \"far\")");
  expect_bad(&t, "{\"mode\":\"mid\"}", "/mode: must be one of \"near\", \"far\" (got \"mid\")");
  expect_bad(&t, "{\"mode\":1}", "/mode: must be one of \"near\", \"far\" (got 1)");
  expect_bad(&t, "{\"taps\":12}", "/taps: must be one of 8, 16, 24 (got 12)");
  expect_bad(&t, "{\"size\":1}", "demo params: /size: unknown parameter");
  expect_bad(&t, "[1]", "demo params: /: must be an object (got [1])");
  /* Every problem is listed, not only the first. */
  expect_bad(&t, "{\"count\":99,\"mode\":\"x\"}", "/mode: must be one of");
  expect_bad(&t, "{\"count\":99,\"mode\":\"x\"}", "/count: must be <= 7");
  /* A value that rounds onto an exclusive float bound stays below it. */
  assert_int_equal(bind_text(&t, "{\"angle\":1.5707963267}", &d, msg, sizeof msg), 0);
  assert_true((double)d.angle < 1.5707963267948966);
  assert_true(d.angle == nextafterf(1.5707963267948966f, 0.0f));
}

static void test_schema(void **state) {
  (void)state;
  obs_technique t = demo_technique();
  json_t *s = obs_technique_params_schema(&t);
  char *text = json_dumps(s, JSON_COMPACT);
  assert_string_equal(
      text,
      "{\"type\":\"object\",\"additionalProperties\":false,\"properties\":{"
      "\"flag\":{\"type\":\"boolean\",\"default\":true,\"description\":\"a switch\"},"
      "\"count\":{\"type\":\"integer\",\"minimum\":-3,\"maximum\":7,\"default\":2,"
      "\"description\":\"an integer\"},"
      "\"seed\":{\"type\":\"integer\",\"minimum\":0,\"maximum\":4294967295,\"default\":5,"
      "\"description\":\"all 32 bits\"},"
      "\"radius\":{\"type\":\"number\",\"exclusiveMinimum\":0,\"maximum\":10,\"default\":0.25,"
      "\"description\":\"a float\"},"
      "\"dist\":{\"type\":[\"number\",\"null\"],\"exclusiveMinimum\":0,\"maximum\":1e30,"
      "\"default\":null,\"description\":\"null = unbounded\"},"
      "\"mode\":{\"enum\":[\"near\",\"far\"],\"default\":\"far\",\"description\":\"an enum\"},"
      "\"angle\":{\"type\":\"number\",\"minimum\":0,\"exclusiveMaximum\":1.5707963267948966,"
      "\"default\":0.5,\"description\":\"below pi/2\"},"
      "\"taps\":{\"type\":\"integer\",\"enum\":[8,16,24],\"default\":16,"
      "\"description\":\"one of three\"}}}");
  free(text);
  json_decref(s);
}


/* Lists of names: null (every object) or distinct non-empty strings, bound into the struct's own
 * storage; a bad item is named by its index. */
typedef struct names_demo {
  int flag;
  obs_param_names only;
} names_demo;

static const obs_param names_params[] = {
    {.name = "only", .type = OBS_PARAM_NAMES, .description = "the objects that count",
     .offset = offsetof(names_demo, only)},
};

static void test_names(void **state) {
  (void)state;
  obs_technique t = {.name = "names", .params = names_params, .params_size = 1,
                     .bound_size = sizeof(names_demo)};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_technique_params_check(&t, &err), 0);
  names_demo d;
  assert_int_equal(obs_params_bind(&t, NULL, &d, &err), 0);
  assert_int_equal(d.only.count, -1);
  assert_true(obs_param_names_has(&d.only, "anything"));
  json_t *j = json_loads("{\"only\":[\"floor\",\"ball 2\"]}", 0, NULL);
  assert_int_equal(obs_params_bind(&t, j, &d, &err), 0);
  json_decref(j);
  assert_int_equal(d.only.count, 2);
  assert_true(obs_param_names_has(&d.only, "floor") && obs_param_names_has(&d.only, "ball 2"));
  assert_false(obs_param_names_has(&d.only, "ball") || obs_param_names_has(&d.only, "floo"));
  j = json_loads("{\"only\":[]}", 0, NULL);
  assert_int_equal(obs_params_bind(&t, j, &d, &err), 0);
  json_decref(j);
  assert_int_equal(d.only.count, 0);
  assert_false(obs_param_names_has(&d.only, "floor"));
  char long_list[4096] = "{\"only\":[";
  for (int i = 0; i < 100; i++)
    snprintf(long_list + strlen(long_list), sizeof long_list - strlen(long_list),
             "%s\"object-%03d-abcdefghij\"", i ? "," : "", i);
  strcat(long_list, "]}");
  const char *bad[][2] = {
      {"{\"only\":\"floor\"}", "names params: /only: must be an array of object names or null"},
      {"{\"only\":[\"a\",3]}", "names params: /only/1: must be a non-empty string (got 3)"},
      {"{\"only\":[\"\"]}", "names params: /only/0: must be a non-empty string"},
      {"{\"only\":[\"a\",\"b\",\"a\"]}", "names params: /only/2: repeats item 0"},
      {long_list, "names params: /only: the names must take at most 1024 bytes"}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    obs_err e = OBS_ERR_INIT;
    j = json_loads(bad[i][0], 0, NULL);
    assert_non_null(j);
    assert_int_equal(obs_params_bind(&t, j, &d, &e), OBS_EINVAL);
    if (!strstr(obs_err_message(&e), bad[i][1]))
      fprintf(stderr, "expected \"%s\", got \"%s\"\n", bad[i][1], obs_err_message(&e));
    assert_non_null(strstr(obs_err_message(&e), bad[i][1]));
    json_decref(j);
    obs_err_free(&e);
  }
  json_t *s = obs_technique_params_schema(&t);
  char *text = json_dumps(s, JSON_COMPACT);
  assert_string_equal(text,
                      "{\"type\":\"object\",\"additionalProperties\":false,\"properties\":{"
                      "\"only\":{\"type\":[\"array\",\"null\"],\"items\":{\"type\":\"string\","
                      "\"minLength\":1},\"uniqueItems\":true,\"default\":null,"
                      "\"description\":\"the objects that count\"}}}");
  free(text);
  json_decref(s);
  obs_err_free(&err);
}
/* RGB parameters: three numbers, each in the range, bound as double[3]; null where allowed. */
typedef struct rgb_demo {
  int flag;
  double tint[3];
  double base[3];
} rgb_demo;

static const obs_param rgb_params[] = {
    {.name = "tint", .type = OBS_PARAM_RGB,
     .flags = OBS_PARAM_NULLABLE | OBS_PARAM_DEFAULT_NULL, .min = 0, .max = 10, .null_value = -1,
     .description = "an optional colour", .offset = offsetof(rgb_demo, tint)},
    {.name = "base", .type = OBS_PARAM_RGB, .flags = OBS_PARAM_MAX_EXCLUSIVE, .min = 0, .max = 1,
     .def = 0.5, .description = "a colour", .offset = offsetof(rgb_demo, base)},
};

static void test_rgb(void **state) {
  (void)state;
  obs_technique t = {.name = "rgb", .params = rgb_params, .params_size = 2,
                     .bound_size = sizeof(rgb_demo)};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_technique_params_check(&t, &err), 0);
  rgb_demo d;
  json_t *j = json_loads("{\"tint\":[1,2.5,10]}", 0, NULL);
  assert_int_equal(obs_params_bind(&t, j, &d, &err), 0);
  json_decref(j);
  assert_true(d.tint[0] == 1 && d.tint[1] == 2.5 && d.tint[2] == 10);
  assert_true(d.base[0] == 0.5 && d.base[1] == 0.5 && d.base[2] == 0.5);
  assert_int_equal(obs_params_bind(&t, NULL, &d, &err), 0);
  assert_true(d.tint[0] == -1 && d.tint[1] == -1 && d.tint[2] == -1);
  static const char *const bad[][2] = {
      {"{\"tint\":[1,2]}", "rgb params: /tint: must be an array of 3 numbers [R, G, B] or null"},
      {"{\"tint\":[1,-1,11]}", "rgb params: /tint/1: must be >= 0 (got -1)"},
      {"{\"tint\":[1,-1,11]}", "rgb params: /tint/2: must be <= 10 (got 11)"},
      {"{\"base\":null}", "rgb params: /base: must be an array of 3 numbers [R, G, B] (got null)"},
      {"{\"base\":[0,1,0]}", "rgb params: /base/1: must be < 1 (got 1)"},
      {"{\"base\":[0,\"x\",0]}", "rgb params: /base: must be an array of 3 numbers"}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    obs_err e = OBS_ERR_INIT;
    j = json_loads(bad[i][0], 0, NULL);
    assert_int_equal(obs_params_bind(&t, j, &d, &e), OBS_EINVAL);
    if (!strstr(obs_err_message(&e), bad[i][1]))
      fprintf(stderr, "%s: expected \"%s\", got \"%s\"\n", bad[i][0], bad[i][1],
              obs_err_message(&e));
    assert_non_null(strstr(obs_err_message(&e), bad[i][1]));
    json_decref(j);
    obs_err_free(&e);
  }
  json_t *s = obs_technique_params_schema(&t);
  char *text = json_dumps(s, JSON_COMPACT);
  assert_string_equal(
      text,
      "{\"type\":\"object\",\"additionalProperties\":false,\"properties\":{"
      "\"tint\":{\"type\":[\"array\",\"null\"],\"items\":{\"type\":\"number\",\"minimum\":0,"
      "\"maximum\":10},\"minItems\":3,\"maxItems\":3,\"default\":null,"
      "\"description\":\"an optional colour\"},"
      "\"base\":{\"type\":\"array\",\"items\":{\"type\":\"number\",\"minimum\":0,"
      "\"exclusiveMaximum\":1},\"minItems\":3,\"maxItems\":3,\"default\":[0.5,0.5,0.5],"
      "\"description\":\"a colour\"}}}");
  free(text);
  json_decref(s);
  obs_err_free(&err);
}

static void test_cost(void **state) {
  (void)state;
  obs_technique t = demo_technique();
  json_t *j = json_loads("{\"taps\":24,\"flag\":false}", 0, NULL);
  assert_true(obs_technique_cost(&t, j) == 24.0);
  assert_true(obs_technique_cost(&t, NULL) == 32.0);
  json_decref(j);
  /* The registered rules, as the server's limits count them. */
  const struct {
    const char *technique, *params;
    double cost;
  } cases[] = {
      {"rt_ao", "{}", 64},
      {"rt_ao", "{\"samples\":16}", 16},
      {"ssao", "{\"samples\":24}", 24},
      {"hbao", "{}", 64},
      {"hbao", "{\"directions\":4,\"steps\":3,\"half_res\":true}", 12},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    json_t *p = json_loads(cases[i].params, 0, NULL);
    assert_true(obs_technique_cost(obs_technique_find(cases[i].technique), p) == cases[i].cost);
    json_decref(p);
  }
}

/* A table that contradicts itself is caught before any document reaches it. */
static void test_self_check(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    int rc = obs_technique_params_check(t, &err);
    if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
    assert_int_equal(rc, 0);
    /* The published defaults bind to what binding nothing gives. */
    void *a = NULL, *b = NULL;
    json_t *schema = obs_technique_params_schema(t);
    json_t *props = json_object_get(schema, "properties");
    json_t *defs = json_object();
    const char *key;
    json_t *v;
    json_object_foreach(props, key, v) json_object_set(defs, key, json_object_get(v, "default"));
    assert_int_equal(obs_params_bind_new(t, defs, &a, NULL), 0);
    assert_int_equal(obs_params_bind_new(t, NULL, &b, NULL), 0);
    assert_memory_equal(a, b, t->bound_size);
    free(a);
    free(b);
    json_decref(defs);
    json_decref(schema);
  }
  assert_int_equal(obs_technique_params_check(&(obs_technique){.name = "empty"}, NULL), 0);

  const struct {
    obs_param p;
    const char *message;
  } bad[] = {
      {{.name = "a", .type = OBS_PARAM_INT, .min = 1, .max = 4, .def = 5, .description = "d"},
       "demo params default: /a: must be <= 4 (got 5)"},
      {{.name = "a",
        .type = OBS_PARAM_FLOAT,
        .flags = OBS_PARAM_MIN_EXCLUSIVE,
        .min = 0,
        .max = 1,
        .def = 0,
        .description = "d"},
       "demo params default: /a: must be > 0 (got 0)"},
      {{.name = "a", .type = OBS_PARAM_ENUM, .choices = modes, .def = 2, .description = "d"},
       "/a: default index 2 is not a choice"},
      {{.name = "a",
        .type = OBS_PARAM_INT,
        .values = tap_counts,
        .nvalues = 3,
        .def = 12,
        .description = "d"},
       "/a: must be one of 8, 16, 24 (got 12)"},
      {{.name = "a", .type = OBS_PARAM_BOOL, .offset = sizeof(demo), .description = "d"},
       "/a: offset"},
      {{.name = "a", .type = OBS_PARAM_DOUBLE, .offset = 4, .description = "d"}, "/a: offset 4"},
      {{.name = "a", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e39, .description = "d"},
       "beyond what its type stores"},
      {{.name = "a", .type = OBS_PARAM_UINT, .min = -1, .max = 3, .description = "d"},
       "beyond what its type stores"},
      {{.name = "a", .type = OBS_PARAM_INT, .min = 0.5, .max = 3, .def = 1, .description = "d"},
       "integer bounds must be integers"},
      {{.name = "a",
        .type = OBS_PARAM_DOUBLE,
        .flags = OBS_PARAM_DEFAULT_NULL,
        .max = 1,
        .description = "d"},
       "a null default needs OBS_PARAM_NULLABLE"},
      {{.name = "a", .type = OBS_PARAM_ENUM, .description = "d"}, "an enum needs choices"},
      /* A size-derived default on a parameter the ranges do not declare a length. */
      {{.name = "a", .type = OBS_PARAM_DOUBLE, .max = 1, .description = "d", .size_default = 0.1},
       "/a: size_default 0.1 needs a positive value and a range entry with size_power 1"},
      {{.name = "a", .type = OBS_PARAM_BOOL}, "/a: has no description"},
      {{.name = "", .type = OBS_PARAM_BOOL, .description = "d"}, "entry 0 has no name"},
  };
  obs_technique t = demo_technique();
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    t.params = &bad[i].p;
    t.params_size = 1;
    t.cost = NULL;
    obs_err_free(&err);
    assert_int_equal(obs_technique_params_check(&t, &err), OBS_EINVAL);
    if (!strstr(obs_err_message(&err), bad[i].message))
      fprintf(stderr, "case %zu: expected \"%s\", got \"%s\"\n", i, bad[i].message,
              obs_err_message(&err));
    assert_non_null(strstr(obs_err_message(&err), bad[i].message));
  }
  /* Twice the same name. */
  obs_param twice[2] = {demo_params[0], demo_params[0]};
  t.params = twice;
  t.params_size = 2;
  obs_err_free(&err);
  assert_int_equal(obs_technique_params_check(&t, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "demo params: /flag: declared twice"));
  /* A cost hook that gives nonsense for the defaults. */
  t = demo_technique();
  obs_param zero_taps = demo_params[7];
  obs_param table[8];
  memcpy(table, demo_params, sizeof table);
  zero_taps.type = OBS_PARAM_INT;
  zero_taps.values = NULL;
  zero_taps.min = 0;
  zero_taps.max = 4;
  zero_taps.def = 0;
  table[7] = zero_taps;
  t.params = table;
  obs_err_free(&err);
  assert_int_equal(obs_technique_params_check(&t, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "the cost of the defaults is 0"));
  /* A size-derived default outside a backend's guaranteed range of its length: the default a
   * scene is given would draw a range warning. On its bound it is accepted (the derivation rounds
   * toward the inside). */
  t = demo_technique();
  obs_param len = {.name = "dist", .type = OBS_PARAM_DOUBLE, .min = 0, .max = 1e30, .def = 1,
                   .description = "d", .offset = offsetof(demo, dist), .size_default = 0.01};
  t.params = &len;
  t.params_size = 1;
  t.cost = NULL;
  t.run[OBS_BACKEND_CPU] = t.run[OBS_BACKEND_VULKAN] = NULL;
  t.range[OBS_BACKEND_CPU].params[0] = (obs_param_range){"dist", 0.01, 1e6, 1};
  t.range[OBS_BACKEND_VULKAN].params[0] = (obs_param_range){"dist", 0.05, 1e6, 1};
  obs_err_free(&err);
  assert_int_equal(obs_technique_params_check(&t, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err),
                         "/dist: size_default 0.01 lies outside [0.05, 1e+06], the range vulkan "
                         "guarantees"));
  len.size_default = 0.05;
  obs_err_free(&err);
  assert_int_equal(obs_technique_params_check(&t, &err), 0);
  obs_err_free(&err);
}

/* An unknown name is answered with the nearest declared one when it is a likely typo. */
static void test_nearest_name(void **state) {
  (void)state;
  obs_technique t = demo_technique();
  assert_string_equal(obs_params_nearest(&t, "raduis"), "radius");
  assert_string_equal(obs_params_nearest(&t, "radiu"), "radius");
  assert_string_equal(obs_params_nearest(&t, "Radius"), "radius");
  assert_string_equal(obs_params_nearest(&t, "tap"), "taps");
  assert_string_equal(obs_params_nearest(&t, "conut"), "count");
  assert_null(obs_params_nearest(&t, "samples"));
  assert_null(obs_params_nearest(&t, "xy"));
  assert_null(
      obs_params_nearest(&t, "a_name_far_longer_than_any_declared_parameter_name_at_all_x"));
  expect_bad(&t, "{\"raduis\":1}",
             "demo params: /raduis: unknown parameter (did you mean \"radius\"?)");
  expect_bad(&t, "{\"size\":1}", "demo params: /size: unknown parameter");
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_defaults_and_offsets),
      cmocka_unit_test(test_bounds_types_messages),
      cmocka_unit_test(test_schema),
      cmocka_unit_test(test_rgb),
      cmocka_unit_test(test_names),
      cmocka_unit_test(test_cost),
      cmocka_unit_test(test_self_check),
      cmocka_unit_test(test_nearest_name),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
