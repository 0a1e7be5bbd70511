/* What lies above a ray origin within reach: what makes an occlusion estimate provably exact, or
 * bounds its error when every ray escaped (docs/accuracy.md, "Standard errors"). */
#ifndef OBS_HALFBALL_H
#define OBS_HALFBALL_H

#include <stdint.h>

#include "obscurance.h"
#include "raytrace.h"

/* The surfaces in the open half-ball of a radius above a ray origin. */
typedef struct obs_halfball {
  double nearest;       /* distance to the nearest; INFINITY: none */
  double cover_cos;     /* upper bound on the share of cosine-weighted directions meeting one */
  double cover_uniform; /* the same for uniformly distributed directions */
} obs_halfball;

/* How much of the half-ball a caller needs to know: past a cover of `cover` (of `uniform` or
 * cosine-weighted directions) both covers are reported as 1 and no longer measured, and the query
 * ends there unless `nearest` asks for the exact nearest distance still. */
typedef struct obs_halfball_need {
  double cover;
  int uniform;
  int nearest;
} obs_halfball_need;

/* What lies in the open half-ball of `radius` (INFINITY: the half-space) above the plane through
 * `org` (the obs_rt_offset origin of `from`) normal to from->ns, the surface `from` lies on
 * excluded as the ray context obs_rt_ctx_init excludes it. Rays from org into that hemisphere
 * meet nothing within `radius` when `nearest` is INFINITY. Conservative: a query that would
 * examine more than a few dozen primitives answers a surface at 0 covering every direction.
 * Measures only what `need` asks for. */
void obs_rt_halfball(const obs_rt *rt, const obs_hit *from, const float org[3], float radius,
                     const obs_halfball_need *need, obs_halfball *out);

/* The standard error of an occlusion estimate at `from` whose every one of n rays escaped, each
 * with the value of "nothing within reach": 0 when nothing lies within `radius` above org (the
 * estimate is exact); else the floor of mcerr.h for the largest change one unseen ray could make
 * (`value_span` when > 0, else 1 - rho at the nearest surface under falloff f), but no more than a
 * third of the largest error possible, that change times the share of directions (cosine-weighted,
 * or `uniform`) that can meet a surface at all. With shading normals off the geometric one (some
 * directions run into the surface) the floor for a change of 1. */
double obs_rt_escape_stderr(const obs_rt *rt, const obs_hit *from, const float org[3],
                            const obs_falloff *f, float radius, int uniform, double value_span,
                            uint32_t n);

#endif
