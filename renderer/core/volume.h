/* Scalar volumes for isosurface techniques: a grid of values normalised to [0, 1] with its voxel
 * spacing, trilinear reconstruction, the procedural volumes that tests and benchmarks use without
 * files (sphere, torus, Marschner-Lobb, seeded noise), the min/max macrocell grid that lets
 * rays skip cells the isosurface cannot cross, and the per-voxel-cell side of one isovalue. */
#ifndef OBS_VOLUME_H
#define OBS_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "obscura/error.h"

/* A volume in object space: voxel (i, j, k) is the sample at ((i + 0.5) sx, (j + 0.5) sy,
 * (k + 0.5) sz), so the volume fills the box [0, n s] per axis (the unit cube scaled by dims x
 * spacing). Owns `data`. */
typedef struct obs_volume {
  int n[3];          /* dims, each >= 1 */
  double spacing[3]; /* > 0 */
  float *data;       /* n[0] x n[1] x n[2], x fastest; values in [0, 1] */
} obs_volume;

/* Allocates a zeroed volume. OBS_EINVAL for a dim below 1, a spacing not finite and positive, or
 * more than OBS_VOLUME_MAX_VOXELS voxels; OBS_ENOMEM. */
#define OBS_VOLUME_MAX_VOXELS ((int64_t)1 << 31)
int obs_volume_init(obs_volume *v, const int n[3], const double spacing[3], obs_err *err);
void obs_volume_free(obs_volume *v);

static inline float obs_volume_at(const obs_volume *v, int i, int j, int k) {
  return v->data[((size_t)k * (size_t)v->n[1] + (size_t)j) * (size_t)v->n[0] + (size_t)i];
}

/* The trilinear interpolation of the voxels (i | i1, j | j1, k | k1) with weights w of the upper
 * ones, in float in one fixed order of operations (x, then y, then z): obs_volume_sample's, and
 * the isosurface lattice's (isosurface.h), whose Vulkan twin repeats it. */
static inline float obs_volume_lerp3(const obs_volume *v, int i, int i1, int j, int j1, int k,
                                     int k1, float wx, float wy, float wz) {
  float c00 =
      obs_volume_at(v, i, j, k) + wx * (obs_volume_at(v, i1, j, k) - obs_volume_at(v, i, j, k));
  float c10 =
      obs_volume_at(v, i, j1, k) + wx * (obs_volume_at(v, i1, j1, k) - obs_volume_at(v, i, j1, k));
  float c01 =
      obs_volume_at(v, i, j, k1) + wx * (obs_volume_at(v, i1, j, k1) - obs_volume_at(v, i, j, k1));
  float c11 = obs_volume_at(v, i, j1, k1) +
              wx * (obs_volume_at(v, i1, j1, k1) - obs_volume_at(v, i, j1, k1));
  float c0 = c00 + wy * (c10 - c00), c1 = c01 + wy * (c11 - c01);
  return c0 + wz * (c1 - c0);
}

/* The trilinear field at object-space point p. Outside the voxel centres the field is constant
 * along the axis (clamped to the nearest sample), so it is defined everywhere and continuous. */
float obs_volume_sample(const obs_volume *v, const double p[3]);

/* Procedural volumes, sampled at the voxel centres of the box [-1, 1]^3 (spacing 2 / n):
 *   sphere:   0.5 - d / 2 clamped to [0, 1], d the signed distance to the sphere of radius 0.6
 *             about the centre (isovalue 0.5 is its surface);
 *   torus:    the same for the torus of radii 0.6 and 0.25 about the z axis;
 *   marschner_lobb: the test signal of Marschner and Lobb (1994), f_M = 6, alpha = 0.25:
 *             (1 - sin(pi z / 2) + alpha (1 + cos(2 pi f_M cos(pi r / 2)))) / (2 (1 + alpha)),
 *             r = sqrt(x^2 + y^2), in [0, 1];
 *   noise:    smooth value noise of `seed` (trilinear lattice of 8^3 cells, smoothstep weights),
 *             in [0, 1].
 * The volume's spacing is set to 2 / n per axis, so it spans [0, 2]^3 in object space. */
typedef enum {
  OBS_VOLUME_SPHERE,
  OBS_VOLUME_TORUS,
  OBS_VOLUME_MARSCHNER_LOBB,
  OBS_VOLUME_NOISE,
  OBS_VOLUME_PROCEDURAL_COUNT
} obs_volume_procedural;
/* "sphere", "torus", "marschner_lobb", "noise"; NULL-terminated (for parameter tables). */
extern const char *const obs_volume_procedural_names[];
/* The procedural value at a point x of [-1, 1]^3 (any point: the formulas extend). */
double obs_volume_procedural_value(obs_volume_procedural kind, uint32_t seed, const double x[3]);
int obs_volume_procedural_fill(obs_volume_procedural kind, uint32_t seed, const int n[3],
                               obs_volume *v, obs_err *err);
/* The part of that fill of `full` voxels that starts at voxel `off` and spans `n`, into a volume of
 * n voxels (spacing 2 / full), each sample with the whole fill's bits. OBS_EINVAL for a part not
 * inside the volume. */
int obs_volume_procedural_fill_part(obs_volume_procedural kind, uint32_t seed, const int full[3],
                                    const int off[3], const int n[3], obs_volume *v, obs_err *err);

/* Min and max of the trilinear field over blocks of `cell` x `cell` x `cell` voxel intervals:
 * cell c spans the voxel centres c * cell ... (c + 1) * cell (shared with the next cell), which
 * bound every value the field takes between them, so a ray segment inside a cell whose [min, max]
 * does not contain the isovalue cannot cross it. Owns its arrays. */
typedef struct obs_volume_cells {
  int cell; /* voxels per cell side */
  int n[3]; /* cells per axis */
  float *min, *max;
} obs_volume_cells;
int obs_volume_cells_build(const obs_volume *v, int cell, obs_volume_cells *c, obs_err *err);
void obs_volume_cells_free(obs_volume_cells *c);

/* Which side of one isovalue the trilinear field lies on in each voxel cell: cell (i, j, k) spans
 * the voxel centres i ... i + 1 per axis (one centre on a 1-voxel axis), n[a] = max(dims - 1, 1)
 * cells per axis, 2 bits each (OBS_VOLUME_BELOW, OBS_VOLUME_ABOVE, or 0 where the field may reach
 * iso). A cell is wholly on one side only with a margin of a few float roundings past its
 * corners, so no float trilinear sample inside it lands on the other side. An AO march reads two
 * bits here instead of eight samples wherever the isosurface is not near; the bits are stored in
 * bricks of 8^3 cells (128 bytes), so the few samples a march takes in one brick share its cache
 * lines. Owns `bits`. */
enum { OBS_VOLUME_BELOW = 1, OBS_VOLUME_ABOVE = 2 };
typedef struct obs_volume_sides {
  int n[3];
  int bricks[3]; /* bricks per axis: ceil(n / 8) */
  uint8_t *bits; /* obs_volume_side_index's cell c at bits c / 4, shift 2 (c % 4) */
  /* Per brick (x fastest): its side when every cell in it has that side (0 otherwise) in the low
   * 2 bits, and above them the Chebyshev distance in bricks to the nearest brick not wholly on
   * that side, capped at OBS_VOLUME_FAR_MAX (0 for a brick on neither side): every brick nearer
   * than that is on the same side, so a march settles the samples within that reach at once. */
  uint8_t *far;
} obs_volume_sides;
#define OBS_VOLUME_FAR_MAX 31
int obs_volume_sides_build(const obs_volume *v, float iso, obs_volume_sides *s, obs_err *err);
void obs_volume_sides_free(obs_volume_sides *s);
/* The brick holding cell (i, j, k), x fastest (its index in `far`). */
static inline size_t obs_volume_brick_index(const obs_volume_sides *s, int i, int j, int k) {
  return ((size_t)(k >> 3) * (size_t)s->bricks[1] + (size_t)(j >> 3)) * (size_t)s->bricks[0] +
         (size_t)(i >> 3);
}
/* Cell (i, j, k)'s place: its brick, then its place in the brick, x fastest in both. */
static inline size_t obs_volume_side_index(const obs_volume_sides *s, int i, int j, int k) {
  return obs_volume_brick_index(s, i, j, k) << 9 | (size_t)((k & 7) << 6 | (j & 7) << 3 | (i & 7));
}
static inline int obs_volume_side(const obs_volume_sides *s, int i, int j, int k) {
  size_t c = obs_volume_side_index(s, i, j, k);
  return s->bits[c >> 2] >> ((c & 3) * 2) & 3;
}
/* obs_volume_sample at p where its voxel cell may reach s's isovalue; -INFINITY or INFINITY where
 * the cell lies wholly below or above it (for tests that read only the side). */
float obs_volume_sample_sided(const obs_volume *v, const obs_volume_sides *s, const double p[3]);

#endif
