/* The volumes of a scene, read for the techniques that need them (OBS_NEED_VOLUME): each volume
 * object's samples (its file or procedural kind), its macrocells, and the maps between world
 * space and the volume's data space, which the marcher (volume_march.h) works in. Built once per
 * render by obs_render, shared by every backend. */
#ifndef OBS_VOLUME_SCENE_H
#define OBS_VOLUME_SCENE_H

#include <stddef.h>

#include "obscura/scene.h"
#include "volume.h"

/* Data space is the volume's own [0, extent] box (volume.h with the spacing scaled so the longest
 * side is 1); object space is the same box moved to be centred on the origin. */
typedef struct obs_scene_volume {
  size_t object;          /* its index in the scene's objects */
  obs_volume v;           /* owned; spacing scaled: the box is [0, extent] */
  obs_volume_cells cells; /* owned */
  float iso;
  double to_world[3][4];  /* data space -> world: rows [linear | translation] */
  double to_data[3][4];   /* world -> data space */
  double normal[3][3];    /* the inverse transpose of to_world's linear part (normals) */
  const double *colormap; /* borrowed from the scene: ncolormap (value, r, g, b) points */
  size_t ncolormap;
} obs_scene_volume;

typedef struct obs_scene_volumes {
  obs_scene_volume *v; /* owned */
  size_t n;
} obs_scene_volumes;

/* The side of the macrocells in voxels. */
#define OBS_VOLUME_CELL 8

/* Reads every volume object of `sc` into `out` (empty when there is none). OBS_EINVAL naming the
 * object (/objects/i) when its transform cannot be inverted or its file no longer reads as it did
 * at validation; OBS_EIO, OBS_ENOMEM. On failure `out` is left empty. */
int obs_scene_volumes_load(const obs_scene *sc, obs_scene_volumes *out, obs_err *err);
void obs_scene_volumes_free(obs_scene_volumes *vs);

/* The colour of data value `value` (the colormap's piecewise-linear ramp, held at its ends;
 * white without one). */
void obs_scene_volume_color(const obs_scene_volume *v, double value, double rgb[3]);

/* Affine maps: y = m x (p, 1), and the linear part alone. */
static inline void obs_affine_point(const double m[3][4], const double p[3], double y[3]) {
  for (int i = 0; i < 3; i++) y[i] = m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3];
}
static inline void obs_affine_dir(const double m[3][4], const double d[3], double y[3]) {
  for (int i = 0; i < 3; i++) y[i] = m[i][0] * d[0] + m[i][1] * d[1] + m[i][2] * d[2];
}

#endif
