/* isosurface_mesh's Vulkan extractor against the CPU's (renderer/core/isosurface.h) on lavapipe,
 * under the validation layer: the same vertex count, the same edge key per vertex, the same
 * triangles index for index, edge parameters within 1e-6 (positions within 1e-6 of the cell), with
 * and without refinement, on volumes with flat, smooth and rough isosurfaces; and whole renders
 * through both backends agree in coverage and depth. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isosurface.h"
#include "vk.h"
#include "vktest.h"
#include "../../renderer/techniques/isosurface_mesh/isosurface_mesh.h"

static void twins(obs_volume_procedural kind, int n, float iso, int cells, int refine) {
  obs_vk *vk = vktest_need_vk();
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  const int dims[3] = {n, n, n - n / 4};
  vktest_check_rc(obs_volume_procedural_fill(kind, 3, dims, &v, &err), &err);
  obs_iso_mesh c, g;
  double ms = 0;
  vktest_check_rc(obs_iso_extract(&v, iso, cells, refine, &c, &err), &err);
  vktest_check_rc(obs_isosurface_mesh_vk_extract(vk, &v, iso, cells, refine, &g, &ms, &err), &err);
  printf("     %s %d^2x%d iso %.2f cells %d refine %d: %zu triangles, device %.1f ms\n",
         obs_volume_procedural_names[kind], n, dims[2], iso, cells, refine, c.ntris, ms);
  assert_true(c.ntris > 0);
  assert_int_equal(g.nverts, c.nverts);
  assert_int_equal(g.ntris, c.ntris);
  assert_memory_equal(g.key, c.key, c.nverts * sizeof *c.key);
  assert_memory_equal(g.idx, c.idx, 3 * c.ntris * sizeof *c.idx);
  double dt = 0, dp = 0;
  for (size_t i = 0; i < c.nverts; i++) {
    dt = fmax(dt, fabs((double)g.t[i] - (double)c.t[i]));
    for (int a = 0; a < 3; a++)
      dp = fmax(dp, fabs(g.pos[3 * i + a] - c.pos[3 * i + a]) / c.lat.h[a]);
  }
  printf("     largest |t| difference %.2e, position difference %.2e cells\n", dt, dp);
  assert_true(dt <= 1e-6);
  assert_true(dp <= 1e-6);
  obs_iso_mesh_free(&c);
  obs_iso_mesh_free(&g);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* Bisection past level 1 is the CPU's: the device extractor refuses it by name. */
static void refuses_deeper(void) {
  obs_vk *vk = vktest_need_vk();
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  const int dims[3] = {16, 16, 16};
  vktest_check_rc(obs_volume_procedural_fill(OBS_VOLUME_SPHERE, 3, dims, &v, &err), &err);
  obs_iso_mesh g;
  double ms = 0;
  assert_int_equal(obs_isosurface_mesh_vk_extract(vk, &v, 0.5f, 8, 2, &g, &ms, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "refine 2"));
  obs_volume_free(&v);
  obs_err_free(&err);
}

static void test_sphere(void **state) {
  (void)state;
  twins(OBS_VOLUME_SPHERE, 24, 0.5f, 16, 0);
  twins(OBS_VOLUME_SPHERE, 24, 0.5f, 16, 1);
  refuses_deeper();
}

static void test_torus_and_rough(void **state) {
  (void)state;
  twins(OBS_VOLUME_TORUS, 32, 0.52f, 24, 0);
  twins(OBS_VOLUME_MARSCHNER_LOBB, 32, 0.5f, 20, 1);
  twins(OBS_VOLUME_NOISE, 24, 0.5f, 20, 0);
}

static void test_full_renders_agree(void **state) {
  (void)state;
  vktest_need_vk();
  const char *fmt =
      "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0.5, -1.6], \"look_at\": [0, 0, 0],"
      " \"up\": [0, 1, 0], \"fov_y\": 40}, \"image\": {\"width\": 48, \"height\": 32, \"spp\": 1},"
      " \"objects\": [{\"name\": \"torus\", \"shape\": {\"type\": \"volume\", \"procedural\":"
      " \"torus\", \"dims\": [32, 32, 32]}, \"transform\": {\"rotate\": [70, 0, 0]}}],"
      " \"environment\": {\"color\": [1, 1, 1]}, \"technique\": {\"name\": \"isosurface_mesh\","
      " \"backend\": \"%s\", \"params\": {\"grid\": 32}}}";
  obs_result a, b;
  obs_test_render(obs_test_fmt(fmt, "cpu"), 2, &a);
  obs_test_render(obs_test_fmt(fmt, "vulkan"), 2, &b);
  const float *aa = obs_image_channel(&a.image, "alpha"), *ba = obs_image_channel(&b.image, "alpha");
  const float *ad = obs_image_channel(&a.image, "depth.Z"), *bd = obs_image_channel(&b.image, "depth.Z");
  size_t both = 0, differ = 0;
  double drel = 0;
  for (int i = 0; i < 48 * 32; i++) {
    differ += (aa[i] > 0) != (ba[i] > 0);
    if (!(aa[i] > 0 && ba[i] > 0)) continue;
    both++;
    drel = fmax(drel, fabs(bd[i] / ad[i] - 1));
  }
  printf("     %zu pixels both, %zu differ in coverage, largest relative depth difference %.2e\n",
         both, differ, drel);
  /* The CPU casts rays through volume_ao's jittered points; the G-buffer samples pixel centres. */
  assert_true(both > 200 && differ * 10 < both && drel < 2e-2);
  obs_result_free(&a);
  obs_result_free(&b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_torus_and_rough, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_full_renders_agree, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
