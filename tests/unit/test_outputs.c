/* Unit tests for typed outputs: the registry's declarations, the generic writer on a technique
 * without "ao" (RGB primary tone-mapped into final.png, false colour, normals, depth, a per-patch
 * output), summary statistics, the per-patch file round trip, per-pixel patch ids and the API's
 * output-name enum against the registry. */
#include "testutil.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "patch_ids.h"

static void test_registry_declarations(void **state) {
  (void)state;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    int primaries = 0;
    for (const obs_output *o = t->outputs; o->name; o++) {
      primaries += !!(o->flags & OBS_OUTPUT_PRIMARY);
      assert_true(strlen(o->name) <= OBS_OUTPUT_NAME_MAX);
      assert_non_null(o->description);
      if (o->stderr_of) assert_non_null(obs_technique_output(t, o->stderr_of));
    }
    assert_int_equal(primaries, 1);
  }
  /* Every file name fits the server's output records (32 bytes with the NUL). */
  char files[64][OBS_OUTPUT_FILE_MAX];
  size_t nf = obs_output_file_names(files, 64);
  for (size_t k = 0; k < nf; k++) assert_true(strlen(files[k]) < 32);
  /* Today's three keep their files and EXR channels. */
  const obs_technique *rt = obs_technique_find("rt_ao");
  assert_int_equal(obs_technique_files(rt, files, 16), 5);
  const char *want[] = {"ao.exr", "ao.png", "bent_normal.png", "depth.png", "summary.json"};
  for (int k = 0; k < 5; k++) assert_string_equal(files[k], want[k]);
  assert_int_equal(obs_technique_files(obs_technique_find("ssao"), files, 16), 4);
  assert_string_equal(files[2], "depth.png");
  char ch[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  assert_int_equal(obs_output_channels(obs_technique_output(rt, "depth"), ch), 1);
  assert_string_equal(ch[0], "depth.Z");
  assert_int_equal(obs_output_channels(obs_technique_output(rt, "bent_normal"), ch), 3);
  assert_string_equal(ch[2], "bent_normal.Z");
  assert_string_equal(obs_technique_primary(obs_technique_find("hbao"))->name, "ao");
  /* The registry JSON carries the typed fields and still the flat list. */
  json_t *reg = obs_technique_registry_json();
  json_t *t0 = json_array_get(reg, 0);
  assert_string_equal(json_string_value(json_object_get(t0, "exr")), "ao.exr");
  json_t *typed = json_object_get(t0, "typed_outputs");
  assert_true(json_array_size(typed) >= 5);
  assert_string_equal(json_string_value(json_object_get(json_array_get(typed, 0), "kind")),
                      "scalar");
  assert_true(json_is_true(json_object_get(json_array_get(typed, 0), "primary")));
  int has_ao = 0;
  json_t *flat = json_object_get(t0, "outputs");
  for (size_t k = 0; k < json_array_size(flat); k++)
    has_ao |= !strcmp(json_string_value(json_array_get(flat, k)), "ao");
  assert_true(has_ao);
  json_decref(reg);
}

/* The output files of GET /jobs/{id}/outputs/{name} in schema/openapi.yaml: the generated
 * OutputFileName enum lists exactly the registry's files, and the route takes those or the
 * comparison's error images. */
static void test_openapi_enum(void **state) {
  (void)state;
  FILE *f = fopen(obs_test_src("schema/openapi.yaml"), "r");
  assert_non_null(f);
  static char text[1 << 17];
  size_t n = fread(text, 1, sizeof text - 1, f);
  fclose(f);
  text[n] = 0;
  const char *route = strstr(text, "/api/v1/jobs/{id}/outputs/{name}:");
  assert_non_null(route);
  const char *ref = strstr(route, "$ref: '#/components/schemas/OutputFileName'");
  assert_non_null(ref);
  assert_non_null(strstr(ref, "enum: [error.exr, error.png]"));
  const char *at = strstr(text, "    OutputFileName:\n");
  assert_non_null(at);
  const char *e = strstr(at, "enum: [");
  assert_non_null(e);
  e += 7;
  const char *end = strchr(e, ']');
  char names[64][OBS_OUTPUT_FILE_MAX];
  size_t nn = obs_output_file_names(names, 64);
  size_t listed = 0;
  while (e < end) {
    while (e < end && (*e == ' ' || *e == ',' || *e == '\n')) e++;
    const char *s = e;
    while (e < end && *e != ',' && *e != ' ' && *e != '\n') e++;
    if (e == s) continue;
    char name[OBS_OUTPUT_FILE_MAX];
    snprintf(name, sizeof name, "%.*s", (int)(e - s), s);
    int found = 0;
    for (size_t k = 0; k < nn; k++) found |= !strcmp(names[k], name);
    if (!found) fprintf(stderr, "openapi lists %s, which no technique writes\n", name);
    assert_true(found);
    listed++;
  }
  if (listed != nn) fprintf(stderr, "OutputFileName differs: run scripts/gen-registry.sh\n");
  assert_int_equal(listed, nn);
}

/* A technique shaped like a path tracer with a per-patch output: no "ao" anywhere. */
static const obs_output fake_outputs[] = {
    {.name = "radiance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "radiance", .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "radiance_stderr", .kind = OBS_OUTPUT_RGB, .description = "its standard error",
     .stderr_of = "radiance"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .show = OBS_SHOW_NORMAL, .png = "normal.png",
     .description = "normal"},
    {.name = "heat", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_FALSE, .png = "heat.png",
     .description = "false colour"},
    {.name = "occl", .kind = OBS_OUTPUT_PATCH, .show = OBS_SHOW_GREY, .png = "occl.png",
     .description = "per patch"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "depth"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR, .description = "coverage"},
    {.name = NULL}};
static const obs_technique fake = {.name = "fake", .outputs = fake_outputs};

static double srgb(double v) {
  v = v < 0 ? 0 : v > 1 ? 1 : v;
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

static double quant(double v) { return floor(v * 255.0 + 0.5) / 255.0; }

/* 4 x 2 image: pixels 0..6 covered, pixel 7 background. */
static void fake_result(obs_result *r) {
  memset(r, 0, sizeof *r);
  r->technique = &fake;
  r->threads = 2;
  const char *names[] = {"radiance.R", "radiance.G", "radiance.B", "radiance_stderr.R",
                         "radiance_stderr.G", "radiance_stderr.B", "normal.X", "normal.Y",
                         "normal.Z", "heat", "occl", "depth.Z", "alpha"};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(&r->image, 4, 2, 13, names, &err), 0);
  for (int i = 0; i < 8; i++) {
    int cov = i < 7;
    obs_image_channel(&r->image, "radiance.R")[i] = 0.1f * (float)i;
    obs_image_channel(&r->image, "radiance.G")[i] = 0.2f;
    obs_image_channel(&r->image, "radiance.B")[i] = 0.3f;
    obs_image_channel(&r->image, "normal.Z")[i] = cov ? -1.0f : 0.0f;
    obs_image_channel(&r->image, "heat")[i] = 2.0f + (float)i;
    obs_image_channel(&r->image, "depth.Z")[i] = cov ? 1.0f + (float)i : 0.0f;
    obs_image_channel(&r->image, "alpha")[i] = (float)cov;
  }
  /* Two patches seen by alternate pixels, rendered into "occl". */
  assert_int_equal(obs_patches_init(&r->patches[0], "occl", 2, 1, 1, &err), 0);
  r->npatches = 1;
  r->patches[0].values[0] = 0.25f, r->patches[0].values[1] = 0.75f;
  r->patches[0].area[0] = 1.0f, r->patches[0].area[1] = 2.0f;
  int32_t ids[8] = {0, 1, 0, 1, 0, 1, 0, -1};
  const char *occl[] = {"occl"};
  assert_int_equal(obs_patches_render(&r->patches[0], ids, &r->image, occl, &err), 0);
  obs_err_free(&err);
}

static void test_writer_without_ao(void **state) {
  (void)state;
  obs_result r;
  fake_result(&r);
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
  sc.name = "fake.json";
  sc.spp = 1;
  sc.params = json_pack("{s:f}", "exposure", 1.0);
  const char *dir = obs_test_tmpdir("outputs-fake");
  /* An earlier AO render's files must not outlive it. */
  FILE *stale = fopen(obs_test_path(dir, "ao.png"), "w");
  assert_non_null(stale);
  fclose(stale);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_result_write(&r, &sc, dir, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  assert_false(obs_test_file_exists(obs_test_path(dir, "ao.png")));
  assert_false(obs_test_file_exists(obs_test_path(dir, "ao.exr")));
  const char *files[] = {"radiance.exr", "final.png", "normal.png", "heat.png", "occl.png",
                         "depth.png", "occl.patches", "summary.json"};
  for (int k = 0; k < 8; k++) assert_true(obs_test_file_exists(obs_test_path(dir, files[k])));
  /* The EXR holds every channel. */
  obs_image back;
  assert_int_equal(obs_image_read_exr(&back, obs_test_path(dir, "radiance.exr"), &err), 0);
  assert_int_equal(back.nchannels, 13);
  assert_true(obs_image_channel(&back, "radiance.G")[3] == 0.2f);
  obs_image_free(&back);
  /* final.png: value x 2^1, sRGB, 8 bits; the background keeps its value. */
  assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "final.png"), &err), 0);
  for (int i = 0; i < 8; i++) {
    assert_true(fabs(obs_image_channel(&back, "R")[i] - quant(srgb(0.2 * i))) < 1e-6);
    assert_true(fabs(obs_image_channel(&back, "B")[i] - quant(srgb(0.6))) < 1e-6);
  }
  obs_image_free(&back);
  /* normal.png: n * 0.5 + 0.5 where covered, black elsewhere. */
  assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "normal.png"), &err), 0);
  assert_true(fabs(obs_image_channel(&back, "R")[0] - quant(0.5)) < 1e-6);
  assert_true(obs_image_channel(&back, "B")[0] == 0.0f);
  assert_true(obs_image_channel(&back, "R")[7] == 0.0f);
  obs_image_free(&back);
  /* heat.png: the ramp's ends at the covered minimum and maximum, background black. */
  assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "heat.png"), &err), 0);
  assert_true(fabs(obs_image_channel(&back, "B")[0] - quant(0.329)) < 1e-6);
  assert_true(fabs(obs_image_channel(&back, "R")[6] - quant(0.993)) < 1e-6);
  assert_true(obs_image_channel(&back, "G")[7] == 0.0f);
  obs_image_free(&back);
  /* depth.png: nearest white, farthest 0.1; occl.png: the patch values per pixel. */
  assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "depth.png"), &err), 0);
  assert_true(obs_image_channel(&back, "Y")[0] == 1.0f);
  assert_true(fabs(obs_image_channel(&back, "Y")[6] - quant(0.1)) < 1e-6);
  obs_image_free(&back);
  assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "occl.png"), &err), 0);
  assert_true(fabs(obs_image_channel(&back, "Y")[1] - quant(0.75)) < 1e-6);
  obs_image_free(&back);
  /* summary.json: per-output statistics over covered pixels, and no AO fields. */
  json_t *sum = json_load_file(obs_test_path(dir, "summary.json"), 0, NULL);
  assert_non_null(sum);
  assert_null(json_object_get(sum, "ao"));
  assert_string_equal(json_string_value(json_object_get(sum, "primary_output")), "radiance");
  json_t *outs = json_object_get(sum, "outputs");
  json_t *rr = json_object_get(json_object_get(json_object_get(outs, "radiance"), "channels"),
                               "radiance.R");
  assert_true(fabs(json_real_value(json_object_get(rr, "mean")) - 0.3) < 1e-6); /* 0..0.6 */
  assert_true(fabs(json_real_value(json_object_get(rr, "max")) - 0.6) < 1e-6);
  assert_int_equal(json_integer_value(json_object_get(rr, "count")), 7);
  double lum = json_real_value(json_object_get(json_object_get(outs, "radiance"),
                                               "luminance_mean"));
  assert_true(fabs(lum - (0.2126 * 0.3 + 0.7152 * 0.2 + 0.0722 * 0.3)) < 1e-6);
  json_t *pv = json_object_get(json_object_get(outs, "occl"), "patch_values");
  assert_true(fabs(json_real_value(json_object_get(pv, "mean")) - 0.5) < 1e-9);
  assert_int_equal(json_integer_value(json_object_get(json_object_get(outs, "occl"), "patches")),
                   2);
  assert_string_equal(json_string_value(json_object_get(json_object_get(outs, "depth"), "kind")),
                      "depth");
  json_decref(sum);
  /* The patch file reads back. */
  obs_patches p;
  assert_int_equal(obs_patches_read(&p, obs_test_path(dir, "occl.patches"), &err), 0);
  assert_int_equal(p.count, 2);
  assert_true(p.values[1] == 0.75f && p.area[1] == 2.0f);
  obs_patches_free(&p);
  json_decref(sc.params);
  obs_result_free(&r);
  obs_err_free(&err);
}

static void test_voxel_refused(void **state) {
  (void)state;
  static const obs_output vox[] = {
      {.name = "v", .kind = OBS_OUTPUT_SCALAR, .flags = OBS_OUTPUT_PRIMARY, .description = "v"},
      {.name = "grid", .kind = OBS_OUTPUT_VOXEL, .description = "grid"},
      {.name = NULL}};
  static const obs_technique t = {.name = "vox", .outputs = vox};
  obs_result r;
  memset(&r, 0, sizeof r);
  r.technique = &t;
  const char *names[] = {"v"};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(&r.image, 2, 2, 1, names, &err), 0);
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
  sc.name = "vox.json";
  assert_int_equal(obs_result_write(&r, &sc, obs_test_tmpdir("outputs-vox"), &err),
                   OBS_EUNSUPPORTED);
  assert_non_null(strstr(obs_err_message(&err), "grid"));
  obs_result_free(&r);
  obs_err_free(&err);
}

static void test_patch_file(void **state) {
  (void)state;
  obs_patches p, q;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_patches_init(&p, "rad", 5, 3, 1, &err), 0);
  uint32_t s = 7;
  for (int i = 0; i < 15; i++) p.values[i] = (float)obs_test_rand(&s) / 4294967296.0f;
  for (int i = 0; i < 5; i++) p.area[i] = (float)(i + 1) * 0.5f;
  p.values[4] = -0.0f;
  p.values[5] = INFINITY;
  const char *path = obs_test_path(obs_test_tmpdir("outputs-patch"), "rad.patches");
  assert_int_equal(obs_patches_write(&p, path, &err), 0);
  /* The layout a user's loader relies on: one JSON line, data 16-byte aligned, little-endian. */
  FILE *f = fopen(path, "rb");
  char line[512];
  assert_non_null(fgets(line, sizeof line, f));
  long off = ftell(f);
  assert_int_equal(off % 16, 0);
  json_t *h = json_loads(line, 0, NULL);
  assert_non_null(h);
  assert_string_equal(json_string_value(json_object_get(h, "format")), "obscura-patches");
  assert_int_equal(json_integer_value(json_object_get(h, "count")), 5);
  assert_string_equal(json_string_value(json_array_get(json_object_get(h, "channels"), 1)),
                      "rad.G");
  json_decref(h);
  unsigned char b[4];
  assert_int_equal(fread(b, 1, 4, f), 4);
  uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
  float v0;
  memcpy(&v0, &u, 4);
  assert_true(v0 == p.values[0]);
  fseek(f, 0, SEEK_END);
  assert_int_equal(ftell(f), off + 4 * (15 + 5));
  fclose(f);
  assert_int_equal(obs_patches_read(&q, path, &err), 0);
  assert_string_equal(q.name, "rad");
  assert_int_equal(q.components, 3);
  assert_memory_equal(q.values, p.values, 15 * sizeof(float));
  assert_memory_equal(q.area, p.area, 5 * sizeof(float));
  obs_patches_free(&q);
  /* A truncated file and a foreign file are refused with the path in the message. */
  f = fopen(path, "r+b");
  assert_int_equal(ftruncate(fileno(f), off + 8), 0);
  fclose(f);
  assert_int_equal(obs_patches_read(&q, path, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "rad.patches"));
  f = fopen(path, "wb");
  fputs("{\"format\":\"other\"}\n", f);
  fclose(f);
  assert_int_equal(obs_patches_read(&q, path, &err), OBS_EINVAL);
  obs_patches_free(&p);
  obs_err_free(&err);
}

/* A quad (2 patches) fills the middle of the view beside a box (12 patches): patch counts,
 * areas, and the ids the primary rays see. */
static const char quad_scene[] =
    "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,5],\"look_at\":[0,0,0],"
    "\"up\":[0,1,0],\"height\":4},\"image\":{\"width\":16,\"height\":16},\"objects\":["
    "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-1,-1,0],[1,-1,0],[1,1,0],[-1,1,0]]},"
    "\"material\":{\"reflectivity\":[0.5,0.5,0.5]}},"
    "{\"shape\":{\"type\":\"box\",\"min\":[5,5,5],\"max\":[6,7,8]},"
    "\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
    "\"environment\":{\"color\":[1,1,1]},"
    "\"technique\":{\"name\":\"rt_ao\",\"params\":{\"samples\":1}}}";

static void test_patch_scene_and_ids(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(quad_scene, "quad.json", &sc);
  obs_err err = OBS_ERR_INIT;
  int64_t n;
  float *area;
  assert_int_equal(obs_patches_scene(&sc, &n, &area, &err), 0);
  assert_int_equal(n, 14);
  assert_true(fabs(area[0] - 2.0f) < 1e-6f && fabs(area[1] - 2.0f) < 1e-6f);
  double box = 0;
  for (int i = 2; i < 14; i++) box += area[i];
  assert_true(fabs(box - 2.0 * (1 * 2 + 1 * 3 + 2 * 3)) < 1e-5);
  free(area);
  obs_rt rt;
  assert_int_equal(obs_rt_build(&sc, &rt, 1, &err), 0);
  int32_t ids[256];
  obs_patch_ids(&rt, &sc, ids);
  int seen[2] = {0, 0};
  for (int y = 0; y < 16; y++)
    for (int x = 0; x < 16; x++) {
      int32_t id = ids[y * 16 + x];
      int inside = x >= 4 && x < 12 && y >= 4 && y < 12; /* the quad spans half the view */
      if (inside) {
        assert_true(id == 0 || id == 1);
        seen[id]++;
      } else {
        assert_int_equal(id, -1);
      }
    }
  assert_true(seen[0] > 0 && seen[1] > 0);
  /* The shown image: each pixel the value of its patch, 0 off the quad. */
  obs_patches p;
  assert_int_equal(obs_patches_init(&p, "w", 14, 1, 0, &err), 0);
  for (int i = 0; i < 14; i++) p.values[i] = 0.5f + (float)i;
  obs_image img;
  const char *ch[] = {"w"};
  assert_int_equal(obs_image_init(&img, 16, 16, 1, ch, &err), 0);
  assert_int_equal(obs_patch_show(&rt, &sc, &p, &img, ch, &err), 0);
  for (int i = 0; i < 256; i++)
    assert_true(img.data[i] == (ids[i] < 0 ? 0.0f : 0.5f + (float)ids[i]));
  obs_image_free(&img);
  obs_patches_free(&p);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Every registered technique's CPU render has exactly the EXR channels its outputs declare. */
static void test_channels_match_declarations(void **state) {
  (void)state;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    if (!obs_technique_has_backend(t, OBS_BACKEND_CPU)) continue;
    char doc[2048], ball[512];
    const char *tail = strstr(quad_scene, "],\"environment\"");
    obs_test_ball(t, 0, 0.5, 0, 0.5, ball, sizeof ball);
    int medium = (t->needs & OBS_NEED_MEDIUM) != 0; /* a marble ball under a directional light */
    snprintf(doc, sizeof doc,
             "%.*s,{%s%s}],%s\"environment\":{\"color\":[1,1,1]},\"technique\":{\"name\":\"%s\","
             "\"backend\":\"cpu\"}}",
             (int)(tail - quad_scene), quad_scene, ball, obs_test_medium_material(t),
             medium ? "\"lights\":[{\"type\":\"directional\",\"direction\":[0,-1,0],"
                      "\"emission\":[1,1,1]}],"
                    : "",
             t->name);
    obs_result r;
    obs_test_render(doc, 1, &r);
    char ch[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
    int declared = 0;
    for (const obs_output *o = t->outputs; o->name; o++) {
      int n = obs_output_channels(o, ch);
      for (int c = 0; c < n; c++) {
        if (!obs_image_channel(&r.image, ch[c])) fprintf(stderr, "%s: no %s\n", t->name, ch[c]);
        assert_non_null(obs_image_channel(&r.image, ch[c]));
      }
      declared += n;
    }
    assert_int_equal(r.image.nchannels, declared);
    obs_result_free(&r);
  }
}

/* An AO render's summary keeps its older fields beside the per-output block. */
static void test_summary_ao(void **state) {
  (void)state;
  obs_result r;
  obs_test_render(quad_scene, 2, &r);
  obs_scene sc;
  obs_test_load(quad_scene, "quad.json", &sc);
  json_t *sum = obs_result_summary_json(&r, &sc);
  obs_stats all, covered, se;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_metrics_stats(&r.image, "ao", NULL, &all, &err), 0);
  assert_int_equal(obs_metrics_stats(&r.image, "ao", "alpha", &covered, &err), 0);
  assert_int_equal(obs_metrics_stats(&r.image, "ao_stderr", "alpha", &se, &err), 0);
  assert_true(covered.count > 0 && covered.count < all.count);
  assert_true(json_real_value(json_object_get(json_object_get(sum, "ao"), "mean")) == all.mean);
  assert_true(json_real_value(json_object_get(sum, "ao_stderr_mean")) == se.mean);
  assert_string_equal(json_string_value(json_object_get(sum, "primary_output")), "ao");
  json_t *outs = json_object_get(sum, "outputs");
  json_t *ao = json_object_get(json_object_get(json_object_get(outs, "ao"), "channels"), "ao");
  assert_true(json_real_value(json_object_get(ao, "mean")) == covered.mean);
  assert_int_equal(json_integer_value(json_object_get(ao, "count")), covered.count);
  /* alpha's own statistics are over every pixel. */
  json_t *al = json_object_get(json_object_get(json_object_get(outs, "alpha"), "channels"),
                               "alpha");
  assert_int_equal(json_integer_value(json_object_get(al, "count")), all.count);
  assert_non_null(json_object_get(json_object_get(json_object_get(outs, "normal"), "channels"),
                                  "normal.X"));
  json_decref(sum);
  obs_scene_free(&sc);
  obs_result_free(&r);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_registry_declarations),
      cmocka_unit_test(test_openapi_enum),
      cmocka_unit_test(test_writer_without_ao),
      cmocka_unit_test(test_voxel_refused),
      cmocka_unit_test(test_patch_file),
      cmocka_unit_test(test_patch_scene_and_ids),
      cmocka_unit_test(test_summary_ao),
      cmocka_unit_test(test_channels_match_declarations),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
