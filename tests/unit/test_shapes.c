/* The shape table (renderer/core/shapes.c): every kind is complete and consistent, and what the
 * table counts and bounds is what the geometry builder makes of it. */
#include <math.h>
#include <string.h>

#include "geometry.h"
#include "shapes.h"
#include "testutil.h"

/* Each kind has a name, a key list naming "type", a parser, bounding points and a triangle
 * count, and is at most one of: given by vertices, made into a mesh, a sphere. */
static void test_table_complete(void **state) {
  (void)state;
  const char *names[OBS_SHAPE_COUNT + 1];
  obs_shape_kind_names(names);
  assert_null(names[OBS_SHAPE_COUNT]);
  for (int t = 0; t < OBS_SHAPE_COUNT; t++) {
    const obs_shape_kind *k = obs_shape_kind_of((obs_shape_type)t);
    assert_non_null(k);
    assert_string_equal(k->name, names[t]);
    for (int u = 0; u < t; u++) assert_string_not_equal(names[u], names[t]);
    assert_string_equal(k->keys[0], "type");
    assert_non_null(k->parse);
    assert_non_null(k->points);
    assert_non_null(k->triangles);
    obs_shape s = {.type = (obs_shape_type)t};
    assert_true(!!k->vertices + !!k->mesh + !!k->sphere <= 1);
    assert_int_equal(obs_shape_is_analytic(&s), !!k->sphere);
  }
  assert_null(obs_shape_kind_of(OBS_SHAPE_COUNT));
}

/* One object of every kind: the triangles the table counts are the ones the builder makes, and
 * every built vertex lies inside the box of the table's bounding points. */
static void test_counts_and_bounds_match_geometry(void **state) {
  (void)state;
  char doc[2048];
  snprintf(doc, sizeof doc,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,0,-20],\"look_at\":[0,0,0],"
           "\"fov_y\":40},\"image\":{\"width\":4,\"height\":4},\"objects\":["
           "{\"shape\":{\"type\":\"quad\",\"vertices\":[[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}},"
           "{\"shape\":{\"type\":\"triangle\",\"vertices\":[[0,0,1],[1,0,1],[0,1,1]]}},"
           "{\"shape\":{\"type\":\"sphere\",\"center\":[3,0,0],\"radius\":0.5}},"
           "{\"shape\":{\"type\":\"box\",\"min\":[-2,-2,-2],\"max\":[-1,-1,-1]},"
           "\"transform\":{\"rotate\":[10,20,30]}},"
           "{\"shape\":{\"type\":\"mesh\",\"file\":\"tests/data/tetra.obj\"},"
           "\"transform\":{\"scale\":[2,2,2]}},"
           "{\"shape\":{\"type\":\"displaced_sphere\",\"subdivisions\":3},"
           "\"transform\":{\"translate\":[0,5,0]}},"
           "{\"shape\":{\"type\":\"volume\",\"procedural\":\"torus\",\"dims\":[8,8,4]},"
           "\"transform\":{\"translate\":[0,-5,0]}}],"
           "\"technique\":{\"name\":\"rt_ao\"}}");
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, doc, "shapes.json", obs_test_src(""), NULL, 0, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  assert_int_equal(sc.nobjects, OBS_SHAPE_COUNT);
  obs_geometry g;
  assert_int_equal(obs_geometry_build(&sc, &g, &err), 0);
  /* Exact counts, but for the volume's, an estimate of the right order (its isosurface mesh is
   * extracted only when built). */
  double counted = 0, volume_bound = 0, volume_tris = 0;
  for (size_t i = 0; i < sc.nobjects; i++) {
    double c = obs_shape_kind_of(sc.objects[i].shape.type)
                   ->triangles(&sc.objects[i].shape, sc.base_dir, &err, "shapes.json");
    if (sc.objects[i].shape.type == OBS_SHAPE_VOLUME)
      volume_bound += c;
    else
      counted += c;
  }
  for (size_t mi = 0; mi < g.nmeshes; mi++)
    if (sc.objects[g.meshes[mi].object].shape.type == OBS_SHAPE_VOLUME)
      volume_tris += (double)g.meshes[mi].ntris;
  assert_true(counted + volume_tris == (double)g.ntris);
  assert_true(volume_bound > 0 && volume_tris <= 4 * volume_bound);
  assert_int_equal(g.nspheres, 1);
  for (size_t mi = 0; mi < g.nmeshes; mi++) {
    const obs_mesh *m = &g.meshes[mi];
    double pts[8][3], r, lo[3] = {INFINITY, INFINITY, INFINITY},
                         hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    int n = obs_geometry_object_points(&sc.objects[m->object], 0, NULL, pts, &r);
    for (int i = 0; i < n; i++)
      for (int k = 0; k < 3; k++)
        lo[k] = fmin(lo[k], pts[i][k] - r), hi[k] = fmax(hi[k], pts[i][k] + r);
    for (size_t v = 0; v < m->nverts; v++)
      for (int k = 0; k < 3; k++) {
        double x = m->pos[3 * v + k];
        assert_true(x >= lo[k] - 1e-5 * (1 + fabs(lo[k])) && x <= hi[k] + 1e-5 * (1 + fabs(hi[k])));
      }
  }
  obs_geometry_free(&g);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_table_complete),
      cmocka_unit_test(test_counts_and_bounds_match_geometry),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
