/* The shape table: per shape kind, how a scene document states it, what bounds it, how it
 * becomes triangles and how many. The loader, the geometry builder, the scene extent and the job
 * server's limits all go through it, so a new kind (a volume, say) is one entry here and its
 * payload in obscura/scene.h's obs_shape. Core-private. */
#ifndef OBS_SHAPES_H
#define OBS_SHAPES_H

#include <stddef.h>
#include <stdint.h>

#include "geometry.h"
#include "json_util.h"
#include "obscura/scene.h"

typedef struct obs_shape_kind {
  const char *name;        /* shape.type in documents */
  const char *const *keys; /* the members a shape of this kind may have, NULL-terminated */
  /* Reads the kind's members of `js` into `s` (its type already set), adding every problem to
   * p's error with its JSON pointer. `base_dir` resolves files. */
  void (*parse)(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s);
  /* Object-space points whose transformed images bound the shape, grown by *radius (in scene
   * units after the transform's uniform scale: spheres); returns how many (at most 8). */
  int (*points)(const obs_shape *s, double pts[8][3], double *radius_object);
  /* Kinds given by the document's own vertices: writes them (object space, at most 8) and points
   * *tri at the kind's triangles (3 indices each, *ntri of them); returns the vertex count. The
   * geometry builder transforms them in double. NULL for the other kinds. */
  size_t (*vertices)(const obs_shape *s, obs_vec3 v[8], const uint32_t **tri, size_t *ntri);
  /* Kinds that make an object-space float mesh (tessellated or imported): fills `m`. NULL for
   * the other kinds. `where` prefixes messages ("scene.json: /objects/3/shape/file"). */
  int (*mesh)(const obs_shape *s, const char *base_dir, obs_mesh *m, obs_err *err,
              const char *where);
  /* Kinds the renderers keep exact as spheres: the object-space centre and radius. NULL for the
   * other kinds. A kind with none of vertices, mesh and sphere adds no surface to the geometry
   * (a volume, which reaches the techniques that need it through their own needs). */
  void (*sphere)(const obs_shape *s, double center[3], double *radius);
  /* How many triangles the kind becomes (0: analytic, kept exact by the renderers), counted
   * without building them where the document says (an imported mesh is read). */
  double (*triangles)(const obs_shape *s, const char *base_dir, obs_err *err, const char *where);
} obs_shape_kind;

/* Resolves member `key` ("file") of `shape` inside the scene's tree (relative, no "..", no link
 * leaving it, a regular file with one of the NULL-terminated `exts`, named `what` in messages:
 * "a .obj or .ply") into real_file and real_base (PATH_MAX bytes each). Returns 1, or 0 after
 * adding the problem with its JSON pointer. */
int obs_shape_resolve_file(obs_jpath *p, const json_t *shape, const char *key,
                           const char *base_dir, const char *const *exts, const char *what,
                           char *real_file, char *real_base);
/* The volume kind (shape_volume.c). */
void obs_shape_volume_parse(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s);
int obs_shape_volume_points(const obs_shape *s, double pts[8][3], double *radius);

/* The entry of kind `type` (never NULL for a valid type). */
const obs_shape_kind *obs_shape_kind_of(obs_shape_type type);
/* The kinds' document names in table order, NULL-terminated (the loader's enum). */
void obs_shape_kind_names(const char *names[OBS_SHAPE_COUNT + 1]);
/* Releases what a shape owns (a mesh's path). */
void obs_shape_free(obs_shape *s);
/* Whether the shape stays analytic: a sphere the renderers keep exact (its kind's `sphere`). */
int obs_shape_is_analytic(const obs_shape *s);

#endif
