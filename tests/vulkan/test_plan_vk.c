/* The Vulkan pass driver (renderer/vulkan/plan_vk.h) on the test shader test_scale.comp.glsl
 * (image1 = image0 * factor): host data up, dependent passes, frame-sized images and dispatches,
 * skipped passes, stages, downloads, callers' images, and bad plans refused before anything is
 * made. The sanitizer build proves every path frees what it made. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plan_vk.h"
#include "shaders.h"
#include "vktest.h"

typedef struct scale_push {
  float factor;
  int32_t width, height;
} scale_push;

enum { SRC = OBS_VK_PLAN_IMAGE0, MID, DST, UNUSED };

/* W x H (odd, so the dispatch rounds up) rgba values. */
#define W 67
#define H 45
#define N ((size_t)W * H * 4)

static float *ramp(void) {
  float *in = malloc(N * sizeof *in);
  assert_non_null(in);
  for (size_t i = 0; i < N; i++) in[i] = (float)i * 0.25f - 100.0f;
  return in;
}

/* SRC (uploaded) -> x3 -> MID -> x0.5 -> DST, then a skipped pass that binds an image nobody
 * describes: a skipped pass's images are neither checked nor made. */
static obs_vk_plan scale_plan(const float *in, const scale_push *p1, const scale_push *p2,
                              float *out, float *mid) {
  obs_vk_plan plan = {.technique = "plan-test",
                      .width = W,
                      .height = H,
                      .images = {[SRC] = {.width = W, .height = H, .channels = 4, .data = in},
                                 [MID] = {.channels = 4},
                                 [DST] = {.channels = 4}},
                      .passes = {{.stage = "scale",
                                  OBS_VK_SPIRV(test_scale_comp),
                                  OBS_VK_PUSH(*p1),
                                  .images = {SRC, MID}},
                                 {.stage = "scale",
                                  OBS_VK_SPIRV(test_scale_comp),
                                  OBS_VK_PUSH(*p2),
                                  .images = {MID, DST},
                                  .grid = DST},
                                 {.stage = "never",
                                  OBS_VK_SPIRV(test_scale_comp),
                                  OBS_VK_PUSH(*p2),
                                  .images = {DST, UNUSED},
                                  .skip = 1}},
                      .downloads = {{DST, out}, {MID, mid}}};
  return plan;
}

static void test_plan_runs(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  float *in = ramp(), *out = malloc(N * sizeof *out), *mid = malloc(N * sizeof *mid);
  assert_non_null(out);
  assert_non_null(mid);
  scale_push p1 = {3.0f, W, H}, p2 = {0.5f, W, H};
  obs_vk_plan plan = scale_plan(in, &p1, &p2, out, mid);
  obs_vk_plan_times t;
  vktest_check_rc(obs_vk_plan_run(vk, NULL, &plan, &t, &err), &err);
  /* Every texel, the last row and column included (groups rounded up from the frame's size). */
  for (size_t i = 0; i < N; i++) {
    assert_true(mid[i] == in[i] * 3.0f);
    assert_true(out[i] == in[i] * 3.0f * 0.5f);
  }
  /* Both passes under one stage, then the readback; the skipped pass's stage is absent. */
  assert_int_equal(t.n, 2);
  assert_string_equal(t.stage[0], "scale");
  assert_string_equal(t.stage[1], "readback");
  assert_true(t.ms[0] >= 0 && t.ms[1] >= 0);
  assert_true(obs_vk_plan_ms(&t, "never") == 0.0);
  const char *names[3] = {"readback", "absent", "scale"};
  double ms[3] = {-1, -1, -1};
  obs_vk_plan_stage_ms(&t, names, 3, ms);
  assert_true(ms[0] == t.ms[1] && ms[1] == 0.0 && ms[2] == t.ms[0]);
  /* Without the MID download, and with a caller's image as the source. */
  obs_vk_image *src = NULL;
  vktest_check_rc(obs_vk_image_create(vk, W, H, 4, &src, &err), &err);
  vktest_check_rc(obs_vk_image_upload(vk, src, in, &err), &err);
  plan.images[SRC] = (obs_vk_plan_image){.use = src};
  plan.downloads[1].to = NULL;
  memset(out, 0, N * sizeof *out);
  vktest_check_rc(obs_vk_plan_run(vk, NULL, &plan, NULL, &err), &err);
  for (size_t i = 0; i < N; i++) assert_true(out[i] == in[i] * 3.0f * 0.5f);
  /* The caller's image is still the caller's: readable after the run. */
  vktest_check_rc(obs_vk_image_download(vk, src, mid, &err), &err);
  assert_memory_equal(mid, in, N * sizeof *in);
  obs_vk_image_free(vk, src);
  free(in);
  free(out);
  free(mid);
  obs_err_free(&err);
}

/* Runs a bad plan: OBS_EINVAL (or `code`) with every fragment in the message, times zeroed. */
static void refused(obs_vk *vk, const obs_vk_gbuffer *g, const obs_vk_plan *plan, int code,
                    const char *a, const char *b) {
  obs_err err = OBS_ERR_INIT;
  obs_vk_plan_times t = {.n = 7};
  assert_int_equal(obs_vk_plan_run(vk, g, plan, &t, &err), code);
  fprintf(stderr, "refused: %s\n", obs_err_message(&err));
  assert_non_null(strstr(obs_err_message(&err), "plan-test"));
  assert_non_null(strstr(obs_err_message(&err), a));
  if (b) assert_non_null(strstr(obs_err_message(&err), b));
  assert_int_equal(t.n, 0);
  obs_err_free(&err);
}

static void test_plan_refused(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  float *in = ramp(), *out = malloc(N * sizeof *out);
  assert_non_null(out);
  scale_push p1 = {3.0f, W, H}, p2 = {0.5f, W, H}, big = p1;
  obs_vk_plan good = scale_plan(in, &p1, &p2, out, NULL), plan = good;
  plan.passes[1].images[1] = OBS_VK_PLAN_IMAGES;
  refused(vk, NULL, &plan, OBS_EINVAL, "pass 1 (\"scale\"), binding 1", "image handle 16");
  plan = good;
  plan.images[MID].channels = 2;
  refused(vk, NULL, &plan, OBS_EINVAL, "image 5", "2 channels");
  plan = good;
  plan.passes[2].skip = 0; /* now UNUSED, never described, is bound */
  refused(vk, NULL, &plan, OBS_EINVAL, "image 7", "0 channels");
  plan = good;
  plan.downloads[1] = (obs_vk_plan_download){-1, out};
  refused(vk, NULL, &plan, OBS_EINVAL, "download 1", "image handle -1");
  plan = good;
  plan.width = plan.height = 0; /* frame-sized images, no frame and no G-buffer */
  refused(vk, NULL, &plan, OBS_EINVAL, "image 5", "0x0 texels");
  plan = good;
  plan.passes[0].images[0] = OBS_VK_PLAN_DEPTH;
  refused(vk, NULL, &plan, OBS_EINVAL, "depth", "missing");
  plan = good;
  plan.passes[1].images[0] = 0;
  refused(vk, NULL, &plan, OBS_EINVAL, "pass 1", "no image bound");
  /* Past the checks, after the images are made: the device layer refuses the push block (the
   * images made before are freed, which the sanitizer build checks). */
  plan = good;
  plan.passes[1].push = &big;
  plan.passes[1].push_size = 132;
  refused(vk, NULL, &plan, OBS_EINVAL, "plan-test scale", "push constants");
  free(in);
  free(out);
}

/* In steps: each dispatch reads the push block as it is then; a close after a failure frees and
 * downloads nothing. */
static void test_plan_steps(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  float *in = ramp(), *out = malloc(N * sizeof *out);
  assert_non_null(out);
  scale_push p = {3.0f, W, H};
  obs_vk_plan plan = {.technique = "plan-test",
                      .width = W,
                      .height = H,
                      .images = {[SRC] = {.channels = 4, .data = in}, [DST] = {.channels = 4}},
                      .passes = {{.stage = "scale",
                                  OBS_VK_SPIRV(test_scale_comp),
                                  OBS_VK_PUSH(p),
                                  .images = {SRC, DST}}},
                      .downloads = {{DST, out}}};
  obs_vk_plan_state s;
  obs_vk_plan_times t;
  vktest_check_rc(obs_vk_plan_open(vk, NULL, &plan, &s, &err), &err);
  vktest_check_rc(obs_vk_plan_dispatch(&s, &err), &err);
  p.factor = 5.0f;
  vktest_check_rc(obs_vk_plan_dispatch(&s, &err), &err);
  vktest_check_rc(obs_vk_plan_close(&s, 0, &t, &err), &err);
  for (size_t i = 0; i < N; i++) assert_true(out[i] == in[i] * 5.0f);
  assert_int_equal(t.n, 2);
  assert_string_equal(t.stage[0], "scale");
  /* A failure between the steps: close keeps the code, downloads nothing, zeroes the times. */
  memset(out, 0, N * sizeof *out);
  vktest_check_rc(obs_vk_plan_open(vk, NULL, &plan, &s, &err), &err);
  vktest_check_rc(obs_vk_plan_dispatch(&s, &err), &err);
  assert_int_equal(obs_vk_plan_close(&s, OBS_ECANCELED, &t, &err), OBS_ECANCELED);
  assert_int_equal(t.n, 0);
  for (size_t i = 0; i < N; i++) assert_true(out[i] == 0.0f);
  /* A failed open still needs its close, which returns the open's code. */
  plan.images[DST].channels = 3;
  int rc = obs_vk_plan_open(vk, NULL, &plan, &s, &err);
  assert_int_equal(rc, OBS_EINVAL);
  assert_int_equal(obs_vk_plan_close(&s, rc, NULL, &err), OBS_EINVAL);
  free(in);
  free(out);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_plan_runs, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_plan_refused, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_plan_steps, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
