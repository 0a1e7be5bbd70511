/* The sampling frame (obs_onb, renderer/core/sampling.h) and the face normals it is built on: a
 * normal component that is 0 in exact arithmetic counts as +0 whatever sign of zero or rounding
 * noise it carries, and the ray tracer's face normal of a triangle whose products cancel
 * (dx dy - dy dx) has that component exactly 0 at every scale and translation, on both of its
 * paths (obs_rt_intersect and the primary-ray packets). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "raytrace.h"
#include "sampling.h"
#include "testutil.h"

static void assert_orthonormal(const float n[3], const float t[3], const float b[3], float tol) {
  float tb = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
  float tn = t[0] * n[0] + t[1] * n[1] + t[2] * n[2];
  float bn = b[0] * n[0] + b[1] * n[1] + b[2] * n[2];
  float tt = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
  float bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
  assert_true(fabsf(tb) < tol && fabsf(tn) < tol && fabsf(bn) < tol);
  assert_true(fabsf(tt - 1.0f) < tol && fabsf(bb - 1.0f) < tol);
}

/* Walls, floors and poles with every zero component replaced by noise inside the guard (both
 * signs of zero, a few float roundings of 1, just under 2^-20): the same bits as with +0, and a
 * frame still orthonormal to the noisy normal within the guard. */
static void test_guard_takes_noise_as_zero(void **state) {
  (void)state;
  const float base[][3] = {{0.6f, 0.8f, 0}, {0.8f, -0.6f, 0},   {-1, 0, 0}, {0, 1, 0}, {0, -1, 0},
                           {0.6f, 0, 0.8f}, {0, 0.28f, -0.96f}, {0, 0, 1},  {0, 0, -1}};
  const float noise[] = {0.0f,       -0.0f,     0x1p-24f,        -0x1p-24f,
                         0x1.8p-23f, -0x1p-22f, 0x1.fffffep-21f, -0x1.fffffep-21f};
  const int nb = sizeof base / sizeof base[0], nn = sizeof noise / sizeof noise[0];
  for (int i = 0; i < nb; i++) {
    float t0[3], b0[3];
    obs_onb(base[i], t0, b0);
    assert_orthonormal(base[i], t0, b0, 1e-6f);
    for (int j = 0; j < nn; j++)
      for (int mask = 1; mask < 8; mask++) { /* which zero components get noise j (or -j) */
        float n[3], t[3], b[3];
        memcpy(n, base[i], sizeof n);
        for (int k = 0; k < 3; k++)
          if ((mask >> k & 1) && base[i][k] == 0) n[k] = k & 1 ? -noise[j] : noise[j];
        obs_onb(n, t, b);
        assert_memory_equal(t, t0, sizeof t);
        assert_memory_equal(b, b0, sizeof b);
        assert_orthonormal(n, t, b, 2e-6f);
      }
  }
}

/* From 2^-20 on a component counts: z = -2^-20 takes the other half of the frame (the flip moved
 * from 0 to there), and both halves stay orthonormal. */
static void test_guard_edge(void **state) {
  (void)state;
  const float lo[3] = {1, 0, -0x1p-20f}, in[3] = {1, 0, -0x1.fffffep-21f};
  float tl[3], bl[3], ti[3], bi[3];
  obs_onb(lo, tl, bl);
  obs_onb(in, ti, bi);
  assert_orthonormal(lo, tl, bl, 1e-6f);
  assert_orthonormal(in, ti, bi, 2e-6f);
  assert_true(bl[1] < -0.5f && bi[1] > 0.5f); /* b = -y against +y: the frame turned */
  assert_true(tl[2] > 0.5f && ti[2] < -0.5f);
}

/* A leaning wall: two vertices differ only in z, so the face normal's z is dx dy - dy dx. At 24
 * scales from 1e-9 to 1e9 (with translations of 0 to 100 sizes) both hit paths give z exactly 0,
 * and the frame built on the hit normal is the scale-1 one within float rounding (not turned). */
static void test_cancelling_face_normal(void **state) {
  (void)state;
  const double p0[3] = {0.3171, -0.2113, 2.0}, dx = 0.1713, dy = 0.9377;
  const double v[3][3] = {{p0[0], p0[1], p0[2]},
                          {p0[0] + dx, p0[1] + dy, p0[2] + 0.4},
                          {p0[0] + dx, p0[1] + dy, p0[2] - 0.35}};
  float t1[3] = {0}, b1[3] = {0};
  for (int k = 0; k < 24; k++) {
    double s = k ? 1e-9 * pow(1e18, (k - 1) / 22.0) : 1.0, off = s * (k % 4 == 3 ? 100 : k % 4);
    double c[3], cam[3];
    for (int a = 0; a < 3; a++) c[a] = (v[0][a] + v[1][a] + v[2][a]) / 3;
    const double look[3] = {-1.5, 0.3, -0.2}; /* off the wall's plane, on its -x side */
    for (int a = 0; a < 3; a++) cam[a] = (c[a] + look[a]) * s + off;
    char doc[2048];
    snprintf(doc, sizeof doc,
             "{\"camera\":{\"type\":\"perspective\",\"position\":[%.17g,%.17g,%.17g],"
             "\"look_at\":[%.17g,%.17g,%.17g],\"up\":[0,1,0],\"fov_y\":30},"
             "\"image\":{\"width\":4,\"height\":4},\"objects\":[{\"shape\":{\"type\":\"triangle\","
             "\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}}],"
             "\"technique\":{\"name\":\"rt_ao\"}}",
             cam[0], cam[1], cam[2], c[0] * s + off, c[1] * s + off, c[2] * s + off,
             v[0][0] * s + off, v[0][1] * s + off, v[0][2] * s + off, v[1][0] * s + off,
             v[1][1] * s + off, v[1][2] * s + off, v[2][0] * s + off, v[2][1] * s + off,
             v[2][2] * s + off);
    obs_scene sc;
    obs_test_load(doc, "wall.json", &sc);
    obs_rt rt;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_rt_build(&sc, &rt, 1, &err), 0);
    double dir[3], org[3];
    for (int a = 0; a < 3; a++) org[a] = cam[a], dir[a] = -look[a];
    obs_hit hit;
    assert_int_equal(obs_rt_intersect(&rt, org, dir, INFINITY, &hit), 1);
    assert_true(hit.ng[2] == 0.0f);
    assert_true(hit.ng[0] * dir[0] + hit.ng[1] * dir[1] < 0); /* faced against the ray */
    obs_rt_view view = {.ortho = 0};
    for (int a = 0; a < 3; a++) {
      view.eye[a] = cam[a] - rt.geo.origin[a];
      view.forward[a] = dir[a];
      view.right[a] = view.up[a] = 0;
    }
    const double sx = 0, sy = 0;
    obs_rt_primary pr;
    obs_rt_intersect_primary(&rt, &view, 1, &sx, &sy, &pr);
    assert_true(pr.geom != RTC_INVALID_GEOMETRY_ID && pr.ng[2] == 0.0);
    for (int a = 0; a < 3; a++) assert_true((float)pr.ng[a] == hit.ng[a]); /* one normal */
    float t[3], b[3];
    obs_onb(hit.ng, t, b);
    if (!k) memcpy(t1, t, sizeof t), memcpy(b1, b, sizeof b);
    for (int a = 0; a < 3; a++)
      assert_true(fabsf(t[a] - t1[a]) < 1e-6f && fabsf(b[a] - b1[a]) < 1e-6f);
    obs_rt_free(&rt);
    obs_scene_free(&sc);
    obs_err_free(&err);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_guard_takes_noise_as_zero),
      cmocka_unit_test(test_guard_edge),
      cmocka_unit_test(test_cancelling_face_normal),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
