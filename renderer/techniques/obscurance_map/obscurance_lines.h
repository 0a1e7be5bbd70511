/* The line sets of the per-patch obscurance estimators, shared by every backend that casts them:
 * the bounding sphere of the geometry, the bundle directions with their grids of parallel lines
 * (the CPU `bundles` estimator and a depth-peeling renderer use the same ones), and the global
 * lines through pairs of uniformly random points on the sphere. */
#ifndef OBS_OBSCURANCE_LINES_H
#define OBS_OBSCURANCE_LINES_H

#include <stdint.h>

#include "geometry.h"

/* A sphere holding every surface of `geo`, in its frame (coordinates world minus geo->origin). */
typedef struct obs_bound_sphere {
  double center[3];
  double radius; /* > 0 */
} obs_bound_sphere;

void obs_bound_sphere_of(const obs_geometry *geo, obs_bound_sphere *s);

/* Bundle k of `count`: direction `dir`, the grid's axes `u`, `v` (an orthonormal frame with dir)
 * and the origin of line (i, j) of the res x res grid,
 *   org = corner + (i + offset[0]) cell u + (j + offset[1]) cell v,
 * the lines starting one radius behind the sphere's centre and running 2 radii along dir. The
 * directions are spherical Fibonacci sets, one per group of directions (obs_bundle_groups), each
 * turned by its own random rotation from `seed`; the grid covers the disc the sphere projects to,
 * shifted by a random fraction of a cell per direction (`offset`), so that a patch's sample count
 * has no aliasing with the grid. */
typedef struct obs_bundle {
  double dir[3], u[3], v[3];
  double corner[3];
  double cell;      /* 2 radius / res */
  double offset[2]; /* in [0, 1) cells */
} obs_bundle;

void obs_bundle_get(const obs_bound_sphere *s, uint32_t seed, uint32_t count, uint32_t k,
                    uint32_t res, obs_bundle *b);
/* The bundles' directions form independent groups for the standard error (sampling.h's
 * replicates, mcerr.h's ratio over groups): min(count, 8) blocks of
 * consecutive directions, each a spherical Fibonacci set of its own size turned by its own random
 * rotation, so that the groups' estimates are independent. Group r holds directions
 * [obs_bundle_group_first(count, r), obs_bundle_group_first(count, r + 1)). */
uint32_t obs_bundle_groups(uint32_t count);
uint32_t obs_bundle_group_first(uint32_t count, uint32_t r);
/* The origin of line (i, j) of bundle `b`. */
static inline void obs_bundle_line(const obs_bundle *b, uint32_t i, uint32_t j, double org[3]) {
  double x = (i + b->offset[0]) * b->cell, y = (j + b->offset[1]) * b->cell;
  for (int c = 0; c < 3; c++) org[c] = b->corner[c] + x * b->u[c] + y * b->v[c];
}

/* Global line `index`: from a uniformly random point of the sphere toward another one (`dir` a
 * unit vector, `len` the chord's length); the pair depends only on (seed, index). Lines through
 * two independent uniform points of a sphere are uniformly distributed in the lines meeting it. */
void obs_global_line(const obs_bound_sphere *s, uint32_t seed, uint64_t index, double org[3],
                     double dir[3], double *len);

#endif
