/* Scene shapes turned into what ray tracers and rasterisers consume: triangle meshes in world
 * space (quads, boxes, triangles, displaced spheres, imported meshes) and analytic spheres. */
#ifndef OBS_GEOMETRY_H
#define OBS_GEOMETRY_H

#include <stddef.h>
#include <stdint.h>
#include "obscura/scene.h"

typedef struct obs_mesh {
  float *pos;      /* 3 floats per vertex, world space; owned */
  float *nrm;      /* 3 floats per vertex (shading normals) or NULL; owned */
  uint32_t *idx;   /* 3 indices per triangle; owned */
  size_t nverts, ntris;
  size_t object;   /* index into scene->objects */
  /* A moving object's vertices (and normals, when nrm is set) in object space, rounded to float
   * once, from which obs_geometry_mesh_place puts it where each frame wants it; NULL for the
   * objects that stay put. Owned. */
  float *obj_pos, *obj_nrm;
} obs_mesh;

typedef struct obs_sphere {
  double center[3];
  double radius;
  size_t object;
} obs_sphere;

/* World-space geometry of a whole scene. Owns everything inside. */
typedef struct obs_geometry {
  obs_mesh *meshes;
  size_t nmeshes;
  obs_sphere *spheres;
  size_t nspheres;
  size_t ntris;       /* total triangles */
  double bounds[2][3];/* world bounds of everything (empty scene: zeros) */
  double extent;      /* largest absolute coordinate of the bounds: the scene's scale */
  double origin[3];   /* world position of this geometry's (0,0,0): coordinates are world - origin */
} obs_geometry;

/* Builds world-space geometry for every object (importing mesh files through assimp), moving
 * objects in frame 0; `bounds` and `extent` cover every frame. */
int obs_geometry_build(const obs_scene *scene, obs_geometry *geo, obs_err *err);
/* The same in a frame shifted to `origin` (e.g. the camera): transforms and the shift are applied
 * in double before rounding to float, so geometry far from the world origin but near the camera
 * keeps its precision. Fails if any coordinate would exceed the ray tracer's float range. */
int obs_geometry_build_at(const obs_scene *scene, const double origin[3], obs_geometry *geo,
                          obs_err *err);
void obs_geometry_free(obs_geometry *geo);
/* Object `oi`'s triangles in its own object space (no transform), for structures built per
 * object and reused whatever its placement (proximity fields). OBS_EINVAL for shapes without
 * triangles (analytic spheres, volumes). `m` is the caller's (obs_geometry_mesh_free). */
int obs_geometry_object_mesh(const obs_scene *sc, size_t oi, obs_mesh *m, obs_err *err);


/* Imports a mesh file (object space), reading only files inside the directory tree `root` (the
 * scene's). Messages are prefixed with `where` (e.g. "scene.json: /objects/3/shape/file"). Every
 * mesh import of the library (scene validation, geometry builds) goes through here, and so
 * through the importer installed with obs_geometry_set_importer, if any. */
int obs_geometry_import_mesh(const char *path, const char *root, obs_mesh *m, obs_err *err,
                             const char *where);
/* The same with assimp in this process: the default importer, and what an importer that runs
 * assimp elsewhere (a worker process) calls there. */
int obs_geometry_import_mesh_assimp(const char *path, const char *root, obs_mesh *m, obs_err *err,
                                    const char *where);
/* A mesh importer: the contract of obs_geometry_import_mesh, with the `user` it was installed
 * with. It must return a valid mesh (indices below nverts, finite coordinates) or an error. */
typedef int (*obs_mesh_importer)(void *user, const char *path, const char *root, obs_mesh *m,
                                 obs_err *err, const char *where);
/* Installs `fn` for every later mesh import of the process (NULL: assimp in-process again). Not
 * synchronised: call it before any thread imports (a server, at start) and after they stop. */
void obs_geometry_set_importer(obs_mesh_importer fn, void *user);
void obs_geometry_mesh_free(obs_mesh *m);
/* Places moving mesh `m` (obj_pos set) by `t` into the frame at `origin`: pos (and nrm) from
 * obj_pos (and obj_nrm), each vertex through the transform and the shift in double, rounded once.
 * Frame 0 of a geometry build is placed so too: a frame's vertices depend only on its transform. */
void obs_geometry_mesh_place(obs_mesh *m, const obs_transform *t, const double origin[3]);
/* The area of the triangle (a, b, c), in double. */
double obs_geometry_tri_area(const float a[3], const float b[3], const float c[3]);
/* The area of m's triangle t. */
double obs_geometry_mesh_tri_area(const obs_mesh *m, size_t t);
/* The box of m's vertices (zeros when it has none). */
void obs_geometry_mesh_bounds(const obs_mesh *m, double bounds[2][3]);

/* The affine map of `t` (scale, then rotations about X, Y, Z, then translation) as rows of
 * [linear | translation]: world = m x (object, 1). */
void obs_geometry_transform_matrix(const obs_transform *t, double m[3][4]);

/* The inverse of the 3x3 matrix a (by its adjugate) into inv: returns 1, or 0 when a is singular
 * or an entry of the inverse is not finite. */
int obs_geometry_invert3(const double a[3][3], double inv[3][3]);

/* The ray tracer's range: Embree rejects coordinates beyond about 1.8e19, and float products of
 * coordinates must stay finite. */
#define OBS_GEOMETRY_MAX 1e18
/* The largest |coordinate| relative to `origin` that object `o` reaches once transformed, in any
 * of its frames, from obs_geometry_object_points. Non-finite when the transform overflows. */
double obs_geometry_object_reach(const obs_object *o, const double mesh_bounds[2][3],
                                 const double origin[3]);
/* The world-space points (in double, through its transform in `frame`) that bound object `o`: its
 * shape kind's object-space points (core/shapes.c: the vertices of quads and triangles, the
 * corners of a box, of a displaced sphere's bound or of a mesh's imported box, a sphere's centre)
 * with *radius to grow them by (a sphere's radius, 0 for the others); with `mesh_bounds`, the
 * corners of that object-space box instead (a mesh just built). Returns how many (at most 8). */
int obs_geometry_object_points(const obs_object *o, int frame, const double mesh_bounds[2][3],
                               double pts[8][3], double *radius);
/* Refuses object `oi` of `sc` when its reach from `origin` (the camera) exceeds OBS_GEOMETRY_MAX,
 * with a message "<doc>: /objects/<oi>: ..."; the check scene validation and every geometry build
 * run alike. Returns 0 or OBS_EINVAL. */
int obs_geometry_check_reach(const obs_scene *sc, size_t oi, const double mesh_bounds[2][3],
                             const double origin[3], const char *doc, obs_err *err);

/* Fills a displaced_sphere of 2^(2s) triangles into `m` (object space, unit-ish radius). */
int obs_geometry_displaced_sphere(int subdivisions, obs_mesh *m);

#endif
