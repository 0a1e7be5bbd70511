/* The Vulkan device layer and rasterised G-buffer: image round trips, compute passes, and the
 * G-buffer against the CPU ray caster, all under the validation layer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"
#include "geometry.h"
#include "raytrace.h"
#include "shaders.h"
#include "vktest.h"
#include "vk.h"
#include "vk_internal.h"

#define PI 3.14159265358979323846

/* ---- device and images ---- */

static void test_filter_matches_nothing(void **state) {
  (void)state;
  vktest_need_vk();
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_vk_open(&vk, "no-such-gpu-xyzzy", 1, &err);
  assert_int_equal(rc, OBS_EUNSUPPORTED);
  assert_null(vk);
  assert_non_null(strstr(obs_err_message(&err), "no-such-gpu-xyzzy"));
  obs_err_free(&err);
}

static void test_device_name(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  assert_true(strlen(obs_vk_device_name(vk)) > 0);
  assert_true(obs_vk_validation_requested() || getenv("OBSCURA_VK_VALIDATION") == NULL);
}

static void roundtrip(int w, int h, int ch) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  size_t n = (size_t)w * (size_t)h * (size_t)ch;
  float *in = malloc(n * sizeof *in), *out = malloc(n * sizeof *out);
  assert_non_null(in);
  assert_non_null(out);
  /* Bit patterns that must survive untouched: signed zeros, denormals, NaN payloads, infinities. */
  uint32_t s = 12345u;
  for (size_t i = 0; i < n; i++) {
    s = s * 1664525u + 1013904223u;
    uint32_t bits = s;
    if (i % 7 == 0) bits = 0x80000000u;
    if (i % 11 == 0) bits = 0x00000001u;
    if (i % 13 == 0) bits = 0x7fc01234u;
    if (i % 17 == 0) bits = 0xff800000u;
    memcpy(&in[i], &bits, 4);
  }
  memset(out, 0xAB, n * sizeof *out);
  obs_vk_image *img = NULL;
  vktest_check_rc(obs_vk_image_create(vk, w, h, ch, &img, &err), &err);
  /* New images read back as zeros. */
  vktest_check_rc(obs_vk_image_download(vk, img, out, &err), &err);
  for (size_t i = 0; i < n; i++) assert_true(out[i] == 0.0f);
  vktest_check_rc(obs_vk_image_upload(vk, img, in, &err), &err);
  vktest_check_rc(obs_vk_image_download(vk, img, out, &err), &err);
  assert_memory_equal(in, out, n * sizeof *in);
  obs_vk_image_free(vk, img);
  free(in);
  free(out);
  obs_err_free(&err);
}

static void test_roundtrip(void **state) {
  (void)state;
  const int sizes[][2] = {{1, 1}, {37, 13}, {4096, 16}};
  for (int i = 0; i < 3; i++) {
    roundtrip(sizes[i][0], sizes[i][1], 1);
    roundtrip(sizes[i][0], sizes[i][1], 4);
  }
}

static void test_image_errors(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_vk_image *img = NULL;
  assert_int_equal(obs_vk_image_create(vk, 4, 4, 3, &img, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "3 channels"));
  assert_int_equal(obs_vk_image_create(vk, 0, 4, 1, &img, &err), OBS_EINVAL);
  assert_int_equal(obs_vk_image_create(vk, 1 << 20, 1, 1, &img, &err), OBS_EINVAL);
  assert_null(img);
  /* 16384 x 16384 x 4 floats is 4 GiB: more than one allocation may hold on lavapipe; whatever the
   * device, it either works or fails cleanly with OBS_ENOMEM. */
  obs_err_clear(&err);
  int rc = obs_vk_image_create(vk, 16384, 16384, 4, &img, &err);
  if (rc) {
    assert_int_equal(rc, OBS_ENOMEM);
    assert_non_null(strstr(obs_err_message(&err), "16384x16384"));
    assert_null(img);
  }
  obs_vk_image_free(vk, img);
  obs_err_free(&err);
}

/* Device loss and out-of-memory cannot be provoked on demand, so the one place every Vulkan result
 * goes through is driven directly: each failure is an error code with a message, and after a loss
 * every later call fails at once instead of waiting on a device that will never answer. */
static void test_error_results(void **state) {
  (void)state;
  vktest_need_vk();
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_vk_open(&vk, NULL, 1, &err), &err);
  assert_int_equal(obs_vk_check(vk, VK_ERROR_OUT_OF_DEVICE_MEMORY, "vkAllocateMemory (test)", &err),
                   OBS_ENOMEM);
  assert_non_null(strstr(obs_err_message(&err), "VK_ERROR_OUT_OF_DEVICE_MEMORY"));
  assert_int_equal(obs_vk_check(vk, VK_ERROR_OUT_OF_HOST_MEMORY, "x", &err), OBS_ENOMEM);
  obs_vk_image *img = NULL;
  vktest_check_rc(obs_vk_image_create(vk, 8, 8, 1, &img, &err), &err); /* still usable after OOM */
  obs_err_clear(&err);
  assert_int_equal(obs_vk_check(vk, VK_ERROR_DEVICE_LOST, "vkQueueSubmit (test)", &err),
                   OBS_EINTERNAL);
  assert_non_null(strstr(obs_err_message(&err), "VK_ERROR_DEVICE_LOST"));
  float px[64] = {0};
  obs_err_clear(&err);
  assert_int_equal(obs_vk_image_upload(vk, img, px, &err), OBS_EINTERNAL);
  assert_non_null(strstr(obs_err_message(&err), "lost"));
  obs_vk_image *img2 = NULL;
  assert_int_equal(obs_vk_image_create(vk, 8, 8, 1, &img2, &err), OBS_EINTERNAL);
  assert_null(img2);
  obs_vk_pass p = {.name = "after-loss"};
  assert_int_equal(obs_vk_run(vk, &p, 1, NULL, &err), OBS_EINTERNAL);
  obs_vk_image_free(vk, img);
  assert_int_equal(obs_vk_validation_messages(vk), 0);
  obs_vk_close(vk);
  obs_err_free(&err);
}

/* ---- compute ---- */

typedef struct scale_push {
  float factor;
  int32_t width, height;
} scale_push;

static void test_compute_scale(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  const int w = 67, h = 45;
  size_t n = (size_t)w * h * 4;
  float *in = malloc(n * sizeof *in), *out = malloc(n * sizeof *out);
  assert_non_null(in);
  assert_non_null(out);
  for (size_t i = 0; i < n; i++) in[i] = (float)i * 0.25f - 100.0f;
  obs_vk_image *a = NULL, *b = NULL, *c = NULL;
  vktest_check_rc(obs_vk_image_create(vk, w, h, 4, &a, &err), &err);
  vktest_check_rc(obs_vk_image_create(vk, w, h, 4, &b, &err), &err);
  vktest_check_rc(obs_vk_image_create(vk, w, h, 4, &c, &err), &err);
  vktest_check_rc(obs_vk_image_upload(vk, a, in, &err), &err);
  /* Two dependent passes in one submission: b = 3a, then c = 0.5b (the barrier between them). */
  scale_push p1 = {3.0f, w, h}, p2 = {0.5f, w, h};
  obs_vk_pass passes[2] = {{.name = "scale3",
                            .spirv = obs_spv_test_scale_comp,
                            .spirv_size = obs_spv_test_scale_comp_size,
                            .images = {a, b},
                            .nimages = 2,
                            .push = &p1,
                            .push_size = sizeof p1,
                            .groups_x = (w + 7) / 8,
                            .groups_y = (h + 7) / 8},
                           {.name = "half",
                            .spirv = obs_spv_test_scale_comp,
                            .spirv_size = obs_spv_test_scale_comp_size,
                            .images = {b, c},
                            .nimages = 2,
                            .push = &p2,
                            .push_size = sizeof p2,
                            .groups_x = (w + 7) / 8,
                            .groups_y = (h + 7) / 8}};
  double ms[2] = {-1, -1};
  for (int rep = 0; rep < 2; rep++) { /* the second run reuses the cached pipeline */
    vktest_check_rc(obs_vk_run(vk, passes, 2, ms, &err), &err);
    fprintf(stderr, "pass times: %.4f ms, %.4f ms\n", ms[0], ms[1]);
    assert_true(ms[0] > 0 && ms[1] > 0);
    vktest_check_rc(obs_vk_image_download(vk, c, out, &err), &err);
    for (size_t i = 0; i < n; i++) assert_true(out[i] == in[i] * 3.0f * 0.5f);
  }
  /* Bad passes fail with messages naming the pass. */
  obs_vk_pass bad = passes[0];
  bad.push_size = 130;
  assert_int_equal(obs_vk_run(vk, &bad, 1, NULL, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "scale3"));
  bad = passes[0];
  bad.nimages = OBS_VK_MAX_BINDINGS + 1;
  assert_int_equal(obs_vk_run(vk, &bad, 1, NULL, &err), OBS_EINVAL);
  bad = passes[0];
  bad.groups_x = 0;
  assert_int_equal(obs_vk_run(vk, &bad, 1, NULL, &err), OBS_EINVAL);
  bad = passes[0];
  bad.spirv_size = 6;
  assert_int_equal(obs_vk_run(vk, &bad, 1, NULL, &err), OBS_EINVAL);
  obs_vk_image_free(vk, a);
  obs_vk_image_free(vk, b);
  obs_vk_image_free(vk, c);
  free(in);
  free(out);
  obs_err_free(&err);
}

/* ---- G-buffer: rasteriser against the ray caster ---- */

typedef struct gb_report {
  size_t pixels, covered, silhouette, coverage_diff, checked, sphere_checked;
  size_t snapped; /* flat pixels explained only by sub-pixel edge snapping (see snap_explains) */
  size_t cpu_only; /* pixels the ray caster covers and the rasteriser does not */
  double depth_rel_all; /* max relative depth difference over pixels both cover, silhouettes too */
  double depth_rel, normal_diff;         /* flat faces: max relative depth, max |n_gpu - n_cpu| */
  double sphere_depth_rel, sphere_angle; /* spheres: max relative depth, max angle (degrees) */
  double sphere_depth_excess;            /* max |dz| / (tessellation bound): must stay <= 1 */
  double ms;
} gb_report;

static int same3(const float *a, const float *b) { return !memcmp(a, b, 3 * sizeof(float)); }

/* Silhouette pixels of one G-buffer: an 8-neighbour differs in coverage or in object (albedo,
 * unique per object in these scenes), or the depth jumps by more than 1%. */
static void mark_silhouettes(const obs_gbuffer *g, unsigned char *sil) {
  int w = g->width, h = g->height;
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      size_t i = (size_t)y * w + x;
      for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
          int u = x + dx, v = y + dy;
          if ((!dx && !dy) || u < 0 || v < 0 || u >= w || v >= h) continue;
          size_t j = (size_t)v * w + u;
          if (g->coverage[i] != g->coverage[j]) sil[i] = 1;
          if (!g->coverage[i] || !g->coverage[j]) continue;
          if (!same3(g->albedo + 3 * i, g->albedo + 3 * j)) sil[i] = 1;
          double a = g->depth[i], b = g->depth[j];
          if (fabs(a - b) > 0.01 * fmax(a, b)) sil[i] = 1;
        }
    }
}

static void load_scene(const char *json, obs_scene *sc) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(sc, json, "gbuffer-test.json", NULL, NULL, 0, &err);
  vktest_check_rc(rc, &err);
  /* Albedo identifies the object in the silhouette test, so every object needs its own. */
  for (size_t a = 0; a < sc->nobjects; a++)
    for (size_t b = a + 1; b < sc->nobjects; b++) {
      const obs_object *p = &sc->objects[a], *q = &sc->objects[b];
      assert_true(p->has_material && q->has_material);
      assert_false(p->reflectivity.x == q->reflectivity.x &&
                   p->reflectivity.y == q->reflectivity.y &&
                   p->reflectivity.z == q->reflectivity.z);
    }
  obs_err_free(&err);
}

/* Rasterisers snap vertices to a sub-pixel grid (lavapipe: 8 bits, 1/256 pixel), which moves
 * edges by up to about that much, so a pixel centre that close to an edge between two facets of one
 * object may land on either facet: same depth, the other facet's normal. Such a pixel is accepted
 * when a ray through a point within 1/128 pixel of its centre sees what the rasteriser saw. */
static int snap_explains(const obs_rt *rt, const obs_camera_rig *rig, int x, int y, double zg,
                         const float *ng) {
  const double e = 1.0 / 128;
  for (int dy = -1; dy <= 1; dy++)
    for (int dx = -1; dx <= 1; dx++) {
      double org[3], dir[3];
      obs_camera_ray(rig, x + 0.5 + dx * e, y + 0.5 + dy * e, org, dir);
      obs_hit hit;
      if (!obs_rt_intersect(rt, org, dir, INFINITY, &hit)) continue;
      double fwd = dir[0] * rig->forward[0] + dir[1] * rig->forward[1] + dir[2] * rig->forward[2];
      double z = hit.t * fwd, nd = 0;
      const double *axes[3] = {rig->right, rig->up, rig->forward};
      for (int k = 0; k < 3; k++) {
        double v = hit.ng[0] * axes[k][0] + hit.ng[1] * axes[k][1] + hit.ng[2] * axes[k][2];
        nd += (v - ng[k]) * (v - ng[k]);
      }
      if (fabs(z - zg) <= 1e-4 * z && sqrt(nd) <= 1e-3) return 1;
    }
  return 0;
}

static int is_sphere_albedo(const obs_scene *sc, const float *alb) {
  for (size_t k = 0; k < sc->nobjects; k++) {
    const obs_object *o = &sc->objects[k];
    if (o->shape.type == OBS_SHAPE_SPHERE && (float)o->reflectivity.x == alb[0] &&
        (float)o->reflectivity.y == alb[1] && (float)o->reflectivity.z == alb[2])
      return 1;
  }
  return 0;
}

static int g_world_frame;

/* Renders `json` both ways and checks the G-buffers agree as the contract says. */
static gb_report compare_gbuffers(const char *label, const char *json) {
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  load_scene(json, &sc);
  obs_gbuffer cpu, gpu;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &cpu, 2, NULL, NULL, &err), &err);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, sc.width, sc.height, &rig);
  obs_geometry geo;
  /* Techniques build at the camera (exact camera-relative vertices); the world frame must work too.
   */
  if (g_world_frame)
    vktest_check_rc(obs_geometry_build(&sc, &geo, &err), &err);
  else
    vktest_check_rc(obs_geometry_build_at(&sc, rig.origin, &geo, &err), &err);
  obs_rt rt;
  vktest_check_rc(obs_rt_build(&sc, &rt, 2, &err), &err);
  obs_vk_gbuffer dev;
  gb_report r;
  memset(&r, 0, sizeof r);
  vktest_check_rc(obs_vk_gbuffer_render(vk, &sc, &geo, &dev, &r.ms, &err), &err);
  assert_int_equal(dev.width, sc.width);
  assert_int_equal(dev.height, sc.height);
  vktest_check_rc(obs_gbuffer_alloc(&gpu, sc.width, sc.height, &rig, &err), &err);
  vktest_check_rc(obs_vk_gbuffer_download(vk, &dev, &gpu, 1, &err), &err);

  int w = sc.width, h = sc.height;
  size_t n = (size_t)w * h;
  unsigned char *sil = calloc(n, 1);
  assert_non_null(sil);
  mark_silhouettes(&cpu, sil);
  mark_silhouettes(&gpu, sil);
  r.pixels = n;
  size_t bad = 0;
  for (size_t i = 0; i < n; i++) {
    float cc = cpu.coverage[i], gc = gpu.coverage[i];
    assert_true(gc == 0.0f || gc == 1.0f);
    r.covered += cc != 0;
    r.cpu_only += cc != 0 && gc == 0;
    if (gc) {
      /* Covered pixels hold unit normals at every scale. */
      const float *ng = gpu.normal + 3 * i;
      double l = sqrt((double)ng[0] * ng[0] + (double)ng[1] * ng[1] + (double)ng[2] * ng[2]);
      if (!(fabs(l - 1.0) < 1e-5)) {
        fprintf(stderr, "%s: pixel (%zu,%zu): normal length %g\n", label, i % w, i / w, l);
        bad++;
      }
    }
    r.silhouette += sil[i];
    if (cc != gc) {
      r.coverage_diff++;
      if (!sil[i]) {
        fprintf(stderr, "%s: pixel (%zu,%zu): coverage cpu %g gpu %g off a silhouette\n", label,
                i % w, i / w, cc, gc);
        bad++;
      }
    }
    if (!gc) {
      /* Uncovered pixels hold exactly the cleared values. */
      assert_true(gpu.depth[i] == 0.0f);
      for (int k = 0; k < 3; k++) assert_true(gpu.normal[3 * i + k] == 0.0f);
      for (int k = 0; k < 3; k++) assert_true(gpu.albedo[3 * i + k] == 0.0f);
    }
    if (cc && gc)
      r.depth_rel_all = fmax(r.depth_rel_all, fabs((double)gpu.depth[i] - cpu.depth[i]) / cpu.depth[i]);
    if (!cc || !gc || sil[i]) continue;
    const float *nc = cpu.normal + 3 * i, *ng = gpu.normal + 3 * i;
    double zc = cpu.depth[i], zg = gpu.depth[i];
    double dz = fabs(zg - zc), rel = dz / zc;
    double dot = nc[0] * ng[0] + nc[1] * ng[1] + nc[2] * ng[2];
    double nd = sqrt((nc[0] - ng[0]) * (nc[0] - ng[0]) + (nc[1] - ng[1]) * (nc[1] - ng[1]) +
                     (nc[2] - ng[2]) * (nc[2] - ng[2]));
    int albedo_ok = same3(cpu.albedo + 3 * i, gpu.albedo + 3 * i);
    if (!albedo_ok) {
      fprintf(stderr, "%s: pixel (%zu,%zu): albedo differs off a silhouette\n", label, i % w,
              i / w);
      bad++;
    }
    if (is_sphere_albedo(&sc, cpu.albedo + 3 * i)) {
      /* Facets are inscribed and stay within 0.25 pixel of the sphere; along a ray at angle a to
       * the normal that is 0.25 pixel / cos(a) of depth. */
      double angle = acos(fmin(1.0, dot)) * 180.0 / PI;
      float p[3];
      obs_gbuffer_position(&cpu, (float)(i % w) + 0.5f, (float)(i / w) + 0.5f, (float)zc, p);
      double pl = rig.ortho ? 1.0 : sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      double ray[3] = {rig.ortho ? 0 : p[0] / pl, rig.ortho ? 0 : p[1] / pl,
                       rig.ortho ? 1 : p[2] / pl};
      double cosa = fabs(ray[0] * nc[0] + ray[1] * nc[1] + ray[2] * nc[2]);
      double pix = 2.0 * rig.half_h * (rig.ortho ? 1.0 : zc) / h;
      double bound = 1e-4 * zc + 0.25 * pix / fmax(cosa, 1e-3);
      r.sphere_checked++;
      r.sphere_angle = fmax(r.sphere_angle, angle);
      r.sphere_depth_rel = fmax(r.sphere_depth_rel, rel);
      r.sphere_depth_excess = fmax(r.sphere_depth_excess, dz / bound);
      if (angle >= 2.0 || dz > bound) {
        fprintf(stderr, "%s: sphere pixel (%zu,%zu): angle %.3f deg, depth %g vs %g (bound %g)\n",
                label, i % w, i / w, angle, zg, zc, bound);
        bad++;
      }
    } else {
      r.checked++;
      if ((rel > 1e-4 || nd > 1e-3) &&
          snap_explains(&rt, &rig, (int)(i % w), (int)(i / w), zg, ng)) {
        r.snapped++;
        continue;
      }
      r.depth_rel = fmax(r.depth_rel, rel);
      r.normal_diff = fmax(r.normal_diff, nd);
      if (rel > 1e-4 || nd > 1e-3) {
        fprintf(stderr,
                "%s: pixel (%zu,%zu): depth %.9g vs %.9g, normal (%g %g %g) vs (%g %g %g)\n", label,
                i % w, i / w, zg, zc, ng[0], ng[1], ng[2], nc[0], nc[1], nc[2]);
        bad++;
      }
    }
  }
  fprintf(stderr,
          "%s: %dx%d, %.2f ms; covered %zu, silhouette %.3f%%, coverage differs on %zu (%.3f%% of "
          "pixels); flat: %zu px (%zu on snapped edges), max depth rel %.2e, max normal diff %.2e; "
          "spheres: %zu px, max angle %.3f deg, max depth rel %.2e (%.2f of bound)\n",
          label, w, h, r.ms, r.covered, 100.0 * r.silhouette / n, r.coverage_diff,
          100.0 * r.coverage_diff / n, r.checked, r.snapped, r.depth_rel, r.normal_diff,
          r.sphere_checked, r.sphere_angle, r.sphere_depth_rel, r.sphere_depth_excess);
  assert_int_equal(bad, 0);
  /* Snapping can only explain a sliver of pixels along facet edges. */
  assert_true(r.snapped <= r.checked / 500 + 1);
  obs_rt_free(&rt);
  free(sil);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&cpu);
  obs_gbuffer_free(&gpu);
  obs_geometry_free(&geo);
  obs_scene_free(&sc);
  obs_err_free(&err);
  return r;
}


#define TECH "\"technique\":{\"name\":\"rt_ao\",\"backend\":\"cpu\"}"
#define MAT(r, g, b) "\"material\":{\"reflectivity\":[" #r "," #g "," #b "]}"

/* A Cornell-box-like room: five quads, a rotated box and an axis-aligned box. */
static const char *room_objects =
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[552.8,0,0],[0,0,0],[0,0,559.2],[549.6,0,559.2]]},"
    MAT(0.7, 0.7, 0.7) "},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[556,548.8,0],[556,548.8,559.2],[0,548.8,559.2],"
    "[0,548.8,0]]}," MAT(0.71, 0.7, 0.7) "},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[549.6,0,559.2],[0,0,559.2],[0,548.8,559.2],"
    "[556,548.8,559.2]]}," MAT(0.72, 0.7, 0.7) "},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,559.2],[0,0,0],[0,548.8,0],[0,548.8,559.2]]},"
    MAT(0.14, 0.45, 0.091) "},"
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[552.8,0,0],[549.6,0,559.2],[556,548.8,559.2],"
    "[556,548.8,0]]}," MAT(0.63, 0.065, 0.05) "},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-82.5,0,-82.5],\"max\":[82.5,165,82.5]},"
    "\"transform\":{\"rotate\":[0,-17,0],\"translate\":[185,0,169]}," MAT(0.73, 0.7, 0.7) "},"
    "{\"shape\":{\"type\":\"box\",\"min\":[265,0,296],\"max\":[430,330,461]}," MAT(0.74, 0.7, 0.7)
    "}";

static void test_gb_room(void **state) {
  (void)state;
  g_world_frame = 1;
  compare_gbuffers("room-world-frame",
                   obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[278,273,-800],"
                       "\"look_at\":[278,273,0],\"fov_y\":39.3},"
                       "\"image\":{\"width\":256,\"height\":256},\"objects\":[%s]," TECH "}",
                       room_objects));
  g_world_frame = 0;
  compare_gbuffers("room",
                   obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[278,273,-800],"
                       "\"look_at\":[278,273,0],\"fov_y\":39.3},"
                       "\"image\":{\"width\":256,\"height\":256},\"objects\":[%s]," TECH "}",
                       room_objects));
}

static void test_gb_room_orthographic(void **state) {
  (void)state;
  compare_gbuffers("room-ortho",
                   obs_test_fmt("{\"camera\":{\"type\":\"orthographic\",\"position\":[600,500,-300],"
                       "\"look_at\":[278,150,280],\"height\":700},"
                       "\"image\":{\"width\":200,\"height\":160},\"objects\":[%s]," TECH "}",
                       room_objects));
}

static const char *sphere_on_plane =
    "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-20,0,-20],[-20,0,20],[20,0,20],"
    "[20,0,-20]]}," MAT(0.5, 0.5, 0.5) "},"
    "{\"shape\":{\"type\":\"sphere\",\"center\":[0,1,0],\"radius\":0.5}," MAT(0.8, 0.2, 0.1) "}]";

static void test_gb_sphere_on_plane(void **state) {
  (void)state;
  compare_gbuffers("sphere-on-plane",
                   obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],"
                       "\"look_at\":[0,0.3,0],\"fov_y\":45},"
                       "\"image\":{\"width\":256,\"height\":192},%s," TECH "}",
                       sphere_on_plane));
}

static void test_gb_displaced_sphere(void **state) {
  (void)state;
  compare_gbuffers(
      "displaced-sphere",
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0.6,3.2],"
      "\"look_at\":[0,0,0],\"fov_y\":40},\"image\":{\"width\":256,\"height\":256},"
      "\"objects\":[{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":6}," MAT(
          0.9, 0.9, 0.9) "}]," TECH "}");
}

static void test_gb_orthographic_sphere(void **state) {
  (void)state;
  compare_gbuffers("ortho-sphere-on-plane",
                   obs_test_fmt("{\"camera\":{\"type\":\"orthographic\",\"position\":[0,3,-4],"
                       "\"look_at\":[0,0.3,0],\"height\":3},"
                       "\"image\":{\"width\":160,\"height\":128},%s," TECH "}",
                       sphere_on_plane));
}

/* The camera sits inside a closed box with a sphere and a block: every wall crosses the camera's
 * plane, so the near plane must clip only what is behind. */
static void test_gb_inside_box(void **state) {
  (void)state;
  compare_gbuffers("inside-box",
                   "{\"camera\":{\"type\":\"perspective\",\"position\":[0.2,0.1,-0.3],"
                   "\"look_at\":[1,-0.5,2],\"fov_y\":100},\"image\":{\"width\":192,\"height\":144},"
                   "\"objects\":[{\"shape\":{\"type\":\"box\",\"min\":[-3,-2,-3],\"max\":[3,2,3]},"
                   MAT(0.6, 0.6, 0.6) "},"
                   "{\"shape\":{\"type\":\"sphere\",\"center\":[1,-1,1.5],\"radius\":0.6},"
                   MAT(0.3, 0.6, 0.9) "},"
                   "{\"shape\":{\"type\":\"box\",\"min\":[-1.5,-2,1],\"max\":[-0.5,0,2]},"
                   MAT(0.9, 0.6, 0.3) "}]," TECH "}");
}

/* A millimetre-sized sphere and triangle 1 cm from the camera in front of a wall 10 km away:
 * near/far ratio 1e6. */
static void test_gb_near_far(void **state) {
  (void)state;
  compare_gbuffers("near-far-1e6",
                   "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],"
                   "\"look_at\":[0,0,1],\"fov_y\":60},\"image\":{\"width\":160,\"height\":120},"
                   "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e5,-1e5,1e4],"
                   "[1e5,-1e5,1e4],[1e5,1e5,1.2e4],[-1e5,1e5,1.2e4]]}," MAT(0.5, 0.5, 0.5) "},"
                   "{\"shape\":{\"type\":\"sphere\",\"center\":[0.001,0,0.01],\"radius\":0.002},"
                   MAT(0.8, 0.1, 0.1) "},"
                   "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[-0.006,-0.004,0.011],"
                   "[-0.002,-0.004,0.012],[-0.004,0.003,0.0105]]}," MAT(0.1, 0.8, 0.1) "}]," TECH
                   "}");
}

static void test_gb_tiny_and_wide(void **state) {
  (void)state;
  gb_report r =
      compare_gbuffers("1x1", obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],"
                                  "\"look_at\":[0,0.3,0],\"fov_y\":45},"
                                  "\"image\":{\"width\":1,\"height\":1},%s," TECH "}",
                                  sphere_on_plane));
  assert_int_equal(r.covered, 1);
  /* A 1.5 degree high strip 130 degrees wide through the ball and the ground. */
  r = compare_gbuffers("4096x16", obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],"
                                      "\"look_at\":[0,1,0],\"fov_y\":1.5},"
                                      "\"image\":{\"width\":4096,\"height\":16},%s," TECH "}",
                                      sphere_on_plane));
  assert_true(r.checked > 1000 && r.sphere_checked > 100);
}

/* The sphere on a plane scaled by s about the origin and moved by t (all three axes, by different
 * irrational-looking multiples so nothing rounds exactly), ground half-size g (before scaling),
 * seen from (0,3,-4) * s + t towards (0,look_y,look_z) * s + t at fov_y degrees. */
static const char *moved_scene_at(double s, double t, double g, double fov, double look_y,
                                  double look_z, int w, int h) {
  double tx = t * 1.2345678901, ty = t * 0.3141592653, tz = -t * 0.7654321098;
  return obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[%.17g,%.17g,%.17g],"
             "\"look_at\":[%.17g,%.17g,%.17g],\"fov_y\":%.17g},"
             "\"image\":{\"width\":%d,\"height\":%d},\"objects\":["
             "{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
             "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}," MAT(0.5, 0.5, 0.5) "},"
             "{\"shape\":{\"type\":\"sphere\",\"center\":[%.17g,%.17g,%.17g],\"radius\":%.17g},"
             MAT(0.8, 0.2, 0.1) "}]," TECH "}",
             tx, ty + 3 * s, tz - 4 * s, tx, ty + look_y * s, tz + look_z * s, fov, w, h, tx - g * s, ty, tz - g * s,
             tx - g * s, ty, tz + g * s, tx + g * s, ty, tz + g * s, tx + g * s, ty, tz - g * s, tx,
             ty + s, tz, 0.5 * s);
}

static const char *moved_scene(double s, double t, double g, double fov, int w, int h) {
  return moved_scene_at(s, t, g, fov, 0.3, 0, w, h);
}

/* Far from the world origin and at extreme scales the rasteriser still matches the ray caster
 * within the contract (it works camera-relative, rotated in double on the host). */
static void test_gb_far_and_scaled(void **state) {
  (void)state;
  const double cases[][2] = {{1, 1e6}, {1, 1e7}, {1, 1e9}, {1e-9, 0}, {1e9, 0},
                             {1e-9, 1e-3}, {1e9, 1e9}, {1e-12, 0}, {1e12, 0}};
  for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
    char label[64];
    snprintf(label, sizeof label, "scale %g translate %g", cases[c][0], cases[c][1]);
    gb_report r = compare_gbuffers(label, moved_scene(cases[c][0], cases[c][1], 20, 12, 64, 48));
    assert_true(r.checked > 1000 && r.sphere_checked > 100);
    assert_int_equal(r.cpu_only, 0);
  }
}

/* Ground quads far larger than the view, seen from 3 units above: every pixel the ray caster
 * covers is covered (device rasterisers clip or snap such triangles in float otherwise). */
static void test_gb_huge_ground(void **state) {
  (void)state;
  const double halves[] = {5e7, 1e10, 1e15, 1e18};
  for (size_t k = 0; k < sizeof halves / sizeof halves[0]; k++) {
    char label[64];
    snprintf(label, sizeof label, "ground +-%g", halves[k]);
    gb_report r = compare_gbuffers(label, moved_scene(1, 0, halves[k], 12, 64, 48));
    assert_true(r.covered > 2000);
    assert_int_equal(r.cpu_only, 0);
    /* Towards the horizon: depths from a few units to the quad's edge. Every pixel there is a
     * "silhouette" (depth changes by over 1 % per pixel), so depth is checked on all of them:
     * measured at most 1.3e-5 relative (grazing pixels magnify sub-pixel differences). */
    r = compare_gbuffers(label, moved_scene_at(1, 0, halves[k], 30, 2.9, 10, 64, 48));
    printf("%s towards the horizon: max relative depth difference %.2e on %zu covered pixels\n",
           label, r.depth_rel_all, r.covered);
    assert_true(r.covered > 1000);
    assert_int_equal(r.cpu_only, 0);
    assert_true(r.depth_rel_all < 1e-4);
    /* A 160-degree view: the guard band's corners lie below and behind the camera's foot. */
    r = compare_gbuffers(label, moved_scene_at(1, 0, halves[k], 160, 0.3, 0, 64, 48));
    printf("%s at fov 160: max relative depth difference %.2e on %zu covered pixels\n", label,
           r.depth_rel_all, r.covered);
    assert_true(r.covered > 1000);
    assert_int_equal(r.cpu_only, 0);
    assert_true(r.depth_rel_all < 1e-4);
  }
}

/* Fields of view down to 1e-4 degrees: the view transform in float would err by pixels. */
static void test_gb_tiny_fov(void **state) {
  (void)state;
  const double fovs[] = {1e-2, 1e-4};
  for (size_t k = 0; k < sizeof fovs / sizeof fovs[0]; k++) {
    char label[64];
    snprintf(label, sizeof label, "fov %g", fovs[k]);
    gb_report r = compare_gbuffers(label, moved_scene(1, 0, 20, fovs[k], 64, 48));
    assert_true(r.checked > 1000);
    assert_int_equal(r.cpu_only, 0);
  }
}

static void test_gb_empty(void **state) {
  (void)state;
  gb_report r = compare_gbuffers("empty",
                                 "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,"
                                 "-1],\"look_at\":[0,0,0],\"fov_y\":45},"
                                 "\"image\":{\"width\":33,\"height\":17},"
                                 "\"objects\":[]," TECH "}");
  assert_int_equal(r.covered, 0);
  assert_int_equal(r.coverage_diff, 0);
}

/* Everything behind the camera: nothing drawn, nothing clipped into view. */
static void test_gb_behind(void **state) {
  (void)state;
  gb_report r = compare_gbuffers(
      "behind",
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],"
      "\"fov_y\":45},\"image\":{\"width\":16,\"height\":16},\"objects\":[{\"shape\":{"
      "\"type\":\"sphere\",\"center\":[0,0,-5],\"radius\":1}," MAT(0.5, 0.5, 0.5) "}]," TECH "}");
  assert_int_equal(r.covered, 0);
}

/* Geometry through the eye: a ground in the camera's own plane and one 1e-20 below it, seen
 * level and pitched down. The near-plane cut of their triangles must not collapse onto the
 * vertex behind the eye (that left a depth of 0 and an endless slab walk). */
static void test_gb_eye_in_plane(void **state) {
  (void)state;
  static const double below[] = {0, 1e-20};
  static const double pitch[] = {0, -0.1};
  for (size_t i = 0; i < 2; i++)
    for (size_t k = 0; k < 2; k++) {
      char label[64];
      snprintf(label, sizeof label, "eye in plane, floor -%g, pitch %g", below[i], pitch[k]);
      gb_report r = compare_gbuffers(
          label,
          obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,%g,1],"
              "\"fov_y\":45},\"image\":{\"width\":32,\"height\":24},\"objects\":[{\"shape\":{"
              "\"type\":\"quad\",\"vertices\":[[-10,%g,-10],[10,%g,-10],[10,%g,10],[-10,%g,10]]},"
              MAT(0.5, 0.5, 0.5) "}]," TECH "}",
              pitch[k], -below[i], -below[i], -below[i], -below[i]));
      assert_int_equal(r.cpu_only, 0);
    }
}

/* A host G-buffer survives upload and download unchanged. */
static void test_gb_upload_download(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  load_scene(
      obs_test_fmt("{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],"
          "\"look_at\":[0,0.3,0],\"fov_y\":45},\"image\":{\"width\":41,\"height\":23},%s," TECH "}",
          sphere_on_plane),
      &sc);
  obs_gbuffer a, b;
  vktest_check_rc(obs_gbuffer_raycast(&sc, &a, 1, NULL, NULL, &err), &err);
  obs_vk_gbuffer dev;
  vktest_check_rc(obs_vk_gbuffer_upload(vk, &a, &dev, &err), &err);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, sc.width, sc.height, &rig);
  vktest_check_rc(obs_gbuffer_alloc(&b, sc.width, sc.height, &rig, &err), &err);
  vktest_check_rc(obs_vk_gbuffer_download(vk, &dev, &b, 1, &err), &err);
  assert_memory_equal(a.depth, b.depth, (size_t)41 * 23 * 8 * sizeof(float));
  obs_gbuffer c;
  obs_camera_setup(&sc.camera, 40, 23, &rig);
  vktest_check_rc(obs_gbuffer_alloc(&c, 40, 23, &rig, &err), &err);
  assert_int_equal(obs_vk_gbuffer_download(vk, &dev, &c, 1, &err), OBS_EINVAL);
  obs_gbuffer_free(&c);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&a);
  obs_gbuffer_free(&b);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

int main(void) {
  /* The loader's own debug output would be counted as validation messages. */
  unsetenv("VK_LOADER_DEBUG");
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_filter_matches_nothing, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_device_name, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_roundtrip, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_image_errors, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_error_results, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_compute_scale, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_room, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_room_orthographic, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_sphere_on_plane, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_displaced_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_orthographic_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_inside_box, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_near_far, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_tiny_and_wide, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_far_and_scaled, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_huge_ground, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_tiny_fov, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_eye_in_plane, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_empty, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_behind, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_gb_upload_download, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
