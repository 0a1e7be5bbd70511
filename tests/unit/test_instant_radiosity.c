/* instant_radiosity on the CPU: the clamped form factor against the article's construction (the
 * receiver moved along the VPL's normal), the gather of hand-made VPLs over a hand-made G-buffer
 * against that closed form (finite and bounded at the VPL itself), the adaptive filter across a
 * depth step, the direct light of a square emitter against its analytic irradiance within the
 * estimate's standard error, the renewal schedule, determinism for a seed and what exact
 * visibility removes. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#include "raytrace.h"
#include "../../renderer/techniques/instant_radiosity/instant_radiosity.h"

static const obs_technique *tech(void) { return obs_technique_find("instant_radiosity"); }

static const char *const SPHERE_DOC =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,0],\"look_at\":[0,0,1],\"fov_y\":40},"
    "\"image\":{\"width\":4,\"height\":4},\"objects\":[{\"shape\":{\"type\":\"sphere\","
    "\"center\":[0,0,5],\"radius\":1},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
    "\"technique\":{\"name\":\"instant_radiosity\",\"backend\":\"%s\",\"params\":%s}}";

static int load_rc(const char *backend, const char *params) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, obs_test_fmt(SPHERE_DOC, backend, params), "irad.json", NULL,
                                 NULL, 0, &err);
  if (!rc)
    obs_scene_free(&sc);
  else
    printf("refused as expected: %s\n", obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

/* Defaults bound from an empty params object; bad values refused by the loader; exact visibility
 * refused on Vulkan, naming the parameter and the backend. */
static void test_params(void **state) {
  (void)state;
  json_t *js = json_object();
  obs_instant_radiosity_params p;
  assert_int_equal(obs_params_bind(tech(), js, &p, NULL), 0);
  json_decref(js);
  assert_int_equal(p.vpls, 512);
  assert_int_equal(p.max_bounces, 3);
  assert_int_equal(p.visibility, OBS_IRAD_VIS_NONE);
  assert_int_equal(p.filter, 1);
  const char *bad[] = {"{\"vpls\":0}",          "{\"max_bounces\":17}",  "{\"renew\":1.5}",
                       "{\"clamp_distance\":0}", "{\"filter_normal\":2}", "{\"filter_depth\":-1}",
                       "{\"visibility\":\"exact_or_not\"}", "{\"shadow_bias\":0}"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) assert_true(load_rc("cpu", bad[i]) != 0);
  assert_int_equal(load_rc("cpu", "{\"visibility\":\"exact\"}"), 0);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, obs_test_fmt(SPHERE_DOC, "vulkan", "{\"visibility\":\"exact\"}"),
                                 "irad.json", NULL, NULL, 0, &err);
  assert_true(rc != 0);
  assert_non_null(strstr(obs_err_message(&err), "/technique/params/visibility"));
  assert_non_null(strstr(obs_err_message(&err), "cpu backend only"));
  obs_err_free(&err);
}

static double dot(const double a[3], const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The article's clamp, built geometrically: a receiver x nearer than N_c to the VPL's plane is
 * moved along the VPL normal m until it lies N_c from the plane, and the point-to-point form
 * factor is taken there with the receiver's own cos(theta). */
static double clamp_construction(const double n[3], const double m[3], const double v[3],
                                 double nc) {
  double d2 = dot(v, v), d = sqrt(d2), nv = dot(n, v);
  double cpsi = -dot(m, v) / d, cth = nv / d, N = d * cpsi;
  if (!(cth > 0) || !(cpsi >= 0)) return 0;
  if (N >= nc) return cth * cpsi / d2;
  double w[3]; /* from the moved receiver x' = x + m (N_c - N) to the VPL */
  for (int k = 0; k < 3; k++) w[k] = v[k] - m[k] * (nc - N);
  double d2m = dot(w, w), cpsim = -dot(m, w) / sqrt(d2m);
  return cth * cpsim / d2m;
}

static void test_form_factor(void **state) {
  (void)state;
  uint32_t s = 7;
  const double nc = 0.3;
  int clamped = 0, open = 0;
  for (int i = 0; i < 20000; i++) {
    double n[3], m[3], v[3];
    for (int k = 0; k < 3; k++) {
      n[k] = obs_test_unit(&s) - 0.5, m[k] = obs_test_unit(&s) - 0.5;
      v[k] = (obs_test_unit(&s) - 0.5) * (i % 2 ? 0.4 : 4.0);
    }
    double ln = sqrt(dot(n, n)), lm = sqrt(dot(m, m));
    for (int k = 0; k < 3; k++) n[k] /= ln, m[k] /= lm;
    double f = obs_irad_form_factor(n, m, v, 0, nc * nc);
    double g = clamp_construction(n, m, v, nc);
    assert_true(isfinite(f) && f >= 0);
    /* The clamp's bound: delta >= N_c, so F <= 1 / N_c^2 whatever the distance. */
    assert_true(f <= 1.0 / (nc * nc) * (1 + 1e-12));
    assert_true(fabs(f - g) <= 1e-9 * (1 + g));
    double N = -dot(m, v);
    if (f > 0 && N < nc) clamped++;
    if (f > 0 && N >= nc) open++;
  }
  printf("form factor: %d clamped and %d open configurations match the construction\n", clamped,
         open);
  assert_true(clamped > 1000 && open > 1000);
  /* Continuous where the clamp starts (N = N_c): the two branches agree. */
  const double n[3] = {0, 0, 1}, m[3] = {0, 0, -1};
  for (double x = 0; x < 3; x += 0.25) {
    const double lo[3] = {x, 0, nc * (1 - 1e-9)}, hi[3] = {x, 0, nc * (1 + 1e-9)};
    double a = obs_irad_form_factor(n, m, lo, 0, nc * nc), b = obs_irad_form_factor(n, m, hi, 0, nc * nc);
    assert_true(fabs(a - b) <= 1e-7 * b);
  }
  /* Behind the VPL nothing, unless it emits on both sides; a receiver at the VPL: finite. */
  const double behind[3] = {0.1, 0, -0.5};
  assert_true(obs_irad_form_factor(n, m, behind, 0, nc * nc) == 0);
  const double zero[3] = {0, 0, 0};
  assert_true(obs_irad_form_factor(n, m, zero, 0, nc * nc) == 0);
}

/* ---- hand-made VPLs over a hand-made G-buffer ----
 * Orthographic, W x H pixels over [-1, 1]^2, a plane at view depth Z facing the camera (normal
 * (0, 0, -1)), the right half at depth Z2 when `step`; VPLs placed by hand in view space. */
enum { GW = 32, GH = 32 };

static void plane_gbuffer(obs_gbuffer *g, float z, float z2, int step) {
  obs_camera_rig rig;
  memset(&rig, 0, sizeof rig);
  rig.ortho = 1;
  rig.half_w = rig.half_h = 1.0;
  assert_int_equal(obs_gbuffer_alloc(g, GW, GH, &rig, NULL), 0);
  for (int i = 0; i < GW * GH; i++) {
    g->depth[i] = step && i % GW >= GW / 2 ? z2 : z;
    g->normal[3 * i + 2] = -1.0f;
    for (int k = 0; k < 3; k++) g->albedo[3 * i + k] = 0.5f;
    g->coverage[i] = 1.0f;
  }
}

/* One VPL per class (nv of them: classes = nv), at view position pos, normal (0, 0, 1) toward the
 * plane, coefficient (k + 1) (1, 2, 3) for class k. */
static void hand_vpls(obs_irad_light *l, int nv, const float pos[3]) {
  memset(l, 0, sizeof *l);
  l->vpls.n = l->vpls.paths = l->vpls.classes = nv;
  l->vpls.rec = calloc((size_t)nv * 4 * OBS_IRAD_VPL_VEC4, sizeof(float));
  for (int k = 0; k < nv; k++) {
    float *r = l->vpls.rec + (size_t)k * 4 * OBS_IRAD_VPL_VEC4;
    for (int c = 0; c < 3; c++) r[c] = pos[c], r[8 + c] = (float)(k + 1) * (float)(c + 1);
    r[6] = 1.0f;
  }
  for (int k = 0; k <= OBS_IRAD_CLASSES; k++) l->vpls.start[k] = k < nv ? k : nv;
}

static obs_instant_radiosity_params hand_params(float nc, int filter) {
  obs_instant_radiosity_params p;
  memset(&p, 0, sizeof p);
  p.clamp_distance = nc;
  p.filter = filter;
  p.filter_depth = 0.02f;
  p.filter_normal = 0.9f;
  return p;
}

/* The view-space centre of pixel (x, y) on the plane at depth z. */
static void pixel_pos(int x, int y, double z, double out[3]) {
  out[0] = 2.0 * (x + 0.5) / GW - 1.0;
  out[1] = 1.0 - 2.0 * (y + 0.5) / GH;
  out[2] = z;
}

/* One VPL h above the plane: every pixel's irradiance is the closed form, clamped (h < N_c) or
 * not; h = 0 puts the VPL on the plane, where the receivers are coplanar: nothing, and finite. */
static void test_gather_one_vpl(void **state) {
  (void)state;
  const float hs[] = {0.5f, 0.05f, 1e-6f, 0.0f};
  for (size_t c = 0; c < sizeof hs / sizeof hs[0]; c++) {
    obs_gbuffer g;
    plane_gbuffer(&g, 10.0f, 10.0f, 0);
    const float pos[3] = {0.03125f, -0.0625f, 10.0f - hs[c]}; /* above pixel (16, 17)'s centre */
    obs_irad_light l;
    hand_vpls(&l, 1, pos);
    obs_instant_radiosity_params p = hand_params(0.1f, 0);
    float *raw = malloc(4 * GW * GH * sizeof *raw);
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_irad_cpu_apply(&g, &l, &p, 2, raw, NULL, NULL, &err), 0);
    double worst = 0, peak = 0;
    for (int y = 0; y < GH; y++)
      for (int x = 0; x < GW; x++) {
        double P[3], v[3];
        pixel_pos(x, y, 10.0, P);
        for (int k = 0; k < 3; k++) v[k] = (double)pos[k] - P[k];
        const double n[3] = {0, 0, -1}, m[3] = {0, 0, 1};
        double f = obs_irad_form_factor(n, m, v, 0, 0.01);
        const float *r = raw + 4 * (y * GW + x);
        for (int k = 0; k < 3; k++) {
          assert_true(isfinite(r[k]));
          double want = (k + 1) * f;
          worst = fmax(worst, fabs(r[k] - want) / (want + 1e-30));
          assert_true(fabs(r[k] - want) <= 2e-5 * want + 1e-30);
          /* The clamp bounds the irradiance by coef / N_c^2 even at the VPL. */
          assert_true(r[k] <= (k + 1) / 0.01 * (1 + 1e-5));
        }
        assert_true(r[3] == 1.0f);
        peak = fmax(peak, r[0]);
      }
    printf("one VPL at h = %g: worst relative error %.2g, peak irradiance %.4g\n", hs[c], worst,
           peak);
    if (hs[c] == 0.0f) assert_true(peak == 0.0);
    else assert_true(peak > 0.0);
    free(raw);
    free(l.vpls.rec);
    obs_gbuffer_free(&g);
    obs_err_free(&err);
  }
}

/* Sixteen classes, one VPL each, far above the plane, so the form factor is nearly the same at
 * every pixel: the filter makes each interior pixel the mean of the 16 classes. Across a depth
 * step it rejects the other side and takes those classes from 4 pixels the other way, so pixels
 * beside the step still hold every class. */
static void test_filter(void **state) {
  (void)state;
  obs_gbuffer g;
  plane_gbuffer(&g, 10.0f, 20.0f, 1);
  const float pos[3] = {0.0f, 0.0f, -990.0f};
  obs_irad_light l;
  hand_vpls(&l, OBS_IRAD_CLASSES, pos);
  obs_instant_radiosity_params p = hand_params(0.1f, 1);
  float *raw = malloc(4 * GW * GH * sizeof *raw), *out = malloc(4 * GW * GH * sizeof *out);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_irad_cpu_apply(&g, &l, &p, 2, raw, out, NULL, &err), 0);
  const double n[3] = {0, 0, -1}, m[3] = {0, 0, 1};
  for (int y = 4; y < GH - 4; y++)
    for (int x = 4; x < GW - 4; x++) {
      double P[3], v[3];
      pixel_pos(x, y, x >= GW / 2 ? 20.0 : 10.0, P);
      for (int k = 0; k < 3; k++) v[k] = (double)pos[k] - P[k];
      double want = 8.5 * obs_irad_form_factor(n, m, v, 0, 0.01); /* mean of 1 .. 16 */
      const float *r = out + 4 * (y * GW + x);
      assert_true(fabs(r[0] - want) <= 1e-4 * want);
      assert_true(fabs(r[2] - 3 * want) <= 1e-4 * 3 * want);
      /* The raw pixel holds its own class only. */
      int cls = (y & 3) * 4 + (x & 3);
      assert_true(fabs(raw[4 * (y * GW + x)] - want / 8.5 * (cls + 1)) <= 1e-4 * want);
    }
  free(raw);
  free(out);
  free(l.vpls.rec);
  obs_gbuffer_free(&g);
  obs_err_free(&err);
}

/* Approximate visibility on a hand-made G-buffer: the plane at depth 10 with a strip (columns 12
 * to 19) 0.3 in front of it, one VPL 0.01 in front of the plane at the right. Receivers right of
 * the strip see it exactly (visibility 1); the march from receivers left of it lands on the
 * strip, 0.3 nearer than the segment: beyond 2 bias z (0.2) and short of thickness z (0.4), so
 * fully occluded. With a thickness below the bias the strip counts as too far in front: all 1.
 * A VPL beyond the right edge sends the segments off screen into the distance cube: an empty
 * cube hides nothing, a cube whose surfaces lie 0.5 from its centre hides every VPL beyond. */
static void approx_case(float thickness, float vx, float cube_d, float *vis_row) {
  obs_gbuffer g;
  plane_gbuffer(&g, 10.0f, 10.0f, 0);
  for (int y = 0; y < GH; y++)
    for (int x = 12; x < 20; x++) g.depth[y * GW + x] = 9.7f;
  const float pos[3] = {vx, 0.0f, 9.99f};
  obs_irad_light l;
  hand_vpls(&l, 1, pos);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_irad_pyramid_make(&g, &l, &err), 0);
  l.cube = malloc(6 * OBS_IRAD_CUBE * OBS_IRAD_CUBE * sizeof(float));
  for (int i = 0; i < 6 * OBS_IRAD_CUBE * OBS_IRAD_CUBE; i++) l.cube[i] = cube_d;
  l.cube_c[2] = 10.0f;
  obs_instant_radiosity_params p = hand_params(0.001f, 0);
  p.visibility = OBS_IRAD_VIS_APPROX;
  p.shadow_bias = 0.01f;
  p.shadow_thickness = thickness;
  float *raw = malloc(4 * GW * GH * sizeof *raw);
  assert_int_equal(obs_irad_cpu_apply(&g, &l, &p, 2, raw, NULL, NULL, &err), 0);
  for (int x = 0; x < GW; x++) vis_row[x] = raw[4 * (17 * GW + x) + 3];
  free(raw);
  free(l.vpls.rec);
  free(l.pyramid);
  free(l.cube);
  obs_gbuffer_free(&g);
  obs_err_free(&err);
}

static void test_approximate(void **state) {
  (void)state;
  float v[GW];
  approx_case(0.04f, 0.95f, (float)OBS_IRAD_FAR, v);
  int hidden = 0;
  for (int x = 0; x < GW; x++) {
    assert_true(v[x] >= 0.0f && v[x] <= 1.0f);
    if (x >= 20 && x < 30) assert_true(v[x] == 1.0f);
    if (x >= 2 && x < 11) hidden += v[x] < 1e-3f;
  }
  printf("approximate: %d of 9 receivers left of the strip fully hidden\n", hidden);
  assert_true(hidden >= 7);
  approx_case(0.001f, 0.95f, (float)OBS_IRAD_FAR, v);
  for (int x = 0; x < GW; x++) assert_true(v[x] == 1.0f);
  /* Off screen: segments from receivers right of the strip leave the image toward x = 3. */
  approx_case(0.04f, 3.0f, (float)OBS_IRAD_FAR, v);
  for (int x = 20; x < GW; x++) assert_true(v[x] == 1.0f);
  approx_case(0.04f, 3.0f, 0.5f, v);
  for (int x = 20; x < GW; x++) assert_true(v[x] < 1e-3f);
}

/* The point-to-rectangle form factor for a point under a corner of an a x b rectangle parallel to
 * its plane at distance c. */
static double corner_ff(double a, double b, double c) {
  double X = a / c, Y = b / c, sx = sqrt(1 + X * X), sy = sqrt(1 + Y * Y);
  return (X / sx * atan(Y / sx) + Y / sy * atan(X / sy)) / (2 * M_PI);
}

/* A square emitter of side 1 and radiance 1 one unit above a floor of reflectivity 0.5, seen from
 * above by an orthographic camera a thousandth of its size: with max_bounces 1 the VPLs all lie on
 * the emitter (direct light), and the 16 pixels of a 4x4 block hold the 16 classes' independent
 * estimates of the irradiance below the emitter's centre, E = pi L 4 F_corner(1/2, 1/2, 1). Their
 * mean agrees within 4 standard errors, and 16 times the VPLs shrink the error about 4 times. */
static double direct_square(int vpls, double *se) {
  const char *doc = obs_test_fmt(
      "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,3,0],\"look_at\":[0,0,0],"
      "\"up\":[0,0,1],\"height\":0.001},\"image\":{\"width\":8,\"height\":8,\"spp\":1},"
      "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-5,0,-5],[5,0,-5],[5,0,5],"
      "[-5,0,5]]},\"material\":{\"reflectivity\":[0.5,0.5,0.5]}}],"
      "\"lights\":[{\"type\":\"quad\",\"vertices\":[[-0.5,1,-0.5],[0.5,1,-0.5],[0.5,1,0.5],"
      "[-0.5,1,0.5]],\"emission\":[1,1,1]}],"
      "\"technique\":{\"name\":\"instant_radiosity\",\"backend\":\"cpu\",\"params\":{\"vpls\":%d,"
      "\"max_bounces\":1,\"filter\":false,\"clamp_distance\":0.001}}}",
      vpls);
  obs_result r;
  obs_test_render(doc, 2, &r);
  const float *R = obs_image_channel(&r.image, "radiance.R");
  double want = 0.5 / M_PI * M_PI * 4 * corner_ff(0.5, 0.5, 1.0), s = 0, ss = 0;
  for (int y = 2; y < 6; y++)
    for (int x = 2; x < 6; x++) s += R[y * 8 + x], ss += (double)R[y * 8 + x] * R[y * 8 + x];
  double mean = s / 16, var = (ss / 16 - mean * mean) * 16 / 15;
  *se = sqrt(var / 16);
  printf("square emitter, %d VPLs: radiance %.5f, closed form %.5f, standard error %.2g\n", vpls,
         mean, want, *se);
  obs_result_free(&r);
  assert_true(fabs(mean - want) <= 4 * *se + 1e-6 * want);
  return fabs(mean - want);
}

static void test_direct_square(void **state) {
  (void)state;
  double se1, se2;
  direct_square(256, &se1);
  direct_square(4096, &se2);
  assert_true(se2 < se1 / 2 && se2 > se1 / 8);
}

/* The renewal schedule: frame 0 is generation 0 everywhere; renew 1 renews every path every
 * frame; renew 0 never; a share m / paths renews m paths a frame, round robin. */
static void test_renew(void **state) {
  (void)state;
  for (uint32_t p = 0; p < 40; p++) {
    assert_int_equal(obs_irad_generation(p, 40, 0.25f, 0), 0);
    assert_int_equal(obs_irad_generation(p, 40, 1.0f, 7), 7);
    assert_int_equal(obs_irad_generation(p, 40, 0.0f, 7), 0);
  }
  /* 10 a frame: frame 1 renews paths 0..9, frame 4 has renewed each once, frame 5 0..9 again. */
  for (uint32_t p = 0; p < 40; p++) {
    assert_int_equal(obs_irad_generation(p, 40, 0.25f, 1), p < 10 ? 1 : 0);
    assert_int_equal(obs_irad_generation(p, 40, 0.25f, 4), 1);
    assert_int_equal(obs_irad_generation(p, 40, 0.25f, 5), p < 10 ? 2 : 1);
  }
  uint64_t total = 0;
  for (uint32_t f = 0; f <= 12; f++) {
    uint64_t sum = 0;
    for (uint32_t p = 0; p < 170; p++) sum += obs_irad_generation(p, 170, 0.125f, f);
    assert_true(sum == total + (f ? 21 : 0)); /* round(0.125 x 170) = 21 paths a frame */
    total = sum;
  }
}

static const char *cornell(int w, const char *params) {
  return obs_test_fmt("{\"technique\":{\"name\":\"instant_radiosity\",\"backend\":\"cpu\","
                      "\"params\":%s},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1}}",
                      params, w, w);
}

static void render_cornell(const char *params, obs_result *r) {
  char tech[512];
  const char *all = cornell(24, params);
  json_t *js = json_loads(all, 0, NULL);
  char *t = json_dumps(json_object_get(js, "technique"), JSON_COMPACT);
  char *im = json_dumps(json_object_get(js, "image"), JSON_COMPACT);
  snprintf(tech, sizeof tech, "%s", t);
  const obs_override ov[] = {{"/technique", tech}, {"/image", im}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src("scenes/cornell_box.json"), ov, 2, &err);
  if (rc) printf("%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_render_opts o = {.threads = 2};
  rc = obs_render(&sc, &o, r, &err);
  if (rc) printf("%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_test_assert_finite(&r->image);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free(t);
  free(im);
  json_decref(js);
}

static int same_channel(const obs_result *a, const obs_result *b, const char *ch) {
  size_t n = (size_t)a->image.width * (size_t)a->image.height;
  return !memcmp(obs_image_channel(&a->image, ch), obs_image_channel(&b->image, ch),
                 n * sizeof(float));
}

/* The same seed, frame and renew give the same bits; another seed, or another frame with a share
 * renewed, another image; exact visibility darkens what the blocks hide and nothing else. */
static void test_deterministic(void **state) {
  (void)state;
  obs_result a, b, c, d, e;
  render_cornell("{\"vpls\":64}", &a);
  render_cornell("{\"vpls\":64}", &b);
  render_cornell("{\"vpls\":64,\"seed\":2}", &c);
  render_cornell("{\"vpls\":64,\"frame\":3}", &d);
  render_cornell("{\"vpls\":64,\"visibility\":\"exact\"}", &e);
  assert_true(same_channel(&a, &b, "radiance.R") && same_channel(&a, &b, "radiance.B"));
  assert_false(same_channel(&a, &c, "radiance.R"));
  assert_false(same_channel(&a, &d, "radiance.R"));
  size_t n = 24 * 24, shadowed = 0;
  const float *vn = obs_image_channel(&a.image, "ao"), *ve = obs_image_channel(&e.image, "ao");
  const float *ln = obs_image_channel(&a.image, "radiance.G"),
              *le = obs_image_channel(&e.image, "radiance.G");
  for (size_t i = 0; i < n; i++) {
    assert_true(vn[i] == 1.0f);
    assert_true(ve[i] >= 0.0f && ve[i] <= 1.0f + 1e-6f);
    assert_true(le[i] <= ln[i] * (1 + 1e-5f) + 1e-7f);
    shadowed += ve[i] < 0.99f;
  }
  printf("exact visibility: %zu of %zu pixels lose more than 1%% of the VPLs' light\n", shadowed,
         n);
  assert_true(shadowed > n / 20);
  obs_result_free(&a);
  obs_result_free(&b);
  obs_result_free(&c);
  obs_result_free(&d);
  obs_result_free(&e);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_params),         cmocka_unit_test(test_form_factor),
      cmocka_unit_test(test_gather_one_vpl), cmocka_unit_test(test_filter),
      cmocka_unit_test(test_approximate),    cmocka_unit_test(test_direct_square),
      cmocka_unit_test(test_renew),
      cmocka_unit_test(test_deterministic),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
