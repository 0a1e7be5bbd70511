/* The volumes of a scene, read for the techniques that need them (OBS_NEED_VOLUME): each volume
 * object's samples (its file or procedural kind), its macrocells (and cell sides for a backend
 * that reads them), and the maps between world space and the volume's data space, which the
 * marcher (volume_march.h) works in. Built once per render by obs_render, shared by every
 * backend. */
#ifndef OBS_VOLUME_SCENE_H
#define OBS_VOLUME_SCENE_H

#include <stddef.h>

#include "obscura/render.h"
#include "obscura/scene.h"
#include "volume.h"

/* Data space is the volume's own [0, extent] box (volume.h with the spacing scaled so the longest
 * side is 1); object space is the same box moved to be centred on the origin. */
typedef struct obs_scene_volume {
  size_t object;          /* its index in the scene's objects */
  obs_volume v;           /* owned; spacing scaled: the box is [0, extent] */
  obs_volume_cells cells; /* owned */
  float iso;
  obs_volume_sides sides; /* owned: the voxel cells' sides of iso (all zero when not built) */
  double to_world[3][4];  /* data space -> world: rows [linear | translation] */
  double to_data[3][4];   /* world -> data space */
  double normal[3][3];    /* the inverse transpose of to_world's linear part (normals) */
  const double *colormap; /* borrowed from the scene: ncolormap (value, r, g, b) points */
  size_t ncolormap;
  /* A brick of the volume (obs_render_opts.brick): `v` holds only the voxels origin .. origin +
   * v.n of the full volume's full_n (the owned slab along `axis` and its ghost zone), and the maps
   * above are those of v's own data space, so a world point samples the same field in v as in the
   * full volume wherever v holds the voxels around it. The render owns the slab [own[0], own[1]]
   * along `axis` (v's data space; the whole box on the other axes); open[s] says whether that
   * side is shared with the neighbouring brick (1) or is the volume's own face (0). Without a
   * brick: brick 0, origin 0, full_n = v.n, own = the whole box, open = {0, 0}. */
  int brick;
  int axis;
  int full_n[3], origin[3];
  double own[2];
  int open[2];
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

/* The same for one brick of every volume (brick->count > 0; count 0 reads them whole), with the
 * cells' sides of the isovalue when `sides` (obs_scene_volumes_load builds them): each
 * volume is cut in brick->count slabs of whole voxels along its axis with the most voxels (the
 * first of equals), and brick->index's slab is kept with a ghost zone on each side (clamped to the
 * volume) that holds every voxel a march of `reach` (data-space units of the volume hit, the
 * technique's AO distance) from the slab can read: ceil(reach' / spacing) + 2 voxels, reach'
 * being `reach` carried into this volume's data space from the most stretching of the scene's
 * volumes (reach itself for one volume); none with brick->no_ghost. A procedural volume computes
 * only the kept voxels; a file is read whole, then cut. OBS_EINVAL naming the object when a
 * volume has fewer voxels along its axis than brick->count, or for a brick index out of range. */
int obs_scene_volumes_load_brick(const obs_scene *sc, const obs_brick *brick, double reach,
                                 int sides, obs_scene_volumes *out, obs_err *err);
void obs_scene_volumes_free(obs_scene_volumes *vs);

/* The samples of volume shape `s` (its file or procedural kind) whole, the spacing scaled so the
 * longest side is 1 (the box [0, extent] of data space): what obs_scene_volumes_load reads. */
int obs_scene_volume_read_shape(const obs_shape *s, obs_volume *v, obs_err *err);

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
