/* volume_ao on Vulkan (lavapipe) against its CPU twin on the same volumes and seeds: AO RMSE at
 * most 1e-2 and first-hit depth equal within a small relative tolerance off silhouettes, over
 * procedural sphere and torus volumes under a sky with point and directional lights, every ibl
 * method, both crossings, every sampler, perspective and orthographic cameras and jittered pixel
 * samples; and closed forms on Vulkan alone: AO = 1 on a lone sphere, final = AO under a constant
 * white environment, a region rendered alone equal to the same pixels of the whole image. One case
 * marches more directions per pixel than lavapipe runs loop iterations in one invocation
 * (obs_vk_loop_limit), so the render is split across dispatches. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stderr_check.h"
#include "vktest.h"

/* Acceptance bounds of the Vulkan twin against the CPU's render: AO RMSE, and depth relative to
 * the depth (float32 depth's precision after the march). */
#define AO_RMSE_MAX 1e-2
#define DEPTH_REL 1e-4

static const char *volume_obj(const char *kind, int n, const char *extra, double scale, double tx,
                              double ty, double tz) {
  static char buf[4][512];
  static int k;
  char *b = buf[k++ & 3];
  snprintf(b, 512,
           "{\"shape\": {\"type\": \"volume\", \"procedural\": \"%s\", \"dims\": [%d, %d, %d]%s}, "
           "\"transform\": {\"scale\": [%.17g, %.17g, %.17g], \"translate\": [%.17g, %.17g, "
           "%.17g]}}",
           kind, n, n, n, extra, scale, scale, scale, tx, ty, tz);
  return b;
}

static const char *PERSP =
    "{\"type\": \"perspective\", \"position\": [0.4, 1.5, -2.6], \"look_at\": [0.2, 0, 0], "
    "\"up\": [0, 1, 0], \"fov_y\": 45}";
static const char *ORTHO_X =
    "{\"type\": \"orthographic\", \"position\": [4, 0, 0], \"look_at\": [0, 0, 0], \"up\": [0, 1, "
    "0], \"height\": 2.4}";
/* Where the torus leans on the sphere: every pixel covered, most occluded. */
static const char *CLOSE =
    "{\"type\": \"perspective\", \"position\": [0.35, 1.2, -1.8], \"look_at\": [0.35, 0.15, 0], "
    "\"up\": [0, 1, 0], \"fov_y\": 14}";
static const char *SKY = "\"environment\": {\"map\": \"sky\", \"resolution\": 16}";

/* A sphere and a torus leaning over it, close enough to occlude each other; the torus coloured. */
static const char *two_volumes(void) {
  static char objs[1200];
  snprintf(
      objs, sizeof objs, "%s, %s", volume_obj("sphere", 48, "", 2, 0, 0, 0),
      volume_obj("torus", 48, ", \"colormap\": [[0.5, 0.8, 0.55, 0.35], [0.7, 0.95, 0.85, 0.7]]",
                 1.5, 0.7, 0.2, 0.1));
  return objs;
}

static char *scene_doc(const char *camera, int w, int h, int spp, const char *objects,
                       const char *rest, const char *params, const char *backend) {
  char *doc = malloc(8192);
  snprintf(doc, 8192,
           "{\"camera\": %s, \"image\": {\"width\": %d, \"height\": %d, \"spp\": %d}, "
           "\"objects\": [%s]%s, \"technique\": {\"name\": \"volume_ao\", \"backend\": \"%s\", "
           "\"params\": {%s}}}",
           camera, w, h, spp, objects, rest, backend, params);
  return doc;
}

static void render(const char *camera, int w, int h, int spp, const char *objects, const char *rest,
                   const char *params, const char *backend, obs_result *res) {
  char *doc = scene_doc(camera, w, h, spp, objects, rest, params, backend);
  obs_test_render(doc, 2, res);
  obs_test_assert_finite(&res->image);
  free(doc);
}

/* A pixel whose 3x3 neighbourhood changes coverage, or depth by more than 10 % (one surface
 * behind another; the smooth surfaces here change less from pixel to pixel), in either image:
 * there a sub-voxel difference in where the surface is found may change what the pixel sees. */
static int silhouette(const obs_image *a, const obs_image *b, int x, int y) {
  const obs_image *im[2] = {a, b};
  for (int k = 0; k < 2; k++) {
    const float *al = obs_image_channel(im[k], "alpha"), *z = obs_image_channel(im[k], "depth.Z");
    size_t c = (size_t)y * (size_t)a->width + (size_t)x;
    for (int dy = -1; dy <= 1; dy++)
      for (int dx = -1; dx <= 1; dx++) {
        int u = x + dx, v = y + dy;
        if (u < 0 || v < 0 || u >= a->width || v >= a->height) continue;
        size_t i = (size_t)v * (size_t)a->width + (size_t)u;
        if (al[i] != al[c]) return 1;
        if (al[c] > 0 && fabs(z[i] - z[c]) > 0.1 * fabs(z[c])) return 1;
      }
  }
  return 0;
}

typedef struct agreement {
  double ao_rmse, final_rmse, depth_rel, normal_max, ao_mean; /* ao_mean: covered, CPU */
  size_t coverage_off, coverage_sil, silhouettes, compared;
} agreement;

/* CPU (a) against Vulkan (b): AO and final RMSE over every pixel, the largest relative depth
 * and normal differences over covered non-silhouette pixels, coverage differences on and off
 * silhouettes. */
static agreement agree(const obs_image *a, const obs_image *b) {
  agreement g = {0};
  size_t n = (size_t)a->width * (size_t)a->height;
  const float *ao[2] = {obs_image_channel(a, "ao"), obs_image_channel(b, "ao")};
  const float *al[2] = {obs_image_channel(a, "alpha"), obs_image_channel(b, "alpha")};
  const float *z[2] = {obs_image_channel(a, "depth.Z"), obs_image_channel(b, "depth.Z")};
  static const char *const fin[3] = {"final.R", "final.G", "final.B"};
  static const char *const nrm[3] = {"normal.X", "normal.Y", "normal.Z"};
  double sa = 0, sf = 0;
  for (size_t i = 0; i < n; i++) {
    int x = (int)(i % (size_t)a->width), y = (int)(i / (size_t)a->width);
    sa += (ao[0][i] - ao[1][i]) * (ao[0][i] - ao[1][i]);
    for (int c = 0; c < 3; c++) {
      double d = obs_image_channel(a, fin[c])[i] - obs_image_channel(b, fin[c])[i];
      sf += d * d / 3;
    }
    int sil = silhouette(a, b, x, y);
    g.silhouettes += sil;
    if (al[0][i] != al[1][i]) {
      if (sil)
        g.coverage_sil++;
      else
        g.coverage_off++;
      continue;
    }
    if (sil || !(al[0][i] > 0)) continue;
    g.compared++;
    g.ao_mean += ao[0][i];
    g.depth_rel = fmax(g.depth_rel, fabs(z[0][i] - z[1][i]) / fabs(z[0][i]));
    for (int c = 0; c < 3; c++)
      g.normal_max = fmax(g.normal_max,
                          fabs(obs_image_channel(a, nrm[c])[i] - obs_image_channel(b, nrm[c])[i]));
  }
  g.ao_rmse = sqrt(sa / (double)n);
  if (g.compared) g.ao_mean /= (double)g.compared;
  g.final_rmse = sqrt(sf / (double)n);
  return g;
}

typedef struct vcase {
  const char *label, *camera;
  int w, h, spp;
  const char *rest, *params;
} vcase;

static void compare_case(const vcase *c) {
  obs_result cpu, vk;
  render(c->camera, c->w, c->h, c->spp, two_volumes(), c->rest, c->params, "cpu", &cpu);
  render(c->camera, c->w, c->h, c->spp, two_volumes(), c->rest, c->params, "vulkan", &vk);
  agreement g = agree(&cpu.image, &vk.image);
  printf(
      "%-34s AO mean %.3f, RMSE %.2e  final RMSE %.2e  depth rel %.2e  normal %.2e  "
      "coverage %zu+%zu  (%zu compared, %zu silhouette px)\n",
      c->label, g.ao_mean, g.ao_rmse, g.final_rmse, g.depth_rel, g.normal_max, g.coverage_off,
      g.coverage_sil, g.compared, g.silhouettes);
  assert_true(g.compared >= (size_t)(c->w * c->h) / 16);
  assert_true(g.ao_mean < 0.98); /* the volumes do occlude each other */
  assert_true(g.ao_rmse <= AO_RMSE_MAX);
  assert_true(g.depth_rel <= DEPTH_REL);
  assert_int_equal(g.coverage_off, 0);
  /* Shading from the same hits and directions: a far looser bound than AO's, as a guard. */
  assert_true(g.final_rmse <= 0.05);
  assert_true(vk.rays > 0);
  obs_result_free(&cpu);
  obs_result_free(&vk);
}

static void test_against_cpu(void **state) {
  (void)state;
  vktest_need_vk();
  char lights[512];
  snprintf(lights, sizeof lights,
           ", %s, \"lights\": [{\"type\": \"point\", \"position\": [1.5, 2, -1.5], "
           "\"emission\": [3, 3, 3]}, {\"type\": \"directional\", \"direction\": [-0.4, -1, 0.5], "
           "\"emission\": [0.6, 0.5, 0.4]}]",
           SKY);
  const vcase cases[] = {
      {"lookup, sobol, point+directional", PERSP, 48, 40, 1, lights,
       "\"samples\": 32, \"ibl\": \"bent_normal_lookup\""},
      {"irradiance, blinn_phong, halton", PERSP, 48, 40, 1, lights,
       "\"samples\": 32, \"ibl\": \"irradiance\", \"shading\": \"blinn_phong\", "
       "\"sampler\": \"halton\", \"seed\": 7"},
      {"reference, crossing any, random", PERSP, 48, 40, 1, lights,
       "\"samples\": 32, \"ibl\": \"reference\", \"crossing\": \"any\", \"sampler\": \"random\""},
      {"none, orthographic, spp 2", ORTHO_X, 40, 40, 2, lights,
       "\"samples\": 16, \"ibl\": \"none\", \"step\": 0.02, \"max_distance\": 0.5"},
      {"lookup, no environment, 64 samples", PERSP, 32, 32, 1, "", "\"samples\": 64"},
      /* Far past lavapipe's 65535 loop iterations per invocation: split across dispatches. */
      {"irradiance, 1600 samples, close-up", CLOSE, 12, 12, 1, lights,
       "\"samples\": 1600, \"ibl\": \"irradiance\""},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) compare_case(&cases[i]);
}

/* A lone sphere is convex: AO is exactly 1 at every covered pixel. */
static void test_lone_sphere_open(void **state) {
  (void)state;
  vktest_need_vk();
  obs_result res;
  render(ORTHO_X, 32, 32, 1, volume_obj("sphere", 64, "", 2, 0, 0, 0), "", "\"samples\": 64",
         "vulkan", &res);
  const float *ao = obs_image_channel(&res.image, "ao"),
              *al = obs_image_channel(&res.image, "alpha");
  const float *nx = obs_image_channel(&res.image, "normal.X"),
              *bx = obs_image_channel(&res.image, "bent_normal.X");
  int covered = 0;
  for (int i = 0; i < 32 * 32; i++) {
    assert_true(ao[i] == 1.0f);
    if (al[i] < 1) continue;
    covered++;
    assert_true(nx[i] > 0 && bx[i] > 0);
  }
  assert_true(covered > 150);
  obs_result_free(&res);
}

/* Under a constant white environment and no lights every ibl method gives final = AO (and none
 * gives 0). */
static void test_white_environment(void **state) {
  (void)state;
  vktest_need_vk();
  static const char *const ibls[] = {"bent_normal_lookup", "irradiance", "reference", "none"};
  for (int m = 0; m < 4; m++) {
    char params[128];
    snprintf(params, sizeof params, "\"samples\": 16, \"ibl\": \"%s\"", ibls[m]);
    obs_result res;
    render(ORTHO_X, 24, 24, 1,
           obs_test_fmt("%s, %s", volume_obj("sphere", 48, "", 2, 0, 0, 0),
                        volume_obj("torus", 48, "", 1.5, 0.9, 0, 0)),
           ", \"environment\": {\"color\": [1, 1, 1]}", params, "vulkan", &res);
    const float *ao = obs_image_channel(&res.image, "ao"),
                *al = obs_image_channel(&res.image, "alpha");
    int occluded = 0;
    double worst = 0;
    for (int c = 0; c < 3; c++) {
      const float *f = obs_image_channel(&res.image, c == 0   ? "final.R"
                                                     : c == 1 ? "final.G"
                                                              : "final.B");
      for (int i = 0; i < 24 * 24; i++) {
        if (al[i] < 1) continue;
        occluded += ao[i] < 1;
        worst = fmax(worst, fabs(f[i] - (m < 3 ? ao[i] : 0.0f)));
      }
    }
    printf("white environment, %s: max |final - AO| %.2e\n", ibls[m], worst);
    assert_true(worst <= 1e-4);
    assert_true(occluded > 0);
    obs_result_free(&res);
  }
}

/* A region rendered alone has the whole render's bits there and zeros elsewhere. */
static void test_region(void **state) {
  (void)state;
  vktest_need_vk();
  char *doc = scene_doc(PERSP, 40, 32, 1, two_volumes(), obs_test_fmt(", %s", SKY),
                        "\"samples\": 8", "vulkan");
  obs_scene sc;
  obs_test_load(doc, "region.json", &sc);
  obs_result whole, part;
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 2};
  vktest_check_rc(obs_render(&sc, &o, &whole, &err), &err);
  o.region = (obs_region){5, 3, 29, 30};
  vktest_check_rc(obs_render(&sc, &o, &part, &err), &err);
  vktest_assert_region(&whole, &part, o.region);
  obs_result_free(&whole);
  obs_result_free(&part);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free(doc);
}

/* The AO's standard error on Vulkan, held to the CPU's check (stderr_check.h): replicates and the
 * pooled prior's pilots rendered on the device. */
static void test_stderr_calibrated(void **state) {
  (void)state;
  vktest_need_vk();
  static const obs_stderr_case c = {"volume_ao sobol (vulkan)", "scenes/volume_torus.json",
                                    "volume_ao", "vulkan",
                                    "{\"samples\":$N,\"sampler\":\"sobol\",\"seed\":$S}", "ao",
                                    "ao_stderr", 0, 64};
  obs_test_stderr_check(&c, 16);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_against_cpu, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_lone_sphere_open, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_white_environment, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_region, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_stderr_calibrated, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
