/* The CPU G-buffer's two ways (renderer/cpu/gbuffer_raster.c): the rasteriser gives the ray cast's
 * buffers on bundled and synthetic scenes, perspective and orthographic, near the camera plane and
 * at extreme scales and translations: the same coverage but on a small share of pixels whose
 * centre lies on an edge, and there alone other depth or normal bits; the raster's fast loops
 * the same bits as its plain per-pixel reference at every instruction-set level; and the method
 * rule and its override. */
#include "testutil.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gbuffer_cpu.h"

/* Pixels where the two ways may disagree: at most this share of the image (plus two pixels),
 * all of them on triangle edges or sphere silhouettes. */
#define EDGE_SHARE 0.002

static void load_string(const char *json, obs_scene *sc) {
  obs_test_load(json, "gbuffer.json", sc);
}

/* A bundled scene, from the directory its models really lie in (scenes/models may be a link to
 * another checkout's, and a scene may only read files inside its own tree). */
static void load_file(const char *name, int w, int h, obs_scene *sc) {
  char dir[PATH_MAX], path[PATH_MAX + 64];
  assert_non_null(realpath(obs_test_src("scenes/models"), dir));
  *strrchr(dir, '/') = 0;
  snprintf(path, sizeof path, "%s/%s", dir, name);
  char ws[16], hs[16];
  snprintf(ws, sizeof ws, "%d", w);
  snprintf(hs, sizeof hs, "%d", h);
  const obs_override ov[] = {{"/image/width", ws}, {"/image/height", hs}};
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(sc, path, ov, 2, &err);
  if (rc) fprintf(stderr, "load failed: %s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

/* The raster at each instruction-set level against its plain per-pixel reference: every bit of
 * every buffer. */
static void same_as_reference(const obs_scene *sc, const obs_gbuffer *r, const char *what) {
  obs_gbuffer ref;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_raster_reference(sc, &ref, 2, &err), 0);
  const size_t n = (size_t)sc->width * (size_t)sc->height;
  static const char *const isa[] = {"sse2", "native"};
  for (size_t k = 0; k <= sizeof isa / sizeof *isa; k++) {
    obs_gbuffer f;
    if (k < sizeof isa / sizeof *isa) {
      setenv("OBSCURA_ISA", isa[k], 1);
      assert_int_equal(obs_gbuffer_raster(sc, &f, 2, NULL, NULL, &err), 0);
      unsetenv("OBSCURA_ISA");
    }
    const obs_gbuffer *g = k < sizeof isa / sizeof *isa ? &f : r;
    size_t diff = 0;
    for (size_t i = 0; i < n; i++)
      diff += memcmp(&g->depth[i], &ref.depth[i], sizeof(float)) ||
              memcmp(&g->coverage[i], &ref.coverage[i], sizeof(float)) ||
              memcmp(g->normal + 3 * i, ref.normal + 3 * i, 3 * sizeof(float)) ||
              memcmp(g->albedo + 3 * i, ref.albedo + 3 * i, 3 * sizeof(float));
    if (diff)
      printf("%s: %zu pixels differ from the reference (%s)\n", what, diff,
             k < sizeof isa / sizeof *isa ? isa[k] : "default level");
    assert_int_equal(diff, 0);
    if (k < sizeof isa / sizeof *isa) obs_gbuffer_free(&f);
  }
  obs_gbuffer_free(&ref);
  obs_err_free(&err);
}

/* Both ways on `sc`; returns the pixels that differ in any bit of any buffer, after asserting
 * that they are few and that the rest agree. */
static size_t compare(const obs_scene *sc, const char *what) {
  obs_gbuffer r, c;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_raster(sc, &r, 2, NULL, NULL, &err), 0);
  assert_int_equal(obs_gbuffer_raycast(sc, &c, 2, NULL, NULL, &err), 0);
  same_as_reference(sc, &r, what);
  const size_t n = (size_t)sc->width * (size_t)sc->height;
  size_t covered = 0, cov_diff = 0, val_diff = 0;
  for (size_t i = 0; i < n; i++) {
    covered += c.coverage[i] > 0;
    if (r.coverage[i] != c.coverage[i]) {
      cov_diff++;
      continue;
    }
    if (memcmp(&r.depth[i], &c.depth[i], sizeof(float)) ||
        memcmp(r.normal + 3 * i, c.normal + 3 * i, 3 * sizeof(float)) ||
        memcmp(r.albedo + 3 * i, c.albedo + 3 * i, 3 * sizeof(float)))
      val_diff++;
  }
  printf("%-34s %7zu px, %7zu covered: coverage differs on %zu, depth/normal on %zu\n", what, n,
         covered, cov_diff, val_diff);
  assert_true(covered > 0);
  assert_true((double)(cov_diff + val_diff) <= EDGE_SHARE * (double)n + 2.0);
  obs_gbuffer_free(&r);
  obs_gbuffer_free(&c);
  obs_err_free(&err);
  return cov_diff + val_diff;
}

static void test_bundled_scenes(void **state) {
  (void)state;
  static const struct {
    const char *file;
    int w, h;
  } s[] = {{"cornell_box.json", 320, 240},
           {"sphere_on_plane.json", 320, 240},
           {"teapot.json", 240, 180},
           {"displaced_sphere.json", 160, 120}};
  for (size_t k = 0; k < sizeof s / sizeof *s; k++) {
    obs_scene sc;
    load_file(s[k].file, s[k].w, s[k].h, &sc);
    compare(&sc, s[k].file);
    obs_scene_free(&sc);
  }
}

/* A scene of `objects` seen by camera `camera` (its JSON members) at 96x64. */
static void synthetic(const char *camera, const char *objects, const char *what) {
  char doc[4096];
  snprintf(doc, sizeof doc,
           "{\"camera\":{%s},\"image\":{\"width\":96,\"height\":64},\"objects\":%s,"
           "\"technique\":{\"name\":\"ssao\"}}",
           camera, objects);
  obs_scene sc;
  load_string(doc, &sc);
  compare(&sc, what);
  obs_scene_free(&sc);
}

/* A unit sphere on a plane and a box, scaled by s and moved by d (the camera with them). */
static void scaled(double s, double d, int ortho) {
  char cam[512], obj[2048], what[96];
  snprintf(cam, sizeof cam,
           "\"type\":\"%s\",\"position\":[%.17g,%.17g,%.17g],\"look_at\":[%.17g,%.17g,%.17g],"
           "\"up\":[0,1,0],%s",
           ortho ? "orthographic" : "perspective", d + 0.3 * s, d + 2.0 * s, d - 5.0 * s, d, d, d,
           ortho ? "\"height\":4" : "\"fov_y\":45");
  if (ortho) {
    /* The orthographic height is in world units. */
    char *h = strstr(cam, "\"height\":4");
    snprintf(h, sizeof cam - (size_t)(h - cam), "\"height\":%.17g", 4 * s);
  }
  snprintf(obj, sizeof obj,
           "[{\"shape\":{\"type\":\"sphere\",\"center\":[%.17g,%.17g,%.17g],\"radius\":%.17g}},"
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
           "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[%.17g,%.17g,%.17g],\"max\":[%.17g,%.17g,%.17g]},"
           "\"transform\":{\"rotate\":[0,30,0]}}]",
           d, d + s, d, s, d - 4 * s, d, d - 4 * s, d - 4 * s, d, d + 4 * s, d + 4 * s, d,
           d + 4 * s, d + 4 * s, d, d - 4 * s, d + 1.2 * s, d, d - 1.5 * s, d + 2.2 * s,
           d + 0.7 * s, d - 0.5 * s);
  snprintf(what, sizeof what, "%s scale %g at %g", ortho ? "ortho" : "persp", s, d);
  synthetic(cam, obj, what);
}

static void test_synthetic(void **state) {
  (void)state;
  const char *persp =
      "\"type\":\"perspective\",\"position\":[0,1,-3],\"look_at\":[0,0.5,0],"
      "\"up\":[0,1,0],\"fov_y\":50";
  /* A ground quad far larger than the view, under a camera just above it. */
  synthetic(
      "\"type\":\"perspective\",\"position\":[0,0.01,0],\"look_at\":[0,0,10],"
      "\"up\":[0,1,0],\"fov_y\":60",
      "[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e7,0,-1e7],[-1e7,0,1e7],"
      "[1e7,0,1e7],[1e7,0,-1e7]]}}]",
      "huge ground quad");
  /* Triangles crossing the camera plane: their parts behind the eye must not show. */
  synthetic(persp,
            "[{\"shape\":{\"type\":\"triangle\",\"vertices\":[[-2,0,-6],[2,0.2,-6],[0,1.5,4]]}},"
            "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0.5,2,-4],[3,-1,-4],[-1,-1,2]]}},"
            "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-5,-0.5,-5],[-5,-0.5,5],[5,-0.5,5],"
            "[5,-0.5,-5]]}}]",
            "triangles through the camera plane");
  /* The eye inside a sphere and inside a box. */
  synthetic(persp,
            "[{\"shape\":{\"type\":\"sphere\",\"center\":[0,1,-3],\"radius\":2}},"
            "{\"shape\":{\"type\":\"sphere\",\"center\":[0.3,0.4,0],\"radius\":0.5}}]",
            "camera inside a sphere");
  synthetic(persp,
            "[{\"shape\":{\"type\":\"box\",\"min\":[-2,-1,-4],\"max\":[2,3,2]}},"
            "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":5},"
            "\"transform\":{\"scale\":[0.5,0.5,0.5]}}]",
            "camera inside a box");
  /* Orthographic rays start on the camera plane: the parts behind it must not show either. */
  const char *ortho =
      "\"type\":\"orthographic\",\"position\":[0,1,-3],\"look_at\":[0,0.5,0],"
      "\"up\":[0,1,0],\"height\":3";
  synthetic(ortho,
            "[{\"shape\":{\"type\":\"triangle\",\"vertices\":[[-2,0,-6],[2,0.2,-6],[0,1.5,4]]}},"
            "{\"shape\":{\"type\":\"sphere\",\"center\":[0.5,1,-3],\"radius\":0.8}},"
            "{\"shape\":{\"type\":\"box\",\"min\":[-1,-1,-4],\"max\":[0,2,1]}}]",
            "ortho through the camera plane");
  /* The eye a hair above a plane that runs off to the horizon, looking along it. */
  synthetic(
      "\"type\":\"perspective\",\"position\":[0,1e-6,0],\"look_at\":[0,1e-6,1],"
      "\"up\":[0,1,0],\"fov_y\":90",
      "[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1e6,0,-1e6],[-1e6,0,1e6],"
      "[1e6,0,1e6],[1e6,0,-1e6]]}},"
      "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":4},"
      "\"transform\":{\"translate\":[0,0.5,3]}}]",
      "grazing plane to the horizon");
  const double scales[] = {1e-9, 1, 1e9};
  for (int o = 0; o < 2; o++) {
    for (size_t k = 0; k < 3; k++) scaled(scales[k], 0, o);
    scaled(1, 1e9, o);
    scaled(1e-3, -1e9, o);
  }
}

static void test_method_rule(void **state) {
  (void)state;
  unsetenv("OBSCURA_GBUFFER");
  assert_int_equal(obs_gbuffer_method(3e6, 1280 * 720), OBS_GBUFFER_RASTER);
  assert_int_equal(obs_gbuffer_method(1e9, 320 * 240), OBS_GBUFFER_RAYCAST);
  setenv("OBSCURA_GBUFFER", "raycast", 1);
  assert_int_equal(obs_gbuffer_method(3e6, 1280 * 720), OBS_GBUFFER_RAYCAST);
  setenv("OBSCURA_GBUFFER", "raster", 1);
  assert_int_equal(obs_gbuffer_method(1e9, 320 * 240), OBS_GBUFFER_RASTER);
  setenv("OBSCURA_GBUFFER", "auto", 1);
  assert_int_equal(obs_gbuffer_method(3e6, 1280 * 720), OBS_GBUFFER_RASTER);
  unsetenv("OBSCURA_GBUFFER");
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_bundled_scenes),
      cmocka_unit_test(test_synthetic),
      cmocka_unit_test(test_method_rule),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
