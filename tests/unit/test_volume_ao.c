/* volume_ao through the whole renderer on procedural volumes, against closed forms: AO = 1 on a
 * lone convex sphere, the occlusion of one sphere volume by another (1 - cos(alpha) (r/d)^2),
 * first-hit depth within a tenth of a voxel, the three environment methods equal under a constant
 * white sky, the reference's error halving when its samples quadruple, the extremes (isovalues
 * at the data's ends, 1-voxel and 4096 x 1 x 1 volumes, tiny and huge scales, a step longer than
 * the volume, the camera inside), mixed scenes and the loader's refusals. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "testutil.h"

/* A volume object of procedural `kind`; `extra` adds members to the shape. */
static const char *volume_obj(const char *name, const char *kind, int n, const char *extra,
                              double scale, double tx, double ty, double tz) {
  static char buf[4][512];
  static int k;
  char *b = buf[k++ & 3];
  snprintf(b, 512,
           "{\"name\": \"%s\", \"shape\": {\"type\": \"volume\", \"procedural\": \"%s\", "
           "\"dims\": [%d, %d, %d]%s}, \"transform\": {\"scale\": [%.17g, %.17g, %.17g], "
           "\"translate\": [%.17g, %.17g, %.17g]}}",
           name, kind, n, n, n, extra, scale, scale, scale, tx, ty, tz);
  return b;
}

/* A scene of `objects` seen by an orthographic camera from +x (or `camera`). */
static char *scene_doc(const char *camera, int w, int h, const char *objects, const char *rest,
                       const char *params) {
  char *doc = malloc(8192);
  snprintf(doc, 8192,
           "{\"camera\": %s, \"image\": {\"width\": %d, \"height\": %d}, \"objects\": [%s]%s, "
           "\"technique\": {\"name\": \"volume_ao\", \"backend\": \"cpu\", \"params\": {%s}}}",
           camera, w, h, objects, rest, params);
  return doc;
}

static const char *ORTHO_X =
    "{\"type\": \"orthographic\", \"position\": [4, 0, 0], \"look_at\": [0, 0, 0], \"up\": [0, 1, "
    "0], \"height\": 2.4}";

static void render(const char *doc, obs_result *res) {
  obs_test_render(doc, 2, res);
  obs_test_assert_finite(&res->image);
}

/* A lone sphere is convex: every AO direction leaves it with the field falling, so AO is 1 at
 * every covered pixel, and the bent normal is the normal's side. */
static void test_lone_sphere_open(void **state) {
  (void)state;
  char *doc = scene_doc(ORTHO_X, 32, 32, volume_obj("a", "sphere", 64, "", 2, 0, 0, 0), "",
                        "\"samples\": 64");
  obs_result res;
  render(doc, &res);
  const float *ao = obs_image_channel(&res.image, "ao"),
              *al = obs_image_channel(&res.image, "alpha");
  const float *nx = obs_image_channel(&res.image, "normal.X");
  const float *bx = obs_image_channel(&res.image, "bent_normal.X");
  int covered = 0;
  for (int i = 0; i < 32 * 32; i++) {
    if (al[i] < 1) continue;
    covered++;
    assert_true(ao[i] == 1.0f);
    assert_true(nx[i] > 0 && bx[i] > 0);
  }
  assert_true(covered > 150);
  obs_result_free(&res);
  free(doc);
}

/* Sphere A (world radius 0.6 at the origin) seen along -x hits its equator point P = (0.6, 0, 0)
 * with normal +x; sphere B of world radius r sits at distance d from P, its centre alpha from the
 * normal toward +y, wholly above the horizon and within max_distance, and out of the camera ray's
 * way. AO at P = 1 - cos(alpha) (r / d)^2 within 3 sigma plus the march's discretisation. */
static void test_two_spheres(void **state) {
  (void)state;
  const double r = 0.2, d = 0.5, alpha = M_PI / 4, R = 0.6;
  const double bx = R + d * cos(alpha), by = d * sin(alpha);
  /* The procedural sphere has object radius 0.3 (0.6 of the box's half side 1, the box's longest
   * side 1): scale = world radius / 0.3. */
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 128, "", R / 0.3, 0, 0, 0),
           volume_obj("b", "sphere", 64, "", r / 0.3, bx, by, 0));
  const char *cam =
      "{\"type\": \"orthographic\", \"position\": [4, 0, 0], \"look_at\": [0, 0, 0], \"up\": [0, "
      "1, 0], \"height\": 0.004}";
  const int n = 16384;
  char params[128];
  snprintf(params, sizeof params, "\"samples\": %d, \"step\": 0.001, \"max_distance\": 0.5", n);
  char *doc = scene_doc(cam, 1, 1, objs, "", params);
  obs_result res;
  render(doc, &res);
  double ao = obs_image_channel(&res.image, "ao")[0];
  double want = 1 - cos(alpha) * (r / d) * (r / d);
  double sigma = sqrt(want * (1 - want) / n);
  printf("two sphere volumes: AO %.5f, closed form %.5f (sigma %.5f)\n", ao, want, sigma);
  assert_true(obs_image_channel(&res.image, "alpha")[0] == 1.0f);
  assert_true(fabs(ao - want) < 3 * sigma + 0.005);
  /* The bent normal leans away from B (toward -y). */
  assert_true(obs_image_channel(&res.image, "bent_normal.Y")[0] < -0.01f);
  obs_result_free(&res);
  free(doc);
}

/* Orthographic view along -z of a sphere of world radius 0.6: the depth of each pixel well inside
 * the silhouette is 4 - sqrt(R^2 - x^2 - y^2) within a tenth of a voxel. */
static void test_depth_sphere(void **state) {
  (void)state;
  const char *cam =
      "{\"type\": \"orthographic\", \"position\": [0, 0, 4], \"look_at\": [0, 0, 0], \"up\": [0, "
      "1, 0], \"height\": 1.6}";
  const int dims = 64, w = 40;
  char *doc =
      scene_doc(cam, w, w, volume_obj("a", "sphere", dims, "", 2, 0, 0, 0), "", "\"samples\": 1");
  obs_result res;
  render(doc, &res);
  const float *z = obs_image_channel(&res.image, "depth.Z");
  const double R = 0.6, voxel = 2.0 / dims; /* world units: the box is 2 wide */
  int checked = 0;
  double worst = 0;
  for (int j = 0; j < w; j++)
    for (int i = 0; i < w; i++) {
      double x = ((i + 0.5) / w - 0.5) * 1.6, y = (0.5 - (j + 0.5) / w) * 1.6;
      if (x * x + y * y > 0.64 * R * R) continue;
      double want = 4 - sqrt(R * R - x * x - y * y);
      worst = fmax(worst, fabs(z[j * w + i] - want));
      checked++;
    }
  printf("sphere volume depth: worst error %.3g voxels over %d pixels\n", worst / voxel, checked);
  assert_true(checked > 400);
  assert_true(worst < 0.1 * voxel);
  obs_result_free(&res);
  free(doc);
}

/* Under a constant white environment and no lights, every ibl method gives final = AO in each
 * channel: the lookup and the SH convolution of a constant are the constant, and the reference
 * averages it over the open directions, which are the AO's. */
static void test_white_environment(void **state) {
  (void)state;
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 64, "", 2, 0, 0, 0),
           volume_obj("b", "torus", 64, "", 1.5, 0.9, 0, 0));
  static const char *const ibls[] = {"bent_normal_lookup", "irradiance", "reference"};
  for (int m = 0; m < 3; m++) {
    char params[128];
    snprintf(params, sizeof params, "\"samples\": 16, \"ibl\": \"%s\"", ibls[m]);
    char *doc =
        scene_doc(ORTHO_X, 24, 24, objs, ", \"environment\": {\"color\": [1, 1, 1]}", params);
    obs_result res;
    render(doc, &res);
    const float *ao = obs_image_channel(&res.image, "ao"),
                *al = obs_image_channel(&res.image, "alpha");
    int occluded = 0;
    for (int c = 0; c < 3; c++) {
      const float *f = obs_image_channel(&res.image, c == 0   ? "final.R"
                                                     : c == 1 ? "final.G"
                                                              : "final.B");
      for (int i = 0; i < 24 * 24; i++) {
        if (al[i] < 1) continue;
        occluded += ao[i] < 1;
        assert_true(fabs(f[i] - ao[i]) < 1e-5);
      }
    }
    assert_true(occluded > 0);
    obs_result_free(&res);
    free(doc);
  }
}

/* The RMSE of the reference's `final` against a 1024-sample one under the sky: four times the
 * samples, about half the error with independent samples, more with the scrambled Sobol
 * replicates (sampling.h: 4 of n/4 points each converge faster; measured 2.96): 1.5 to 4x, one
 * noisy draw of each. */
static double sky_rmse(int samples, uint32_t seed) {
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 48, "", 2, 0, 0, 0),
           volume_obj("b", "torus", 48, "", 1.5, 0.9, 0, 0));
  const char *env = ", \"environment\": {\"map\": \"sky\", \"resolution\": 16}";
  char params[160];
  snprintf(params, sizeof params, "\"samples\": %d, \"ibl\": \"reference\", \"seed\": %u", samples,
           seed);
  char *doc = scene_doc(ORTHO_X, 20, 20, objs, env, params);
  obs_result a, b;
  render(doc, &a);
  free(doc);
  snprintf(params, sizeof params, "\"samples\": 1024, \"ibl\": \"reference\", \"seed\": 777");
  doc = scene_doc(ORTHO_X, 20, 20, objs, env, params);
  render(doc, &b);
  free(doc);
  double sum = 0;
  int n = 0;
  const float *al = obs_image_channel(&a.image, "alpha");
  const float *fa = obs_image_channel(&a.image, "final.G"),
              *fb = obs_image_channel(&b.image, "final.G");
  for (int i = 0; i < 400; i++)
    if (al[i] == 1) sum += (fa[i] - fb[i]) * (fa[i] - fb[i]), n++;
  obs_result_free(&a);
  obs_result_free(&b);
  return sqrt(sum / n);
}

static void test_reference_converges(void **state) {
  (void)state;
  double e16 = sky_rmse(16, 3), e64 = sky_rmse(64, 3);
  printf("ibl reference under the sky: RMSE %.4g at 16 samples, %.4g at 64 (ratio %.2f)\n", e16,
         e64, e16 / e64);
  assert_true(e16 / e64 > 1.5 && e16 / e64 < 4.0);
}

/* Each ibl method's error against the reference under the sky is finite and reported. */
static void test_methods_against_reference(void **state) {
  (void)state;
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 48, "", 2, 0, 0, 0),
           volume_obj("b", "torus", 48, "", 1.5, 0.9, 0, 0));
  const char *env = ", \"environment\": {\"map\": \"sky\", \"resolution\": 16}";
  static const char *const ibls[] = {"reference", "bent_normal_lookup", "irradiance"};
  obs_result r[3];
  for (int m = 0; m < 3; m++) {
    char params[128];
    snprintf(params, sizeof params, "\"samples\": 256, \"ibl\": \"%s\"", ibls[m]);
    char *doc = scene_doc(ORTHO_X, 20, 20, objs, env, params);
    render(doc, &r[m]);
    free(doc);
  }
  const float *al = obs_image_channel(&r[0].image, "alpha"),
              *ref = obs_image_channel(&r[0].image, "final.G");
  for (int m = 1; m < 3; m++) {
    const float *f = obs_image_channel(&r[m].image, "final.G");
    double sum = 0, mean = 0;
    int n = 0;
    for (int i = 0; i < 400; i++)
      if (al[i] == 1) sum += (f[i] - ref[i]) * (f[i] - ref[i]), mean += ref[i], n++;
    printf("ibl %s vs reference under the sky: RMSE %.4g (reference mean %.4g)\n", ibls[m],
           sqrt(sum / n), mean / n);
    assert_true(n > 50 && isfinite(sum) && sum > 0);
    assert_true(sqrt(sum / n) < mean / n); /* an approximation, not another quantity */
  }
  for (int m = 0; m < 3; m++) obs_result_free(&r[m]);
}

/* The extremes: every output finite, coverage and AO in [0, 1], and a warning where one is due. */
static void extreme(const char *what, const char *objects, const char *params, const char *warn) {
  char *doc = scene_doc(ORTHO_X, 12, 12, objects, "", params);
  obs_result res;
  render(doc, &res);
  const float *ao = obs_image_channel(&res.image, "ao"),
              *al = obs_image_channel(&res.image, "alpha");
  for (int i = 0; i < 144; i++) assert_true(ao[i] >= 0 && ao[i] <= 1 && al[i] >= 0 && al[i] <= 1);
  int warned = 0;
  for (int i = 0; i < res.nwarnings; i++) warned |= warn && strstr(res.warnings[i], warn) != NULL;
  printf("%s: %d warnings%s\n", what, res.nwarnings, warn && !warned ? " (missing!)" : "");
  assert_true(!warn || warned);
  obs_result_free(&res);
  free(doc);
}

static void test_extremes(void **state) {
  (void)state;
  extreme("isovalue 0", volume_obj("a", "noise", 16, ", \"isovalue\": 0", 2, 0, 0, 0), "", NULL);
  extreme("isovalue 1", volume_obj("a", "noise", 16, ", \"isovalue\": 1", 2, 0, 0, 0), "", NULL);
  extreme("1 voxel", volume_obj("a", "sphere", 1, "", 2, 0, 0, 0), "", NULL);
  char line[512];
  snprintf(line, sizeof line,
           "{\"name\": \"l\", \"shape\": {\"type\": \"volume\", \"procedural\": \"noise\", "
           "\"dims\": [4096, 1, 1], \"isovalue\": 0.5}, \"transform\": {\"scale\": [2, 2, 2]}}");
  extreme("4096 x 1 x 1", line, "", NULL);
  extreme("spacing 1e-4",
          volume_obj("a", "torus", 24, ", \"spacing\": [1e-4, 1e-4, 1e-4]", 2, 0, 0, 0), "", NULL);
  extreme("spacing 1e4", volume_obj("a", "torus", 24, ", \"spacing\": [1e4, 1e4, 2e4]", 2, 0, 0, 0),
          "", NULL);
  extreme("step longer than the volume", volume_obj("a", "torus", 24, "", 2, 0, 0, 0),
          "\"step\": 5, \"max_distance\": 3", "longer than the march");
  extreme("max_distance below start", volume_obj("a", "torus", 24, "", 2, 0, 0, 0),
          "\"start\": 0.5, \"max_distance\": 0.1", "every direction is open");
  /* The camera inside the sphere's solid: every ray hits where it starts. */
  const char *inside =
      "{\"type\": \"perspective\", \"position\": [0.05, 0, 0], \"look_at\": [1, 0, 0], \"up\": "
      "[0, 1, 0], \"fov_y\": 60}";
  char *doc =
      scene_doc(inside, 8, 8, volume_obj("a", "sphere", 32, "", 2, 0, 0, 0), "", "\"samples\": 8");
  obs_result res;
  render(doc, &res);
  const float *al = obs_image_channel(&res.image, "alpha"),
              *z = obs_image_channel(&res.image, "depth.Z");
  for (int i = 0; i < 64; i++) assert_true(al[i] == 1 && z[i] >= 0 && z[i] < 1e-9);
  obs_result_free(&res);
  free(doc);
}

/* A scene far away and scaled: the same AO as at the origin at scale 1 (the march runs in the
 * volume's own data space). */
static void test_scale_translation(void **state) {
  (void)state;
  const double scales[] = {1e-6, 1e6};
  obs_result base;
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 32, "", 2, 0, 0, 0),
           volume_obj("b", "torus", 32, "", 1.5, 0.9, 0, 0));
  char *doc = scene_doc(ORTHO_X, 16, 16, objs, "", "\"samples\": 16");
  render(doc, &base);
  free(doc);
  for (int k = 0; k < 2; k++) {
    double s = scales[k], t = 1e3 * s;
    char cam[256];
    snprintf(cam, sizeof cam,
             "{\"type\": \"orthographic\", \"position\": [%.17g, %.17g, %.17g], \"look_at\": "
             "[%.17g, %.17g, %.17g], \"up\": [0, 1, 0], \"height\": %.17g}",
             4 * s + t, t, t, t, t, t, 2.4 * s);
    snprintf(objs, sizeof objs, "%s, %s", volume_obj("a", "sphere", 32, "", 2 * s, t, t, t),
             volume_obj("b", "torus", 32, "", 1.5 * s, 0.9 * s + t, t, t));
    doc = scene_doc(cam, 16, 16, objs, "", "\"samples\": 16");
    obs_result res;
    render(doc, &res);
    const float *a = obs_image_channel(&base.image, "ao"), *b = obs_image_channel(&res.image, "ao");
    const float *aa = obs_image_channel(&base.image, "alpha"),
                *ab = obs_image_channel(&res.image, "alpha");
    int differ = 0;
    for (int i = 0; i < 256; i++) differ += aa[i] != ab[i] || fabsf(a[i] - b[i]) > 1e-4f;
    printf("scale %g, translation %g: %d of 256 pixels differ\n", s, t, differ);
    assert_true(differ <= 5);
    obs_result_free(&res);
    free(doc);
  }
  obs_result_free(&base);
}

static void expect_refused(const char *doc, const char *needle) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "t.json", NULL, NULL, 0, &err);
  if (rc == 0 || !strstr(obs_err_message(&err), needle))
    printf("expected \"%s\", got rc %d: %s\n", needle, rc, obs_err_message(&err));
  assert_int_equal(rc, OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), needle));
  obs_err_free(&err);
}

static void test_refusals(void **state) {
  (void)state;
  const char *cam =
      "\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, 4], \"look_at\": [0, 0, 0], "
      "\"up\": [0, 1, 0], \"fov_y\": 40}, \"image\": {\"width\": 8, \"height\": 8}";
  const char *vol =
      "{\"shape\": {\"type\": \"volume\", \"procedural\": \"sphere\", \"dims\": [8, 8, 8]}}";
  const char *quad =
      "{\"shape\": {\"type\": \"quad\", \"vertices\": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}}";
  /* A surface technique renders a scene of volumes alone through their isosurface meshes
   * (tests/unit/test_isosurface_mesh.c), so it is no longer refused. */
  (void)vol;
  expect_refused(
      obs_test_fmt("{%s, \"objects\": [%s], \"technique\": {\"name\": \"volume_ao\"}}", cam, quad),
      "/objects: technique \"volume_ao\" renders volumes, and the scene has none");
  expect_refused(
      obs_test_fmt("{%s, \"objects\": [{\"shape\": {\"type\": \"volume\", \"procedural\": "
                   "\"sphere\", \"dims\": [8, 8, 8], \"file\": \"x.nrrd\"}}], "
                   "\"technique\": {\"name\": \"volume_ao\"}}",
                   cam),
      "/objects/0/shape: a volume names either a \"file\" or a \"procedural\" kind (got both)");
  expect_refused(
      obs_test_fmt("{%s, \"objects\": [{\"shape\": {\"type\": \"volume\", \"procedural\": "
                   "\"sphere\", \"dims\": [0, 8, 8]}}], \"technique\": {\"name\": \"volume_ao\"}}",
                   cam),
      "/objects/0/shape/dims: must be 3 integers of 1 to 65536");
  expect_refused(obs_test_fmt("{%s, \"objects\": [%s, %s], \"lights\": [{\"type\": \"point\", "
                              "\"position\": [0, 2, 0], \"emission\": [1, 1, 1]}], "
                              "\"technique\": {\"name\": \"rt_ao\"}}",
                              cam, vol, quad),
                 "/lights/0/type: technique \"rt_ao\" lights with quad lights only");
  expect_refused(obs_test_fmt("{%s, \"objects\": [%s], \"environment\": {\"map\": \"sky\"}, "
                              "\"technique\": {\"name\": \"rt_ao\"}}",
                              cam, quad),
                 "/environment/map: technique \"rt_ao\" takes a constant environment");
  expect_refused(obs_test_fmt("{%s, \"objects\": [%s], \"environment\": {\"map\": \"latlong\", "
                              "\"file\": \"sky.exr\"}, \"technique\": {\"name\": \"volume_ao\"}}",
                              cam, vol),
                 "/environment/file: files need a scene directory");
  expect_refused(
      obs_test_fmt("{%s, \"objects\": [{\"shape\": {\"type\": \"volume\", \"procedural\": "
                   "\"sphere\", \"dims\": [8, 8, 8]}, \"motion\": [{}]}], "
                   "\"technique\": {\"name\": \"volume_ao\"}}",
                   cam),
      "/objects/0/motion: a volume cannot move");
  expect_refused(
      obs_test_fmt(
          "{%s, \"objects\": [{\"shape\": {\"type\": \"volume\", \"procedural\": "
          "\"sphere\", \"dims\": [8, 8, 8], \"colormap\": [[0.5, 1, 1, 1], [0.2, 1, 1, 1]]}}], "
          "\"technique\": {\"name\": \"volume_ao\"}}",
          cam),
      "/objects/0/shape/colormap/1: must be [value, r, g, b]");
}

/* Mixed scenes: a volume technique renders the volumes and warns about the surfaces; a surface
 * technique renders both, the volume as its isosurface mesh, without a warning about it. */
static void test_mixed_scene_warns(void **state) {
  (void)state;
  const char *quad =
      "{\"name\": \"floor\", \"shape\": {\"type\": \"quad\", \"vertices\": [[-2,-1,-2],[-2,-1,2],"
      "[2,-1,2],[2,-1,-2]]}}";
  char objs[1200];
  snprintf(objs, sizeof objs, "%s, %s", volume_obj("ball", "sphere", 16, "", 2, 0, 0, 0), quad);
  char *doc = scene_doc(ORTHO_X, 8, 8, objs, "", "\"samples\": 4");
  obs_result res;
  render(doc, &res);
  assert_true(res.nwarnings >= 1);
  assert_non_null(
      strstr(res.warnings[0], "renders volumes only: it ignores the surface object \"floor\""));
  obs_result_free(&res);
  free(doc);
  const char *rt = obs_test_fmt(
      "{\"camera\": %s, \"image\": {\"width\": 8, \"height\": 8}, \"objects\": [%s], "
      "\"technique\": {\"name\": \"rt_ao\", \"params\": {\"samples\": 4}}}",
      ORTHO_X, objs);
  render(rt, &res);
  for (int i = 0; i < res.nwarnings; i++) assert_null(strstr(res.warnings[i], "ball"));
  obs_result_free(&res);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_lone_sphere_open),
      cmocka_unit_test(test_two_spheres),
      cmocka_unit_test(test_depth_sphere),
      cmocka_unit_test(test_white_environment),
      cmocka_unit_test(test_reference_converges),
      cmocka_unit_test(test_methods_against_reference),
      cmocka_unit_test(test_extremes),
      cmocka_unit_test(test_scale_translation),
      cmocka_unit_test(test_refusals),
      cmocka_unit_test(test_mixed_scene_warns),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
