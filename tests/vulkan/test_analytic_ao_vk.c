/* analytic_ao on Vulkan against its CPU twin: one G-buffer through both gives the same bits
 * (spheres, quads, a non-planar quad, triangles, boxes; perspective and orthographic; bounded and
 * unbounded cubes; occluders split over several dispatches under lavapipe's loop limit), the
 * rasterised proxies (method raster) agree with the compute pass, an occluder outside the view
 * included, and full renders through both backends agree, all under the validation layer. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "gbuffer_cpu.h"
#include "vk.h"
#include "vktest.h"
#include "../../renderer/techniques/analytic_ao/analytic_ao.h"

/* The scene of `json` (a whole scene document), its ray-cast G-buffer on the host and on the
 * device, and its occluders at `extent`; release frees them. */
static void setup(obs_vk *vk, const char *json, double extent, obs_scene *sc, obs_gbuffer *g,
                  obs_vk_gbuffer *dev, obs_aao_occluder **occ, size_t *nocc) {
  obs_err err = OBS_ERR_INIT;
  obs_test_load(json, "aao_vk.json", sc);
  vktest_check_rc(obs_gbuffer_raycast(sc, g, 2, NULL, NULL, &err), &err);
  vktest_check_rc(obs_vk_gbuffer_upload(vk, g, dev, &err), &err);
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, g->width, g->height, &rig);
  vktest_check_rc(obs_aao_occluders(sc, &rig, extent, NULL, occ, nocc, NULL, &err), &err);
  obs_err_free(&err);
}

static void release(obs_vk *vk, obs_scene *sc, obs_gbuffer *g, obs_vk_gbuffer *dev,
                    obs_aao_occluder *occ) {
  free(occ);
  obs_vk_gbuffer_free(vk, dev);
  obs_gbuffer_free(g);
  obs_scene_free(sc);
}

/* The G-buffer and occluders of `json` on both sides, compared bit for bit; returns the mean
 * AO. */
static double twins_at(const char *label, const char *json, double extent, int resolution,
                       int upsample) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  obs_gbuffer g;
  obs_vk_gbuffer dev;
  obs_aao_occluder *occ;
  size_t nocc;
  setup(vk, json, extent, &sc, &g, &dev, &occ, &nocc);
  obs_analytic_ao_params p = {.extent = extent, .resolution = resolution, .upsample = upsample,
                             .occluders = {.count = -1}};
  size_t n = (size_t)g.width * (size_t)g.height;
  float *ca = malloc(n * sizeof *ca), *va = malloc(n * sizeof *va);
  vktest_check_rc(obs_analytic_ao_cpu_apply(&g, occ, nocc, &p, 2, ca, NULL, &err), &err);
  double ms[OBS_AAO_STAGES];
  vktest_check_rc(obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc, &p, va, ms, &err), &err);
  size_t same = 0, open = 0;
  double mean = 0, worst = 0;
  for (size_t i = 0; i < n; i++) {
    same += memcmp(&ca[i], &va[i], sizeof(float)) == 0;
    open += ca[i] == 1.0f;
    mean += ca[i];
    worst = fmax(worst, fabs((double)ca[i] - va[i]));
  }
  printf("%-34s %4zu occluders: same bits %zu/%zu (max |d| %.3g, mean %.4f, %zu open)\n", label,
         nocc, same, n, worst, mean / (double)n, open);
  assert_int_equal(same, n);
  assert_true(open < n);
  free(ca);
  free(va);
  release(vk, &sc, &g, &dev, occ);
  obs_err_free(&err);
  return mean / (double)n;
}

static double raster_at(const char *label, const char *json, double extent, size_t drop,
                        double *without);

static double twins(const char *label, const char *json, double extent) {
  return twins_at(label, json, extent, OBS_AAO_FULL, OBS_AAO_BILATERAL);
}

static const char *with(const char *objects, const char *camera) {
  static char buf[128 * 1024];
  snprintf(buf, sizeof buf,
           "{\"camera\":%s,\"image\":{\"width\":64,\"height\":48},\"objects\":[%s],"
           "\"technique\":{\"name\":\"analytic_ao\",\"backend\":\"cpu\"}}",
           camera, objects);
  return buf;
}

static const char *MIXED =
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]]}},"
    "{\"shape\":{\"type\":\"sphere\",\"center\":[0.8,0.5,0],\"radius\":0.5}},"
    "{\"shape\":{\"type\":\"sphere\",\"center\":[-0.6,0.1,0.4],\"radius\":0.3}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.4,0,-0.4],\"max\":[0.4,0.7,0.4]},"
    "\"transform\":{\"rotate\":[0,25,0],\"translate\":[-0.9,0,-0.8]}},"
    "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0.5,0,-1],[1.5,0.9,-1.2],[1.2,0,-0.3]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1.5,0,1],[-0.5,0.2,1],[-0.5,1,1.3],"
    "[-1.5,0.9,1]]}}";

static const char *PERSPECTIVE = "{\"type\":\"perspective\",\"position\":[0,2.5,-4],"
                                 "\"look_at\":[0,0.3,0],\"up\":[0,1,0],\"fov_y\":45}";
static const char *ORTHO = "{\"type\":\"orthographic\",\"position\":[3,3,-3],"
                           "\"look_at\":[0,0.3,0],\"up\":[0,1,0],\"height\":4}";

static void test_twins_mixed(void **state) {
  (void)state;
  twins("mixed, perspective, unbounded", with(MIXED, PERSPECTIVE), INFINITY);
  twins("mixed, perspective, extent 3", with(MIXED, PERSPECTIVE), 3);
  twins("mixed, orthographic, extent 16", with(MIXED, ORTHO), 16);
}

/* Half resolution: the half grid, the bilateral upsampling and the pixels it left, on both; then
 * the push-pull over the same samples. */
static void test_twins_half(void **state) {
  (void)state;
  twins_at("half: mixed, perspective, extent 16", with(MIXED, PERSPECTIVE), 16, OBS_AAO_HALF,
           OBS_AAO_BILATERAL);
  twins_at("half: mixed, orthographic, unbounded", with(MIXED, ORTHO), INFINITY, OBS_AAO_HALF,
           OBS_AAO_BILATERAL);
  twins_at("push_pull: mixed, perspective, ext 16", with(MIXED, PERSPECTIVE), 16, OBS_AAO_HALF,
           OBS_AAO_PUSH_PULL);
  twins_at("push_pull: mixed, ortho, unbounded", with(MIXED, ORTHO), INFINITY, OBS_AAO_HALF,
           OBS_AAO_PUSH_PULL);
}

/* Method raster against method compute on one G-buffer: the worst |difference| over the covered
 * pixels (the factors multiply in the same order, so only the shader's rounding could differ).
 * With `drop`, also the raster AO without the last `drop` occluders; returns the mean raster AO
 * over the covered pixels, and that without them in *without. */
static double raster_at(const char *label, const char *json, double extent, size_t drop,
                        double *without) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  obs_gbuffer g;
  obs_vk_gbuffer dev;
  obs_aao_occluder *occ;
  size_t nocc;
  setup(vk, json, extent, &sc, &g, &dev, &occ, &nocc);
  assert_true(nocc > drop);
  obs_analytic_ao_params p = {.extent = extent, .occluders = {.count = -1}};
  size_t n = (size_t)g.width * (size_t)g.height;
  float *ca = malloc(n * sizeof *ca), *ra = malloc(n * sizeof *ra), *da = malloc(n * sizeof *da);
  double ms[OBS_AAO_STAGES];
  vktest_check_rc(obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc, &p, ca, ms, &err), &err);
  p.method = OBS_AAO_RASTER;
  vktest_check_rc(obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc, &p, ra, ms, &err), &err);
  if (drop)
    vktest_check_rc(obs_analytic_ao_vk_apply(vk, &dev, &g, occ, nocc - drop, &p, da, ms, &err),
                    &err);
  size_t same = 0, covered = 0, open = 0;
  double worst = 0, mean = 0, mean_without = 0;
  for (size_t i = 0; i < n; i++) {
    assert_true(ra[i] >= 0.0f && ra[i] <= 1.0f);
    same += memcmp(&ca[i], &ra[i], sizeof(float)) == 0;
    if (!(g.depth[i] > 0.0f)) continue;
    covered++;
    open += ca[i] == 1.0f;
    worst = fmax(worst, fabs((double)ca[i] - ra[i]));
    mean += ra[i];
    mean_without += drop ? da[i] : ra[i];
  }
  mean /= (double)covered;
  mean_without /= (double)covered;
  printf("%-38s %4zu occluders: raster vs compute max |d| %.3g over %zu covered pixels, same "
         "bits %zu/%zu, mean %.5f (%.5f without the last %zu)\n",
         label, nocc, worst, covered, same, n, mean, mean_without, drop);
  assert_true(covered > 0 && open < covered);
  assert_true(worst < 1e-5);
  if (without) *without = mean_without;
  free(ca);
  free(ra);
  free(da);
  release(vk, &sc, &g, &dev, occ);
  obs_err_free(&err);
  return mean;
}

static void test_raster_mixed(void **state) {
  (void)state;
  raster_at("raster: mixed, perspective, unbounded", with(MIXED, PERSPECTIVE), INFINITY, 0, NULL);
  raster_at("raster: mixed, perspective, extent 3", with(MIXED, PERSPECTIVE), 3, 0, NULL);
  raster_at("raster: mixed, orthographic, extent 16", with(MIXED, ORTHO), 16, 0, NULL);
  raster_at("raster: mixed, orthographic, unbounded", with(MIXED, ORTHO), INFINITY, 0, NULL);
}

/* A sphere left of the view darkens the floor near the image's left edge under raster too: at
 * extent 3 its cube is partly on screen, at extent 16 the cube holds the camera. */
static void test_raster_hidden(void **state) {
  (void)state;
  static const char *HIDDEN =
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-6,0,-6],[-6,0,6],[6,0,6],[6,0,-6]]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[-4,0.5,-1],\"radius\":0.5}}";
  static const double extents[2] = {3, 16};
  for (int k = 0; k < 2; k++) {
    char label[64];
    snprintf(label, sizeof label, "raster: hidden sphere, extent %g", extents[k]);
    double without, with_it = raster_at(label, with(HIDDEN, PERSPECTIVE), extents[k], 1, &without);
    assert_true(without == 1.0);
    assert_true(with_it < 1.0 - 1e-5);
  }
}

static void test_twins_cornell(void **state) {
  (void)state;
  char ov[64];
  snprintf(ov, sizeof ov, "{\"width\":64,\"height\":64,\"spp\":1}");
  obs_scene sc;
  obs_override o[1] = {{"/image", ov}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_scene_load_file(&sc, obs_test_src("scenes/cornell_box.json"), o, 1, &err),
                  &err);
  char *text = json_dumps(sc.doc, JSON_COMPACT);
  obs_scene_free(&sc);
  twins("cornell_box (non-planar left wall)", text, INFINITY);
  free(text);
}

/* More occluders than one dispatch may loop over on lavapipe: the product carries over from one
 * dispatch to the next with the CPU's bits; the proxies of as many give the same product. */
static void test_twins_many(void **state) {
  (void)state;
  static char objs[96 * 1024];
  size_t at = (size_t)snprintf(objs, sizeof objs, "%s",
                               "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-6,0,-6],[-6,0,6],"
                               "[6,0,6],[6,0,-6]]}}");
  for (int i = 0; i < 900; i++) {
    double x = -5 + 10 * ((i * 37) % 900) / 900.0, z = -5 + 10 * ((i * 61) % 900) / 900.0;
    at += (size_t)snprintf(objs + at, sizeof objs - at,
                           i % 3 ? ",{\"shape\":{\"type\":\"sphere\",\"center\":[%.4f,0.12,%.4f],"
                                   "\"radius\":0.1}}"
                                 : ",{\"shape\":{\"type\":\"box\",\"min\":[%.4f,0,%.4f],"
                                   "\"max\":[0,0.2,0]},\"transform\":{\"translate\":[0.1,0,0.1]}}",
                           i % 3 ? x : -0.1, i % 3 ? z : -0.1);
  }
  twins("900 spheres and boxes, extent 8", with(objs, PERSPECTIVE), 8);
  raster_at("raster: 900 spheres and boxes, extent 8", with(objs, PERSPECTIVE), 8, 0, NULL);
}

/* Whole renders on each backend (each its own G-buffer: rasterised on the device, ray cast on the
 * CPU) agree but for the pixels whose surface the two G-buffers see differently. */
static void test_full_renders_agree(void **state) {
  (void)state;
  vktest_need_vk();
  obs_result r[2];
  static const char *const backends[2] = {"cpu", "vulkan"};
  for (int b = 0; b < 2; b++)
    obs_test_render(obs_test_fmt("{\"camera\":%s,\"image\":{\"width\":64,\"height\":48},"
                                 "\"objects\":[%s],\"technique\":{\"name\":\"analytic_ao\","
                                 "\"backend\":\"%s\"}}",
                                 PERSPECTIVE, MIXED, backends[b]),
                    2, &r[b]);
  double max;
  size_t over;
  vktest_ao_diff(&r[0], &r[1], "ao", 2e-2, &max, &over);
  printf("cpu and vulkan renders: max |d| %.3g, %zu pixels over 2e-2\n", max, over);
  assert_true(over <= 64 * 48 / 100);
  obs_result_free(&r[0]);
  obs_result_free(&r[1]);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_twins_mixed, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_twins_cornell, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_twins_half, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_twins_many, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_raster_mixed, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_raster_hidden, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_full_renders_agree, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
