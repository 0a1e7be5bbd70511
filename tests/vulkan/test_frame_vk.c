/* The sampling frame on Vulkan: the shaders' obs_onb (renderer/vulkan/shaders/include/frame.glsl)
 * gives the CPU's obs_onb (renderer/core/sampling.h) bit for bit, over random unit normals, the
 * poles, axis-aligned and leaning walls whose zero components carry either sign of zero or
 * rounding noise inside the guard, and components just outside it. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling.h"
#include "shaders.h"
#include "vktest.h"

#define FW 16
#define FH 16

typedef struct frame_push {
  int32_t width, height;
} frame_push;

/* Normal i of the test set, as float xyz (unit up to rounding or noise). */
static void test_normal(int i, uint32_t *seed, float n[3]) {
  static const float walls[][3] = {{0.6f, 0.8f, 0}, {-0.8f, 0.6f, 0},   {1, 0, 0}, {0, -1, 0},
                                   {0.6f, 0, 0.8f}, {0, 0.28f, -0.96f}, {0, 0, 1}, {0, 0, -1}};
  static const float noise[] = {0.0f,      -0.0f,           0x1p-24f,         -0x1p-24f,
                                -0x1p-21f, 0x1.fffffep-21f, -0x1.fffffep-21f, 0x1p-20f,
                                -0x1p-20f, -0x1p-19f};
  const int nw = 8, nn = 10;
  if (i < nw * nn * 3) { /* wall w, component k, noise j (components that are 0 only) */
    int w = i / (nn * 3), k = i / nn % 3, j = i % nn;
    memcpy(n, walls[w], 3 * sizeof(float));
    if (n[k] == 0) n[k] = noise[j];
    return;
  }
  double v[3], l2;
  do { /* uniform on the sphere by rejection */
    for (int k = 0; k < 3; k++) v[k] = 2 * obs_test_unit(seed) - 1;
    l2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  } while (!(l2 > 1e-4 && l2 <= 1));
  for (int k = 0; k < 3; k++) n[k] = (float)(v[k] / sqrt(l2));
}

static void test_frame_same_bits(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  const size_t n = (size_t)FW * FH;
  float *in = calloc(4 * n, sizeof(float)), *t = calloc(4 * n, sizeof(float)),
        *b = calloc(4 * n, sizeof(float));
  assert_true(in && t && b);
  uint32_t seed = 0x2545f491u;
  for (size_t i = 0; i < n; i++) test_normal((int)i, &seed, in + 4 * i);
  obs_vk_image *img[3] = {NULL, NULL, NULL};
  for (int k = 0; k < 3; k++)
    vktest_check_rc(obs_vk_image_create(vk, FW, FH, 4, &img[k], &err), &err);
  vktest_check_rc(obs_vk_image_upload(vk, img[0], in, &err), &err);
  frame_push push = {FW, FH};
  obs_vk_pass pass = {.name = "frame",
                      .spirv = obs_spv_test_frame_comp,
                      .spirv_size = obs_spv_test_frame_comp_size,
                      .images = {img[0], img[1], img[2]},
                      .nimages = 3,
                      .push = &push,
                      .push_size = sizeof push,
                      .groups_x = (FW + 7) / 8,
                      .groups_y = (FH + 7) / 8};
  vktest_check_rc(obs_vk_run(vk, &pass, 1, NULL, &err), &err);
  vktest_check_rc(obs_vk_image_download(vk, img[1], t, &err), &err);
  vktest_check_rc(obs_vk_image_download(vk, img[2], b, &err), &err);
  size_t differ = 0, flipped = 0;
  for (size_t i = 0; i < n; i++) {
    float ct[3], cb[3];
    obs_onb(in + 4 * i, ct, cb);
    if (memcmp(ct, t + 4 * i, sizeof ct) || memcmp(cb, b + 4 * i, sizeof cb)) {
      if (differ++ < 8)
        print_message(
            "normal (%a, %a, %a): cpu t (%a, %a, %a) b (%a, %a, %a), vulkan t (%a, %a, "
            "%a) b (%a, %a, %a)\n",
            in[4 * i], in[4 * i + 1], in[4 * i + 2], ct[0], ct[1], ct[2], cb[0], cb[1], cb[2],
            t[4 * i], t[4 * i + 1], t[4 * i + 2], b[4 * i], b[4 * i + 1], b[4 * i + 2]);
    }
    flipped += in[4 * i + 2] <= -OBS_ONB_FLAT;
  }
  print_message("%zu normals, %zu in the frame's lower half, %zu differ\n", n, flipped, differ);
  assert_int_equal(differ, 0);
  assert_true(flipped > 0 && flipped < n); /* both halves of the frame were exercised */
  for (int k = 0; k < 3; k++) obs_vk_image_free(vk, img[k]);
  free(in);
  free(t);
  free(b);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_frame_same_bits, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
