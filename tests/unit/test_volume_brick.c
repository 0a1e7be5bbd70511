/* Bricks of a data-parallel render (obs_render_opts.brick, volume_scene.h): a brick keeps only its
 * slab's voxels and a ghost zone as wide as the AO reach, its samples are the whole volume's at
 * the same world points wherever it holds the voxels around them, the owned slabs tile the volume,
 * and what cannot render a brick refuses it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "testutil.h"
#include "volume_scene.h"

/* A torus volume of 40 x 24 x 20 voxels (x the longest axis), turned, stretched and moved. */
static const char *DOC =
    "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, 4], \"look_at\": [0, 0, 0], "
    "\"up\": [0, 1, 0], \"fov_y\": 40}, \"image\": {\"width\": 8, \"height\": 8}, "
    "\"objects\": [{\"name\": \"t\", \"shape\": {\"type\": \"volume\", \"procedural\": "
    "\"torus\", \"dims\": [40, 24, 20], \"spacing\": [1, 1.5, 1], \"isovalue\": 0.5}, "
    "\"transform\": {\"rotate\": [20, 35, 0], \"scale\": [1.5, 1, 0.7], \"translate\": [0.3, "
    "-0.2, 0.1]}}], \"technique\": {\"name\": \"volume_ao\", \"backend\": \"cpu\", "
    "\"params\": {\"samples\": 4, \"max_distance\": 0.2}}}";

static void load_brick(const obs_scene *sc, int index, int count, int no_ghost, double reach,
                       obs_scene_volumes *out) {
  obs_err err = OBS_ERR_INIT;
  obs_brick b = {index, count, no_ghost};
  int rc = obs_scene_volumes_load_brick(sc, &b, reach, 1, out, &err);
  if (rc) printf("brick %d of %d: %s\n", index, count, obs_err_message(&err));
  assert_int_equal(rc, 0);
  assert_int_equal(out->n, 1);
  obs_err_free(&err);
}

/* Samples of brick `bv` against the whole volume `fv` at world points of every voxel interval the
 * brick holds on both sides (its outer half voxels clamp the field, as the whole volume does only
 * at its own faces). */
static void check_samples(const obs_scene_volume *fv, const obs_scene_volume *bv, uint32_t *rng) {
  const int ax = bv->axis;
  double sp = bv->v.spacing[ax];
  double lo = bv->origin[ax] == 0 ? 0 : 0.5 * sp;
  double hi =
      bv->origin[ax] + bv->v.n[ax] == bv->full_n[ax] ? bv->v.n[ax] * sp : (bv->v.n[ax] - 0.5) * sp;
  double worst = 0;
  for (int i = 0; i < 4000; i++) {
    double p[3], w[3], q[3];
    for (int a = 0; a < 3; a++) {
      double u = obs_test_unit(rng);
      p[a] = a == ax ? lo + u * (hi - lo) : u * bv->v.n[a] * bv->v.spacing[a];
    }
    obs_affine_point(bv->to_world, p, w);
    obs_affine_point(fv->to_data, w, q);
    worst = fmax(worst, fabs(obs_volume_sample(&bv->v, p) - obs_volume_sample(&fv->v, q)));
  }
  /* Only the affine round trip's rounding separates the two points. */
  assert_true(worst < 1e-5);
}

static void test_bricks_match_the_whole(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(DOC, "brick.json", &sc);
  obs_err err = OBS_ERR_INIT;
  obs_scene_volumes full;
  assert_int_equal(obs_scene_volumes_load(&sc, &full, &err), 0);
  const obs_scene_volume *fv = &full.v[0];
  assert_int_equal(fv->brick, 0);
  const double reach = 0.2;
  uint32_t rng = 12345;
  for (int count = 1; count <= 4; count++) {
    double seam = 0; /* the last brick's owned end, in the whole volume's data space */
    for (int index = 0; index < count; index++) {
      obs_scene_volumes bs;
      load_brick(&sc, index, count, 0, reach, &bs);
      const obs_scene_volume *bv = &bs.v[0];
      const int ax = bv->axis;
      double sp = bv->v.spacing[ax], off = bv->origin[ax] * sp;
      assert_int_equal(ax, 0);
      assert_int_equal(bv->full_n[ax], 40);
      for (int a = 0; a < 3; a++) assert_true(bv->v.spacing[a] == fv->v.spacing[a]);
      /* The owned slabs tile the volume, and only inner sides are open. */
      assert_true(fabs(bv->own[0] + off - seam) < 1e-12);
      seam = bv->own[1] + off;
      assert_int_equal(bv->open[0], index > 0);
      assert_int_equal(bv->open[1], index < count - 1);
      /* The ghost zone holds a march of `reach` past either side, plus the voxel it reads. */
      assert_true(bv->origin[ax] == 0 || bv->own[0] - reach >= sp);
      assert_true(bv->origin[ax] + bv->v.n[ax] == 40 ||
                  bv->own[1] + reach <= (bv->v.n[ax] - 1) * sp);
      if (count > 1) assert_true(bv->v.n[ax] < 40);
      check_samples(fv, bv, &rng);
      obs_scene_volumes_free(&bs);
    }
    assert_true(fabs(seam - 40 * fv->v.spacing[0]) < 1e-12);
  }
  /* Without a ghost zone a brick is its slab alone: a third of the voxels of three. */
  obs_scene_volumes bs;
  load_brick(&sc, 1, 3, 1, reach, &bs);
  assert_int_equal(bs.v[0].v.n[0], 26 - 13);
  assert_int_equal(bs.v[0].origin[0], 13);
  check_samples(fv, &bs.v[0], &rng);
  obs_scene_volumes_free(&bs);
  obs_scene_volumes_free(&full);
  obs_scene_free(&sc);
}

static void test_refusals(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(DOC, "brick.json", &sc);
  obs_err err = OBS_ERR_INIT;
  obs_scene_volumes vs;
  obs_brick b = {0, 41, 0};
  assert_int_equal(obs_scene_volumes_load_brick(&sc, &b, 0.2, 1, &vs, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "too few for 41 bricks"));
  assert_non_null(strstr(obs_err_message(&err), "/objects/0/shape"));
  obs_err_clear(&err);
  obs_render_opts o = {.threads = 1, .brick = {3, 3, 0}};
  obs_result res;
  assert_int_equal(obs_render(&sc, &o, &res, &err), OBS_EINVAL);
  obs_err_clear(&err);
  obs_scene_free(&sc);
  const char *rt =
      "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, 4], "
      "\"look_at\": [0, 0, 0], \"up\": [0, 1, 0], \"fov_y\": 40}, \"image\": "
      "{\"width\": 8, \"height\": 8}, \"objects\": [{\"name\": \"s\", \"shape\": "
      "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1}}], \"technique\": {\"name\": "
      "\"rt_ao\", \"params\": {\"samples\": 4}}}";
  obs_test_load(rt, "rt.json", &sc);
  o.brick = (obs_brick){0, 2, 0};
  assert_int_equal(obs_render(&sc, &o, &res, &err), OBS_EUNSUPPORTED);
  assert_non_null(strstr(obs_err_message(&err), "renders no volumes"));
  obs_err_free(&err);
  obs_scene_free(&sc);
}

/* One brick of one is the whole volume: the same image bit for bit. */
static void test_one_brick_is_the_whole(void **state) {
  (void)state;
  obs_scene sc;
  obs_test_load(DOC, "brick.json", &sc);
  obs_err err = OBS_ERR_INIT;
  obs_render_opts o = {.threads = 1};
  obs_result a, b;
  assert_int_equal(obs_render(&sc, &o, &a, &err), 0);
  o.brick = (obs_brick){0, 1, 0};
  assert_int_equal(obs_render(&sc, &o, &b, &err), 0);
  size_t n = (size_t)a.image.width * a.image.height * a.image.nchannels;
  assert_memory_equal(a.image.data, b.image.data, n * sizeof(float));
  obs_result_free(&a);
  obs_result_free(&b);
  obs_err_free(&err);
  obs_scene_free(&sc);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_bricks_match_the_whole),
      cmocka_unit_test(test_refusals),
      cmocka_unit_test(test_one_brick_is_the_whole),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
