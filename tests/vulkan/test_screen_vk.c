/* The Vulkan screen-space driver: a region's pixels are the whole render's and the rest stays 0,
 * progress reaches 1 without going back, a cancelled render returns OBS_ECANCELED and no image,
 * and the stages are named as on the CPU. */
#include <stdio.h>
#include <string.h>

#include "vktest.h"

#define W 70
#define H 45

static const char *doc(const char *technique, const char *params) {
  static char buf[1024];
  snprintf(buf, sizeof buf,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0.3,0],"
           "\"up\":[0,1,0],\"fov_y\":45},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{\"name\":\"ground\",\"shape\":{\"type\":\"quad\",\"vertices\":"
           "[[-20,0,-20],[-20,0,20],[20,0,20],[20,0,-20]]}},{\"name\":\"ball\",\"shape\":"
           "{\"type\":\"sphere\",\"center\":[0,1,0],\"radius\":0.5}}],"
           "\"technique\":{\"name\":\"%s\",\"backend\":\"vulkan\",\"params\":%s}}",
           W, H, technique, params);
  return buf;
}

typedef struct progress_log {
  atomic_int *flag;
  int cancel_at, calls;
  double last;
} progress_log;

static void on_progress(void *user, double f) {
  progress_log *p = user;
  assert_true(f >= p->last && f <= 1.0);
  p->last = f;
  if (++p->calls == p->cancel_at) atomic_store(p->flag, 1);
}

static void check(const char *technique, const char *params, const char *const *stages,
                  int nstages) {
  vktest_need_vk();
  obs_scene sc;
  obs_test_load(doc(technique, params), "d.json", &sc);
  obs_err err = OBS_ERR_INIT;
  atomic_int cancel;
  atomic_init(&cancel, 0);
  progress_log pl = {&cancel, -1, 0, 0};
  obs_render_opts o = {.threads = 2, .cancel = &cancel, .progress = on_progress,
                       .progress_user = &pl};
  obs_result full, part;
  vktest_check_rc(obs_render(&sc, &o, &full, &err), &err);
  assert_true(pl.last == 1.0);
  assert_int_equal(full.nstages, nstages);
  for (int i = 0; i < nstages; i++) assert_string_equal(full.stage_names[i], stages[i]);
  obs_region r = {17, 9, 53, 40};
  obs_render_opts op = {.threads = 2, .region = r};
  vktest_check_rc(obs_render(&sc, &op, &part, &err), &err);
  obs_test_assert_region(&full.image, &part.image, r);
  obs_result_free(&full);
  obs_result_free(&part);
  /* Raised at the first report (after the G-buffer): the passes never run. */
  pl = (progress_log){&cancel, 1, 0, 0};
  obs_result cut;
  assert_int_equal(obs_render(&sc, &o, &cut, &err), OBS_ECANCELED);
  assert_null(cut.image.data);
  assert_true(pl.last < 1.0);
  assert_non_null(strstr(obs_err_message(&err), "cancelled"));
  obs_err_free(&err);
  obs_scene_free(&sc);
}

static void test_ssao(void **state) {
  (void)state;
  static const char *const st[] = {"prepare", "device", "gbuffer", "geometry",
                                   "ao",      "blur",   "readback", "other"};
  check("ssao", "{\"samples\":8,\"blur\":true}", st, 8);
}

static void test_hbao(void **state) {
  (void)state;
  static const char *const st[] = {"prepare", "device", "gbuffer", "geometry", "downsample",
                                   "ao",      "upsample", "blur",  "readback", "other"};
  check("hbao", "{\"directions\":4,\"steps\":4,\"radius\":1,\"half_res\":true,\"blur_radius\":2}",
        st, 10);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_ssao, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_hbao, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
