/* Scene documents: strict loading and validation of the JSON scene format into plain C structs. */
#ifndef OBSCURA_SCENE_H
#define OBSCURA_SCENE_H

#include <stddef.h>
#include "obscura/backend.h"
#include "obscura/error.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct json_t json_t; /* jansson */

typedef struct obs_vec3 {
  double x, y, z;
} obs_vec3;

typedef enum { OBS_CAMERA_PERSPECTIVE, OBS_CAMERA_ORTHOGRAPHIC } obs_camera_type;

typedef struct obs_camera {
  obs_camera_type type;
  obs_vec3 position, look_at, up;
  double fov_y;  /* degrees, perspective only */
  double height; /* view height in scene units, orthographic only */
} obs_camera;

/* Shape kinds. Each kind is one entry of the shape table (renderer/core/shapes.c), which says how
 * it is read from a document, bounded, tessellated and counted: adding a kind is an enum value,
 * its payload below and its table entry. */
typedef enum {
  OBS_SHAPE_QUAD,
  OBS_SHAPE_TRIANGLE,
  OBS_SHAPE_SPHERE,
  OBS_SHAPE_BOX,
  OBS_SHAPE_MESH,
  OBS_SHAPE_DISPLACED_SPHERE,
  OBS_SHAPE_VOLUME,
  OBS_SHAPE_COUNT
} obs_shape_type;

/* One object's shape: the kind and its payload (object space). */
typedef struct obs_shape {
  obs_shape_type type;
  union {
    obs_vec3 v[4]; /* quad: 4 vertices; triangle: 3 */
    struct {
      obs_vec3 center;
      double radius;
    } sphere; /* analytic: the renderers keep it exact */
    struct {
      obs_vec3 min, max;
    } box;
    struct {
      char *path;            /* owned: the resolved absolute path inside the scene tree */
      double bounds[2][3];   /* object-space box of the vertices imported at validation */
    } mesh;
    struct {
      int subdivisions;
    } displaced;
    /* A scalar volume whose isosurface is the surface: read from a file (path set) or procedural.
     * It fills a box centred on the object's origin whose sides are dims x spacing scaled so the
     * longest is 1 (`extent`). Read by the techniques that need volumes, not at validation (which
     * reads the file's header only). */
    struct {
      char *path;          /* owned: the resolved file; NULL for a procedural volume */
      int format;          /* the file's format (renderer/core/volume_io.h's obs_volume_file) */
      int procedural;      /* a procedural kind (renderer/core/volume.h), or -1 for a file */
      unsigned seed;       /* procedural noise */
      int dims[3];         /* samples per axis (the file's, or as given) */
      int data_type;       /* raw files: obs_volume_type */
      double spacing[3];   /* as given, 0 = the file's (1 where it has none) */
      double range[2];     /* normalisation range as given; equal = the type's or the data's */
      double isovalue;     /* in [0, 1]: the surface */
      int mesh_cells;      /* surface techniques' extraction cells along the longest side; 0 =
                            * the longest of dims less one (renderer/core/isosurface.h) */
      double extent[3];    /* object-space box sides (longest 1) */
      double *colormap;    /* owned: ncolormap points (value, r, g, b) by rising value; NULL */
      size_t ncolormap;
    } volume;
  };
} obs_shape;

typedef struct obs_transform {
  obs_vec3 scale;     /* default (1,1,1) */
  obs_vec3 rotate;    /* degrees about X, then Y, then Z */
  obs_vec3 translate; /* default 0 */
  int present;        /* 0 when the object had no transform (identity) */
} obs_transform;

/* A homogeneous participating medium filling an object (its material's `medium`), for the
 * techniques that scatter light under the surface (sss_single). Coefficients are per unit length
 * of the technique's choosing (sss_single's `unit_length`; the presets are per millimetre). */
typedef struct obs_medium {
  obs_vec3 sigma_a; /* absorption coefficient per channel */
  obs_vec3 sigma_s; /* scattering coefficient per channel */
  double g;         /* Henyey-Greenstein asymmetry, in (-1, 1) */
  double eta;       /* index of refraction relative to the outside, in [1, 3] */
} obs_medium;

typedef struct obs_object {
  char *name;           /* owned; "object<i>" when the document gave none */
  obs_shape shape;
  int has_material;
  obs_vec3 reflectivity;
  obs_vec3 emission;    /* radiance emitted from both sides of the surface; zero when absent */
  int has_medium;       /* material.medium given: the object is filled with `medium` */
  obs_medium medium;
  obs_transform transform;
  /* A moving object's transforms in frames 1..nmotion (frame 0 is `transform`); NULL and 0 when
   * it stays put. Owned. Motion is rigid: every entry has `transform`'s scale. */
  obs_transform *motion;
  size_t nmotion;
} obs_object;

/* Light kinds: an area light (a quad, emitting from its front), or the punctual lights that
 * shading techniques light with (OBS_NEED_PUNCTUAL_LIGHTS). */
typedef enum { OBS_LIGHT_QUAD, OBS_LIGHT_POINT, OBS_LIGHT_DIRECTIONAL } obs_light_type;

/* An ambient-occlusion probe (ShaderX7 6.4): a disc-like occluder facing every receiver, centred
 * at `position`, of visible area pi radius^2; placed inside a mesh so that the mesh's own faces,
 * which see it behind them, are not darkened. */
typedef struct obs_probe {
  obs_vec3 position;
  double radius;
} obs_probe;

typedef struct obs_light {
  obs_light_type type;
  obs_vec3 v[4];      /* quad: its vertices */
  obs_vec3 position;  /* point: where it is */
  obs_vec3 direction; /* directional: the way its light travels (unit) */
  /* quad: emitted radiance; point: radiant intensity per steradian; directional: irradiance on
   * a surface facing it. */
  obs_vec3 emission;
} obs_light;

/* The kinds of environment: a constant colour, or a map (a lat-long EXR, six cube-face EXRs or
 * a procedural sky) that techniques with OBS_NEED_ENV_MAP turn into a cube map. */
typedef enum { OBS_ENV_COLOR, OBS_ENV_LATLONG, OBS_ENV_FACES, OBS_ENV_SKY } obs_env_kind;

typedef struct obs_environment {
  obs_env_kind kind;
  char *files[6];      /* owned, resolved: latlong's file in [0]; faces' six in cube-face order */
  int resolution;      /* latlong, sky: the cube map's face size */
  double intensity;    /* maps: radiance scale */
  /* sky: radiance up, at the horizon and below it; the sun's direction (unit, toward it), its
   * angular radius in degrees (0: none) and radiance. */
  obs_vec3 zenith, horizon, ground, sun_direction, sun;
  double sun_radius;
} obs_environment;

/* A validated scene. Owns every pointer inside it, `doc` included; release with obs_scene_free. */
typedef struct obs_scene {
  char *name;           /* document name used in messages (file base name or caller's label) */
  char *base_dir;       /* directory mesh files resolve against (absolute); NULL for inline docs
                           without one, which may then not use meshes */
  obs_camera camera;
  int width, height, spp;
  obs_object *objects;
  size_t nobjects;
  obs_light *lights;
  size_t nlights;
  obs_probe *probes; /* techniques that read no probes ignore them */
  size_t nprobes;
  int frames;           /* 1, or 1 + the nmotion every moving object shares */
  int has_environment;
  obs_vec3 environment; /* the constant colour (env.kind OBS_ENV_COLOR) */
  obs_environment env;  /* what the environment is (an environment map for techniques with
                           OBS_NEED_ENV_MAP) */
  const struct obs_technique *technique; /* from the registry; never NULL once loaded */
  obs_backend backend;                   /* as requested: may be AUTO */
  json_t *params;       /* technique parameters with defaults filled in (owned reference) */
  json_t *doc;          /* the whole document after overrides (owned reference) */
} obs_scene;

/* The most transforms an object's `motion` may list. */
#define OBS_MOTION_MAX 1024
/* Object `o`'s transform in frame f (0 <= f < the scene's frames). */
static inline const obs_transform *obs_object_transform_at(const obs_object *o, int f) {
  return f > 0 && o->motion ? &o->motion[f - 1] : &o->transform;
}

/* Bounds on untrusted input (the bundled scene documents nest 6 levels, the job server's requests 7):
 * documents may nest at most OBS_JSON_MAX_DEPTH arrays/objects, counted from the top (`[1]` is 1,
 * `1` is 0), after overrides too; an override pointer may have at most OBS_POINTER_MAX_TOKENS
 * reference tokens. Deeper input is refused with OBS_EINVAL before it is parsed, so nothing ever
 * recurses through an unbounded document. */
#define OBS_JSON_MAX_DEPTH 32
#define OBS_POINTER_MAX_TOKENS 32

/* One `--set /json/pointer=VALUE` override: VALUE is JSON text. */
typedef struct obs_override {
  const char *pointer;
  const char *value;
} obs_override;

/* Parses, applies overrides, validates every rule and fills `scene`. On failure every problem found
 * is added to `err` as "<name>: <json pointer>: <rule> (got <value>)" and OBS_EINVAL is returned;
 * `scene` is left empty. `name` prefixes messages; `base_dir` resolves mesh files (may be NULL). */
int obs_scene_load_string(obs_scene *scene, const char *json_text, const char *name,
                          const char *base_dir, const obs_override *ov, size_t nov, obs_err *err);
/* Same for a parsed document. `doc` is borrowed: the overrides (if any) are applied to it in
 * place, and on success scene->doc holds its own new reference to it (the caller still releases
 * its own). On failure `doc` may hold the overrides that applied. The document's depth is checked
 * (OBS_JSON_MAX_DEPTH) before anything else reads it. */
int obs_scene_load_json(obs_scene *scene, json_t *doc, const char *name, const char *base_dir,
                        const obs_override *ov, size_t nov, obs_err *err);
/* Same for a file (at most 256 MiB); the file's base name and directory are used. */
int obs_scene_load_file(obs_scene *scene, const char *path, const obs_override *ov, size_t nov,
                        obs_err *err);
/* Validates an already-parsed document (borrowed, not modified) without keeping the result; its
 * depth is checked first, as for obs_scene_load_json. */
int obs_scene_validate_json(const json_t *doc, const char *name, const char *base_dir, obs_err *err);
void obs_scene_free(obs_scene *scene);

/* Applies `value` (JSON text) at `pointer` (RFC 6901) in `doc`, creating missing object members on
 * the way. Refuses (OBS_EINVAL, doc unchanged) a pointer of more than OBS_POINTER_MAX_TOKENS tokens
 * and a value nested deeper than OBS_JSON_MAX_DEPTH, naming the pointer. */
int obs_json_pointer_set(json_t *doc, const char *pointer, const char *value, obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
