/* disc_ao on Vulkan against its CPU twin: the same G-buffer and discs through both, quad and
 * pyramid proxies, both sides, perspective and orthographic cameras; the on-axis fraction on the
 * device; the proxies cover every receiver within reach (the device shades at least every pair the
 * CPU finds); all under the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "disc_ao.h"
#include "gbuffer_cpu.h"
#include "vktest.h"

#define PI 3.14159265358979323846

static obs_disc_ao_params defaults(void) {
  obs_disc_ao_params p = {.proxy = OBS_DISC_PROXY_QUAD, .area_over_pi = 1,
                          .influence_scale = 4.0f, .side = OBS_DISC_SIDE_FRONT,
                          .subdivide = 0.05f};
  return p;
}

/* A box and a ball on a floor with a wall behind them (single-sided quads), seen in perspective
 * from close by (influence spheres reach past the camera plane) or orthographically. */
static const char *scene(int ortho) {
  static char buf[2048];
  snprintf(buf, sizeof buf,
           "{\"camera\":%s,\"image\":{\"width\":48,\"height\":36},\"objects\":["
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]]}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,2],[-3,3,2],[3,3,2],[3,0,2]]}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[-0.8,0,-0.2],\"max\":[-0.2,1,0.4]}},"
           "{\"shape\":{\"type\":\"sphere\",\"center\":[0.6,0.5,0],\"radius\":0.5}}],"
           "\"technique\":{\"name\":\"disc_ao\",\"backend\":\"cpu\",\"params\":{}}}",
           ortho ? "{\"type\":\"orthographic\",\"position\":[2,3,-3],\"look_at\":[0,0.5,0],"
                   "\"height\":4}"
                 : "{\"type\":\"perspective\",\"position\":[0.5,1.2,-1.6],\"look_at\":[0,0.4,0.5],"
                   "\"fov_y\":70}");
  return buf;
}

/* The twins on one G-buffer: every parameter combination that changes the device's work. Both
 * evaluate the same float expression in the same order and sum in the discs' order, but the
 * device's sqrt and division need not round as the host's do (a few ulps), and such a difference
 * can move a disc sitting on a receiver's reach across it: no pixel may differ by more than 1e-4
 * save 0.2 % of them (printed), and none by more than the largest single term, 0.05. */
static void twins(int ortho) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  obs_test_load(scene(ortho), "disc_ao_vk.json", &sc);
  obs_gbuffer g;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, g.width, g.height, &rig);
  size_t n = (size_t)g.width * (size_t)g.height;
  float *ca = malloc(n * sizeof *ca), *cr = malloc(n * sizeof *cr);
  float *va = malloc(n * sizeof *va), *vr = malloc(n * sizeof *vr);
  for (int k = 0; k < 8; k++) {
    obs_disc_ao_params p = defaults();
    p.proxy = k & 1, p.side = (k >> 1) & 1, p.area_over_pi = !(k & 4);
    p.influence_scale = k & 4 ? 9.0f : 4.0f;
    obs_disc_set s;
    vktest_check_rc(obs_disc_set_build(&sc, &rig, &p, &s, &err), &err);
    obs_disc_ao_stats cs, vs;
    vktest_check_rc(obs_disc_ao_cpu_apply(&g, &s, &p, 2, ca, cr, &cs, &err), &err);
    vktest_check_rc(obs_disc_ao_vk_apply(vk, &dev, &g, &s, &p, va, vr, &vs, NULL, &err), &err);
    double max = 0, ss = 0;
    size_t over = 0, exact = 0, dark = 0;
    for (size_t i = 0; i < n; i++) {
      assert_true(isfinite(va[i]) && va[i] >= 0.0f && va[i] <= 1.0f && isfinite(vr[i]));
      double e = fabs((double)cr[i] - (double)vr[i]);
      max = fmax(max, e), ss += e * e;
      over += e > 1e-4, exact += cr[i] == vr[i], dark += ca[i] < 0.8f;
      assert_true(fabs((double)ca[i] - (double)va[i]) <= e);
    }
    printf("%s %s side %s area_over_pi %d scale %.0f: %zu discs, max %.3g rmse %.3g >1e-4 %zu "
           "exact %zu/%zu dark %zu; pairs in reach %llu, fragments %llu (max overdraw %u)\n",
           ortho ? "ortho" : "persp", p.proxy ? "pyramid" : "quad", p.side ? "back" : "front",
           p.area_over_pi, (double)p.influence_scale, s.n, max, sqrt(ss / (double)n), over, exact,
           n, dark, (unsigned long long)cs.fragments, (unsigned long long)vs.fragments,
           vs.max_overdraw);
    assert_true(max <= 0.05);
    assert_true((double)over <= 0.002 * (double)n);
    assert_true(dark > 0);
    assert_true(vs.fragments >= cs.fragments);
    obs_disc_set_free(&s);
  }
  free(ca), free(cr), free(va), free(vr);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_twins_perspective(void **state) {
  (void)state;
  twins(0);
}

static void test_twins_ortho(void **state) {
  (void)state;
  twins(1);
}

/* The on-axis fraction on the device: receivers at depth 10 facing the camera, one per pixel of
 * a row, each under its own disc of radius r at distance d_i; AO = 1/sqrt(r^2/d^2 + 1). */
static void test_on_axis(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  const int w = 6;
  obs_camera_rig rig = {.ortho = 1, .half_w = 3, .half_h = 0.5, .width = w, .height = 1};
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_gbuffer_alloc(&g, w, 1, &rig, &err), &err);
  obs_disc_ao_params p = defaults();
  p.influence_scale = 1.5f; /* reach 1.5 sqrt(pi) r = 0.8: no disc reaches a neighbour (1) */
  const double r = 0.3, dist[6] = {0.05, 0.1, 0.2, 0.3, 0.4, 0.45};
  obs_disc d[6];
  for (int i = 0; i < w; i++) {
    g.depth[i] = 10.0f, g.normal[3 * i + 2] = -1.0f, g.coverage[i] = 1.0f;
    double x = (2.0 * (i + 0.5) / w - 1.0) * rig.half_w, z = 10.0 - dist[i];
    double s = sqrt(4 * PI * r * r / sqrt(3.0)), h = s * sqrt(3.0) / 2;
    double a[3] = {x + s / 2, -h / 3, z}, b[3] = {x - s / 2, -h / 3, z}, c[3] = {x, 2 * h / 3, z};
    assert_int_equal(obs_disc_make(a, b, c, &p, &d[i]), 1);
  }
  obs_disc_set set = {.d = d, .n = 6, .triangles = 6};
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &g, &dev, &err), &err);
  for (int proxy = 0; proxy < 2; proxy++) {
    p.proxy = proxy;
    float ao[6];
    vktest_check_rc(obs_disc_ao_vk_apply(vk, &dev, &g, &set, &p, ao, NULL, NULL, NULL, &err),
                    &err);
    for (int i = 0; i < w; i++) {
      double want = 1 / sqrt(r * r / (dist[i] * dist[i]) + 1);
      printf("%s d %.2f: ao %.7f exact %.7f\n", proxy ? "pyramid" : "quad", dist[i], ao[i], want);
      assert_true(fabs(ao[i] - want) <= 2e-6);
    }
  }
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&g);
}

/* Whole renders through both backends (each its own G-buffer) agree in the mean. */
static void test_renders(void **state) {
  (void)state;
  vktest_need_vk();
  const char *doc = scene(0);
  const char *be = strstr(doc, "\"backend\":\"cpu\"");
  assert_non_null(be);
  char vdoc[2048];
  snprintf(vdoc, sizeof vdoc, "%.*s\"backend\":\"vulkan\"%s", (int)(be - doc), doc, be + 15);
  obs_result rc, rv;
  obs_test_render(doc, 2, &rc);
  obs_test_render(vdoc, 1, &rv);
  double max;
  size_t over;
  vktest_ao_diff(&rc, &rv, "ao", 0.02, &max, &over);
  printf("CPU and Vulkan renders: max |d ao| %.3g, %zu pixels over 0.02\n", max, over);
  assert_true(over <= 10);
  obs_result_free(&rc);
  obs_result_free(&rv);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_twins_perspective, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_twins_ortho, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_on_axis, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_renders, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
