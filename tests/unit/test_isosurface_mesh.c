/* Isosurface extraction (renderer/core/isosurface.h) and the isosurface_mesh technique: the
 * procedural sphere's area and enclosed volume converge to the analytic ones as h^2, the surface
 * is closed and consistently wound at every refinement level, deeper levels lower the error and
 * find surface the coarse samples miss, the mesh scales with the volume,
 * the geometry build turns volume objects into meshes for surface techniques, and the technique's
 * depth and normals agree with the exact isosurface (volume_ao's bisected ray cast). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"
#include "isosurface.h"
#include "testutil.h"
#include "volume.h"

#define PI 3.14159265358979323846

/* The procedural sphere is 0.5 - d / 2 (clamped) for d the signed distance to radius 0.6 in
 * [-1, 1]^3, so isovalue `iso` is the sphere of radius 0.6 + (1 - 2 iso); the fill spans [0, 2]^3,
 * the same units. */
static double sphere_radius(double iso) { return 0.6 + (1.0 - 2.0 * iso); }

static void sphere_volume(int n, obs_volume *v) {
  obs_err err = OBS_ERR_INIT;
  const int dims[3] = {n, n, n};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_SPHERE, 1, dims, v, &err), 0);
  obs_err_free(&err);
}

static int cmp_u64(const void *a, const void *b) {
  uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return x < y ? -1 : x > y;
}

/* Closed and oriented: every directed edge once, its reverse once (so every undirected edge has
 * exactly two triangles, wound against each other); no degenerate index triple. */
static void assert_watertight(const obs_iso_mesh *m) {
  size_t ne = 3 * m->ntris;
  uint64_t *d = malloc(ne * sizeof *d), *r = malloc(ne * sizeof *r);
  assert_non_null(d);
  assert_non_null(r);
  for (size_t t = 0; t < m->ntris; t++)
    for (int e = 0; e < 3; e++) {
      uint64_t a = m->idx[3 * t + e], b = m->idx[3 * t + (e + 1) % 3];
      assert_true(a != b);
      d[3 * t + e] = a << 32 | b;
      r[3 * t + e] = b << 32 | a;
    }
  qsort(d, ne, sizeof *d, cmp_u64);
  qsort(r, ne, sizeof *r, cmp_u64);
  for (size_t i = 0; i < ne; i++) {
    if (i) assert_true(d[i] != d[i - 1]); /* a directed edge twice: inconsistent winding */
    assert_true(d[i] == r[i]);            /* each directed edge has its reverse */
  }
  /* Welded per lattice edge: keys strictly rising. */
  for (size_t i = 1; i < m->nverts; i++) assert_true(m->key[i] > m->key[i - 1]);
  free(d);
  free(r);
}

/* Area and volume against 4 pi r^2 and 4/3 pi r^3 on lattices of 8, 16 and 32 cells: each
 * relative error small, and falling by at least 2.5x per halving of h (h^2 gives 4x). */
static void converge(int refine, double iso) {
  obs_volume v;
  sphere_volume(128, &v);
  double r = sphere_radius(iso), A = 4 * PI * r * r, V = 4.0 / 3.0 * PI * r * r * r;
  double ea[3], ev[3];
  const int cells[3] = {8, 16, 32};
  for (int c = 0; c < 3; c++) {
    obs_iso_mesh m;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_iso_extract(&v, (float)iso, cells[c], refine, &m, &err), 0);
    assert_watertight(&m);
    double area, vol;
    obs_iso_mesh_measure(&m, &area, &vol);
    ea[c] = fabs(area / A - 1);
    ev[c] = fabs(vol / V - 1);
    printf("     refine %d iso %.2f cells %2d: %6zu triangles, area err %.2e, volume err %.2e\n",
           refine, iso, cells[c], m.ntris, ea[c], ev[c]);
    assert_true(vol > 0); /* outward winding */
    obs_iso_mesh_free(&m);
    obs_err_free(&err);
  }
  assert_true(ea[2] < 5e-3 && ev[2] < 1e-2);
  for (int c = 1; c < 3; c++) {
    assert_true(ea[c] * 2.5 < ea[c - 1]);
    assert_true(ev[c] * 2.5 < ev[c - 1]);
  }
  obs_volume_free(&v);
}

static void test_sphere_converges(void **state) {
  (void)state;
  converge(0, 0.5);
  converge(0, 0.45); /* radius 0.7 */
}

static void test_refined_converges(void **state) {
  (void)state;
  for (int r = 1; r <= OBS_ISO_REFINE_MAX; r++) converge(r, 0.5);
}

/* On one coarse lattice, each bisection level samples more of the field: the sphere's area and
 * volume errors fall with the level, and level 3 (every half-lattice point) is within a factor of
 * the lattice of half the spacing. */
static void test_levels_improve(void **state) {
  (void)state;
  obs_volume v;
  sphere_volume(64, &v);
  double r = sphere_radius(0.45), A = 4 * PI * r * r, V = 4.0 / 3.0 * PI * r * r * r;
  double ea[OBS_ISO_REFINE_MAX + 1], ev[OBS_ISO_REFINE_MAX + 1];
  obs_err err = OBS_ERR_INIT;
  for (int l = 0; l <= OBS_ISO_REFINE_MAX; l++) {
    obs_iso_mesh m;
    assert_int_equal(obs_iso_extract(&v, 0.45f, 6, l, &m, &err), 0);
    assert_watertight(&m);
    double area, vol;
    obs_iso_mesh_measure(&m, &area, &vol);
    ea[l] = fabs(area / A - 1);
    ev[l] = fabs(vol / V - 1);
    printf("     cells 6 refine %d: %6zu triangles, area err %.2e, volume err %.2e\n", l, m.ntris,
           ea[l], ev[l]);
    obs_iso_mesh_free(&m);
  }
  for (int l = 1; l <= OBS_ISO_REFINE_MAX; l++) {
    assert_true(ea[l] < ea[l - 1]);
    assert_true(ev[l] < ev[l - 1]);
  }
  assert_true(ea[3] * 2.5 < ea[0] && ev[3] * 2.5 < ev[0]);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* A sphere too small for the coarse lattice's corners: refinement's centre samples find it. */
static void test_refine_finds_missed_surface(void **state) {
  (void)state;
  obs_volume v;
  sphere_volume(64, &v);
  obs_iso_mesh a, b;
  obs_err err = OBS_ERR_INIT;
  /* Radius 0.1 (in [-1, 1] units) about the centre, 0.58 from the nearest corner of 3 cells. */
  float iso = 0.75f;
  assert_int_equal(obs_iso_extract(&v, iso, 3, 0, &a, &err), 0);
  assert_int_equal(obs_iso_extract(&v, iso, 3, 1, &b, &err), 0);
  assert_int_equal(a.ntris, 0);
  assert_true(b.ntris > 0);
  assert_watertight(&b);
  obs_iso_mesh_free(&a);
  obs_iso_mesh_free(&b);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* A small sphere centred on the face between two cells (the box squashed along z to two cells of
 * three): no corner or cell centre reaches it, the face centres of level 2 and 3 do, and their
 * surface is closed. */
static void test_deeper_levels_find_thin_features(void **state) {
  (void)state;
  obs_volume v;
  sphere_volume(64, &v);
  v.spacing[2] *= 2.0 / 3.0;
  obs_err err = OBS_ERR_INIT;
  for (int l = 0; l <= OBS_ISO_REFINE_MAX; l++) {
    obs_iso_mesh m;
    assert_int_equal(obs_iso_extract(&v, 0.75f, 3, l, &m, &err), 0);
    assert_int_equal(m.lat.c[2], 2);
    if (l < 2)
      assert_int_equal(m.ntris, 0);
    else
      assert_true(m.ntris > 0);
    assert_watertight(&m);
    obs_iso_mesh_free(&m);
  }
  obs_iso_mesh m;
  assert_int_equal(obs_iso_extract(&v, 0.75f, 3, OBS_ISO_REFINE_MAX + 1, &m, &err), OBS_EINVAL);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* One, two and three threads give the same mesh, bit for bit, at every level. */
static void test_threads_same_bits(void **state) {
  (void)state;
  obs_volume v;
  obs_err err = OBS_ERR_INIT;
  const int dims[3] = {40, 40, 40};
  assert_int_equal(obs_volume_procedural_fill(OBS_VOLUME_TORUS, 1, dims, &v, &err), 0);
  for (int l = 0; l <= OBS_ISO_REFINE_MAX; l++) {
    obs_iso_mesh base;
    assert_int_equal(obs_iso_extract(&v, 0.5f, 20, l, &base, &err), 0);
    assert_true(base.ntris > 100);
    for (int th = 2; th <= 3; th++) {
      obs_iso_mesh m;
      assert_int_equal(obs_iso_extract_threads(&v, 0.5f, 20, l, th, &m, &err), 0);
      assert_int_equal(m.ntris, base.ntris);
      assert_int_equal(m.nverts, base.nverts);
      assert_memory_equal(m.idx, base.idx, 3 * m.ntris * sizeof *m.idx);
      assert_memory_equal(m.key, base.key, m.nverts * sizeof *m.key);
      assert_memory_equal(m.t, base.t, m.nverts * sizeof *m.t);
      assert_memory_equal(m.pos, base.pos, 3 * m.nverts * sizeof *m.pos);
      obs_iso_mesh_free(&m);
    }
    obs_iso_mesh_free(&base);
  }
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* The mesh of a volume scaled by s is the mesh scaled by s: the same indices, positions within
 * float's rounding. */
static void test_scale_invariance(void **state) {
  (void)state;
  obs_volume v;
  sphere_volume(48, &v);
  obs_iso_mesh base;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_iso_extract(&v, 0.5f, 24, 0, &base, &err), 0);
  const double scales[2] = {1e-4, 1e4};
  for (int s = 0; s < 2; s++) {
    obs_volume w = v;
    for (int a = 0; a < 3; a++) w.spacing[a] = v.spacing[a] * scales[s];
    obs_iso_mesh m;
    assert_int_equal(obs_iso_extract(&w, 0.5f, 24, 0, &m, &err), 0);
    assert_int_equal(m.ntris, base.ntris);
    assert_int_equal(m.nverts, base.nverts);
    assert_memory_equal(m.idx, base.idx, 3 * m.ntris * sizeof(uint32_t));
    for (size_t i = 0; i < 3 * m.nverts; i++)
      assert_true(fabs(m.pos[i] / scales[s] - base.pos[i]) <= 1e-6 * v.spacing[0]);
    obs_iso_mesh_free(&m);
  }
  obs_iso_mesh_free(&base);
  obs_volume_free(&v);
  obs_err_free(&err);
}

/* Every table case: the triangles' edges are edges of the tetrahedron that cross (one corner
 * above, one below), and the counts are 0, 1 or 2 as the corners split. */
static void test_tables(void **state) {
  (void)state;
  for (int r = 0; r < 2; r++) {
    const obs_iso_table *tb = obs_iso_table_get(r);
    assert_int_equal(tb->ntets, r ? 12 : 6);
    for (int t = 0; t < tb->ntets; t++)
      for (int cs = 0; cs < 16; cs++) {
        int up = __builtin_popcount((unsigned)cs);
        assert_int_equal(tb->ntri[t][cs], up == 0 || up == 4 ? 0 : up == 2 ? 2 : 1);
        for (int k = 0; k < tb->ntri[t][cs]; k++)
          for (int e = 0; e < 3; e++) {
            int u = tb->edge[t][cs][k][e][0], w = tb->edge[t][cs][k][e][1], su = -1, sw = -1;
            for (int q = 0; q < 4; q++) {
              if (tb->tet[t][q] == u) su = cs >> q & 1;
              if (tb->tet[t][q] == w) sw = cs >> q & 1;
            }
            assert_true(su >= 0 && sw >= 0 && su != sw);
            assert_true(obs_iso_edge_slot(u, w) >= 0);
          }
      }
  }
}

/* A surface technique on a scene made only of volumes renders their meshes; the geometry build
 * places each by its object's transform. */
static const char *volume_scene =
    "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0.4, -2], \"look_at\": [0, 0, 0],"
    " \"up\": [0, 1, 0], \"fov_y\": 40},"
    " \"image\": {\"width\": 32, \"height\": 24, \"spp\": 1},"
    " \"objects\": [{\"name\": \"ball\", \"shape\": {\"type\": \"volume\", \"procedural\":"
    " \"sphere\", \"dims\": [32, 32, 32], \"mesh_cells\": 16},"
    " \"transform\": {\"scale\": [2, 2, 2], \"translate\": [0.25, 0, 0]}}],"
    " \"technique\": {\"name\": \"rt_ao\", \"backend\": \"cpu\", \"params\": {\"samples\": 4}}}";

static void test_geometry_build(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(volume_scene, "vol.json", &sc);
  obs_geometry g;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_geometry_build(&sc, &g, &err), 0);
  assert_int_equal(g.nmeshes, 1);
  assert_true(g.ntris > 100);
  /* Radius 0.3 in object space (the box's longest side is 1), times 2, about (0.25, 0, 0). */
  double rmin = 1e9, rmax = 0;
  const obs_mesh *m = &g.meshes[0];
  for (size_t i = 0; i < m->nverts; i++) {
    double d[3] = {m->pos[3 * i] - 0.25, m->pos[3 * i + 1], m->pos[3 * i + 2]};
    double rr = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    rmin = fmin(rmin, rr);
    rmax = fmax(rmax, rr);
  }
  assert_true(rmin > 0.6 * 0.97 && rmax < 0.6 * 1.01);
  obs_geometry_free(&g);
  obs_result res;
  obs_test_render(volume_scene, 1, &res);
  const float *alpha = obs_image_channel(&res.image, "alpha");
  assert_non_null(alpha);
  double cov = 0;
  for (int i = 0; i < 32 * 24; i++) cov += alpha[i];
  assert_true(cov > 50);
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* The technique against the exact isosurface (volume_ao's bisected hit and gradient normal) on
 * the same camera rays: depth within a fraction of a cell, normals within a few degrees, the same
 * coverage but at the silhouette. */
static void test_against_exact(void **state) {
  (void)state;
  char doc[1024];
  const char *fmt =
      "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0.5, -1.6], \"look_at\": [0, 0, "
      "0],"
      " \"up\": [0, 1, 0], \"fov_y\": 40}, \"image\": {\"width\": 48, \"height\": 32, \"spp\": 1},"
      " \"objects\": [{\"name\": \"torus\", \"shape\": {\"type\": \"volume\", \"procedural\":"
      " \"torus\", \"dims\": [48, 48, 48]}, \"transform\": {\"rotate\": [70, 0, 0]}}],"
      " \"environment\": {\"color\": [1, 1, 1]},"
      " \"technique\": {\"name\": \"%s\", \"backend\": \"cpu\", \"params\": {%s}}}";
  obs_result a, b;
  snprintf(doc, sizeof doc, fmt, "isosurface_mesh", "\"grid\": 48");
  obs_test_render(doc, 2, &a);
  snprintf(doc, sizeof doc, fmt, "volume_ao", "\"samples\": 1, \"ibl\": \"none\"");
  obs_test_render(doc, 2, &b);
  const float *aa = obs_image_channel(&a.image, "alpha"),
              *ba = obs_image_channel(&b.image, "alpha");
  const float *ad = obs_image_channel(&a.image, "depth.Z"),
              *bd = obs_image_channel(&b.image, "depth.Z");
  const float *an[3] = {obs_image_channel(&a.image, "normal.X"),
                        obs_image_channel(&a.image, "normal.Y"),
                        obs_image_channel(&a.image, "normal.Z")};
  const float *bn[3] = {obs_image_channel(&b.image, "normal.X"),
                        obs_image_channel(&b.image, "normal.Y"),
                        obs_image_channel(&b.image, "normal.Z")};
  size_t both = 0, differ = 0;
  double angle = 0, drel = 0;
  for (int i = 0; i < 48 * 32; i++) {
    if ((aa[i] > 0) != (ba[i] > 0)) differ++;
    if (!(aa[i] > 0 && ba[i] > 0)) continue;
    both++;
    double dot = an[0][i] * bn[0][i] + an[1][i] * bn[1][i] + an[2][i] * bn[2][i];
    angle += acos(fmin(1, fmax(-1, dot)));
    drel = fmax(drel, fabs(ad[i] / bd[i] - 1));
  }
  angle = angle / (double)both * 180 / PI;
  printf("     %zu pixels both, %zu differ in coverage; mean angle %.2f deg, max depth rel %.2e\n",
         both, differ, angle, drel);
  assert_true(both > 200);
  assert_true(differ * 20 < both);
  /* A cell of 1/48 of the box against depths near 1.6: a fraction of a cell is ~1e-2. */
  assert_true(drel < 1e-2);
  assert_true(angle < 5);
  obs_result_free(&a);
  obs_result_free(&b);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_tables),
      cmocka_unit_test(test_sphere_converges),
      cmocka_unit_test(test_refined_converges),
      cmocka_unit_test(test_refine_finds_missed_surface),
      cmocka_unit_test(test_levels_improve),
      cmocka_unit_test(test_deeper_levels_find_thin_features),
      cmocka_unit_test(test_threads_same_bits),
      cmocka_unit_test(test_scale_invariance),
      cmocka_unit_test(test_geometry_build),
      cmocka_unit_test(test_against_exact),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
