/* The shape table (shapes.h): one entry per kind of scene shape, with how a document states it,
 * what bounds it, how it becomes triangles and how many. */
#include "shapes.h"

#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "isosurface.h"
#include "obscura/path.h"

#define COORD_MAX 1e30
/* Object-space radius bound of the displaced sphere: 1 + 0.15 + 0.05. */
#define DISPLACED_MAX_R 1.2

static void set_vec(obs_vec3 *v, const double a[3]) {
  v->x = a[0];
  v->y = a[1];
  v->z = a[2];
}

static void get_vec(const obs_vec3 *v, double a[3]) {
  a[0] = v->x;
  a[1] = v->y;
  a[2] = v->z;
}

/* The 8 corners of the box lo..hi. */
static int box_corners(const double lo[3], const double hi[3], double pts[8][3]) {
  for (int i = 0; i < 8; i++) {
    pts[i][0] = i & 1 ? hi[0] : lo[0];
    pts[i][1] = i & 2 ? hi[1] : lo[1];
    pts[i][2] = i & 4 ? hi[2] : lo[2];
  }
  return 8;
}

/* ---- quad and triangle: the document's vertices ----------------------------------------- */

static void parse_vertices(obs_jpath *p, const json_t *shape, size_t n, obs_shape *s) {
  json_t *a = obs_json_get_array(p, shape, "vertices", 1, NULL);
  if (!a) return;
  size_t m = obs_jpath_push_key(p, "vertices");
  if (json_array_size(a) != n) {
    obs_jpath_fail(p, "must have exactly %zu vertices (got %zu)", n, json_array_size(a));
  } else {
    /* Wrap each vertex so the vec3 getter reports /vertices/<i>. */
    for (size_t i = 0; i < n; i++) {
      char key[24];
      snprintf(key, sizeof key, "%zu", i);
      json_t *wrap = json_object();
      json_object_set(wrap, key, json_array_get(a, i));
      double v[3] = {0, 0, 0};
      obs_json_get_vec3(p, wrap, key, 1, -COORD_MAX, COORD_MAX, v);
      set_vec(&s->v[i], v);
      json_decref(wrap);
    }
  }
  obs_jpath_pop(p, m);
}

static void parse_quad(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  (void)base_dir;
  parse_vertices(p, js, 4, s);
}

static void parse_triangle(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  (void)base_dir;
  parse_vertices(p, js, 3, s);
}

static int nverts_of(const obs_shape *s) { return s->type == OBS_SHAPE_QUAD ? 4 : 3; }

static int points_vertices(const obs_shape *s, double pts[8][3], double *radius) {
  *radius = 0;
  for (int i = 0; i < nverts_of(s); i++) get_vec(&s->v[i], pts[i]);
  return nverts_of(s);
}

static size_t vertices_polygon(const obs_shape *s, obs_vec3 v[8], const uint32_t **tri,
                               size_t *ntri) {
  static const uint32_t quad[6] = {0, 1, 2, 0, 2, 3}, one[3] = {0, 1, 2};
  for (int i = 0; i < nverts_of(s); i++) v[i] = s->v[i];
  *tri = s->type == OBS_SHAPE_QUAD ? quad : one;
  *ntri = s->type == OBS_SHAPE_QUAD ? 2 : 1;
  return (size_t)nverts_of(s);
}

static double triangles_polygon(const obs_shape *s, const char *base_dir, obs_err *err,
                                const char *where) {
  (void)base_dir, (void)err, (void)where;
  return s->type == OBS_SHAPE_QUAD ? 2 : 1;
}

/* ---- sphere: analytic ------------------------------------------------------------------- */

static void parse_sphere(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  (void)base_dir;
  double c[3] = {0, 0, 0};
  obs_json_get_vec3(p, js, "center", 1, -COORD_MAX, COORD_MAX, c);
  obs_json_get_number(p, js, "radius", 1, 0, COORD_MAX, 1, 0, &s->sphere.radius);
  set_vec(&s->sphere.center, c);
}

static int points_sphere(const obs_shape *s, double pts[8][3], double *radius) {
  get_vec(&s->sphere.center, pts[0]);
  *radius = s->sphere.radius;
  return 1;
}

static void sphere_sphere(const obs_shape *s, double center[3], double *radius) {
  get_vec(&s->sphere.center, center);
  *radius = s->sphere.radius;
}

static double triangles_none(const obs_shape *s, const char *base_dir, obs_err *err,
                             const char *where) {
  (void)s, (void)base_dir, (void)err, (void)where;
  return 0;
}

/* ---- box --------------------------------------------------------------------------------- */

static void parse_box(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  (void)base_dir;
  double a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
  int bad = obs_json_get_vec3(p, js, "min", 1, -COORD_MAX, COORD_MAX, a) < 0;
  bad |= obs_json_get_vec3(p, js, "max", 1, -COORD_MAX, COORD_MAX, b) < 0;
  if (!bad && (a[0] > b[0] || a[1] > b[1] || a[2] > b[2])) {
    size_t mk = obs_jpath_push_key(p, "max");
    obs_jpath_fail(p, "must be >= /min in every component (got %s)",
                   obs_json_brief(json_object_get(js, "max")));
    obs_jpath_pop(p, mk);
  }
  set_vec(&s->box.min, a);
  set_vec(&s->box.max, b);
}

static int points_box(const obs_shape *s, double pts[8][3], double *radius) {
  double lo[3], hi[3];
  get_vec(&s->box.min, lo);
  get_vec(&s->box.max, hi);
  *radius = 0;
  return box_corners(lo, hi, pts);
}

static size_t vertices_box(const obs_shape *s, obs_vec3 v[8], const uint32_t **tri, size_t *ntri) {
  static const uint32_t box[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                   3, 7, 6, 3, 6, 2, 0, 4, 7, 0, 7, 3, 1, 2, 6, 1, 6, 5};
  obs_vec3 a = s->box.min, b = s->box.max;
  const obs_vec3 c[8] = {{a.x, a.y, a.z}, {b.x, a.y, a.z}, {b.x, b.y, a.z}, {a.x, b.y, a.z},
                         {a.x, a.y, b.z}, {b.x, a.y, b.z}, {b.x, b.y, b.z}, {a.x, b.y, b.z}};
  memcpy(v, c, sizeof c);
  *tri = box;
  *ntri = 12;
  return 8;
}

static double triangles_box(const obs_shape *s, const char *base_dir, obs_err *err,
                            const char *where) {
  (void)s, (void)base_dir, (void)err, (void)where;
  return 12;
}

/* ---- mesh: a file inside the scene's tree ------------------------------------------------ */

/* Whether a relative path has a ".." component. */
static int has_dotdot(const char *path) {
  for (const char *c = path; *c;) {
    size_t n = strcspn(c, "/");
    if (n == 2 && c[0] == '.' && c[1] == '.') return 1;
    c += n;
    while (*c == '/') c++;
  }
  return 0;
}

/* Imports the resolved file now, so a broken or empty mesh is a validation error rather than a
 * failed render; the render imports again (meshes are small next to the work they cause), which
 * a server's importer answers from its cache. */
static void import_checked(obs_jpath *p, const char *real_file, const char *real_base,
                           obs_shape *s) {
  obs_mesh mesh;
  char where[1200];
  snprintf(where, sizeof where, "%s: %s", p->doc, p->buf);
  if (obs_geometry_import_mesh(real_file, real_base, &mesh, p->err, where) == 0) {
    size_t n = strlen(real_file) + 1;
    if ((s->mesh.path = malloc(n))) memcpy(s->mesh.path, real_file, n);
    obs_geometry_mesh_bounds(&mesh, s->mesh.bounds);
    obs_geometry_mesh_free(&mesh);
  }
}

int obs_shape_resolve_file(obs_jpath *p, const json_t *shape, const char *key,
                           const char *base_dir, const char *const *exts, const char *what,
                           char *real_file, char *real_base) {
  const char *file = NULL;
  if (obs_json_get_string(p, shape, key, 1, NULL, &file) || !file) return 0;
  size_t m = obs_jpath_push_key(p, key);
  const char *ext = strrchr(file, '.');
  int ext_ok = 0, ok = 0;
  for (const char *const *e = exts; ext && *e; e++) ext_ok |= !strcasecmp(ext, *e);
  char joined[PATH_MAX + 2];
  struct stat st;
  if (!*file || strlen(file) > 4096) {
    obs_jpath_fail(p, "must be a relative path of 1 to 4096 characters (got %s)",
                   obs_json_brief(json_object_get(shape, key)));
  } else if (file[0] == '/') {
    obs_jpath_fail(p, "must be relative to the scene file, not absolute (got \"%s\")", file);
  } else if (has_dotdot(file)) {
    /* Refused before the file system is asked, so the answer never tells whether a file outside
     * the tree exists; symlinks that leave the tree are caught after realpath below. */
    obs_jpath_fail(p, "must stay inside the scene's directory tree (got \"%s\")", file);
  } else if (!ext_ok) {
    obs_jpath_fail(p, "must name %s file (got \"%s\")", what, file);
  } else if (!base_dir) {
    obs_jpath_fail(p, "files need a scene directory to resolve against (got \"%s\")", file);
  } else if (!realpath(base_dir, real_base)) {
    obs_jpath_fail(p, "scene directory cannot be resolved (got \"%s\")", base_dir);
  } else if ((size_t)snprintf(joined, sizeof joined, "%s/%s", real_base, file) >= sizeof joined) {
    obs_jpath_fail(p, "path too long (got \"%s\")", file);
  } else if (!realpath(joined, real_file)) {
    obs_jpath_fail(p, "file not found (got \"%s\")", file);
  } else if (!obs_path_is_inside(real_base, real_file)) {
    obs_jpath_fail(p, "must stay inside the scene's directory tree (got \"%s\")", file);
  } else if (stat(real_file, &st) || !S_ISREG(st.st_mode)) {
    obs_jpath_fail(p, "is not a regular file (got \"%s\")", file);
  } else {
    ok = 1;
  }
  obs_jpath_pop(p, m);
  return ok;
}

static void parse_mesh(obs_jpath *p, const json_t *shape, const char *base_dir, obs_shape *s) {
  static const char *const exts[] = {".obj", ".ply", ".gltf", ".glb", ".stl", NULL};
  char real_base[PATH_MAX], real_file[PATH_MAX];
  if (!obs_shape_resolve_file(p, shape, "file", base_dir, exts, "a .obj, .ply, .gltf, .glb or .stl",
                              real_file, real_base))
    return;
  size_t m = obs_jpath_push_key(p, "file");
  import_checked(p, real_file, real_base, s);
  obs_jpath_pop(p, m);
}

static int points_mesh(const obs_shape *s, double pts[8][3], double *radius) {
  *radius = 0;
  return box_corners(s->mesh.bounds[0], s->mesh.bounds[1], pts);
}

static int mesh_import(const obs_shape *s, const char *base_dir, obs_mesh *m, obs_err *err,
                       const char *where) {
  return obs_geometry_import_mesh(s->mesh.path, base_dir ? base_dir : ".", m, err, where);
}

static double triangles_mesh(const obs_shape *s, const char *base_dir, obs_err *err,
                             const char *where) {
  obs_mesh m;
  if (mesh_import(s, base_dir, &m, err, where)) return 0;
  double n = (double)m.ntris;
  obs_geometry_mesh_free(&m);
  return n;
}

/* ---- displaced_sphere: the benchmark surface --------------------------------------------- */

static void parse_displaced(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  (void)base_dir;
  long long sub = 1;
  obs_json_get_int(p, js, "subdivisions", 1, 1, 12, &sub);
  s->displaced.subdivisions = (int)sub;
}

static int points_displaced(const obs_shape *s, double pts[8][3], double *radius) {
  (void)s;
  const double lo[3] = {-DISPLACED_MAX_R, -DISPLACED_MAX_R, -DISPLACED_MAX_R};
  const double hi[3] = {DISPLACED_MAX_R, DISPLACED_MAX_R, DISPLACED_MAX_R};
  *radius = 0;
  return box_corners(lo, hi, pts);
}

static int mesh_displaced(const obs_shape *s, const char *base_dir, obs_mesh *m, obs_err *err,
                          const char *where) {
  (void)base_dir;
  int rc = obs_geometry_displaced_sphere(s->displaced.subdivisions, m);
  return rc ? obs_err_set(err, rc, "%s: out of memory", where) : 0;
}

static double triangles_displaced(const obs_shape *s, const char *base_dir, obs_err *err,
                                  const char *where) {
  (void)base_dir, (void)err, (void)where;
  return ldexp(1.0, 2 * s->displaced.subdivisions);
}

/* A volume's isosurface mesh (the lattice, not the data, sets its size). */
static int mesh_volume(const obs_shape *s, const char *base_dir, obs_mesh *m, obs_err *err,
                       const char *where) {
  (void)base_dir;
  return obs_iso_shape_mesh(s, m, err, where);
}

/* An estimate without extracting: a surface crossing a lattice of c cells per side cuts about
 * 2 c^2 cells (a sphere filling the box, the largest smooth case), each into about 4 triangles
 * of its six tetrahedra. */
static double triangles_volume(const obs_shape *s, const char *base_dir, obs_err *err,
                               const char *where) {
  (void)base_dir, (void)err, (void)where;
  double c = s->volume.mesh_cells;
  if (c <= 0)
    c = fmin(OBS_ISO_CELLS_MAX,
             fmax(1, fmax(s->volume.dims[0], fmax(s->volume.dims[1], s->volume.dims[2])) - 1));
  return 8 * c * c;
}

/* ---- the table --------------------------------------------------------------------------- */

static const char *const keys_vertices[] = {"type", "vertices", NULL};
static const char *const keys_sphere[] = {"type", "center", "radius", NULL};
static const char *const keys_box[] = {"type", "min", "max", NULL};
static const char *const keys_mesh[] = {"type", "file", NULL};
static const char *const keys_displaced[] = {"type", "subdivisions", NULL};
static const char *const keys_volume[] = {"type",    "file",   "format",     "procedural",
                                          "seed",    "dims",   "data_type",  "spacing",
                                          "range",   "isovalue", "colormap", "mesh_cells", NULL};

#define KIND(n, k, parse_, points_, vertices_, mesh_, sphere_, triangles_)           \
  {                                                                                  \
    .name = n, .keys = k, .parse = parse_, .points = points_, .vertices = vertices_, \
    .mesh = mesh_, .sphere = sphere_, .triangles = triangles_                        \
  }
static const obs_shape_kind kinds[OBS_SHAPE_COUNT] = {
    [OBS_SHAPE_QUAD] = KIND("quad", keys_vertices, parse_quad, points_vertices, vertices_polygon,
                            NULL, NULL, triangles_polygon),
    [OBS_SHAPE_TRIANGLE] = KIND("triangle", keys_vertices, parse_triangle, points_vertices,
                                vertices_polygon, NULL, NULL, triangles_polygon),
    [OBS_SHAPE_SPHERE] = KIND("sphere", keys_sphere, parse_sphere, points_sphere, NULL, NULL,
                              sphere_sphere, triangles_none),
    [OBS_SHAPE_BOX] =
        KIND("box", keys_box, parse_box, points_box, vertices_box, NULL, NULL, triangles_box),
    [OBS_SHAPE_MESH] =
        KIND("mesh", keys_mesh, parse_mesh, points_mesh, NULL, mesh_import, NULL, triangles_mesh),
    [OBS_SHAPE_DISPLACED_SPHERE] =
        KIND("displaced_sphere", keys_displaced, parse_displaced, points_displaced, NULL,
             mesh_displaced, NULL, triangles_displaced),
    /* The techniques that need volumes read its samples (renderer/core/volume_scene.h); for the
     * surface techniques its surface is its isosurface, extracted into a mesh
     * (renderer/core/isosurface.h) only when a geometry build asks for it. */
    [OBS_SHAPE_VOLUME] = KIND("volume", keys_volume, obs_shape_volume_parse,
                              obs_shape_volume_points, NULL, mesh_volume, NULL, triangles_volume),
};
#undef KIND

const obs_shape_kind *obs_shape_kind_of(obs_shape_type type) {
  return (unsigned)type < OBS_SHAPE_COUNT ? &kinds[type] : NULL;
}

void obs_shape_kind_names(const char *names[OBS_SHAPE_COUNT + 1]) {
  for (int i = 0; i < OBS_SHAPE_COUNT; i++) names[i] = kinds[i].name;
  names[OBS_SHAPE_COUNT] = NULL;
}

void obs_shape_free(obs_shape *s) {
  if (s->type == OBS_SHAPE_MESH) {
    free(s->mesh.path);
    s->mesh.path = NULL;
  } else if (s->type == OBS_SHAPE_VOLUME) {
    free(s->volume.path);
    free(s->volume.colormap);
    s->volume.path = NULL;
    s->volume.colormap = NULL;
  }
}

int obs_shape_is_analytic(const obs_shape *s) {
  const obs_shape_kind *k = obs_shape_kind_of(s->type);
  return k && k->sphere;
}
