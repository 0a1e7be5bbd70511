/* proximity_ao on Vulkan (lavapipe) against the CPU: the device flood gives the CPU flood's bits
 * (a sphere's field from the builder, random occupancy and values on grids of odd sizes, a row
 * decaying into denormals); the reconstruction from the rasterised G-buffer with object ids
 * agrees with the CPU's ray-cast one (AO RMSE over the pixels both cover at most 1e-3, coverage
 * equal off silhouettes, normals within 1e-4) on the Cornell box, a box on a quad and a sphere on
 * a plane, for both reconstructions, both combinations and without self-occlusion, and with more
 * fields around every pixel than one invocation may walk on lavapipe; a region alone equals the
 * same pixels of the whole image; the Vulkan backend's flood hook is the device flood. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "params.h"
#include "proximity.h"
#include "proximity_ao.h"
#include "proximity_vk.h"
#include "vktest.h"
#include "prox_bound_cases.h"

/* Floods a copy of `f` on both backends and asserts every value's bits are equal. */
static void flood_both(obs_vk *vk, const obs_prox_field *f, size_t *nonzero) {
  obs_prox_field a = *f, b = *f;
  a.value = malloc(f->count * sizeof *a.value);
  b.value = malloc(f->count * sizeof *b.value);
  assert_non_null(a.value);
  assert_non_null(b.value);
  memcpy(a.value, f->value, f->count * sizeof *a.value);
  memcpy(b.value, f->value, f->count * sizeof *b.value);
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_prox_flood_cpu(NULL, &a, 2, &err), &err);
  vktest_check_rc(obs_prox_flood_vulkan(vk, &b, 2, &err), &err);
  size_t differ = 0, first = 0;
  *nonzero = 0;
  for (size_t i = 0; i < f->count; i++) {
    uint32_t x, y;
    memcpy(&x, &a.value[i], 4);
    memcpy(&y, &b.value[i], 4);
    if (x != y && !differ++) first = i;
    *nonzero += a.value[i] != 0.0f;
  }
  if (differ)
    fprintf(stderr, "%zu of %zu voxels differ; first %zu: cpu %.9g vulkan %.9g\n", differ, f->count,
            first, a.value[first], b.value[first]);
  assert_int_equal(differ, 0);
  free(a.value);
  free(b.value);
  obs_err_free(&err);
}

/* The builder's field of a sphere (a closed surface: the flood runs inside and out). */
static void test_flood_sphere(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_scene sc;
  obs_test_load(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-5],\"look_at\":[0,0,0],"
      "\"fov_y\":50},\"image\":{\"width\":8,\"height\":8},\"objects\":[{\"shape\":{\"type\":"
      "\"sphere\",\"center\":[0.1,0,0],\"radius\":1}}],\"technique\":{\"name\":\"proximity_ao\"}}",
      "sphere.json", &sc);
  obs_prox_layout lay = {.fraction = 0.3, .box = OBS_PROX_BOX_LARGEST, .res = 48, .min_res = 8};
  obs_prox_fields fs;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_prox_build(&sc, &lay, 2, NULL, NULL, &fs, &err), &err);
  obs_prox_field f = fs.f[0];
  /* The builder flooded on the CPU: back to the voxelisation, where both floods start. */
  for (size_t i = 0; i < f.count; i++) f.value[i] = f.occupied[i] ? 1.0f : 0.0f;
  printf("sphere field %dx%dx%d, %d iterations\n", f.dims[0], f.dims[1], f.dims[2], f.iterations);
  assert_true(f.iterations >= 8);
  size_t nonzero;
  flood_both(vk, &f, &nonzero);
  assert_true(nonzero > f.occupied_count);
  /* Far more iterations than the layout asks: values decay into float's denormals. */
  f.iterations = 70;
  flood_both(vk, &f, &nonzero);
  printf("sphere field, 70 iterations: %zu of %zu voxels nonzero, equal bits\n", nonzero, f.count);
  obs_prox_fields_free(&fs);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Random occupancy and random starting values on grids of odd sides (work groups overhang). */
static void test_flood_random(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  static const int sides[][3] = {{1, 1, 1}, {13, 7, 5}, {33, 17, 40}, {70, 3, 9}};
  uint32_t seed = 12345;
  for (size_t c = 0; c < sizeof sides / sizeof sides[0]; c++) {
    obs_prox_field f;
    memset(&f, 0, sizeof f);
    memcpy(f.dims, sides[c], sizeof f.dims);
    f.count = (size_t)f.dims[0] * (size_t)f.dims[1] * (size_t)f.dims[2];
    f.iterations = 1 + (int)(c * 9);
    f.occupied = malloc(f.count);
    f.value = malloc(f.count * sizeof *f.value);
    assert_non_null(f.occupied);
    assert_non_null(f.value);
    for (size_t i = 0; i < f.count; i++) {
      f.occupied[i] = obs_test_unit(&seed) < 0.05;
      f.value[i] = f.occupied[i] ? 1.0f : (float)obs_test_unit(&seed) * 0.25f;
    }
    size_t nonzero;
    flood_both(vk, &f, &nonzero);
    printf("random grid %dx%dx%d, %d iterations: equal bits\n", f.dims[0], f.dims[1], f.dims[2],
           f.iterations);
    free(f.occupied);
    free(f.value);
  }
}

/* One occupied voxel at the end of a long row: the flood's front decays by ~1/52 per voxel, so
 * far along the row the values are denormal floats and then 0, and the device must keep the
 * denormals as the CPU does. */
static void test_flood_denormals(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  obs_prox_field f;
  memset(&f, 0, sizeof f);
  f.dims[0] = 120, f.dims[1] = 2, f.dims[2] = 1;
  f.count = 240;
  f.iterations = 100;
  f.occupied = calloc(f.count, 1);
  f.value = calloc(f.count, sizeof *f.value);
  assert_non_null(f.occupied);
  assert_non_null(f.value);
  f.occupied[0] = 1;
  f.value[0] = 1.0f;
  size_t nonzero;
  flood_both(vk, &f, &nonzero);
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_prox_flood_cpu(NULL, &f, 1, &err), &err);
  size_t denormal = 0;
  for (size_t i = 0; i < f.count; i++)
    denormal += f.value[i] != 0.0f && fabsf(f.value[i]) < 0x1p-126f;
  printf("decaying row: %zu nonzero, %zu denormal voxels, equal bits\n", nonzero, denormal);
  assert_true(denormal > 0);
  assert_true(nonzero < f.count);
  free(f.occupied);
  free(f.value);
  obs_err_free(&err);
}

/* ---- reconstruction: CPU (ray cast) against Vulkan (raster) ------------------------------ */

#define AO_RMSE_MAX 1e-3

/* Renders scene file `scene` (or the document `doc` when scene is NULL) at w x h on `backend`. */
static void render(const char *scene, const char *doc, int w, int h, const char *backend,
                   const char *params, obs_result *res) {
  char ws[16], hs[16], be[32];
  snprintf(ws, sizeof ws, "%d", w);
  snprintf(hs, sizeof hs, "%d", h);
  snprintf(be, sizeof be, "\"%s\"", backend);
  obs_override ov[5] = {{"/image/width", ws},
                        {"/image/height", hs},
                        {"/technique/name", "\"proximity_ao\""},
                        {"/technique/backend", be},
                        {"/technique/params", params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = scene ? obs_scene_load_file(&sc, obs_test_src(scene), ov, 5, &err)
                 : obs_scene_load_string(&sc, doc, "two.json", NULL, ov, 5, &err);
  vktest_check_rc(rc, &err);
  obs_render_opts opts = {.threads = 2};
  vktest_check_rc(obs_render(&sc, &opts, res, &err), &err);
  obs_test_assert_finite(&res->image);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* A pixel whose 3x3 neighbourhood changes coverage in either image: an object's outline, where
 * raster and ray cast may disagree about coverage. */
static int silhouette(const obs_image *a, const obs_image *b, int x, int y) {
  const obs_image *im[2] = {a, b};
  for (int k = 0; k < 2; k++) {
    const float *al = obs_image_channel(im[k], "alpha");
    size_t c = (size_t)y * (size_t)a->width + (size_t)x;
    for (int dy = -1; dy <= 1; dy++)
      for (int dx = -1; dx <= 1; dx++) {
        int u = x + dx, v = y + dy;
        if (u < 0 || v < 0 || u >= a->width || v >= a->height) continue;
        if (al[(size_t)v * (size_t)a->width + (size_t)u] != al[c]) return 1;
      }
  }
  return 0;
}

static const char *const normal_names[3] = {"normal.X", "normal.Y", "normal.Z"};

typedef struct agreement {
  double rmse, worst, ao_mean, normal_max;
  size_t both, other_surface, fields_off, coverage_off, coverage_sil;
} agreement;

/* CPU (a) against Vulkan (b) over the pixels both cover: AO RMSE and largest difference, pixels
 * where the two see another surface (depth off by more than 1e-4 relative) or read other fields,
 * the largest normal difference on the others; and coverage differences off and on silhouettes. */
static agreement agree(const obs_image *a, const obs_image *b) {
  agreement g = {0};
  const float *ao[2] = {obs_image_channel(a, "ao"), obs_image_channel(b, "ao")};
  const float *al[2] = {obs_image_channel(a, "alpha"), obs_image_channel(b, "alpha")};
  const float *z[2] = {obs_image_channel(a, "depth.Z"), obs_image_channel(b, "depth.Z")};
  const float *nf[2] = {obs_image_channel(a, "fields"), obs_image_channel(b, "fields")};
  double s = 0;
  for (int y = 0; y < a->height; y++)
    for (int x = 0; x < a->width; x++) {
      size_t i = (size_t)y * (size_t)a->width + (size_t)x;
      if (al[0][i] != al[1][i]) {
        *(silhouette(a, b, x, y) ? &g.coverage_sil : &g.coverage_off) += 1;
        continue;
      }
      if (!(al[0][i] > 0)) {
        assert_true(ao[0][i] == 1.0f && ao[1][i] == 1.0f);
        continue;
      }
      double d = (double)ao[0][i] - (double)ao[1][i];
      s += d * d;
      g.both++;
      g.worst = fmax(g.worst, fabs(d));
      g.ao_mean += ao[0][i];
      int other = !(fabs(z[0][i] - z[1][i]) <= 1e-4 * fabs(z[0][i]));
      g.other_surface += other;
      g.fields_off += nf[0][i] != nf[1][i];
      for (int k = 0; k < 3 && !other; k++)
        g.normal_max = fmax(g.normal_max, fabs(obs_image_channel(a, normal_names[k])[i] -
                                               obs_image_channel(b, normal_names[k])[i]));
    }
  if (g.both) {
    g.rmse = sqrt(s / (double)g.both);
    g.ao_mean /= (double)g.both;
  }
  return g;
}

typedef struct rcase {
  const char *label, *scene, *doc, *params;
  int w, h;
} rcase;

static void compare_case(const rcase *c) {
  obs_result cpu, vk;
  render(c->scene, c->doc, c->w, c->h, "cpu", c->params, &cpu);
  render(c->scene, c->doc, c->w, c->h, "vulkan", c->params, &vk);
  agreement g = agree(&cpu.image, &vk.image);
  printf(
      "%-40s AO mean %.4f, RMSE %.2e, max %.2e over %zu px both cover; other surface %zu, "
      "other fields %zu; normal max %.1e; coverage differs %zu off + %zu on silhouettes\n",
      c->label, g.ao_mean, g.rmse, g.worst, g.both, g.other_surface, g.fields_off, g.normal_max,
      g.coverage_off, g.coverage_sil);
  assert_true(g.both >= (size_t)(c->w * c->h) / 4);
  assert_true(g.ao_mean < 0.995); /* the fields do occlude */
  assert_true(g.rmse <= AO_RMSE_MAX);
  assert_true(g.other_surface <= g.both / 100);
  assert_true(g.normal_max <= 1e-4);
  assert_int_equal(g.coverage_off, 0);
  obs_result_free(&cpu);
  obs_result_free(&vk);
}

/* A tilted box standing on a ground quad, well inside each other's fields. */
static const char *TWO =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[1.2,2.2,-3.2],\"look_at\":[0,0.3,0],"
    "\"fov_y\":40},\"image\":{\"width\":8,\"height\":8},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],[2,0,-2]]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[-0.5,0,-0.5],\"max\":[0.5,0.8,0.5]},"
    "\"transform\":{\"rotate\":[0,30,0],\"translate\":[0.1,0.02,0.2]}}],"
    "\"technique\":{\"name\":\"proximity_ao\"}}";

static void test_against_cpu(void **state) {
  (void)state;
  vktest_need_vk();
  const rcase cases[] = {
      {"cornell box, defaults", "scenes/cornell_box.json", NULL, "{}", 64, 64},
      {"cornell box, corrected, multiplicative", "scenes/cornell_box.json", NULL,
       "{\"reconstruction\":\"corrected\",\"combine\":\"multiplicative\",\"steps\":24}", 64, 64},
      {"cornell box, no self-occlusion", "scenes/cornell_box.json", NULL,
       "{\"self_occlusion\":false,\"propagation_fraction\":0.2}", 64, 64},
      {"box on a quad, defaults", NULL, TWO, "{}", 64, 48},
      {"box on a quad, corrected, range 0.5", NULL, TWO,
       "{\"reconstruction\":\"corrected\",\"range\":0.5,\"volume_res\":64}", 64, 48},
      {"sphere on a plane (tessellated here)", "scenes/sphere_on_plane.json", NULL, "{}", 64, 48},
  };
  /* The sanitizer builds walk the Vulkan paths once per kind of scene (a file, one in memory);
   * the release build holds every case to the CPU's bits. */
  size_t n = obs_test_sanitized() ? 2 : sizeof cases / sizeof cases[0];
  for (size_t i = 0; i < n; i++) compare_case(&cases[i + (obs_test_sanitized() && i ? 2 : 0)]);
}

/* More fields around every pixel than one invocation may walk on lavapipe (at 64 steps a field
 * costs ~1060 loop iterations of the 65535 allowed), so the pass splits them across dispatches
 * and carries the combination; still the CPU's result. */
static void test_many_fields(void **state) {
  (void)state;
  obs_vk *vk = vktest_need_vk();
  char objs[16384];
  size_t n = 0;
  for (int i = 0; i < 72; i++) {
    double x = (i % 9) * 0.5 - 2, z = (i / 9) * 0.5 - 1.5, y = 0.1 * (i % 5);
    n += (size_t)snprintf(objs + n, sizeof objs - n,
                          "%s{\"shape\":{\"type\":\"box\",\"min\":[%g,%g,%g],\"max\":[%g,%g,%g]}}",
                          i ? "," : "", x, y, z, x + 0.3, y + 0.3, z + 0.3);
  }
  const char *doc = obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2.5,-2.5],\"look_at\":[0,0,0],"
      "\"fov_y\":50},\"image\":{\"width\":8,\"height\":8},\"objects\":[%s],"
      "\"technique\":{\"name\":\"proximity_ao\"}}",
      objs);
  /* r_p the union's diagonal: every field's box holds every box, far from its faces. */
  const char *params =
      "{\"steps\":64,\"volume_res\":32,\"min_res\":8,\"range\":0.1,"
      "\"propagation_fraction\":1,\"propagation_box\":\"union\","
      "\"combine\":\"multiplicative\"}";
  obs_result cpu, dev;
  render(NULL, doc, 24, 16, "cpu", params, &cpu);
  render(NULL, doc, 24, 16, "vulkan", params, &dev);
  agreement g = agree(&cpu.image, &dev.image);
  const float *nf = obs_image_channel(&dev.image, "fields");
  float most = 0;
  for (int i = 0; i < 24 * 16; i++) most = fmaxf(most, nf[i]);
  printf(
      "72 boxes, 64 steps: up to %.0f fields per pixel (lavapipe's loop limit: %u iterations), "
      "AO mean %.4f, RMSE %.2e, max %.2e over %zu px, other fields %zu\n",
      most, obs_vk_loop_limit(vk), g.ao_mean, g.rmse, g.worst, g.both, g.fields_off);
  assert_true(most == 72.0f);
  assert_true(g.both > 24 * 16 / 4);
  assert_true(g.ao_mean < 0.99);
  assert_true(g.rmse <= AO_RMSE_MAX);
  assert_int_equal(g.fields_off, 0);
  obs_result_free(&cpu);
  obs_result_free(&dev);
}

/* A region rendered alone has the whole render's bits there and zeros elsewhere. */
static void test_region(void **state) {
  (void)state;
  vktest_need_vk();
  obs_result whole, part;
  render(NULL, TWO, 40, 32, "vulkan", "{}", &whole);
  obs_scene sc;
  obs_override ov[4] = {{"/image/width", "40"},
                        {"/image/height", "32"},
                        {"/technique/backend", "\"vulkan\""},
                        {"/technique/params", "{}"}};
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_scene_load_string(&sc, TWO, "two.json", NULL, ov, 4, &err), &err);
  obs_render_opts o = {.threads = 2, .region = {5, 3, 29, 30}};
  vktest_check_rc(obs_render(&sc, &o, &part, &err), &err);
  assert_true(vktest_assert_region(&whole, &part, o.region) > 100);
  obs_result_free(&whole);
  obs_result_free(&part);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* proximity_ao's prepare hook builds its fields for the backend that runs it: flooded on the
 * device for Vulkan, on the CPU otherwise, with the same bits, and released by its release hook. */
static void test_prepare_hook(void **state) {
  (void)state;
  vktest_need_vk();
  const obs_technique *t = obs_technique_find("proximity_ao");
  assert_non_null(t);
  assert_non_null(t->prepare);
  assert_non_null(t->release);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  vktest_check_rc(obs_scene_load_string(&sc, TWO, "two.json", NULL, NULL, 0, &err), &err);
  void *bound = NULL;
  vktest_check_rc(obs_params_bind_new(t, sc.params, &bound, &err), &err);
  obs_prepared *by[2] = {NULL, NULL};
  const obs_backend bes[2] = {OBS_BACKEND_CPU, OBS_BACKEND_VULKAN};
  for (int i = 0; i < 2; i++) {
    obs_render_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    ctx.scene = &sc;
    ctx.params = sc.params;
    ctx.bound = bound;
    ctx.threads = 2;
    ctx.built = json_array();
    vktest_check_rc(t->prepare(&ctx, bes[i], &by[i], &err), &err);
    assert_non_null(by[i]);
    /* Each field is listed in what was built, and the build's stages are named. */
    assert_int_equal(json_array_size(ctx.built), by[i]->fields.n);
    int named = 0;
    for (int k = 0; k < ctx.nstages; k++)
      named += !strcmp(ctx.stage_names[k], "voxelise") || !strcmp(ctx.stage_names[k], "flood");
    assert_int_equal(named, 2);
    json_decref(ctx.built);
  }
  assert_true(by[0]->fields.n >= 2);
  assert_int_equal(by[0]->fields.n, by[1]->fields.n);
  for (size_t f = 0; f < by[0]->fields.n; f++) {
    const obs_prox_field *a = &by[0]->fields.f[f], *b = &by[1]->fields.f[f];
    assert_int_equal(a->count, b->count);
    assert_int_equal(memcmp(a->value, b->value, a->count * sizeof(float)), 0);
  }
  for (int i = 0; i < 2; i++) t->release(by[i]);
  free(bound);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Accessibility over several fields on the device: the same bound, reached (prox_bound_cases.c). */
static void test_bound_several_fields(void **state) {
  (void)state;
  vktest_need_vk();
  assert_int_equal(obs_prox_bound_cases(OBS_BACKEND_VULKAN), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_flood_sphere, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_flood_random, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_flood_denormals, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_against_cpu, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_many_fields, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_region, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_bound_several_fields, vktest_quiet_teardown),
      cmocka_unit_test_teardown(test_prepare_hook, vktest_quiet_teardown),
  };
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
