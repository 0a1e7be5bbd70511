/* Proximity fields and proximity_ao: the overlap test, the voxelisation, the flood against a
 * brute-force one, the two-plane superposition, the reconstruction's arithmetic, renders with
 * objects outside each other's fields, the camera rays against one ray at a time and under
 * regions and tiles, moving objects, the extremes of the layout, r_p's reference boxes and the
 * accessibility bound over several fields. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "proximity.h"
#include "proximity_ao.h"
#include "raytrace.h"
#include "testutil.h"
#include "prox_bound_cases.h"

static const obs_prox_layout default_layout = {.fraction = 0.1, .box = OBS_PROX_BOX_LARGEST,
                                               .res = 32, .min_res = 8};

static const char *scene_doc(const char *objects, const char *params) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[0,2,-5],\"look_at\":[0,0,0],"
      "\"up\":[0,1,0],\"fov_y\":50},\"image\":{\"width\":24,\"height\":16,\"spp\":1},"
      "\"objects\":[%s],\"technique\":{\"name\":\"proximity_ao\",\"backend\":\"cpu\","
      "\"params\":{%s}}}",
      objects, params);
}

static void build(const char *doc, const obs_prox_layout *lay, int threads, obs_scene *sc,
                  obs_prox_fields *fs) {
  obs_test_load(doc, "prox.json", sc);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_prox_build(sc, lay, threads, NULL, NULL, fs, &err);
  if (rc) fprintf(stderr, "%s\n", err.text);
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

static size_t at(const obs_prox_field *f, int x, int y, int z) {
  return ((size_t)z * (size_t)f->dims[1] + (size_t)y) * (size_t)f->dims[0] + (size_t)x;
}

static void test_tri_box(void **state) {
  (void)state;
  const double c[3] = {0, 0, 0}, h[3] = {0.5, 0.5, 0.5};
  double a[3] = {-0.2, -0.2, 0}, b[3] = {0.2, -0.2, 0}, d[3] = {0, 0.2, 0};
  assert_true(obs_prox_tri_box(c, h, a, b, d)); /* inside */
  double a2[3] = {-5, -5, 0.1}, b2[3] = {5, -5, 0.1}, d2[3] = {0, 5, 0.1};
  assert_true(obs_prox_tri_box(c, h, a2, b2, d2)); /* a large triangle through the box */
  double a3[3] = {-5, -5, 0.6}, b3[3] = {5, -5, 0.6}, d3[3] = {0, 5, 0.6};
  assert_false(obs_prox_tri_box(c, h, a3, b3, d3)); /* its plane above the box */
  /* Boxes overlap, but the edge x + y = 1.2 separates: only an edge axis finds it. */
  double a4[3] = {1.2, 0, 0}, b4[3] = {0, 1.2, 0}, d4[3] = {1.2, 1.2, 0};
  assert_false(obs_prox_tri_box(c, h, a4, b4, d4));
  double a5[3] = {0.9, 0, 0}, b5[3] = {0, 0.9, 0}, d5[3] = {0.9, 0.9, 0};
  assert_true(obs_prox_tri_box(c, h, a5, b5, d5));
  /* A triangle in the plane of a face touches the closed box. */
  double a6[3] = {-0.3, -0.3, 0.5}, b6[3] = {0.3, -0.3, 0.5}, d6[3] = {0, 0.3, 0.5};
  assert_true(obs_prox_tri_box(c, h, a6, b6, d6));
}

/* One sphere: occupied voxels hold exactly 1, the field is mirror-symmetric about the centre
 * and falls with distance outside the surface along each axis. */
static void test_sphere_field(void **state) {
  (void)state;
  obs_scene sc;
  obs_prox_fields fs;
  build(scene_doc("{\"shape\":{\"type\":\"sphere\",\"center\":[0,0,0],\"radius\":1}}", ""),
        &default_layout, 2, &sc, &fs);
  assert_int_equal(fs.n, 1);
  const obs_prox_field *f = &fs.f[0];
  assert_int_equal(f->dims[0], 32);
  assert_int_equal(f->dims[1], 32);
  assert_int_equal(f->dims[2], 32);
  assert_true(f->iterations >= 2);
  assert_true(f->occupied_count > 0);
  for (size_t i = 0; i < f->count; i++) {
    if (f->occupied[i]) assert_true(f->value[i] == 1.0f);
    assert_true(f->value[i] >= 0.0f && f->value[i] <= 1.0f);
  }
  int n = f->dims[0];
  double worst = 0;
  for (int z = 0; z < n; z++)
    for (int y = 0; y < n; y++)
      for (int x = 0; x < n; x++) {
        float v = f->value[at(f, x, y, z)];
        worst = fmax(worst, fabs(v - f->value[at(f, n - 1 - x, y, z)]));
        worst = fmax(worst, fabs(v - f->value[at(f, x, n - 1 - y, z)]));
        worst = fmax(worst, fabs(v - f->value[at(f, x, y, n - 1 - z)]));
        worst = fmax(worst, fabs(v - f->value[at(f, y, x, z)]));
      }
  assert_true(worst <= 1e-6);
  /* Outward from the last occupied voxel along +x of the middle row: never rising, and falling
   * to below 1 % within the propagation radius. */
  int m = n / 2, x0 = n - 1;
  while (x0 > 0 && !f->occupied[at(f, x0, m, m)]) x0--;
  assert_true(x0 > m && x0 < n - 1);
  for (int x = x0 + 1; x < n; x++)
    assert_true(f->value[at(f, x, m, m)] <= f->value[at(f, x - 1, m, m)]);
  assert_true(f->value[at(f, n - 1, m, m)] < 0.01f);
  assert_true(f->value[at(f, x0 + 1, m, m)] > 0.1f);
  obs_prox_fields_free(&fs);
  obs_scene_free(&sc);
}

/* The flood against its definition, taken literally in double: the mean of the 26 neighbours
 * (0 outside), P <- (P + mean) / 2, occupied voxels fixed at 1. */
static void brute_flood(const obs_prox_field *f, double *v, int iterations) {
  int nx = f->dims[0], ny = f->dims[1], nz = f->dims[2];
  double *next = malloc(f->count * sizeof *next);
  for (int it = 0; it < iterations; it++) {
    for (int z = 0; z < nz; z++)
      for (int y = 0; y < ny; y++)
        for (int x = 0; x < nx; x++) {
          size_t i = at(f, x, y, z);
          if (f->occupied[i]) {
            next[i] = 1;
            continue;
          }
          double s = 0;
          for (int dz = -1; dz <= 1; dz++)
            for (int dy = -1; dy <= 1; dy++)
              for (int dx = -1; dx <= 1; dx++) {
                int a = x + dx, b = y + dy, c = z + dz;
                if ((dx || dy || dz) && a >= 0 && a < nx && b >= 0 && b < ny && c >= 0 && c < nz)
                  s += v[at(f, a, b, c)];
              }
          next[i] = 0.5 * (v[i] + s / 26);
        }
    memcpy(v, next, f->count * sizeof *v);
  }
  free(next);
}

static void random_field(obs_prox_field *f, int nx, int ny, int nz, uint32_t seed) {
  memset(f, 0, sizeof *f);
  f->dims[0] = nx, f->dims[1] = ny, f->dims[2] = nz;
  f->count = (size_t)nx * ny * nz;
  for (int k = 0; k < 3; k++) f->voxel[k] = 1;
  f->occupied = calloc(f->count, 1);
  f->value = calloc(f->count, sizeof *f->value);
  for (size_t i = 0; i < f->count; i++) {
    f->occupied[i] = obs_test_unit(&seed) < 0.05;
    f->value[i] = f->occupied[i];
  }
}

static void test_flood_brute_force(void **state) {
  (void)state;
  obs_prox_field f;
  random_field(&f, 13, 10, 9, 7);
  double *want = malloc(f.count * sizeof *want);
  for (size_t i = 0; i < f.count; i++) want[i] = f.value[i];
  f.iterations = 6;
  brute_flood(&f, want, 6);
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_prox_flood_cpu(NULL, &f, 3, &err), 0);
  double worst = 0;
  for (size_t i = 0; i < f.count; i++) worst = fmax(worst, fabs(f.value[i] - want[i]));
  printf("flood vs brute force (13x10x9, 6 iterations): max |d| %.3g\n", worst);
  assert_true(worst <= 1e-6);
  /* Threads change nothing: the same bits on 1 thread. */
  obs_prox_field g;
  random_field(&g, 13, 10, 9, 7);
  g.iterations = 6;
  assert_int_equal(obs_prox_flood_cpu(NULL, &g, 1, &err), 0);
  assert_memory_equal(f.value, g.value, f.count * sizeof *f.value);
  free(want);
  free(f.occupied), free(f.value), free(g.occupied), free(g.value);
}

/* A field over [0, 32]^3 (voxel 1) holding the planes z = z1 and z = z2 (two triangles each). */
static void planes_field(obs_prox_field *f, const double *zs, int nplanes, int iterations) {
  memset(f, 0, sizeof *f);
  for (int k = 0; k < 3; k++) f->dims[k] = 32, f->voxel[k] = 1, f->lo[k] = 0;
  f->count = 32 * 32 * 32;
  f->occupied = calloc(f->count, 1);
  f->value = calloc(f->count, sizeof *f->value);
  float pos[8 * 3];
  uint32_t idx[4 * 3];
  for (int p = 0; p < nplanes; p++) {
    float z = (float)zs[p];
    float v[4][3] = {{2, 2, z}, {30, 2, z}, {30, 30, z}, {2, 30, z}};
    memcpy(pos + 12 * p, v, sizeof v);
    uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; i++) idx[6 * p + i] = t[i] + 4 * (uint32_t)p;
  }
  obs_mesh m = {.pos = pos, .idx = idx, .nverts = 4 * (size_t)nplanes,
                .ntris = 2 * (size_t)nplanes};
  obs_prox_voxelise_mesh(f, &m, 2);
  for (size_t i = 0; i < f->count; i++) f->value[i] = f->occupied[i];
  f->iterations = iterations;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_prox_flood_cpu(NULL, f, 2, &err), 0);
}

/* Every voxel the surface passes through is occupied: random points of a tilted open sheet, two
 * triangles through each other and a sliver all land in occupied voxels (no holes). */
static void test_voxelise_no_holes(void **state) {
  (void)state;
  float pos[] = {4, 4, 10.3f, 28, 4, 18.1f, 28, 28, 22.9f, 4, 28, 15.2f, /* tilted sheet */
                 6, 16, 3, 26, 16, 29, 16, 27, 16,                      /* through it */
                 3, 3, 3, 29, 29.5f, 28, 29, 29.6f, 28.02f};            /* sliver */
  uint32_t idx[] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 7, 8, 9};
  obs_mesh m = {.pos = pos, .idx = idx, .nverts = 10, .ntris = 4};
  obs_prox_field f;
  memset(&f, 0, sizeof f);
  for (int k = 0; k < 3; k++) f.dims[k] = 32, f.voxel[k] = 1, f.lo[k] = 0;
  f.count = 32 * 32 * 32;
  f.occupied = calloc(f.count, 1);
  obs_prox_voxelise_mesh(&f, &m, 2);
  uint32_t seed = 11;
  size_t occ = 0;
  for (size_t i = 0; i < f.count; i++) occ += f.occupied[i];
  for (int t = 0; t < 4; t++)
    for (int s = 0; s < 20000; s++) {
      double u = obs_test_unit(&seed), v = obs_test_unit(&seed);
      if (u + v > 1) u = 1 - u, v = 1 - v;
      int c[3];
      for (int k = 0; k < 3; k++) {
        double a = pos[3 * idx[3 * t] + k], b = pos[3 * idx[3 * t + 1] + k],
               d = pos[3 * idx[3 * t + 2] + k];
        c[k] = (int)floor(a + u * (b - a) + v * (d - a));
      }
      assert_true(f.occupied[at(&f, c[0], c[1], c[2])]);
    }
  /* And not much more than the surface: a voxel layer is about as many voxels as the sheet's
   * area, so the occupied count stays within a few layers of 24 x 24. */
  assert_true(occ < 6 * 24 * 24);
  free(f.occupied);
}

/* Two parallel planes 15 voxels apart: while the fronts of their fields have not met, the field
 * of both is the sum of each one's (the thesis's Fig. 3.2.3.2); after, the deviation is
 * reported. */
static void test_two_planes_sum(void **state) {
  (void)state;
  const double zs[2] = {8.5, 23.5};
  for (int iterations = 7; iterations <= 12; iterations += 5) {
    obs_prox_field a, b, both;
    planes_field(&a, zs, 1, iterations);
    planes_field(&b, zs + 1, 1, iterations);
    planes_field(&both, zs, 2, iterations);
    /* Each plane at a voxel centre: one layer, voxels 1..30 (its edges at 2 and 30 touch the
     * voxels on both sides). */
    size_t occ = 0;
    for (size_t i = 0; i < both.count; i++) occ += both.occupied[i];
    assert_int_equal(occ, 2 * 30 * 30);
    double worst = 0;
    for (size_t i = 0; i < both.count; i++)
      worst = fmax(worst, fabs((double)both.value[i] - ((double)a.value[i] + b.value[i])));
    printf("two planes 15 voxels apart, %d iterations: max |joint - sum| %.3g\n", iterations,
           worst);
    if (iterations == 7) assert_true(worst <= 1e-6);
    else assert_true(worst > 0); /* met: the other plane's voxels hold 1, not the sum */
    free(a.occupied), free(a.value), free(b.occupied), free(b.value);
    free(both.occupied), free(both.value);
  }
}

static void test_reconstruction_arithmetic(void **state) {
  (void)state;
  obs_prox_field f;
  memset(&f, 0, sizeof f);
  for (int k = 0; k < 3; k++) f.dims[k] = 8, f.voxel[k] = 1;
  f.count = 512;
  float ones[513];
  for (int i = 0; i < 513; i++) ones[i] = i < 512 ? 1.0f : 0.0f;
  f.value = ones;
  const float gp[3] = {4, 4, 4}, gs[3] = {0.1f, 0, 0}, gt[3] = {0, 0.1f, 0}, gb[3] = {0, 0, 0.1f};
  obs_prox_recon r;
  /* Everything occupied: the first step that reads (i = 2) reaches the stop value. */
  obs_prox_recon_init(&r, 20, OBS_PROX_THESIS_CODE, 0.95f, 0.8f, 0.8f, 1);
  assert_float_equal(obs_prox_occlusion(&f, NULL, &r, gp, gs, gt, gb), 1 * 0.8 / 20 * 0.8, 1e-6);
  obs_prox_recon_init(&r, 20, OBS_PROX_CORRECTED, 0.95f, 0.8f, 0.8f, 1);
  assert_float_equal(obs_prox_occlusion(&f, NULL, &r, gp, gs, gt, gb), 0.9 * 0.8 / 20 * 0.8, 1e-6);
  /* No stop: the code sums floor(i/2) reads per step (90 in all), clamped to 1 after / N; the
   * text averages them and weighs step i by 1 - i/N (8.55 in all for i = 2..19). */
  obs_prox_recon_init(&r, 20, OBS_PROX_THESIS_CODE, 1000.0f, 0.8f, 0.8f, 1);
  assert_float_equal(obs_prox_occlusion(&f, NULL, &r, gp, gs, gt, gb), 0.8, 1e-6);
  obs_prox_recon_init(&r, 20, OBS_PROX_CORRECTED, 1000.0f, 0.8f, 0.8f, 1);
  assert_float_equal(obs_prox_occlusion(&f, NULL, &r, gp, gs, gt, gb), 8.55 * 0.8 / 20 * 0.8, 1e-6);
  /* Every read outside the box is skipped: nothing occludes. */
  const float far[3] = {40, 4, 4};
  assert_float_equal(obs_prox_occlusion(&f, NULL, &r, far, gs, gt, gb), 0.0, 0.0);
  /* The disc points lie in the unit disc, floor(i/2) per step. */
  for (int i = 0; i < 20; i++) {
    assert_int_equal(r.first[i + 1] - r.first[i], i / 2);
    for (int j = r.first[i]; j < r.first[i + 1]; j++)
      assert_true(r.disc[j][0] * r.disc[j][0] + r.disc[j][1] * r.disc[j][1] <= 1.0f);
  }
}

/* The eight-lane reads (from the corner copy) give the scalar reads' bits: random fields, points
 * and axes, both reconstructions, and a grid one voxel thin on two axes (every read clamped). */
static void reconstruction_paths(int nx, int ny, int nz) {
  obs_prox_field f;
  random_field(&f, nx, ny, nz, 3);
  f.iterations = 4;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_prox_flood_cpu(NULL, &f, 2, &err), 0);
  assert_int_equal(obs_prox_corners_count(&f), 2 * (size_t)(nx + 1) * ny * (size_t)(nz + 1));
  uint32_t seed = 5;
  for (int mode = 0; mode < 2; mode++) {
    obs_prox_recon scalar, wide;
    obs_prox_recon_init(&scalar, 20, mode, 0.95f, 0.8f, 0.8f, 9);
    scalar.isa = 0; /* OBS_ISA_SSE2 */
    obs_prox_recon_init(&wide, 20, mode, 0.95f, 0.8f, 0.8f, 9);
    assert_null(obs_prox_corners(&f, &scalar, 2));
    float *corners = obs_prox_corners(&f, &wide, 2);
    if (wide.isa < 1) { /* below OBS_ISA_AVX2: one path only */
      assert_null(corners);
      continue;
    }
    assert_non_null(corners);
    for (int t = 0; t < 2000; t++) {
      float gp[3], gs[3], gt[3], gb[3];
      for (int k = 0; k < 3; k++) {
        gp[k] = (float)(obs_test_unit(&seed) * (f.dims[k] + 4) - 2);
        gs[k] = (float)(obs_test_unit(&seed) - 0.5);
        gt[k] = (float)(obs_test_unit(&seed) - 0.5);
        gb[k] = (float)(obs_test_unit(&seed) - 0.5);
      }
      float a = obs_prox_occlusion(&f, NULL, &scalar, gp, gs, gt, gb);
      float b = obs_prox_occlusion(&f, corners, &wide, gp, gs, gt, gb);
      assert_memory_equal(&a, &b, sizeof a);
    }
    free(corners);
  }
  free(f.occupied), free(f.value);
}

static void test_reconstruction_paths(void **state) {
  (void)state;
  reconstruction_paths(17, 12, 9);
  reconstruction_paths(1, 5, 1);
}

static const char *const two_balls =
    "{\"shape\":{\"type\":\"sphere\",\"center\":[-2,0,0],\"radius\":0.5}},"
    "{\"shape\":{\"type\":\"sphere\",\"center\":[2,0,0],\"radius\":0.5}}";

static const float *channel(const obs_image *img, const char *name) {
  const float *c = obs_image_channel(img, name);
  assert_non_null(c);
  return c;
}

/* The result's "built" (summary.json's): each of the `n` fields with its dims and bytes, and the CPU walk's
 * corner copy of each where it reads eight points at a time. */
static void check_built(const obs_result *res, size_t n) {
  const json_t *built = res->built;
  obs_prox_recon r;
  obs_prox_recon_init(&r, 1, OBS_PROX_THESIS_CODE, 1, 1, 1, 1);
  size_t per = r.isa >= 1 ? 2 : 1; /* OBS_ISA_AVX2 and above: a copy per field */
  /* First the BVH of the camera rays (Embree's memory: some, and at least as much at its peak). */
  assert_int_equal(json_array_size(built), 1 + n * per);
  json_t *bvh = json_array_get(built, 0);
  assert_string_equal(json_string_value(json_object_get(bvh, "name")), "bvh");
  assert_int_equal(json_integer_value(json_object_get(bvh, "spheres")), n);
  assert_true(json_integer_value(json_object_get(bvh, "bytes")) > 0);
  assert_true(json_integer_value(json_object_get(bvh, "peak_bytes")) >=
              json_integer_value(json_object_get(bvh, "bytes")));
  for (size_t i = 0; i < n; i++) {
    json_t *f = json_array_get(built, 1 + i), *d = json_object_get(f, "dims");
    assert_string_equal(json_string_value(json_object_get(f, "name")), "proximity_field");
    json_int_t nx = json_integer_value(json_array_get(d, 0)),
               ny = json_integer_value(json_array_get(d, 1)),
               nz = json_integer_value(json_array_get(d, 2));
    assert_true(nx > 0 && ny > 0 && nz > 0);
    assert_int_equal(json_integer_value(json_object_get(f, "bytes")), 5 * nx * ny * nz);
    assert_true(json_integer_value(json_object_get(f, "occupied")) > 0);
    if (per == 1) continue;
    json_t *c = json_array_get(built, 1 + n + i);
    assert_string_equal(json_string_value(json_object_get(c, "name")), "proximity_corners");
    assert_int_equal(json_integer_value(json_object_get(c, "object")),
                     json_integer_value(json_object_get(f, "object")));
    assert_int_equal(json_integer_value(json_object_get(c, "bytes")),
                     8 * (nx + 1) * ny * (nz + 1));
  }
}

/* Receivers outside every field are open; inside their own, they read one field. */
static void test_render_outside_fields(void **state) {
  (void)state;
  for (int self = 0; self <= 1; self++) {
    obs_result res;
    obs_test_render(scene_doc(two_balls, self ? "" : "\"self_occlusion\":false"), 2, &res);
    const float *ao = channel(&res.image, "ao"), *nf = channel(&res.image, "fields"),
                *alpha = channel(&res.image, "alpha");
    int covered = 0;
    for (int i = 0; i < res.image.width * res.image.height; i++) {
      if (alpha[i] == 0) {
        assert_true(ao[i] == 1.0f);
        continue;
      }
      covered++;
      assert_true(nf[i] == (float)self);
      if (self) assert_true(ao[i] >= 0.2f && ao[i] <= 1.0f);
      else assert_true(ao[i] == 1.0f);
    }
    assert_true(covered > 0);
    assert_int_equal(obs_test_check_sane("two balls", res.technique, &res.image), 0);
    if (self) check_built(&res, 2);
    obs_result_free(&res);
  }
}

/* A floor, a ball on it and a box beside it, seen at an angle: triangles, an analytic sphere and
 * the background in one view, at `spp` samples per pixel. */
static const char *gbuffer_doc(int spp) {
  return obs_test_fmt(
      "{\"camera\":{\"type\":\"perspective\",\"position\":[1.3,2.1,-4.2],\"look_at\":"
      "[0,0.4,0],\"up\":[0,1,0],\"fov_y\":47},\"image\":{\"width\":37,\"height\":23,"
      "\"spp\":%d},\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],"
      "[-2,0,2],[2,0,2],[2,0,-2]]}},{\"shape\":{\"type\":\"sphere\",\"center\":[-0.4,0.5,0],"
      "\"radius\":0.5}},{\"shape\":{\"type\":\"box\",\"min\":[0.3,0,-0.5],\"max\":[1,0.8,"
      "0.4]}}],\"technique\":{\"name\":\"proximity_ao\",\"backend\":\"cpu\",\"params\":"
      "{\"volume_res\":32}}}",
      spp);
}

/* The camera rays go to Embree a cell of pixels at a time: each pixel's depth, normal and
 * coverage are those of one ray through its centre (obs_rt_intersect, the ray caster's other
 * entry), to the rounding of the hit's depth. */
static void test_camera_rays(void **state) {
  (void)state;
  obs_result res;
  obs_test_render(gbuffer_doc(1), 2, &res);
  obs_scene sc;
  obs_test_load(gbuffer_doc(1), "rays.json", &sc);
  obs_rt rt;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_rt_build(&sc, &rt, 1, &err), 0);
  obs_camera_rig cam;
  obs_camera_setup(&sc.camera, sc.width, sc.height, &cam);
  const float *depth = channel(&res.image, "depth.Z"), *alpha = channel(&res.image, "alpha");
  const float *nrm[3] = {channel(&res.image, "normal.X"), channel(&res.image, "normal.Y"),
                         channel(&res.image, "normal.Z")};
  int hits = 0, misses = 0;
  for (int y = 0; y < sc.height; y++)
    for (int x = 0; x < sc.width; x++) {
      size_t i = (size_t)y * (size_t)sc.width + (size_t)x;
      double org[3], dir[3];
      obs_camera_ray(&cam, x + 0.5, y + 0.5, org, dir);
      obs_hit h;
      if (!obs_rt_intersect(&rt, org, dir, INFINITY, &h)) {
        assert_true(alpha[i] == 0.0f && depth[i] == 0.0f);
        misses++;
        continue;
      }
      hits++;
      assert_true(alpha[i] == 1.0f);
      double z = h.t * (dir[0] * cam.forward[0] + dir[1] * cam.forward[1] +
                        dir[2] * cam.forward[2]);
      assert_true(fabs(depth[i] - z) <= 1e-6 * z);
      for (int k = 0; k < 3; k++) assert_true(fabsf(nrm[k][i] - h.ng[k]) <= 1e-6f);
    }
  assert_true(hits > 200 && misses > 20);
  obs_rt_free(&rt);
  obs_scene_free(&sc);
  obs_result_free(&res);
  obs_err_free(&err);
}

/* A region and tiles that cut the cells of four pixels, on 1 and 2 threads, at one sample per
 * pixel and at three: every pixel they shade has the whole render's bits, and the rays add up. */
static void test_camera_rays_tiles(void **state) {
  (void)state;
  for (int spp = 1; spp <= 3; spp += 2) {
    obs_scene sc;
    obs_test_load(gbuffer_doc(spp), "tiles.json", &sc);
    obs_err err = OBS_ERR_INIT;
    obs_render_opts o = {.threads = 2};
    obs_result whole, part;
    assert_int_equal(obs_render(&sc, &o, &whole, &err), 0);
    assert_int_equal(whole.rays, (uint64_t)spp * 37 * 23);
    const obs_region r = {3, 1, 35, 22};
    for (int threads = 1; threads <= 2; threads++) {
      o = (obs_render_opts){.threads = threads, .region = r};
      assert_int_equal(obs_render(&sc, &o, &part, &err), 0);
      assert_int_equal(part.rays, (uint64_t)spp * (35 - 3) * (22 - 1));
      obs_test_assert_region(&whole.image, &part.image, r);
      obs_result_free(&part);
    }
    obs_result_free(&whole);
    obs_err_free(&err);
    obs_scene_free(&sc);
  }
}

static const char *const floor_quad =
    "{\"name\":\"floor\",\"shape\":{\"type\":\"quad\",\"vertices\":[[-2,0,-2],[-2,0,2],"
    "[2,0,2],[2,0,-2]]}}";

/* A moving occluder: the fields are built once, every frame is rendered, and the last frame's
 * image is the bits of a static scene with the occluder where that frame puts it. */
static void test_motion_last_frame(void **state) {
  (void)state;
  char objs[1024];
  snprintf(objs, sizeof objs,
           "%s,{\"name\":\"block\",\"shape\":{\"type\":\"box\",\"min\":[-0.5,0,-0.5],"
           "\"max\":[0.5,1,0.5]},\"transform\":{\"translate\":[0,0.05,0]},"
           "\"motion\":[{\"translate\":[0.3,0.4,0]}]}",
           floor_quad);
  obs_result moving, still;
  obs_test_render(scene_doc(objs, ""), 2, &moving);
  snprintf(objs, sizeof objs,
           "%s,{\"name\":\"block\",\"shape\":{\"type\":\"box\",\"min\":[-0.5,0,-0.5],"
           "\"max\":[0.5,1,0.5]},\"transform\":{\"translate\":[0.3,0.4,0]}}",
           floor_quad);
  obs_test_render(scene_doc(objs, ""), 2, &still);
  assert_non_null(moving.frames);
  assert_int_equal(json_array_size(moving.frames), 2);
  int voxelise = 0;
  for (int i = 0; i < moving.nstages; i++) voxelise += !strcmp(moving.stage_names[i], "voxelise");
  assert_int_equal(voxelise, 1);
  assert_int_equal(moving.image.nchannels, still.image.nchannels);
  size_t n = (size_t)moving.image.width * moving.image.height * moving.image.nchannels;
  assert_memory_equal(moving.image.data, still.image.data, n * sizeof(float));
  /* The block shades the floor under it: some pixel is darker than the open floor. */
  const float *ao = channel(&still.image, "ao");
  float lo = 1;
  for (int i = 0; i < still.image.width * still.image.height; i++) lo = fminf(lo, ao[i]);
  assert_true(lo < 0.95f);
  obs_result_free(&moving);
  obs_result_free(&still);
}

/* The layout's extremes render finite, in-range accessibility: no propagation, a radius larger
 * than the scene, one voxel, 512 voxels along a thin bar, an object far smaller than a voxel. */
static void test_extremes(void **state) {
  (void)state;
  const char *bar = "{\"shape\":{\"type\":\"box\",\"min\":[-1,-0.01,-0.01],"
                    "\"max\":[1,0.01,0.01]}}";
  const char *speck = "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0,0.6,0],"
                      "[1e-4,0.6,0],[0,0.6,1e-4]]}},{\"shape\":{\"type\":\"sphere\","
                      "\"center\":[0,0,0],\"radius\":0.5}}";
  const struct {
    const char *objects, *params, *what;
  } cases[] = {
      {two_balls, "\"propagation_fraction\":0", "no propagation"},
      {two_balls, "\"propagation_fraction\":10", "r_p ten times the largest box"},
      {two_balls, "\"volume_res\":1,\"min_res\":1", "one voxel"},
      {bar, "\"volume_res\":512,\"propagation_fraction\":0.02", "512 voxels"},
      {speck, "\"reconstruction\":\"corrected\",\"combine\":\"multiplicative\"",
       "an object smaller than a voxel"},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    obs_result res;
    obs_test_render(scene_doc(cases[i].objects, cases[i].params), 2, &res);
    assert_int_equal(obs_test_check_sane(cases[i].what, res.technique, &res.image), 0);
    obs_result_free(&res);
  }
}

/* r_p's reference boxes: the thesis's maximal box takes per axis the largest extent over all
 * objects, `largest` the largest single object's box, `union` the box of all. A floor 10 x 4 and a
 * pillar 1 x 6 x 1 standing apart: sqrt(10^2 + 6^2 + 4^2), the floor's sqrt(10^2 + 4^2), the
 * union's. And a room of six wall quads has the same maximal box as one box shape, while its
 * largest object is one wall: the maximal box does not depend on how the scene is cut up. */
static void test_propagation_boxes(void **state) {
  (void)state;
  const char *floor_pillar =
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,0,4],[10,0,4],[10,0,0]]}},"
      "{\"shape\":{\"type\":\"box\",\"min\":[12,0,1],\"max\":[13,6,2]}}";
  obs_prox_layout lay = {.fraction = 1, .res = 8, .min_res = 8};
  const double want[3] = {sqrt(100.0 + 36 + 16), sqrt(100.0 + 16), sqrt(169.0 + 36 + 16)};
  obs_scene sc;
  obs_test_load(scene_doc(floor_pillar, ""), "boxes.json", &sc);
  for (int b = OBS_PROX_BOX_MAXIMAL; b <= OBS_PROX_BOX_UNION; b++) {
    lay.box = b;
    assert_float_equal(obs_prox_radius(&sc, &lay), want[b], 1e-12);
  }
  obs_scene_free(&sc);
  const char *walls =
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,0,5],[4,0,5],[4,0,0]]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,3,0],[4,3,0],[4,3,5],[0,3,5]]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[0,3,0],[0,3,5],[0,0,5]]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[4,0,0],[4,0,5],[4,3,5],[4,3,0]]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[4,0,0],[4,3,0],[0,3,0]]}},"
      "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,5],[0,3,5],[4,3,5],[4,0,5]]}}";
  const char *box = "{\"shape\":{\"type\":\"box\",\"min\":[0,0,0],\"max\":[4,3,5]}}";
  double r[2][2];
  const char *rooms[2] = {walls, box};
  for (int k = 0; k < 2; k++) {
    obs_test_load(scene_doc(rooms[k], ""), "room.json", &sc);
    lay.box = OBS_PROX_BOX_MAXIMAL;
    r[k][0] = obs_prox_radius(&sc, &lay);
    lay.box = OBS_PROX_BOX_LARGEST;
    r[k][1] = obs_prox_radius(&sc, &lay);
    obs_scene_free(&sc);
  }
  assert_true(r[0][0] == r[1][0]);
  assert_float_equal(r[0][0], sqrt(50.0), 1e-12);
  assert_float_equal(r[0][1], sqrt(41.0), 1e-12); /* the floor's 4 x 5 */
  assert_float_equal(r[1][1], sqrt(50.0), 1e-12);
  /* The default is the maximal box. */
  obs_proximity_ao_params p;
  assert_int_equal(obs_params_bind(obs_technique_find("proximity_ao"), NULL, &p, NULL), 0);
  assert_int_equal(p.propagation_box, OBS_PROX_BOX_MAXIMAL);
}

/* Accessibility over several fields: the bound of the combination, reached (prox_bound_cases.c). */
static void test_bound_several_fields(void **state) {
  (void)state;
  assert_int_equal(obs_prox_bound_cases(OBS_BACKEND_CPU), 0);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_tri_box),
      cmocka_unit_test(test_sphere_field),
      cmocka_unit_test(test_flood_brute_force),
      cmocka_unit_test(test_voxelise_no_holes),
      cmocka_unit_test(test_two_planes_sum),
      cmocka_unit_test(test_reconstruction_arithmetic),
      cmocka_unit_test(test_reconstruction_paths),
      cmocka_unit_test(test_render_outside_fields),
      cmocka_unit_test(test_camera_rays),
      cmocka_unit_test(test_camera_rays_tiles),
      cmocka_unit_test(test_motion_last_frame),
      cmocka_unit_test(test_extremes),
      cmocka_unit_test(test_bound_several_fields),
      cmocka_unit_test(test_propagation_boxes),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
