/* Fixture shared by the Vulkan tests: one validated device per test program, skipped cleanly where
 * no Vulkan device exists, a check after every test that the validation layer stayed silent, and
 * a scene and a comparison used by the range tests. */
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

/* A ball of radius 0.5 on a ground quad of half-size g, seen from (0,3,-4) towards (0,0.3,0) at
 * fov_y degrees, all scaled by s about the origin and then moved by t (times different
 * irrational-looking factors per axis, so nothing rounds exactly). Writes
 * "\"camera\":{...},\"objects\":[...]" into buf. */
void vktest_moved_scene(double s, double t, double g, double fov, char *buf, size_t size);
/* Compares the AO channels of two renders of the same view: largest difference, and how many
 * pixels differ by more than `tol`. Coverage must be identical. */
void vktest_ao_diff(const obs_result *a, const obs_result *b, const char *channel, double tol,
                    double *max, size_t *over);
/* Renders scene sc on the CPU into r[0] and on Vulkan into r[1] (sc's technique on each,
 * 2 threads; `load` fills a scene for a backend name), asserts both finite and the second on
 * Vulkan, and returns the RMSE of their radiance.R/G/B over every pixel, with the CPU's mean in
 * *mean (printed). The caller frees r. */
typedef void (*vktest_load_fn)(const char *backend, obs_scene *sc);
double vktest_pipeline_rmse(vktest_load_fn load, obs_result r[2], double *mean);
/* Asserts that `part`, a render of region r alone, has `whole`'s bits inside r and 0 in every
 * channel outside it; returns how many pixels of r `whole` covers (alpha > 0). */
size_t vktest_assert_region(const obs_result *whole, const obs_result *part, obs_region r);

#endif
