/* The backends' operations table and the one backend-name parser (obscura/backend.h). */
#include <jansson.h>
#include <string.h>

#include "testutil.h"

static void test_parse_round_trip(void **state) {
  (void)state;
  for (int b = OBS_BACKEND_AUTO; b < OBS_BACKEND_COUNT; b++) {
    obs_backend out = (obs_backend)-1;
    assert_int_equal(obs_backend_parse(obs_backend_name((obs_backend)b), &out), 0);
    assert_int_equal(out, b);
  }
  assert_string_equal(obs_backend_name(OBS_BACKEND_CPU), "cpu");
  assert_string_equal(obs_backend_name(OBS_BACKEND_VULKAN), "vulkan");
  assert_string_equal(obs_backend_name(OBS_BACKEND_AUTO), "auto");
}

static void test_parse_refuses(void **state) {
  (void)state;
  static const char *const bad[] = {"", "CPU", "Vulkan", "cpu ", " vulkan", "gpu", "vk", "autos"};
  for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
    obs_backend out = OBS_BACKEND_CPU;
    assert_int_equal(obs_backend_parse(bad[i], &out), OBS_EINVAL);
    assert_int_equal(out, OBS_BACKEND_CPU); /* untouched */
  }
  obs_backend out = OBS_BACKEND_VULKAN;
  assert_int_equal(obs_backend_parse(NULL, &out), OBS_EINVAL);
  assert_int_equal(out, OBS_BACKEND_VULKAN);
}

static void test_ops_table(void **state) {
  (void)state;
  assert_null(obs_backend_ops_get(OBS_BACKEND_AUTO));
  assert_null(obs_backend_ops_get((obs_backend)OBS_BACKEND_COUNT));
  for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
    const obs_backend_ops *ops = obs_backend_ops_get((obs_backend)b);
    assert_non_null(ops);
    assert_int_equal(ops->id, b);
    assert_string_equal(ops->name, obs_backend_name((obs_backend)b));
    assert_non_null(ops->available);
    assert_non_null(ops->device_name);
    /* A device exactly when available. */
    assert_int_equal(ops->device_name() != NULL, ops->available() != 0);
  }
  const obs_backend_ops *cpu = obs_backend_ops_get(OBS_BACKEND_CPU);
  assert_true(cpu->available());
  assert_true(strlen(cpu->device_name()) > 0);
  assert_non_null(cpu->gbuffer); /* what reference hooks get a coarse depth from */
}

/* Which techniques a backend runs: the descriptors' run functions, where the backend is there. */
static void test_runs_follow_descriptors(void **state) {
  (void)state;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
      int runs = obs_backend_runs((obs_backend)b, t);
      assert_int_equal(runs, t->run[b] && obs_backend_ops_get((obs_backend)b)->available());
      assert_int_equal(runs, obs_technique_has_backend(t, (obs_backend)b));
    }
    assert_false(obs_backend_runs(OBS_BACKEND_AUTO, t));
  }
  json_t *reg = obs_backend_registry_json();
  assert_int_equal(json_array_size(reg), OBS_BACKEND_COUNT - 1);
  json_t *cpu = json_array_get(reg, 0);
  assert_string_equal(json_string_value(json_object_get(cpu, "name")), "cpu");
  assert_true(json_is_true(json_object_get(cpu, "available")));
  size_t n = 0;
  for (size_t i = 0; i < obs_technique_count(); i++)
    n += obs_technique_at(i)->run[OBS_BACKEND_CPU] != NULL;
  assert_int_equal(json_array_size(json_object_get(cpu, "techniques")), n);
  json_decref(reg);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_parse_round_trip),
      cmocka_unit_test(test_parse_refuses),
      cmocka_unit_test(test_ops_table),
      cmocka_unit_test(test_runs_follow_descriptors),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
