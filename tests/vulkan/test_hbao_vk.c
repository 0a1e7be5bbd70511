/* hbao on Vulkan against its CPU twin: identical G-buffers through both implementations, the full
 * pipelines (rasterised vs ray-cast G-buffer), analytic cases and extremes, all under validation. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "vktest.h"
#include "screen_rule_cases.h"
#include "vk.h"

#include "hbao.h"

/* A scene document (own buffer): camera, image size, objects (array body), backend, params. */
static const char *scene(const char *camera, int w, int h, const char *objects, const char *backend,
                         const char *params) {
  static char buf[8192];
  snprintf(buf, sizeof buf,
           "{\"camera\":%s,\"image\":{\"width\":%d,\"height\":%d},\"objects\":[%s],"
           "\"technique\":{\"name\":\"hbao\",\"backend\":\"%s\",\"params\":%s}}",
           camera, w, h, objects, backend, params);
  return buf;
}

/* A Cornell-like room with two blocks and a sphere. */
static const char *ROOM =
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[556,0,0],[0,0,0],[0,0,559],[556,0,559]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,559],[556,0,559],[556,548,559],[0,548,559]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,0,559],[0,548,559],[0,548,0]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[556,0,0],[556,548,0],[556,548,559],[556,0,559]]}},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,548,0],[0,548,559],[556,548,559],[556,548,0]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[100,0,100],\"max\":[250,165,300]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[300,0,300],\"max\":[450,330,450]},"
    "\"transform\":{\"rotate\":[0,15,0]}},"
    "{\"shape\":{\"type\":\"sphere\",\"center\":[380,60,150],\"radius\":60}}";
static const char *ROOM_CAM = "{\"type\":\"perspective\",\"position\":[278,273,-800],"
                              "\"look_at\":[278,273,0],\"fov_y\":40}";
static const char *DSPHERE = "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":7}},"
                             "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-5,-1.2,-5],[-5,-1.2,5],"
                             "[5,-1.2,5],[5,-1.2,-5]]}}";
static const char *DSPHERE_CAM = "{\"type\":\"perspective\",\"position\":[0.4,1.5,-3.2],"
                                 "\"look_at\":[0,-0.2,0],\"fov_y\":45}";

static void load(const char *json, obs_scene *sc) { obs_test_load(json, "hbao_vk.json", sc); }

static void assert_unit(const float *a, size_t n) {
  for (size_t i = 0; i < n; i++) assert_true(isfinite(a[i]) && a[i] >= 0.0f && a[i] <= 1.0f);
}

typedef struct diff {
  double rmse, max;
  size_t over, exact, n; /* pixels differing by > 1e-2, bit-equal pixels, all pixels */
} diff;

static diff compare(const float *a, const float *b, size_t n) {
  diff d = {0, 0, 0, 0, n};
  for (size_t i = 0; i < n; i++) {
    double e = fabs((double)a[i] - (double)b[i]);
    d.rmse += e * e;
    d.max = fmax(d.max, e);
    d.over += e > 1e-2;
    d.exact += a[i] == b[i];
  }
  d.rmse = sqrt(d.rmse / (double)n);
  return d;
}

/* Both implementations on one (ray-cast) G-buffer; returns the differences of ao and ao_raw. */
static void cross_backend(const obs_gbuffer *g, const obs_hbao_params *p, diff *dao, diff *draw) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  size_t n = (size_t)g->width * (size_t)g->height;
  float *buf = malloc(4 * n * sizeof(float));
  assert_non_null(buf);
  float *cpu = buf, *cpu_raw = buf + n, *gpu = buf + 2 * n, *gpu_raw = buf + 3 * n;
  double cms[OBS_HBAO_PASS_COUNT], gms[OBS_HBAO_PASS_COUNT + 1];
  vktest_check_rc(obs_hbao_cpu_apply_ex(g, p, 2, cpu, cpu_raw, cms, &err), &err);
  obs_vk_gbuffer dg;
  memset(&dg, 0, sizeof dg);
  vktest_check_rc(obs_vk_gbuffer_upload(vk, g, &dg, &err), &err);
  obs_hbao_projection proj = obs_hbao_projection_of(g);
  vktest_check_rc(obs_hbao_vk_apply_ex(vk, &dg, &proj, p, gpu, gpu_raw, gms, &err), &err);
  obs_vk_gbuffer_free(vk, &dg);
  assert_unit(buf, 4 * n);
  *dao = compare(cpu, gpu, n);
  *draw = compare(cpu_raw, gpu_raw, n);
  /* Uncovered pixels are exactly 1 on both. */
  for (size_t i = 0; i < n; i++)
    if (!(g->depth[i] > 0.0f)) assert_true(cpu[i] == 1.0f && gpu[i] == 1.0f && gpu_raw[i] == 1.0f);
  free(buf);
  obs_err_free(&err);
}

/* A comparison flip (a horizon test landing on the other side by one rounding) moves one texel's
 * raw AO by up to W(r) (sin h - sin h'), which can exceed 1e-2; the passes are written to make the
 * bits equal, so flips must stay rare: at most 0.1 % of the pixels. */
static void assert_agree(const char *label, const diff *d) {
  printf("%-44s rmse %.2e  max %.2e  >1e-2: %zu of %zu  bit-equal %.2f %%\n", label, d->rmse,
         d->max, d->over, d->n, 100.0 * (double)d->exact / (double)d->n);
  assert_true(d->rmse <= 1e-3);
  assert_true((double)d->over <= 1e-3 * (double)d->n);
  if (d->over == 0) assert_true(d->max <= 1e-2);
}

static void run_sets(const char *name, const char *json) {
  obs_scene sc;
  load(json, &sc);
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
  /* The documented settings (directions/steps 4/4, 8/8, 16/16) and the options around them. */
  struct {
    int dirs, steps, blur, half;
    float bias, sharp, radius_scale;
  } sets[] = {
      {4, 4, 4, 0, 0.5235988f, 16, 1},   {8, 8, 4, 0, 0.5235988f, 16, 1},
      {16, 16, 4, 0, 0.5235988f, 16, 1}, {8, 8, 0, 0, 0.0f, 16, 1},
      {8, 8, 4, 1, 0.5235988f, 16, 1},   {16, 16, 16, 1, 0.2f, 0, 2},
      {32, 32, 2, 0, 0.1f, 1e6f, 0.5f},
  };
  obs_hbao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
  float base_radius = json_number_value(json_object_get(sc.params, "radius"));
  for (size_t k = 0; k < sizeof sets / sizeof sets[0]; k++) {
    p.directions = sets[k].dirs;
    p.steps = sets[k].steps;
    p.blur_radius = sets[k].blur;
    p.half_res = sets[k].half;
    p.angle_bias = sets[k].bias;
    p.blur_sharpness = sets[k].sharp;
    p.radius = base_radius * sets[k].radius_scale;
    diff a, r;
    cross_backend(&g, &p, &a, &r);
    char label[128];
    snprintf(label, sizeof label, "%s %d/%d blur %d half %d bias %.2f: ao", name, p.directions,
             p.steps, p.blur_radius, p.half_res, p.angle_bias);
    assert_agree(label, &a);
    snprintf(label, sizeof label, "%s %d/%d blur %d half %d bias %.2f: ao_raw", name, p.directions,
             p.steps, p.blur_radius, p.half_res, p.angle_bias);
    assert_agree(label, &r);
  }
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_cross_room(void **state) {
  (void)state;
  vktest_need_vk();
  run_sets("room", scene(ROOM_CAM, 96, 80, ROOM, "cpu", "{\"radius\":80}"));
  run_sets("room ortho",
           scene("{\"type\":\"orthographic\",\"position\":[278,500,-600],\"look_at\":[278,200,0],"
                 "\"height\":700}",
                 80, 64, ROOM, "cpu", "{\"radius\":60}"));
}

static void test_cross_displaced_sphere(void **state) {
  (void)state;
  vktest_need_vk();
  run_sets("displaced_sphere", scene(DSPHERE_CAM, 96, 80, DSPHERE, "cpu", "{\"radius\":0.4}"));
}

/* Renders a document through obs_render (validation from $OBSCURA_VK_VALIDATION, which ctest sets:
 * the Vulkan render fails on any message). */
static void render(const char *json, obs_result *r) {
  obs_test_render(json, 2, r);
  obs_test_assert_finite(&r->image);
  size_t n = (size_t)r->image.width * (size_t)r->image.height;
  const float *al = obs_image_channel(&r->image, "alpha");
  const float *ao = obs_image_channel(&r->image, "ao"), *raw = obs_image_channel(&r->image, "ao_raw");
  assert_unit(ao, n);
  assert_unit(raw, n);
  for (size_t i = 0; i < n; i++)
    if (al[i] == 0.0f) assert_true(ao[i] == 1.0f && raw[i] == 1.0f);
}

/* The full pipelines: rasterised vs ray-cast G-buffer. They differ on silhouettes (a pixel centre
 * covered by one and not the other, or by different surfaces) and where facets of tessellated
 * spheres differ from the analytic ones; elsewhere the AO agrees. */
static void full_pipeline(const char *name, const char *camera, const char *objects,
                          const char *params, int w, int h) {
  vktest_need_vk();
  obs_result c, v;
  char *cam = strdup(camera), *obj = strdup(objects), *par = strdup(params);
  render(scene(cam, w, h, obj, "cpu", par), &c);
  render(scene(cam, w, h, obj, "vulkan", par), &v);
  assert_int_equal(c.backend, OBS_BACKEND_CPU);
  assert_int_equal(v.backend, OBS_BACKEND_VULKAN);
  size_t n = (size_t)w * (size_t)h, bad = 0, cov = 0, cov_diff = 0;
  const float *a = obs_image_channel(&c.image, "ao"), *b = obs_image_channel(&v.image, "ao");
  const float *ca = obs_image_channel(&c.image, "alpha"), *va = obs_image_channel(&v.image, "alpha");
  double s = 0;
  for (size_t i = 0; i < n; i++) {
    double d = fabs((double)a[i] - (double)b[i]);
    bad += d > 0.05;
    s += d * d;
    cov += ca[i] > 0;
    cov_diff += ca[i] != va[i];
  }
  double frac = (double)bad / (double)n;
  printf("%-28s %dx%d: %.2f %% of pixels differ by > 0.05 (coverage differs on %zu of %zu covered), "
         "rmse %.4f; stages vulkan:",
         name, w, h, 100.0 * frac, cov_diff, cov, sqrt(s / (double)n));
  for (int i = 0; i < v.nstages; i++) printf(" %s=%.2fms", v.stage_names[i], v.stage_ms[i]);
  printf("\n");
  assert_true(frac < 0.05);
  obs_result_free(&c);
  obs_result_free(&v);
  free(cam);
  free(obj);
  free(par);
}

static void test_full_pipeline(void **state) {
  (void)state;
  full_pipeline("room", ROOM_CAM, ROOM, "{\"radius\":80}", 96, 80);
  full_pipeline("room half_res", ROOM_CAM, ROOM, "{\"radius\":80,\"half_res\":true}", 96, 80);
  full_pipeline("displaced_sphere", DSPHERE_CAM, DSPHERE, "{\"radius\":0.4}", 96, 80);
  full_pipeline("displaced_sphere 16/16", DSPHERE_CAM, DSPHERE,
                "{\"radius\":0.4,\"directions\":16,\"steps\":16,\"blur_radius\":0}", 96, 80);
}

/* Analytic cases on the device: a plane is 1, an empty frame is 1, a tiny radius exits with 1. */
static void test_analytic(void **state) {
  (void)state;
  vktest_need_vk();
  const char *plane = "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1000,0,-1000],[-1000,0,1000],"
                      "[1000,0,1000],[1000,0,-1000]]}}";
  const char *cams[] = {
      "{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],\"fov_y\":90}",
      "{\"type\":\"orthographic\",\"position\":[1,0.4,-5],\"look_at\":[0,0,0],\"height\":3}"};
  const char *params[] = {"{\"blur_radius\":0}", "{\"angle_bias\":0}"};
  for (int c = 0; c < 2; c++)
    for (int k = 0; k < 2; k++) {
      obs_result r;
      render(scene(cams[c], 40, 30, plane, "vulkan", params[k]), &r);
      const float *ao = obs_image_channel(&r.image, "ao");
      for (int i = 0; i < 40 * 30; i++) {
        if (k == 0) assert_true(ao[i] == 1.0f);
        else assert_true(ao[i] >= 1.0f - 1e-4f);
      }
      obs_result_free(&r);
    }
  obs_result r;
  render(scene("{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":60}",
               17, 9, "{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,-5],\"radius\":1}}",
               "vulkan", "{\"half_res\":true}"),
         &r);
  for (int i = 0; i < 17 * 9; i++) assert_true(r.image.data[i] == 1.0f);
  obs_result_free(&r);
  char *cam = strdup(ROOM_CAM);
  render(scene(cam, 32, 32, ROOM, "vulkan", "{\"radius\":1e-6}"), &r);
  free(cam);
  for (int i = 0; i < 32 * 32; i++) assert_true(r.image.data[i] == 1.0f);
  obs_result_free(&r);
}

/* Extremes through both backends' full renders, and through the apply on the validated device. */
static void test_extremes(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  const char *params[] = {"{\"radius\":1e-6}",
                          "{\"radius\":1e6}",
                          "{\"radius\":1e30,\"half_res\":true,\"blur_radius\":16}",
                          "{\"directions\":1,\"steps\":1,\"blur_radius\":0}",
                          "{\"directions\":32,\"steps\":32,\"angle_bias\":1.5707963}",
                          "{\"scale\":1e6,\"blur_sharpness\":1e6,\"half_res\":true}"};
  struct {
    const char *cam, *objects;
    int w, h;
  } scenes[] = {
      {"{\"type\":\"perspective\",\"position\":[0,1e-3,0],\"look_at\":[0,0,1],\"fov_y\":60}",
       "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e3,0,1e-3],[-1e3,0,1e3],[1e3,0,1e3],"
       "[1e3,0,1e-3]]}},{\"shape\":{\"type\":\"sphere\",\"center\":[0,0.5,3],\"radius\":0.5}}",
       24, 24},
      {"{\"type\":\"perspective\",\"position\":[0.1,0.2,0.3],\"look_at\":[1,0,0.5],\"fov_y\":120}",
       "{\"shape\":{\"type\":\"box\",\"min\":[-1,-1,-1],\"max\":[1,1,1]}}", 24, 24},
      {"{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":60}",
       "{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,-5],\"radius\":1}}", 8, 8},
      {ROOM_CAM, ROOM, 1, 1},
      {ROOM_CAM, ROOM, 4096, 16},
  };
  for (size_t s = 0; s < sizeof scenes / sizeof scenes[0]; s++)
    for (size_t k = 0; k < sizeof params / sizeof params[0]; k++) {
      if (scenes[s].w == 4096 && k != 1 && k != 4) continue; /* keep the wide image cheap */
      for (int be = 0; be < 2; be++) {
        obs_result r;
        render(scene(scenes[s].cam, scenes[s].w, scenes[s].h, scenes[s].objects,
                     be ? "vulkan" : "cpu", params[k]),
               &r);
        obs_result_free(&r);
      }
      /* And the two applies on the same G-buffer, on the validated device. */
      obs_scene sc;
      load(scene(scenes[s].cam, scenes[s].w, scenes[s].h, scenes[s].objects, "cpu", params[k]),
           &sc);
      obs_hbao_params p;
      assert_int_equal(obs_params_bind(obs_technique_find("hbao"), sc.params, &p, NULL), 0);
      obs_gbuffer g;
      obs_err err = OBS_ERR_INIT;
      vktest_check_rc(obs_gbuffer_raycast(&sc, &g, 2, NULL, NULL, &err), &err);
      diff a, r;
      cross_backend(&g, &p, &a, &r);
      assert_true(a.rmse <= 1e-3 && r.rmse <= 1e-3);
      obs_gbuffer_free(&g);
      obs_scene_free(&sc);
      obs_err_free(&err);
      assert_int_equal(obs_vk_validation_messages(vk), 0);
    }
}

/* The ball on a ground quad (vktest_moved_scene) at 48x48, hbao with `params` (a format taking the
 * radius), rendered by `backend`. */
static void moved_render(double s, double t, double g, double fov, const char *backend,
                         const char *params, double radius, obs_result *r) {
  char body[4096], par[256], doc[8192];
  vktest_moved_scene(s, t, g, fov, body, sizeof body);
  snprintf(par, sizeof par, params, radius);
  snprintf(doc, sizeof doc,
           "{%s,\"image\":{\"width\":48,\"height\":48},\"technique\":{\"name\":\"hbao\","
           "\"backend\":\"%s\",\"params\":%s}}",
           body, backend, par);
  render(doc, r);
}

/* Far from the world origin and at extreme scales (radius scaled alike) each backend's render
 * equals its render at the origin and scale 1. Measured: 4.8e-7 at most on Vulkan, 3.0e-7 on the
 * CPU (the G-buffers' float rounding); asserted: 1e-5, on every pixel. */
static void test_moved_and_scaled(void **state) {
  (void)state;
  vktest_need_vk();
  const double cases[][2] = {{1, 1e6}, {1, 1e7}, {1, 1e9}, {1e-9, 0}, {1e9, 0}, {1e9, 1e9}};
  const char *backends[] = {"vulkan", "cpu"};
  for (int b = 0; b < 2; b++) {
    obs_result ref;
    moved_render(1, 0, 20, 30, backends[b], "{\"radius\":%.17g}", 1.0, &ref);
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
      obs_result r;
      moved_render(cases[c][0], cases[c][1], 20, 30, backends[b], "{\"radius\":%.17g}",
                   cases[c][0], &r);
      double mx;
      size_t over;
      vktest_ao_diff(&ref, &r, "ao", 1e-5, &mx, &over);
      printf("hbao %s scale %g translate %g: max |ao - ao(origin, scale 1)| = %.2e\n",
             backends[b], cases[c][0], cases[c][1], mx);
      assert_int_equal(over, 0);
      obs_result_free(&r);
    }
    obs_result_free(&ref);
  }
}

/* Radii far beyond the scene: a plane reads 1, and a ball on the plane reads what a radius just
 * beyond the scene gives (the falloff 1 - d^2 is 1 for all of it), on both backends; the two
 * backends agree as their G-buffers do. */
static void test_huge_radius(void **state) {
  (void)state;
  vktest_need_vk();
  const char *backends[] = {"vulkan", "cpu"};
  obs_result huge[2];
  for (int b = 0; b < 2; b++) {
    const double radii[] = {1e25, 1e30};
    for (int k = 0; k < 2; k++) {
      obs_result flat;
      /* A ball 1e3 under the ground is hidden: only the plane is seen. */
      char body[4096], doc[8192];
      vktest_moved_scene(1, 0, 20, 30, body, sizeof body);
      char *ball = strstr(body, "\"center\":[");
      assert_non_null(ball);
      strcpy(ball, "\"center\":[0,-1e3,0],\"radius\":0.5}}]");
      snprintf(doc, sizeof doc,
               "{%s,\"image\":{\"width\":48,\"height\":48},\"technique\":{\"name\":\"hbao\","
               "\"backend\":\"%s\",\"params\":{\"radius\":%g}}}",
               body, backends[b], radii[k]);
      render(doc, &flat);
      const float *ao = obs_image_channel(&flat.image, "ao");
      for (int i = 0; i < 48 * 48; i++) assert_true(ao[i] == 1.0f);
      obs_result_free(&flat);
    }
    obs_result near;
    moved_render(1, 0, 20, 30, backends[b], "{\"radius\":%.17g}", 1e6, &near);
    moved_render(1, 0, 20, 30, backends[b], "{\"radius\":%.17g}", 1e25, &huge[b]);
    double mx;
    size_t over;
    vktest_ao_diff(&near, &huge[b], "ao", 1e-5, &mx, &over);
    const float *ao = obs_image_channel(&huge[b].image, "ao");
    float lo = 1.0f;
    for (int i = 0; i < 48 * 48; i++) lo = fminf(lo, ao[i]);
    printf("hbao %s radius 1e25: min ao %.4f, max |ao - ao(radius 1e6)| = %.2e\n", backends[b],
           lo, mx);
    assert_true(lo < 0.9f); /* the ball occludes the ground */
    assert_int_equal(over, 0);
    obs_result_free(&near);
  }
  /* Vulkan against the CPU: rasterised and ray-cast G-buffers differ on silhouettes only. */
  double mx;
  size_t over;
  vktest_ao_diff(&huge[0], &huge[1], "ao", 0.05, &mx, &over);
  printf("hbao radius 1e25: vulkan vs cpu: %zu of %d pixels differ by > 0.05 (max %.3f)\n", over,
         48 * 48, mx);
  assert_true(over <= 48 * 48 / 20);
  obs_result_free(&huge[0]);
  obs_result_free(&huge[1]);
}

/* Fields of view down to 1e-4 degrees: a pixel's footprint is then a few ulps of depth, which the
 * horizon search must not read as occlusion. A flat patch reads 1 on both backends. */
static void test_tiny_fov(void **state) {
  (void)state;
  vktest_need_vk();
  const char *plane = "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-10,0,-10],[-10,0,10],"
                      "[10,0,10],[10,0,-10]]}}";
  const char *cams[] = {
      "{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],\"fov_y\":1e-4}",
      "{\"type\":\"perspective\",\"position\":[0,2,-3],\"look_at\":[0,0,0],\"fov_y\":1e-2}",
      "{\"type\":\"perspective\",\"position\":[0,5,0.1],\"look_at\":[0,0,0],\"fov_y\":1e-4}"};
  const char *params[] = {"{\"radius\":1e-5}", "{\"radius\":1,\"blur_radius\":0}",
                          "{\"radius\":1e-6,\"directions\":16,\"steps\":16}"};
  const char *backends[] = {"vulkan", "cpu"};
  for (int b = 0; b < 2; b++)
    for (int c = 0; c < 3; c++)
      for (int k = 0; k < 3; k++) {
        obs_result r;
        char *cam = strdup(cams[c]);
        render(scene(cam, 32, 32, plane, backends[b], params[k]), &r);
        free(cam);
        const float *ao = obs_image_channel(&r.image, "ao");
        const float *al = obs_image_channel(&r.image, "alpha");
        for (int i = 0; i < 32 * 32; i++) {
          assert_true(al[i] == 1.0f);
          assert_true(ao[i] == 1.0f);
        }
        obs_result_free(&r);
      }
}

/* Bad arguments fail cleanly with a message. */
static void test_errors(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_hbao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("hbao"), NULL, &p, NULL), 0);
  obs_vk_gbuffer dg;
  memset(&dg, 0, sizeof dg);
  float out[4];
  obs_hbao_projection proj = {0, 1.0f, 1.0f};
  assert_int_equal(obs_hbao_vk_apply(vk, &dg, &proj, &p, out, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "hbao"));
  obs_err_free(&err);
}

/* The screen-space rule on Vulkan: the same cases and words as on the CPU. */
static void test_screen_rule(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_screen_rule_hbao_cases(OBS_BACKEND_VULKAN), 0);
}

int main(void) {
  /* The loader's own debug output would be counted as validation messages. */
  unsetenv("VK_LOADER_DEBUG");
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_cross_room, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_cross_displaced_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_full_pipeline, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_analytic, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_extremes, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_errors, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_moved_and_scaled, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_huge_radius, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_tiny_fov, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_screen_rule, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
