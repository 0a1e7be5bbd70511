/* Bounds on untrusted JSON: the pre-scan (depth, value count, string length, strings skipped
 * exactly), JSON pointer depth, and the scene loader and its overrides refusing deep input. */
#include <jansson.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "json_util.h"
#include "testutil.h"

/* `n` opening brackets then `n` closing ones (caller frees). */
static char *nested(const char *open, const char *close, size_t n) {
  size_t lo = strlen(open), lc = strlen(close);
  char *s = malloc(n * (lo + lc) + 1);
  assert_non_null(s);
  for (size_t i = 0; i < n; i++) memcpy(s + i * lo, open, lo);
  for (size_t i = 0; i < n; i++) memcpy(s + n * lo + i * lc, close, lc);
  s[n * (lo + lc)] = '\0';
  return s;
}

static int scan(const char *text, int depth, size_t values, size_t string, size_t *count,
                obs_err *err) {
  obs_json_limits lim = {depth, values, string};
  return obs_json_prescan(text, strlen(text), &lim, "doc", err, count);
}

static int scan_numbers(const char *text, obs_err *err) {
  obs_json_limits lim = {8, 0, 0};
  return obs_json_prescan_strict(text, strlen(text), &lim, "doc", err, NULL);
}

static void test_prescan_depth_bound(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  char *at = nested("[", "]", 32), *over = nested("[", "]", 33);
  assert_int_equal(scan(at, 32, 0, 0, NULL, &err), 0);
  assert_int_equal(err.count, 0);
  assert_int_equal(scan(over, 32, 0, 0, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "doc: /0/0/0"));
  assert_non_null(strstr(obs_err_message(&err), "nested deeper than 32"));
  free(at);
  free(over);
  /* Objects count the same, and the location names the members. */
  obs_err_clear(&err);
  char *obj = nested("{\"a/b~\":", "}", 33);
  /* The innermost member has no value: the scan stops at the depth before the syntax matters. */
  assert_int_equal(scan(obj, 32, 0, 0, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "doc: /a~1b~0/a~1b~0/"));
  free(obj);
  /* 200k levels: refused without recursion or allocation. */
  obs_err_clear(&err);
  char *huge = nested("[", "]", 200000);
  assert_int_equal(scan(huge, 32, 0, 0, NULL, &err), OBS_EINVAL);
  assert_int_equal(err.count, 1);
  free(huge);
  obs_err_free(&err);
}

static void test_prescan_strings_skipped(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  size_t n = 0;
  /* Brackets, braces, commas and escaped quotes inside strings are not structure. */
  const char *text = "{\"k[{\": \"]]]}}}[[[[\\\"[[[\\\\\", \"x\\\"\": [\"\\\\\", \"a,b,c\", "
                     "\"\\u005b\"], \"n\": -1.5e+3, \"t\": true}";
  assert_int_equal(scan(text, 2, 0, 0, &n, &err), 0);
  /* The object, a string, the array and its 3 strings, a number, a literal. */
  assert_int_equal(n, 8);
  assert_int_equal(scan(text, 1, 0, 0, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "doc: /x\\\": nested deeper than 1"));
  /* A string ending in an escaped backslash closes there. */
  obs_err_clear(&err);
  assert_int_equal(scan("[\"\\\\\", [1]]", 2, 0, 0, &n, &err), 0);
  assert_int_equal(n, 4);
  /* Unterminated input never reads past the end. */
  assert_int_equal(scan("[\"abc\\", 4, 0, 0, &n, &err), 0);
  assert_int_equal(scan("[[[[", 4, 0, 0, &n, &err), 0);
  assert_int_equal(n, 4);
  assert_int_equal(scan("", 4, 0, 0, &n, &err), 0);
  assert_int_equal(n, 0);
  obs_err_free(&err);
}

static void test_prescan_counts(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  size_t n = 0;
  assert_int_equal(scan("[1,2,3]", 4, 4, 0, &n, &err), 0);
  assert_int_equal(n, 4);
  assert_int_equal(scan("[1,2,3]", 4, 3, 0, &n, &err), OBS_EINVAL);
  /* The fourth value (the third element) is where the count broke. */
  assert_non_null(strstr(obs_err_message(&err), "doc: /2: more than 3 JSON values"));
  obs_err_clear(&err);
  /* Keys are not values; nested containers are. */
  assert_int_equal(scan("{\"a\":{\"b\":[null,false]},\"c\":\"d\"}", 4, 0, 0, &n, &err), 0);
  assert_int_equal(n, 6);
  /* 8M integers: refused at the bound, long before the end. */
  size_t len = 16u << 20;
  char *big = malloc(len + 1);
  assert_non_null(big);
  big[0] = '[';
  for (size_t i = 1; i + 1 < len; i += 2) memcpy(big + i, "1,", 2);
  big[len - 1] = ']';
  big[len] = '\0';
  obs_json_limits lim = {32, 100000, 0};
  assert_int_equal(obs_json_prescan(big, len, &lim, "request", &err, &n), OBS_EINVAL);
  assert_int_equal(n, 100001);
  assert_non_null(strstr(obs_err_message(&err), "request: /99999: more than 100000"));
  free(big);
  /* String length: values and member names alike. */
  obs_err_clear(&err);
  assert_int_equal(scan("[\"abcd\"]", 4, 0, 4, &n, &err), 0);
  assert_int_equal(scan("[\"abcde\"]", 4, 0, 4, &n, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "string of 5 bytes"));
  assert_int_equal(scan("{\"abcde\":1}", 4, 0, 4, &n, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "member name of 5 bytes"));
  obs_err_free(&err);
}

static void test_check_depth_of_parsed(void **state) {
  (void)state;
  char *text = nested("[", "]", 33);
  json_t *v = json_loads(text, 0, NULL);
  assert_non_null(v);
  obs_err err = OBS_ERR_INIT;
  obs_jpath p;
  obs_jpath_init(&p, "doc", &err);
  assert_int_equal(obs_json_check_depth(&p, json_array_get(v, 0), 32), 0);
  assert_int_equal(obs_json_check_depth(&p, v, 32), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "doc: /0/0/0"));
  assert_int_equal(obs_json_count_values(v, 64), 33);
  json_decref(v);
  free(text);
  obs_err_free(&err);
}

/* A pointer of `tokens` "/a" tokens (caller frees). */
static char *pointer_of(size_t tokens) {
  char *s = malloc(2 * tokens + 1);
  assert_non_null(s);
  for (size_t i = 0; i < tokens; i++) memcpy(s + 2 * i, "/a", 2);
  s[2 * tokens] = '\0';
  return s;
}

static void test_pointer_depth(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  json_t *doc = json_object();
  char *ok = pointer_of(OBS_POINTER_MAX_TOKENS);
  assert_int_equal(obs_json_pointer_set(doc, ok, "1", &err), 0);
  char *over = pointer_of(OBS_POINTER_MAX_TOKENS + 1);
  json_t *before = json_deep_copy(doc);
  assert_int_equal(obs_json_pointer_set(doc, over, "1", &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "has 33 reference tokens; at most 32"));
  assert_non_null(strstr(obs_err_message(&err), "pointer \"/a/a/a"));
  assert_true(json_equal(doc, before));
  /* 30,000 tokens: refused before anything is built, message kept short. */
  obs_err_clear(&err);
  char *huge = pointer_of(30000);
  assert_int_equal(obs_json_pointer_set(doc, huge, "1", &err), OBS_EINVAL);
  assert_true(strlen(obs_err_message(&err)) < 400);
  assert_non_null(strstr(obs_err_message(&err), "(60000 bytes) has 30000 reference tokens"));
  assert_true(json_equal(doc, before));
  /* A value nested too deep is refused too, and nothing changes. */
  obs_err_clear(&err);
  char *deep = nested("[", "]", 33);
  assert_int_equal(obs_json_pointer_set(doc, "/b", deep, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "nested deeper than 32"));
  assert_true(json_equal(doc, before));
  /* A malformed token after a missing member leaves no half-made member behind. */
  obs_err_clear(&err);
  assert_int_equal(obs_json_pointer_set(doc, "/new/x~2", "1", &err), OBS_EINVAL);
  assert_null(json_object_get(doc, "new"));
  free(ok);
  free(over);
  free(huge);
  free(deep);
  json_decref(before);
  json_decref(doc);
  obs_err_free(&err);
}

#define SCENE                                                                                     \
  "{\"camera\":{\"type\":\"perspective\",\"position\":[0,1,-3],\"look_at\":[0,0,0],\"fov_y\":40}," \
  "\"image\":{\"width\":8,\"height\":8},\"objects\":[{\"shape\":{\"type\":\"sphere\",\"center\":"   \
  "[0,0,0],\"radius\":1}}],\"technique\":{\"name\":\"rt_ao\"}}"

static void test_scene_deep_override(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  /* 200k levels: the old walk built the whole chain and json_delete overflowed the stack. */
  char *ptr = pointer_of(200000);
  obs_override ov = {ptr, "1"};
  assert_int_equal(obs_scene_load_string(&sc, SCENE, "s.json", NULL, &ov, 1, &err), OBS_EINVAL);
  assert_null(sc.doc);
  const char *m = obs_err_message(&err);
  assert_non_null(strstr(m, "s.json: --set /a/a/a"));
  assert_non_null(strstr(m, "has 200000 reference tokens"));
  /* Never blamed on the document's syntax. */
  assert_null(strstr(m, "invalid JSON"));
  assert_true(strlen(m) < 600);
  free(ptr);
  /* 31 tokens plus a 2-deep value: 33 levels after the override, refused with the pointer. */
  obs_err_clear(&err);
  char *p31 = pointer_of(31);
  obs_override ov2 = {p31, "[[1]]"};
  assert_int_equal(obs_scene_load_string(&sc, SCENE, "s.json", NULL, &ov2, 1, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "s.json: /a/a/a"));
  assert_non_null(strstr(obs_err_message(&err), "nested deeper than 32"));
  free(p31);
  /* A fine override still loads. */
  obs_err_clear(&err);
  obs_override ok = {"/technique/params/samples", "8"};
  assert_int_equal(obs_scene_load_string(&sc, SCENE, "s.json", NULL, &ok, 1, &err), 0);
  assert_int_equal(json_integer_value(json_object_get(sc.params, "samples")), 8);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_scene_deep_document(void **state) {
  (void)state;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  /* Deeper than jansson's own limit (2048) and than ours: our message, with a location. */
  char *deep = nested("{\"objects\":", "}", 5000);
  assert_int_equal(obs_scene_load_string(&sc, deep, "d.json", NULL, NULL, 0, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "d.json: /objects/objects/"));
  assert_non_null(strstr(obs_err_message(&err), "nested deeper than 32"));
  assert_null(strstr(obs_err_message(&err), "invalid JSON"));
  free(deep);
  /* obs_scene_load_json takes a parsed document: the scene keeps its own reference. */
  obs_err_clear(&err);
  json_t *doc = json_loads(SCENE, 0, NULL);
  assert_non_null(doc);
  assert_int_equal(obs_scene_load_json(&sc, doc, "j.json", NULL, NULL, 0, &err), 0);
  assert_ptr_equal(sc.doc, doc);
  json_decref(doc);
  assert_string_equal(sc.technique->name, "rt_ao");
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_brief_is_bounded(void **state) {
  (void)state;
  size_t n = 1 << 20;
  char *s = malloc(n + 1);
  assert_non_null(s);
  memset(s, 'a', n);
  s[n] = '\0';
  json_t *v = json_string(s);
  const char *b = obs_json_brief(v);
  assert_int_equal(strlen(b), 60);
  assert_memory_equal(b, "\"aaaa", 5);
  assert_string_equal(b + 57, "...");
  assert_string_equal(obs_json_brief(NULL), "nothing");
  json_t *small = json_loads("[1,2]", 0, NULL);
  assert_string_equal(obs_json_brief(small), "[1,2]");
  json_decref(small);
  json_decref(v);
  free(s);
}

/* Numbers beyond what the parser stores (json_int_t integers, doubles) are refused by the
 * pre-scan with their pointer; everything jansson accepts passes it. */
static void test_prescan_number_range(void **state) {
  (void)state;
  const struct {
    const char *text, *needle;
  } bad[] = {
      {"{\"a\":[1,2,1e400]}", "doc: /a/2: number too large for a double"},
      {"{\"a\":{\"b\":-1E+309}}", "doc: /a/b: number too large"},
      {"[1.7976931348623159e308]", "doc: /0: number too large"},
      {"[0.0000001e316]", "doc: /0: number too large"},
      {"[1e99999999999999999999]", "doc: /0: number too large"},
      {"{\"x~/y\":18446744073709551616}", "doc: /x~0~1y: integer outside the 64-bit range"},
      {"[9223372036854775808]", "doc: /0: integer outside the 64-bit range"},
      {"[-9223372036854775809]", "doc: /0: integer outside the 64-bit range"},
      {"[123456789012345678901234567890]", "(got 123456789012345678901234567890)"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(scan_numbers(bad[i].text, &err), OBS_EINVAL);
    /* The plain pre-scan leaves them to the parser. */
    assert_int_equal(scan(bad[i].text, 8, 0, 0, NULL, &err), 0);
    if (!strstr(obs_err_message(&err), bad[i].needle))
      fprintf(stderr, "%s: %s\n", bad[i].text, obs_err_message(&err));
    assert_non_null(strstr(obs_err_message(&err), bad[i].needle));
    assert_null(json_loads(bad[i].text, 0, NULL)); /* jansson refuses them too */
    obs_err_free(&err);
  }
  const char *ok[] = {"[1.7976931348623157e308]", "[-1.7976931348623157e308]",
                      "[9223372036854775807]",    "[-9223372036854775808]",
                      "[0.0000001e314]",          "[1e-400]",
                      "[00000000000000000000001]", "[123456789012345678901234567890.5]",
                      "[\"1e400\"]",              "[true,false,null]"};
  for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
    obs_err err = OBS_ERR_INIT;
    int rc = scan_numbers(ok[i], &err);
    if (rc) fprintf(stderr, "%s: %s\n", ok[i], obs_err_message(&err));
    assert_int_equal(rc, 0);
    obs_err_free(&err);
  }
}

/* Next to DBL_MAX the 41st and later significant digits decide the rounding (the halfway point to
 * 2^1024, 2^1024 - 2^970, is 1.797693134862315807937289714053034150799341327100378269...e308): above it jansson refuses
 * (infinity) and so must the pre-scan; just below it both accept. */
static void test_prescan_numbers_long_tails(void **state) {
  (void)state;
  static const char *const over[] = {
      "[1.7976931348623158079372897140530341507994e308]",
      "[179769313486231580793728971405303415079940000e264]",
      "[1.7976931348623158079372897140530341507993413271004e308]"};
  static const char *const under[] = {"[1.797693134862315807937289714053034150799e308]",
                                      "[1.7976931348623158079372897140530341507993e308]",
                                      "[1.7976931348623158079372897140530341507993413271003e308]"};
  for (size_t i = 0; i < sizeof over / sizeof over[0]; i++) {
    json_t *j = json_loads(over[i], 0, NULL);
    assert_null(j);
    obs_err err = OBS_ERR_INIT;
    assert_int_not_equal(scan_numbers(over[i], &err), 0);
    obs_err_free(&err);
  }
  for (size_t i = 0; i < sizeof under / sizeof under[0]; i++) {
    json_t *j = json_loads(under[i], 0, NULL);
    assert_non_null(j);
    json_decref(j);
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(scan_numbers(under[i], &err), 0);
    obs_err_free(&err);
  }
}

/* The strict pre-scan refuses a number exactly when jansson does: 20000 generated tokens (integers
 * of 1 to 25 digits around the 64-bit edge, reals with exponents near +-308 and beyond). */
static void test_prescan_numbers_match_parser(void **state) {
  (void)state;
  uint64_t x = 0x9e3779b97f4a7c15ULL;
  int refused = 0;
  for (int n = 0; n < 20000; n++) {
    char tok[96], doc[100];
    size_t k = 0;
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    uint64_t r = x >> 11;
    if (r & 1) tok[k++] = '-';
    int digits = 1 + (int)((r >> 1) % 25);
    if (r >> 6 & 1) { /* around 2^63: 9223372036854775807 with the tail varied */
      memcpy(tok + k, "92233720368547758", 17);
      k += 17;
      digits = 2 + (int)((r >> 7) % 2);
    }
    for (int d = 0; d < digits; d++) {
      x = x * 6364136223846793005ULL + 1442695040888963407ULL;
      tok[k++] = (char)('0' + (x >> 33) % 10);
    }
    if (tok[r & 1] == '0' && k > (size_t)(r & 1) + 1) tok[r & 1] = '1'; /* no leading zeros */
    int kind = (int)((r >> 9) % 3); /* 0: integer, 1: fraction, 2: exponent */
    if (kind == 1) k += (size_t)snprintf(tok + k, sizeof tok - k, ".%d", (int)((r >> 12) % 1000));
    if (kind == 2)
      k += (size_t)snprintf(tok + k, sizeof tok - k, "e%s%d", (r >> 12) & 1 ? "-" : "+",
                            280 + (int)((r >> 13) % 60));
    tok[k] = '\0';
    snprintf(doc, sizeof doc, "[%s]", tok);
    obs_err err = OBS_ERR_INIT;
    int ours = scan_numbers(doc, &err) != 0;
    json_t *j = json_loads(doc, 0, NULL);
    if (ours != !j) fprintf(stderr, "%s: pre-scan %d, jansson %d\n", tok, ours, !j);
    assert_int_equal(ours, !j);
    refused += ours;
    json_decref(j);
    obs_err_free(&err);
  }
  printf("%d of 20000 generated numbers refused by both\n", refused);
  assert_true(refused > 2000 && refused < 18000);
}

/* The exact pre-scan refuses, with the pointer and the value it would become, numbers that the
 * parser stores as another value; the strict one (jansson's own refusals) lets them through. A
 * round trip of doubles through jansson's 17-digit output is never refused: the daemon reads the
 * documents it stored with the same scan. */
static void test_prescan_exact_numbers(void **state) {
  (void)state;
  const struct {
    const char *text, *needle;
  } bad[] = {
      {"{\"priority\":1e-99999}", "doc: /priority: nonzero number too small for a double"},
      {"[0,-1e-400]", "doc: /1: nonzero number too small"},
      {"[-0.000000000000000000000000000000001e-300]", "it would be read as -0)"},
      {"[9007199254740993]", "doc: /0: integer a double cannot hold exactly"},
      {"[-9223372036854775807]", "it would be read as -9.2233720368547758e+18"},
      {"{\"a\":[1,{\"b\":0.99999999999999999}]}", "doc: /a/1/b: fraction that a double rounds"},
      {"[4503599627370495.75]", "fraction that a double rounds to a whole number"},
      {"[123456789012345678901234567890.5]", "(got 123456789012345678901234567890.5; it would"},
  };
  obs_json_limits lim = {8, 0, 0};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_json_prescan_exact(bad[i].text, strlen(bad[i].text), &lim, "doc", &err,
                                            NULL),
                     OBS_EINVAL);
    if (!strstr(obs_err_message(&err), bad[i].needle))
      fprintf(stderr, "%s: %s\n", bad[i].text, obs_err_message(&err));
    assert_non_null(strstr(obs_err_message(&err), bad[i].needle));
    obs_err_clear(&err);
    assert_int_equal(scan_numbers(bad[i].text, &err), 0); /* jansson takes them */
    obs_err_free(&err);
  }
  const char *ok[] = {"[0, -0, 0.0, 0e-99999, -0.000e5]",    "[4.9e-324, 1e-310, 2.2e-308]",
                      "[9007199254740992, -9007199254740992]", "[1152921504606846976]",
                      "[1e22, 1.5e300, 9.9999999999999992e+22]", "[0.30000000000000004, 0.1]",
                      "[4503599627370495.5, 1.00000000000000000000000]", "[\"1e-99999\"]",
                      "[1.2345678901234568e+19, 123456789012345678901234567890.0]"};
  for (size_t i = 0; i < sizeof ok / sizeof ok[0]; i++) {
    obs_err err = OBS_ERR_INIT;
    int rc = obs_json_prescan_exact(ok[i], strlen(ok[i]), &lim, "doc", &err, NULL);
    if (rc) fprintf(stderr, "%s: %s\n", ok[i], obs_err_message(&err));
    assert_int_equal(rc, 0);
    obs_err_free(&err);
  }
  /* Doubles as jansson writes them (17 significant digits) read back as themselves. */
  uint64_t x = 0x243f6a8885a308d3ULL;
  for (int n = 0; n < 20000; n++) {
    x = x * 6364136223846793005ULL + 1442695040888963407ULL;
    double d;
    uint64_t bits = x;
    memcpy(&d, &bits, sizeof d);
    if (d != d || d - d != 0) continue; /* NaN, infinities */
    json_t *a = json_pack("[f]", d);
    char *text = json_dumps(a, JSON_COMPACT | JSON_REAL_PRECISION(17));
    obs_err err = OBS_ERR_INIT;
    int rc = obs_json_prescan_exact(text, strlen(text), &lim, "doc", &err, NULL);
    if (rc) fprintf(stderr, "%s: %s\n", text, obs_err_message(&err));
    assert_int_equal(rc, 0);
    obs_err_free(&err);
    free(text);
    json_decref(a);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_prescan_depth_bound),   cmocka_unit_test(test_prescan_strings_skipped),
      cmocka_unit_test(test_prescan_counts),        cmocka_unit_test(test_check_depth_of_parsed),
      cmocka_unit_test(test_pointer_depth),         cmocka_unit_test(test_scene_deep_override),
      cmocka_unit_test(test_scene_deep_document),   cmocka_unit_test(test_brief_is_bounded),
      cmocka_unit_test(test_prescan_number_range),
      cmocka_unit_test(test_prescan_numbers_long_tails),
      cmocka_unit_test(test_prescan_numbers_match_parser),
      cmocka_unit_test(test_prescan_exact_numbers),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
