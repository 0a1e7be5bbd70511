/* disc_ao on the CPU: a disc's on-axis fraction exactly, the disc of a triangle, the side
 * choice, the reach, the subdivision's area, and the grid against every disc summed by brute
 * force on a scene's G-buffer. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testutil.h"

#include "disc_ao.h"
#include "gbuffer_cpu.h"

#define PI 3.14159265358979323846

static obs_disc_ao_params defaults(void) {
  obs_disc_ao_params p = {.proxy = OBS_DISC_PROXY_QUAD, .area_over_pi = 1,
                          .influence_scale = 4.0f, .side = OBS_DISC_SIDE_FRONT,
                          .subdivide = 0.05f};
  return p;
}

/* A 1 x 1 orthographic G-buffer whose one receiver sits at view depth z facing the camera. */
static void one_receiver(obs_gbuffer *g, float z) {
  obs_camera_rig rig = {.ortho = 1, .half_w = 1, .half_h = 1, .width = 1, .height = 1};
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_alloc(g, 1, 1, &rig, &err), 0);
  g->depth[0] = z;
  g->normal[0] = 0, g->normal[1] = 0, g->normal[2] = -1;
  g->coverage[0] = 1;
}

/* An equilateral triangle of area A centred on the view axis at depth z, in the plane z = const,
 * wound so that its (world) normal is -z (towards the camera) or +z. */
static void axis_disc(double area, double z, int towards_camera, const obs_disc_ao_params *p,
                      obs_disc *d) {
  double s = sqrt(4 * area / sqrt(3.0)), h = s * sqrt(3.0) / 2;
  double a[3] = {-s / 2, -h / 3, z}, b[3] = {s / 2, -h / 3, z}, c[3] = {0, 2 * h / 3, z};
  assert_int_equal(towards_camera ? obs_disc_make(a, b, c, p, d) : obs_disc_make(b, a, c, p, d),
                   1);
}

/* A receiver on the axis of a disc of radius r that faces it, at distance d: AO is
 * 1/sqrt(r^2/d^2 + 1) with area_over_pi (the disc's exact solid-angle fraction), and with the
 * listing's area (A = pi r^2 in place of r^2) otherwise. */
static void test_on_axis(void **state) {
  (void)state;
  const double r = 0.75, dist[] = {0.2, 0.75, 1.0, 2.0, 2.9};
  for (int over_pi = 0; over_pi < 2; over_pi++)
    for (size_t k = 0; k < sizeof dist / sizeof dist[0]; k++) {
      obs_disc_ao_params p = defaults();
      p.area_over_pi = over_pi;
      obs_gbuffer g;
      one_receiver(&g, 10.0f);
      obs_disc_set s = {.n = 1, .triangles = 1};
      obs_disc d;
      axis_disc(PI * r * r, 10.0 - dist[k], 0, &p, &d);
      s.d = &d;
      float ao, raw;
      obs_err err = OBS_ERR_INIT;
      assert_int_equal(obs_disc_ao_cpu_apply(&g, &s, &p, 1, &ao, &raw, NULL, &err), 0);
      double a = over_pi ? r * r : PI * r * r, want = 1 / sqrt(a / (dist[k] * dist[k]) + 1);
      printf("r %.2f d %.2f area_over_pi %d: ao %.7f, exact %.7f\n", r, dist[k], over_pi, ao,
             want);
      assert_true(fabs(ao - want) <= 2e-6);
      assert_true(fabs(raw - want) <= 2e-6);
      obs_gbuffer_free(&g);
    }
}

/* The side: a disc facing the receiver occludes it under "front" (the text) and not under "back"
 * (the listing); one facing away, the other way round. */
static void test_side(void **state) {
  (void)state;
  for (int side = 0; side < 2; side++)
    for (int towards = 0; towards < 2; towards++) {
      obs_disc_ao_params p = defaults();
      p.side = side;
      obs_disc d;
      axis_disc(1.0, 9.0, towards, &p, &d);
      const float pos[3] = {0, 0, 10}, nr[3] = {0, 0, -1};
      float occ = obs_disc_occlusion(&d, pos, nr, p.side);
      int occludes = (side == OBS_DISC_SIDE_FRONT) == (towards == 0);
      printf("side %s, disc normal %s the receiver: occlusion %.6f\n", side ? "back" : "front",
             towards ? "away from" : "towards", occ);
      /* The disc at depth 9 faces the receiver at 10 when its normal is +z, "away from" the
       * camera. */
      assert_true(occludes ? occ > 0.1f : occ == 0.0f);
    }
}

/* The disc of a triangle: the centroid, the area (over pi), the unit normal of the winding, and
 * the reach influence_scale sqrt(A); nothing for a degenerate triangle. */
static void test_disc_make(void **state) {
  (void)state;
  obs_disc_ao_params p = defaults();
  p.influence_scale = 3.0f;
  const double a[3] = {1, 2, 5}, b[3] = {4, 2, 5}, c[3] = {1, 6, 5}; /* area 6 */
  obs_disc d;
  assert_int_equal(obs_disc_make(a, b, c, &p, &d), 1);
  assert_float_equal(d.c[0], 2.0, 1e-6);
  assert_float_equal(d.c[1], 10.0 / 3, 1e-6);
  assert_float_equal(d.c[2], 5.0, 1e-6);
  assert_float_equal(d.a, 6 / PI, 1e-6);
  assert_float_equal(d.r2, 9 * 6.0, 1e-4);
  /* (b - a) x (c - a) is +z in view coordinates, which mirror the world: the normal is -z. */
  assert_float_equal(d.n[2], -1.0, 1e-7);
  p.area_over_pi = 0;
  assert_int_equal(obs_disc_make(a, b, c, &p, &d), 1);
  assert_float_equal(d.a, 6.0, 1e-6);
  assert_int_equal(obs_disc_make(a, a, c, &p, &d), 0);
}

/* The reach cuts at influence_scale sqrt(A) exactly; the centroid itself and a receiver below
 * the disc's plane or facing away get 0, finite. */
static void test_reach(void **state) {
  (void)state;
  obs_disc_ao_params p = defaults();
  obs_disc d;
  axis_disc(1.0, 0.0, 0, &p, &d); /* A = 1: reach 4, normal +z */
  const float nr[3] = {0, 0, -1}, up[3] = {0, 0, 1};
  const float in[3] = {0, 0, 3.99f}, out[3] = {0, 0, 4.01f}, at[3] = {d.c[0], d.c[1], d.c[2]};
  assert_true(obs_disc_occlusion(&d, in, nr, p.side) > 0.0f);
  assert_true(obs_disc_occlusion(&d, out, nr, p.side) == 0.0f);
  assert_true(obs_disc_occlusion(&d, at, nr, p.side) == 0.0f);
  assert_true(obs_disc_occlusion(&d, in, up, p.side) == 0.0f);
  const float behind[3] = {0, 0, -1};
  assert_true(obs_disc_occlusion(&d, behind, up, p.side) == 0.0f);
  /* Past black: the clamp, and the raw value below 0. */
  float ao, raw;
  obs_disc_ao_finish(1.25f, &ao, &raw);
  assert_true(ao == 0.0f && raw == -0.25f);
}

static const char *QUAD_SCENE =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0,0],"
    "\"fov_y\":45},\"image\":{\"width\":8,\"height\":8},\"objects\":[{\"shape\":{\"type\":"
    "\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],[2,0,2],[2,0,-2]]}}],"
    "\"technique\":{\"name\":\"disc_ao\",\"backend\":\"cpu\",\"params\":{}}}";

/* The subdivision: a 4 x 4 quad (diagonal 4 sqrt 2) with edges of at most 0.1 of it splits each
 * of its triangles into m^2 with m = ceil(4 sqrt 2 / (0.1 * 4 sqrt 2)) = 10, their areas summing
 * to the quad's. */
static void test_subdivide(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(QUAD_SCENE, "disc_ao.json", &sc);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, 8, 8, &rig);
  obs_disc_ao_params p = defaults();
  p.area_over_pi = 0;
  for (int k = 0; k < 2; k++) {
    p.subdivide = k ? 0.1f : 1.0f;
    obs_disc_set s;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_disc_set_build(&sc, &rig, &p, &s, &err), 0);
    double area = 0;
    for (size_t i = 0; i < s.n; i++) area += s.d[i].a;
    printf("subdivide %.2f: %zu discs from %zu triangles, area %.6f\n", (double)p.subdivide, s.n,
           s.triangles, area);
    assert_int_equal(s.triangles, 2);
    assert_int_equal(s.n, k ? 200 : 2);
    assert_float_equal(area, 16.0, 1e-4);
    obs_disc_set_free(&s);
  }
  obs_scene_free(&sc);
}

/* A box on a floor with a ball: the grid's sums equal every disc's, summed in the discs' order by
 * brute force, bit for bit. */
static void test_grid_matches_brute_force(void **state) {
  (void)state;
  const char *doc =
      "{\"camera\":{\"type\":\"perspective\",\"position\":[1,2.5,-4],\"look_at\":[0,0.4,0],"
      "\"fov_y\":45},\"image\":{\"width\":40,\"height\":30},\"objects\":["
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]]}},"
      "{\"shape\":{\"type\":\"box\",\"min\":[-0.8,0,-0.2],\"max\":[-0.2,1,0.4]}},"
      "{\"shape\":{\"type\":\"sphere\",\"center\":[0.6,0.5,0],\"radius\":0.5}}],"
      "\"technique\":{\"name\":\"disc_ao\",\"backend\":\"cpu\",\"params\":{}}}";
  obs_scene sc;
  obs_test_load(doc, "disc_ao.json", &sc);
  obs_gbuffer g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_gbuffer_cpu(&sc, &g, 2, NULL, NULL, &err), 0);
  obs_camera_rig rig;
  obs_camera_setup(&sc.camera, g.width, g.height, &rig);
  for (int side = 0; side < 2; side++) {
    obs_disc_ao_params p = defaults();
    p.side = side;
    p.influence_scale = side ? 8.0f : 4.0f;
    obs_disc_set s;
    assert_int_equal(obs_disc_set_build(&sc, &rig, &p, &s, &err), 0);
    size_t n = (size_t)g.width * (size_t)g.height;
    float *ao = malloc(n * sizeof *ao), *raw = malloc(n * sizeof *raw);
    obs_disc_ao_stats st;
    assert_int_equal(obs_disc_ao_cpu_apply(&g, &s, &p, 3, ao, raw, &st, &err), 0);
    size_t dark = 0;
    for (int y = 0; y < g.height; y++)
      for (int x = 0; x < g.width; x++) {
        size_t i = (size_t)y * (size_t)g.width + (size_t)x;
        float want = 1.0f, want_raw = 1.0f;
        if (g.depth[i] > 0) {
          float pos[3], sum = 0.0f;
          obs_gbuffer_position(&g, (float)x + 0.5f, (float)y + 0.5f, g.depth[i], pos);
          for (size_t k = 0; k < s.n; k++) sum += obs_disc_occlusion(&s.d[k], pos, g.normal + 3 * i, p.side);
          obs_disc_ao_finish(sum, &want, &want_raw);
        }
        assert_true(ao[i] == want && raw[i] == want_raw);
        dark += want < 0.9f;
      }
    printf("side %d: %zu discs, %zu of %zu pixels below 0.9, %llu pairs in reach, most %u, "
           "%llu clamped\n",
           side, s.n, dark, n, (unsigned long long)st.fragments, st.max_overdraw,
           (unsigned long long)st.clamped);
    assert_true(dark > n / 50);
    free(ao);
    free(raw);
    obs_disc_set_free(&s);
  }
  obs_gbuffer_free(&g);
  obs_scene_free(&sc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_on_axis),
      cmocka_unit_test(test_side),
      cmocka_unit_test(test_disc_make),
      cmocka_unit_test(test_reach),
      cmocka_unit_test(test_subdivide),
      cmocka_unit_test(test_grid_matches_brute_force),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
