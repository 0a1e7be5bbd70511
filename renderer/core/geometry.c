/* Tessellation and world-space transformation of scene shapes; mesh files import through assimp
 * (in this process, or through an importer the embedding program installs). Spheres stay
 * analytic: only their centre and radius are transformed. */
#include "geometry.h"

#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "normalize.h"
#include "shapes.h"
#include "obscura/path.h"

#define PI 3.14159265358979323846

/* Row-major 3x4 affine matrix: translate * Rz * Ry * Rx * scale. */
typedef struct xform {
  double m[3][4];
  double n[3][3]; /* inverse transpose of the linear part, for normals */
} xform;

static void xform_from(const obs_transform *t, xform *x) {
  double ax = t->rotate.x * PI / 180, ay = t->rotate.y * PI / 180, az = t->rotate.z * PI / 180;
  double cx = cos(ax), sx = sin(ax), cy = cos(ay), sy = sin(ay), cz = cos(az), sz = sin(az);
  double rx[3][3] = {{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}};
  double ry[3][3] = {{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}};
  double rz[3][3] = {{cz, -sz, 0}, {sz, cz, 0}, {0, 0, 1}};
  double t1[3][3], r[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      t1[i][j] = 0;
      for (int k = 0; k < 3; k++) t1[i][j] += ry[i][k] * rx[k][j];
    }
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      r[i][j] = 0;
      for (int k = 0; k < 3; k++) r[i][j] += rz[i][k] * t1[k][j];
    }
  double s[3] = {t->scale.x, t->scale.y, t->scale.z};
  double tr[3] = {t->translate.x, t->translate.y, t->translate.z};
  /* Normals are renormalised, so the inverse transpose matters only up to a positive factor: where
   * 1 / s times a file's normal could overflow (|s| below ~1e-240) it is taken times the smallest
   * nonzero |s|, which keeps every entry within [-1, 1]. */
  double smin = INFINITY;
  for (int j = 0; j < 3; j++)
    if (s[j] != 0 && fabs(s[j]) < smin) smin = fabs(s[j]);
  double k = smin < 0x1p-800 ? smin : 1.0;
  for (int i = 0; i < 3; i++) {
    for (int j = 0; j < 3; j++) {
      x->m[i][j] = r[i][j] * s[j];
      /* (R S)^-T = R S^-1; a zero scale collapses normals, which renormalising later repairs
       * where it can (degenerate geometry is allowed and must stay finite). */
      x->n[i][j] = s[j] == 0 ? 0 : k == 1.0 ? r[i][j] / s[j] : r[i][j] * (k / s[j]);
    }
    x->m[i][3] = tr[i];
  }
}

static void xform_point(const xform *x, const double p[3], double o[3]) {
  for (int i = 0; i < 3; i++)
    o[i] = x->m[i][0] * p[0] + x->m[i][1] * p[1] + x->m[i][2] * p[2] + x->m[i][3];
}

static int mesh_alloc(obs_mesh *m, size_t nverts, size_t ntris, int normals) {
  memset(m, 0, sizeof *m);
  m->pos = malloc(nverts * 3 * sizeof(float));
  m->idx = malloc(ntris * 3 * sizeof(uint32_t));
  m->nrm = normals ? malloc(nverts * 3 * sizeof(float)) : NULL;
  m->nverts = nverts;
  m->ntris = ntris;
  if (!m->pos || !m->idx || (normals && !m->nrm)) {
    free(m->pos);
    free(m->idx);
    free(m->nrm);
    memset(m, 0, sizeof *m);
    return OBS_ENOMEM;
  }
  return 0;
}

double obs_geometry_tri_area(const float a[3], const float b[3], const float c[3]) {
  double e1[3], e2[3];
  for (int j = 0; j < 3; j++) {
    e1[j] = (double)b[j] - a[j];
    e2[j] = (double)c[j] - a[j];
  }
  double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
         cz = e1[0] * e2[1] - e1[1] * e2[0];
  return 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
}

double obs_geometry_mesh_tri_area(const obs_mesh *m, size_t t) {
  const uint32_t *i = m->idx + 3 * t;
  return obs_geometry_tri_area(m->pos + 3 * (size_t)i[0], m->pos + 3 * (size_t)i[1],
                               m->pos + 3 * (size_t)i[2]);
}

void obs_geometry_mesh_bounds(const obs_mesh *m, double b[2][3]) {
  for (int k = 0; k < 3; k++) b[0][k] = b[1][k] = 0;
  for (size_t i = 0; i < m->nverts; i++)
    for (int k = 0; k < 3; k++) {
      double v = m->pos[3 * i + k];
      if (i == 0 || v < b[0][k]) b[0][k] = v;
      if (i == 0 || v > b[1][k]) b[1][k] = v;
    }
}

void obs_geometry_mesh_free(obs_mesh *m) {
  free(m->pos);
  free(m->idx);
  free(m->nrm);
  free(m->obj_pos);
  free(m->obj_nrm);
  memset(m, 0, sizeof *m);
}

/* m's vertices (and normals, with both nrm and src_nrm) from the object-space arrays src_pos and
 * src_nrm (m's own for a transform in place) through `t` and the shift to `origin`, each in
 * double and rounded to float once; normals through the inverse transpose, renormalised. */
static void transform_vertices(obs_mesh *m, const float *src_pos, const float *src_nrm,
                               const obs_transform *t, const double origin[3]) {
  xform x;
  xform_from(t, &x);
  for (size_t i = 0; i < m->nverts; i++) {
    const float *sp = src_pos + 3 * i;
    double p[3] = {sp[0], sp[1], sp[2]}, o[3];
    xform_point(&x, p, o);
    for (int k = 0; k < 3; k++) m->pos[3 * i + k] = (float)(o[k] - origin[k]);
    if (m->nrm && src_nrm) {
      const float *sn = src_nrm + 3 * i;
      double q[3];
      for (int k = 0; k < 3; k++) q[k] = x.n[k][0] * sn[0] + x.n[k][1] * sn[1] + x.n[k][2] * sn[2];
      if (obs_normalize3d(q)) q[0] = q[1] = q[2] = 0;
      for (int k = 0; k < 3; k++) m->nrm[3 * i + k] = (float)q[k];
    }
  }
}

/* Transforms an object-space float mesh in place into the frame at `origin`. */
static void mesh_transform(obs_mesh *m, const obs_transform *t, const double origin[3]) {
  if (!t->present && origin[0] == 0 && origin[1] == 0 && origin[2] == 0) return;
  transform_vertices(m, m->pos, m->nrm, t, origin);
}

void obs_geometry_mesh_place(obs_mesh *m, const obs_transform *t, const double origin[3]) {
  transform_vertices(m, m->obj_pos, m->obj_nrm, t, origin);
}

/* Keeps a just-built object-space mesh as the moving object's own (obj_pos, obj_nrm). */
static int keep_object_space(obs_mesh *m) {
  size_t bytes = m->nverts * 3 * sizeof(float);
  m->obj_pos = malloc(bytes ? bytes : 1);
  m->obj_nrm = m->nrm ? malloc(bytes ? bytes : 1) : NULL;
  if (!m->obj_pos || (m->nrm && !m->obj_nrm)) return OBS_ENOMEM;
  memcpy(m->obj_pos, m->pos, bytes);
  if (m->nrm) memcpy(m->obj_nrm, m->nrm, bytes);
  return 0;
}

/* Shapes given by world-space vertices (quads, triangles, boxes) are transformed and shifted in
 * double straight from the document's numbers. */
static int mesh_from_vertices(const obs_vec3 *v, size_t nv, const uint32_t *tri, size_t nt,
                              const obs_transform *t, const double origin[3], obs_mesh *m) {
  if (mesh_alloc(m, nv, nt, 0)) return OBS_ENOMEM;
  xform x;
  xform_from(t, &x);
  for (size_t i = 0; i < nv; i++) {
    double p[3] = {v[i].x, v[i].y, v[i].z}, o[3];
    xform_point(&x, p, o);
    for (int k = 0; k < 3; k++) m->pos[3 * i + k] = (float)(o[k] - origin[k]);
  }
  memcpy(m->idx, tri, nt * 3 * sizeof(uint32_t));
  return 0;
}

/* The displacement, as a factor on the unit radius, at polar angle th and azimuth ph. */
static double displaced_radius(double th, double ph) {
  return 1 + 0.15 * sin(7 * th) * sin(9 * ph) + 0.05 * sin(31 * th) * cos(27 * ph);
}

/* Level 1: a latitude-longitude grid of 2 x 1 cells has only the poles for vertices and encloses
 * nothing, so the 4 triangles make a tetrahedron instead (a pole and three points at the polar
 * angle acos(-1/3)), displaced like the grid. Wound as the grid is. */
static int displaced_tetrahedron(obs_mesh *m) {
  if (mesh_alloc(m, 4, 4, 0)) return OBS_ENOMEM;
  const double th1 = acos(-1.0 / 3.0);
  for (int v = 0; v < 4; v++) {
    double th = v ? th1 : 0, ph = v ? 2 * PI * (v - 1) / 3.0 : 0;
    double r = displaced_radius(th, ph);
    float *p = m->pos + 3 * v;
    p[0] = (float)(r * sin(th) * cos(ph));
    p[1] = (float)(r * cos(th));
    p[2] = (float)(r * sin(th) * sin(ph));
  }
  static const uint32_t tri[12] = {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2};
  memcpy(m->idx, tri, sizeof tri);
  return 0;
}

int obs_geometry_displaced_sphere(int s, obs_mesh *m) {
  if (s <= 1) return displaced_tetrahedron(m);
  size_t ni = ((size_t)1 << s) + 1, nj = ((size_t)1 << (s - 1)) + 1;
  size_t nverts = ni * nj, ntris = (size_t)1 << (2 * s);
  if (mesh_alloc(m, nverts, ntris, 0)) return OBS_ENOMEM;
  double *st = malloc(nj * 4 * sizeof(double)), *sp = malloc(ni * 4 * sizeof(double));
  if (!st || !sp) {
    free(st);
    free(sp);
    obs_geometry_mesh_free(m);
    return OBS_ENOMEM;
  }
  for (size_t j = 0; j < nj; j++) {
    double th = PI * (double)j / (double)(nj - 1);
    st[4 * j] = sin(th);
    st[4 * j + 1] = cos(th);
    st[4 * j + 2] = sin(7 * th);
    st[4 * j + 3] = sin(31 * th);
  }
  for (size_t i = 0; i < ni; i++) {
    double ph = 2 * PI * (double)i / (double)(ni - 1);
    sp[4 * i] = cos(ph);
    sp[4 * i + 1] = sin(ph);
    sp[4 * i + 2] = sin(9 * ph);
    sp[4 * i + 3] = cos(27 * ph);
  }
  for (size_t j = 0; j < nj; j++)
    for (size_t i = 0; i < ni; i++) {
      double r = 1 + 0.15 * st[4 * j + 2] * sp[4 * i + 2] + 0.05 * st[4 * j + 3] * sp[4 * i + 3];
      float *p = m->pos + 3 * (j * ni + i);
      p[0] = (float)(r * st[4 * j] * sp[4 * i]);
      p[1] = (float)(r * st[4 * j + 1]);
      p[2] = (float)(r * st[4 * j] * sp[4 * i + 1]);
    }
  free(st);
  free(sp);
  uint32_t *t = m->idx;
  for (size_t j = 0; j + 1 < nj; j++)
    for (size_t i = 0; i + 1 < ni; i++) {
      uint32_t a = (uint32_t)(j * ni + i), b = a + 1, c = (uint32_t)(a + ni), d = c + 1;
      t[0] = a, t[1] = c, t[2] = b;
      t[3] = b, t[4] = c, t[5] = d;
      t += 6;
    }
  return 0;
}

/* assimp IO confined to one directory tree: mesh files may name others (OBJ mtllib, glTF buffer
 * URIs), and a scene must not reach outside its tree through them. Read-only. */
typedef struct contained_io {
  struct aiFileIO io;
  char root[PATH_MAX];
} contained_io;

static size_t cio_read(struct aiFile *f, char *buf, size_t size, size_t count) {
  return fread(buf, size, count, (FILE *)f->UserData);
}
static size_t cio_write(struct aiFile *f, const char *buf, size_t size, size_t count) {
  (void)f, (void)buf, (void)size, (void)count;
  return 0;
}
static size_t cio_tell(struct aiFile *f) {
  long p = ftell((FILE *)f->UserData);
  return p < 0 ? 0 : (size_t)p;
}
static size_t cio_size(struct aiFile *f) {
  FILE *fp = (FILE *)f->UserData;
  long cur = ftell(fp), end = 0;
  if (cur >= 0 && fseek(fp, 0, SEEK_END) == 0) end = ftell(fp);
  if (cur >= 0) fseek(fp, cur, SEEK_SET);
  return end < 0 ? 0 : (size_t)end;
}
static void cio_flush(struct aiFile *f) { (void)f; }
static enum aiReturn cio_seek(struct aiFile *f, size_t off, enum aiOrigin origin) {
  int whence = origin == aiOrigin_SET ? SEEK_SET : origin == aiOrigin_CUR ? SEEK_CUR : SEEK_END;
  return fseek((FILE *)f->UserData, (long)off, whence) == 0 ? aiReturn_SUCCESS : aiReturn_FAILURE;
}

static struct aiFile *cio_open(struct aiFileIO *io, const char *path, const char *mode) {
  const contained_io *c = (const contained_io *)io;
  char real[PATH_MAX];
  if (!mode || mode[0] != 'r' || !realpath(path, real) || !obs_path_is_inside(c->root, real))
    return NULL;
  FILE *fp = fopen(real, "rb");
  if (!fp) return NULL;
  struct aiFile *f = calloc(1, sizeof *f);
  if (!f) {
    fclose(fp);
    return NULL;
  }
  f->ReadProc = cio_read;
  f->WriteProc = cio_write;
  f->TellProc = cio_tell;
  f->FileSizeProc = cio_size;
  f->SeekProc = cio_seek;
  f->FlushProc = cio_flush;
  f->UserData = (aiUserData)fp;
  return f;
}

static void cio_close(struct aiFileIO *io, struct aiFile *f) {
  (void)io;
  if (!f) return;
  fclose((FILE *)f->UserData);
  free(f);
}

static obs_mesh_importer importer_fn;
static void *importer_user;

void obs_geometry_set_importer(obs_mesh_importer fn, void *user) {
  importer_fn = fn;
  importer_user = user;
}

int obs_geometry_import_mesh(const char *path, const char *root, obs_mesh *m, obs_err *err,
                             const char *where) {
  if (importer_fn) {
    memset(m, 0, sizeof *m);
    return importer_fn(importer_user, path, root, m, err, where);
  }
  return obs_geometry_import_mesh_assimp(path, root, m, err, where);
}

int obs_geometry_import_mesh_assimp(const char *path, const char *root, obs_mesh *m, obs_err *err,
                                    const char *where) {
  memset(m, 0, sizeof *m);
  contained_io cio;
  memset(&cio, 0, sizeof cio);
  if (!realpath(root, cio.root))
    return obs_err_set(err, OBS_EIO, "%s: scene directory cannot be resolved", where);
  cio.io.OpenProc = cio_open;
  cio.io.CloseProc = cio_close;
  const struct aiScene *as =
      aiImportFileEx(path,
                     aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_PreTransformVertices | aiProcess_SortByPType,
                     &cio.io);
  if (!as)
    return obs_err_set(err, OBS_EINVAL, "%s: cannot import mesh: %s", where, aiGetErrorString());
  size_t nv = 0, nt = 0;
  int all_normals = 1;
  for (unsigned i = 0; i < as->mNumMeshes; i++) {
    const struct aiMesh *am = as->mMeshes[i];
    if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    nv += am->mNumVertices;
    for (unsigned f = 0; f < am->mNumFaces; f++) nt += am->mFaces[f].mNumIndices == 3;
    all_normals &= am->mNormals != NULL;
  }
  if (nt == 0 || nv > UINT32_MAX) {
    aiReleaseImport(as);
    return nt == 0 ? obs_err_set(err, OBS_EINVAL, "%s: mesh has no triangles", where)
                   : obs_err_set(err, OBS_EINVAL, "%s: mesh has %zu vertices, more than 2^32",
                                 where, nv);
  }
  if (mesh_alloc(m, nv, nt, all_normals)) {
    aiReleaseImport(as);
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for %zu triangles", where, nt);
  }
  size_t vbase = 0, t = 0;
  for (unsigned i = 0; i < as->mNumMeshes; i++) {
    const struct aiMesh *am = as->mMeshes[i];
    if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    for (unsigned v = 0; v < am->mNumVertices; v++) {
      float *p = m->pos + 3 * (vbase + v);
      p[0] = am->mVertices[v].x;
      p[1] = am->mVertices[v].y;
      p[2] = am->mVertices[v].z;
      if (m->nrm) {
        float *n = m->nrm + 3 * (vbase + v);
        n[0] = am->mNormals[v].x;
        n[1] = am->mNormals[v].y;
        n[2] = am->mNormals[v].z;
      }
    }
    for (unsigned f = 0; f < am->mNumFaces; f++) {
      const struct aiFace *fc = &am->mFaces[f];
      if (fc->mNumIndices != 3) continue;
      for (int k = 0; k < 3; k++) m->idx[3 * t + k] = (uint32_t)(vbase + fc->mIndices[k]);
      t++;
    }
    vbase += am->mNumVertices;
  }
  aiReleaseImport(as);
  /* Files may carry non-finite coordinates; drop them to the origin rather than poison the BVH. */
  for (size_t i = 0; i < 3 * nv; i++) {
    if (!isfinite(m->pos[i])) m->pos[i] = 0.0f;
    if (m->nrm && !isfinite(m->nrm[i])) m->nrm[i] = 0.0f;
  }
  return 0;
}

int obs_geometry_object_points(const obs_object *o, int frame, const double mesh_bounds[2][3],
                               double pts[8][3], double *radius) {
  const obs_transform *t = obs_object_transform_at(o, frame);
  double local[8][3];
  int n;
  if (mesh_bounds) { /* a built mesh's own box, in place of what the document promised */
    for (int i = 0; i < 8; i++)
      for (int k = 0; k < 3; k++) local[i][k] = mesh_bounds[(i >> k) & 1][k];
    n = 8;
    *radius = 0;
  } else {
    n = obs_shape_kind_of(o->shape.type)->points(&o->shape, local, radius);
  }
  *radius *= fabs(t->scale.x);
  xform x;
  xform_from(t, &x);
  for (int i = 0; i < n; i++) xform_point(&x, local[i], pts[i]);
  return n;
}

void obs_geometry_transform_matrix(const obs_transform *t, double m[3][4]) {
  xform x;
  xform_from(t, &x);
  memcpy(m, x.m, sizeof x.m);
}

int obs_geometry_invert3(const double a[3][3], double inv[3][3]) {
  double c[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      c[j][i] = a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1]; /* adjugate (transposed) */
    }
  double det = a[0][0] * c[0][0] + a[0][1] * c[1][0] + a[0][2] * c[2][0];
  if (!(fabs(det) > 0) || !isfinite(det)) return 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      inv[i][j] = c[i][j] / det;
      if (!isfinite(inv[i][j])) return 0;
    }
  return 1;
}

double obs_geometry_object_reach(const obs_object *o, const double mesh_bounds[2][3],
                                 const double origin[3]) {
  double reach = 0;
  for (size_t f = 0; f <= o->nmotion; f++) {
    double pts[8][3], grow;
    int n = obs_geometry_object_points(o, (int)f, mesh_bounds, pts, &grow);
    for (int i = 0; i < n; i++) {
      for (int k = 0; k < 3; k++) {
        double a = fabs(pts[i][k] - origin[k]) + grow;
        if (isnan(a)) return NAN; /* refused as beyond the range, whatever comes after */
        if (a > reach) reach = a;
      }
    }
  }
  return reach;
}

int obs_geometry_check_reach(const obs_scene *sc, size_t oi, const double mesh_bounds[2][3],
                             const double origin[3], const char *doc, obs_err *err) {
  double reach = obs_geometry_object_reach(&sc->objects[oi], mesh_bounds, origin);
  if (reach <= OBS_GEOMETRY_MAX) return 0;
  return obs_err_set(err, OBS_EINVAL,
                     "%s: /objects/%zu: once transformed, object \"%s\" reaches %.3g scene units "
                     "from the camera, beyond the renderer's range of +-%g",
                     doc, oi, sc->objects[oi].name ? sc->objects[oi].name : "", reach,
                     OBS_GEOMETRY_MAX);
}

static int fail_oom(const obs_scene *sc, size_t oi, int rc, obs_err *err) {
  return rc ? obs_err_set(err, rc, "%s: /objects/%zu: out of memory", sc->name, oi) : 0;
}

static int build_object(const obs_scene *sc, size_t oi, const double origin[3], obs_mesh *m,
                        obs_err *err) {
  static const double zero[3] = {0, 0, 0};
  static const obs_transform identity = {{1, 1, 1}, {0, 0, 0}, {0, 0, 0}, 0};
  const obs_object *o = &sc->objects[oi];
  const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
  /* A moving object is built in object space and then placed (obs_geometry_mesh_place). */
  int moves = o->nmotion > 0;
  int rc = obs_geometry_check_reach(sc, oi, NULL, origin, sc->name, err);
  if (rc) return rc;
  if (k->vertices) {
    obs_vec3 v[8];
    const uint32_t *tri;
    size_t nt, nv = k->vertices(&o->shape, v, &tri, &nt);
    rc = mesh_from_vertices(v, nv, tri, nt, moves ? &identity : &o->transform,
                            moves ? zero : origin, m);
    if (!rc && moves && (rc = keep_object_space(m))) obs_geometry_mesh_free(m);
    if (!rc && moves) obs_geometry_mesh_place(m, &o->transform, origin);
    return fail_oom(sc, oi, rc, err);
  }
  char where[256];
  snprintf(where, sizeof where, "%s: /objects/%zu/shape%s", sc->name, oi,
           o->shape.type == OBS_SHAPE_MESH ? "/file" : "");
  if ((rc = k->mesh(&o->shape, sc->base_dir, m, err, where))) return rc;
  /* What was built may reach farther than the document said (a mesh file changed since). */
  double b[2][3];
  obs_geometry_mesh_bounds(m, b);
  if ((rc = obs_geometry_check_reach(sc, oi, b, origin, sc->name, err))) {
    obs_geometry_mesh_free(m);
    return rc;
  }
  if (moves) {
    if ((rc = keep_object_space(m))) {
      obs_geometry_mesh_free(m);
      return fail_oom(sc, oi, rc, err);
    }
    obs_geometry_mesh_place(m, &o->transform, origin);
  } else {
    mesh_transform(m, &o->transform, origin);
  }
  return 0;
}

int obs_geometry_object_mesh(const obs_scene *sc, size_t oi, obs_mesh *m, obs_err *err) {
  static const double zero[3] = {0, 0, 0};
  static const obs_transform identity = {{1, 1, 1}, {0, 0, 0}, {0, 0, 0}, 0};
  const obs_object *o = &sc->objects[oi];
  const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
  memset(m, 0, sizeof *m);
  int rc;
  if (k->vertices) {
    obs_vec3 v[8];
    const uint32_t *tri;
    size_t nt, nv = k->vertices(&o->shape, v, &tri, &nt);
    rc = fail_oom(sc, oi, mesh_from_vertices(v, nv, tri, nt, &identity, zero, m), err);
  } else if (k->mesh) {
    char where[256];
    snprintf(where, sizeof where, "%s: /objects/%zu/shape%s", sc->name, oi,
             o->shape.type == OBS_SHAPE_MESH ? "/file" : "");
    rc = k->mesh(&o->shape, sc->base_dir, m, err, where);
  } else {
    return obs_err_set(err, OBS_EINVAL, "%s: /objects/%zu/shape: a %s is not a triangle mesh",
                       sc->name, oi, k->name);
  }
  m->object = oi;
  return rc;
}

static void grow_bounds(obs_geometry *g, const double p[3], int *first) {
  for (int k = 0; k < 3; k++) {
    if (*first || p[k] < g->bounds[0][k]) g->bounds[0][k] = p[k];
    if (*first || p[k] > g->bounds[1][k]) g->bounds[1][k] = p[k];
  }
  *first = 0;
}

/* A moving mesh's later frames, by the corners of its object-space box: the bounds then hold
 * every frame's geometry. */
static void grow_motion(obs_geometry *g, const obs_object *o, const obs_mesh *m,
                        const double origin[3], int *first) {
  if (!m->obj_pos) return;
  double ob[2][3];
  obs_mesh object_space = *m;
  object_space.pos = m->obj_pos;
  obs_geometry_mesh_bounds(&object_space, ob);
  for (size_t f = 1; f <= o->nmotion; f++) {
    double pts[8][3], r;
    int n = obs_geometry_object_points(o, (int)f, ob, pts, &r);
    for (int i = 0; i < n; i++) {
      double p[3] = {pts[i][0] - origin[0], pts[i][1] - origin[1], pts[i][2] - origin[2]};
      grow_bounds(g, p, first);
    }
  }
}

int obs_geometry_build(const obs_scene *sc, obs_geometry *g, obs_err *err) {
  static const double zero[3] = {0, 0, 0};
  return obs_geometry_build_at(sc, zero, g, err);
}

int obs_geometry_build_at(const obs_scene *sc, const double origin[3], obs_geometry *g,
                          obs_err *err) {
  memset(g, 0, sizeof *g);
  memcpy(g->origin, origin, sizeof g->origin);
  size_t nsph = 0, nmesh = 0;
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (obs_shape_is_analytic(&sc->objects[i].shape))
      nsph++;
    else
      nmesh++;
  }
  g->meshes = calloc(nmesh ? nmesh : 1, sizeof *g->meshes);
  g->spheres = calloc(nsph ? nsph : 1, sizeof *g->spheres);
  if (!g->meshes || !g->spheres) {
    obs_geometry_free(g);
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", sc->name);
  }
  int first = 1;
  for (size_t i = 0; i < sc->nobjects; i++) {
    const obs_object *o = &sc->objects[i];
    if (obs_shape_is_analytic(&o->shape)) {
      int rc = obs_geometry_check_reach(sc, i, NULL, origin, sc->name, err);
      if (rc) {
        obs_geometry_free(g);
        return rc;
      }
      obs_sphere *s = &g->spheres[g->nspheres++];
      double c[3];
      obs_shape_kind_of(o->shape.type)->sphere(&o->shape, c, &s->radius);
      xform x;
      xform_from(&o->transform, &x);
      xform_point(&x, c, s->center);
      for (int k = 0; k < 3; k++) s->center[k] -= origin[k];
      s->radius *= fabs(o->transform.scale.x);
      s->object = i;
      for (int k = 0; k < 2; k++) {
        double p[3];
        for (int a = 0; a < 3; a++) p[a] = s->center[a] + (k ? s->radius : -s->radius);
        grow_bounds(g, p, &first);
      }
      continue;
    }
    const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
    if (!k->vertices && !k->mesh) continue; /* no surface (shapes.h) */
    obs_mesh *m = &g->meshes[g->nmeshes];
    int rc = build_object(sc, i, origin, m, err);
    if (rc) {
      obs_geometry_free(g);
      return rc;
    }
    m->object = i;
    g->nmeshes++;
    g->ntris += m->ntris;
    for (size_t v = 0; v < m->nverts; v++) {
      double p[3] = {m->pos[3 * v], m->pos[3 * v + 1], m->pos[3 * v + 2]};
      grow_bounds(g, p, &first);
    }
    grow_motion(g, o, m, origin, &first);
  }
  for (int k = 0; k < 3; k++) {
    double a = fmax(fabs(g->bounds[0][k]), fabs(g->bounds[1][k]));
    if (a > g->extent) g->extent = a;
  }
  return 0;
}

void obs_geometry_free(obs_geometry *g) {
  for (size_t i = 0; i < g->nmeshes; i++) obs_geometry_mesh_free(&g->meshes[i]);
  free(g->meshes);
  free(g->spheres);
  memset(g, 0, sizeof *g);
}
