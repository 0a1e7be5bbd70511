/* The Vulkan tests' shared fixture (see vktest.h). */
#include "vktest.h"

#include <stdio.h>

obs_vk *g_vk;

int vktest_group_setup(void **state) {
  (void)state;
  if (!obs_vk_available()) return 0;
  obs_err err = OBS_ERR_INIT;
  if (obs_vk_open(&g_vk, NULL, 1, &err)) {
    fprintf(stderr, "cannot open a Vulkan device with validation: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    return -1;
  }
  fprintf(stderr, "vulkan device: %s\n", obs_vk_device_name(g_vk));
  obs_err_free(&err);
  return 0;
}

int vktest_group_teardown(void **state) {
  (void)state;
  obs_vk_close(g_vk);
  g_vk = NULL;
  return 0;
}

int vktest_quiet_teardown(void **state) {
  (void)state;
  if (g_vk && obs_vk_validation_messages(g_vk) != 0) {
    fprintf(stderr, "%u validation messages\n", obs_vk_validation_messages(g_vk));
    return -1;
  }
  return 0;
}

obs_vk *vktest_need_vk(void) {
  if (!g_vk) {
    fprintf(stderr, "skipped: no Vulkan device here (install mesa-vulkan-drivers for lavapipe)\n");
    skip();
  }
  return g_vk;
}

void vktest_check_rc(int rc, obs_err *err) {
  if (rc) fprintf(stderr, "error %d: %s\n", rc, obs_err_message(err));
  assert_int_equal(rc, 0);
}
