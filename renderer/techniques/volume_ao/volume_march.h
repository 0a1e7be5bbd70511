/* Marching a scalar volume (volume.h) in its object space: the first crossing of an isosurface
 * along a ray (steps of at most half a voxel, empty macrocells skipped, the root refined by
 * bisection), the normal from the trilinear field's gradient, and ray-marched ambient occlusion
 * with a bent normal (the RTPara report's AO: cosine-distributed directions, fixed start, step
 * and distance, occluded where the field crosses the isovalue). Used by the volume techniques of
 * both backends' CPU paths and by their tests. */
#ifndef OBS_VOLUME_MARCH_H
#define OBS_VOLUME_MARCH_H

#include <stdint.h>

#include "volume.h"

/* What the marcher needs of a volume: the field, its macrocells (NULL: none skipped), the
 * isovalue and its voxel cells' sides of it (NULL: every AO sample is taken; else built for this
 * isovalue). */
typedef struct obs_volume_iso {
  const obs_volume *v;
  const obs_volume_cells *cells;
  float iso;
  const obs_volume_sides *sides;
} obs_volume_iso;

/* The most steps a camera ray takes across a volume's diagonal (only volumes whose thinnest voxel
 * is below a millionth of the diagonal reach it: their step is then longer than half a voxel). */
#define OBS_VOLUME_HIT_MAX_STEPS (1 << 20)

/* The first t in [t0, t1] where the field along o + t d (object space, d need not be unit) rises
 * from below `iso` to at least it, sampled at steps of at most half the smallest voxel side and
 * refined by bisection to a thousandth of a voxel; the ray is first clipped to the volume's box.
 * A ray that starts inside (at or above iso) hits at once: *t = the clipped start. Returns 1 with
 * *t, or 0. */
int obs_volume_first_hit(const obs_volume_iso *s, const double o[3], const double d[3], double t0,
                         double t1, double *t);

/* The unit normal at p from central differences of the trilinear field (half a voxel apart),
 * pointing down the gradient (out of the region above iso); (0, 0, 1) where the gradient
 * vanishes. */
void obs_volume_normal(const obs_volume *v, const double p[3], double n[3]);

/* How an AO ray counts as occluded: the report's one-sided test (the field rises through iso
 * between two samples) or any crossing. */
typedef enum { OBS_VOLUME_CROSS_RISING, OBS_VOLUME_CROSS_ANY } obs_volume_crossing;

/* The most steps one AO direction takes; (max_distance - start) / step beyond it is cut there. */
#define OBS_VOLUME_AO_MAX_STEPS 1000000

typedef struct obs_volume_ao_params {
  uint32_t samples;                 /* directions */
  double start, step, max_distance; /* object-space units along each direction (step > 0: a
                                       * direction with none counts as open) */
  obs_volume_crossing crossing;
  /* How the samples are taken, with the same answer either way: 0 one by one; with cell sides,
   * OBS_ISA_AVX2 or more (simd.h, asked once per render) eight at a time, their loads as
   * vgatherdps or (gather_loads) scalar loads. */
  int isa, gather_loads;
} obs_volume_ao_params;

/* Whether the field along o + t d crosses iso (a->crossing) between consecutive samples at
 * t = start + i step, i = 0, 1, ... up to max_distance (at most OBS_VOLUME_AO_MAX_STEPS steps);
 * the field reads 0 outside the volume's box. Macrocells and cell sides (when s has them) settle
 * samples that cannot end a crossing, with the same answer as without. */
int obs_volume_grid_crossing(const obs_volume_iso *s, const double o[3], const double d[3],
                             const obs_volume_ao_params *a);

/* AO at surface point p with unit normal n: `samples` directions cosine-distributed about n (the
 * points u[i] of the unit square mapped to the unit disk, r = sqrt(u), phi = 2 pi v, and projected
 * up onto the hemisphere), each marched from `start` by `step` up to `max_distance`; AO = 1 -
 * occluded / samples, and *bent the normalised sum of the open directions (n when none is
 * open). `u` holds 2 x samples values in [0, 1). */
double obs_volume_ao(const obs_volume_iso *s, const double p[3], const double n[3],
                     const obs_volume_ao_params *a, const float *u, double bent[3]);

#endif
