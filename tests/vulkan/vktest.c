/* The Vulkan tests' shared fixture (see vktest.h). */
#include "vktest.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

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

void vktest_moved_scene(double s, double t, double g, double fov, char *buf, size_t size) {
  double tx = t * 1.2345678901, ty = t * 0.3141592653, tz = -t * 0.7654321098;
  snprintf(buf, size,
           "\"camera\":{\"type\":\"perspective\",\"position\":[%.17g,%.17g,%.17g],"
           "\"look_at\":[%.17g,%.17g,%.17g],\"fov_y\":%.17g},\"objects\":["
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
           "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}},"
           "{\"shape\":{\"type\":\"sphere\",\"center\":[%.17g,%.17g,%.17g],\"radius\":%.17g}}]",
           tx, ty + 3 * s, tz - 4 * s, tx, ty + 0.3 * s, tz, fov, tx - g * s, ty, tz - g * s,
           tx - g * s, ty, tz + g * s, tx + g * s, ty, tz + g * s, tx + g * s, ty, tz - g * s, tx,
           ty + 0.5 * s, tz, 0.5 * s);
}

void vktest_ao_diff(const obs_result *a, const obs_result *b, const char *channel, double tol,
                    double *max, size_t *over) {
  assert_int_equal(a->image.width, b->image.width);
  assert_int_equal(a->image.height, b->image.height);
  size_t n = (size_t)a->image.width * (size_t)a->image.height;
  const float *x = obs_image_channel(&a->image, channel), *y = obs_image_channel(&b->image, channel);
  const float *ca = obs_image_channel(&a->image, "alpha"), *cb = obs_image_channel(&b->image, "alpha");
  assert_non_null(x);
  assert_non_null(y);
  *max = 0;
  *over = 0;
  for (size_t i = 0; i < n; i++) {
    assert_true(ca[i] == cb[i]);
    double d = fabs((double)x[i] - (double)y[i]);
    if (d > *max) *max = d;
    *over += d > tol;
  }
}

size_t vktest_assert_region(const obs_result *whole, const obs_result *part, obs_region r) {
  const obs_image *a = &whole->image, *b = &part->image;
  assert_int_equal(a->width, b->width);
  assert_int_equal(a->height, b->height);
  assert_int_equal(a->nchannels, b->nchannels);
  size_t plane = (size_t)a->width * (size_t)a->height, covered = 0;
  for (int c = 0; c < a->nchannels; c++)
    for (int y = 0; y < a->height; y++)
      for (int x = 0; x < a->width; x++) {
        size_t i = (size_t)c * plane + (size_t)y * (size_t)a->width + (size_t)x;
        int in = x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1;
        assert_true(b->data[i] == (in ? a->data[i] : 0.0f));
        covered += in && !strcmp(a->names[c], "alpha") && a->data[i] > 0;
      }
  return covered;
}

double vktest_pipeline_rmse(vktest_load_fn load, obs_result r[2], double *mean) {
  vktest_need_vk();
  for (int b = 0; b < 2; b++) {
    obs_scene sc;
    load(b ? "vulkan" : "cpu", &sc);
    obs_err err = OBS_ERR_INIT;
    obs_render_opts o = {.threads = 2};
    vktest_check_rc(obs_render(&sc, &o, &r[b], &err), &err);
    obs_scene_free(&sc);
    obs_err_free(&err);
    obs_test_assert_finite(&r[b].image);
  }
  assert_int_equal(r[1].backend, OBS_BACKEND_VULKAN);
  size_t n = (size_t)r[0].image.width * (size_t)r[0].image.height;
  double ss = 0, sum = 0;
  static const char *const f[3] = {"radiance.R", "radiance.G", "radiance.B"};
  for (int k = 0; k < 3; k++) {
    const float *a = obs_image_channel(&r[0].image, f[k]),
                *v = obs_image_channel(&r[1].image, f[k]);
    for (size_t i = 0; i < n; i++) ss += ((double)a[i] - v[i]) * ((double)a[i] - v[i]), sum += a[i];
  }
  double rmse = sqrt(ss / (3.0 * (double)n));
  *mean = sum / (3.0 * (double)n);
  printf("pipeline cpu vs vulkan: radiance rmse %.3g (mean %.3g)\n", rmse, *mean);
  return rmse;
}
