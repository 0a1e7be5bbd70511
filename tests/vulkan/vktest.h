/* Fixture shared by the Vulkan tests: one validated device per test program, skipped cleanly where
 * no Vulkan device exists, and a check after every test that the validation layer stayed silent. */
#ifndef OBS_VKTEST_H
#define OBS_VKTEST_H

#include "testutil.h"
#include "vk.h"

/* The device opened by vktest_group_setup (NULL where none exists). */
extern obs_vk *g_vk;

int vktest_group_setup(void **state);
int vktest_group_teardown(void **state);
/* Per-test teardown: fails the test if any validation message appeared. */
int vktest_quiet_teardown(void **state);
/* The device, or skip() the current test with a message. */
obs_vk *vktest_need_vk(void);
/* Asserts rc == 0, printing the error first. */
void vktest_check_rc(int rc, obs_err *err);

#endif
