/* The emitters of a scene as the CPU techniques sample them for direct light: quad lights and
 * emissive objects gathered into one table, chosen in proportion to their power and sampled
 * uniformly in area, each point with its area density and the shadow ray's length. Shared by
 * path_trace (next-event estimation) and obscurance (its direct term). */
#ifndef OBS_EMITTERS_H
#define OBS_EMITTERS_H

#include <stddef.h>

#include "obscura/error.h"
#include "obscura/scene.h"
#include "raytrace.h"

/* One emitting primitive in the ray tracer's frame: a triangle (a, a + e1, a + e2) or, with
 * `sphere`, the whole sphere of centre a and radius r. */
typedef struct obs_emitter {
  double a[3], e1[3], e2[3], n[3]; /* n: unit normal of a triangle (its emitting side) */
  double r, area;
  double le[3];
  int sphere, two_sided;
} obs_emitter;

typedef struct obs_emitters {
  obs_emitter *em; /* quad-light triangles first (nquad of them), then emissive objects */
  size_t n, nquad;
  double *cdf;  /* emitter choice, by area times mean emission */
  double total; /* sum of area times mean emission: an emitter point's area density is
                   mean(le) / total whichever primitive it lies on */
} obs_emitters;

/* A point chosen on the emitters, seen from a surface point. */
typedef struct obs_emitter_sample {
  const obs_emitter *e;
  double wi[3]; /* unit direction from the surface point to the emitter point */
  double dist;  /* their distance */
  double coss;  /* cosine at the surface point (shading normal) */
  double pdf;   /* solid-angle density of wi */
} obs_emitter_sample;

static inline double obs_emitters_mean3(const double v[3]) { return (v[0] + v[1] + v[2]) / 3.0; }

/* Gathers every emitter of `sc` (built into `rt`): quad lights (one-sided, two triangles each)
 * and the triangles and spheres of objects with emission (two-sided). An empty table is no
 * error. obs_emitters_free releases it, also after a failure. */
int obs_emitters_build(const obs_scene *sc, const obs_rt *rt, obs_emitters *out, obs_err *err);
void obs_emitters_free(obs_emitters *em);

/* Chooses an emitter by u[0] (by power) and a point q on it, uniform in area, by (u[1], u[2]);
 * nl is the emitter's unit normal there (a sphere's outward one). Its area density is
 * mean(e->le) / em->total. The table must not be empty. */
const obs_emitter *obs_emitters_point(const obs_emitters *em, const double u[3], double q[3],
                                      double nl[3]);
/* Chooses an emitter by u[0] and a point on it by (u[1], u[2]) as seen from `hit`. Returns 1 and
 * fills `s` when the point faces the hit's hemisphere (a shadow ray is then due), 0 when the
 * sample contributes nothing. The table must not be empty. */
int obs_emitters_sample(const obs_emitters *em, const obs_hit *hit, const double u[3],
                        obs_emitter_sample *s);

/* Distance along (o, d) to the triangle of `e` (Moeller-Trumbore, double), or INFINITY. */
double obs_emitter_tri_hit(const obs_emitter *e, const double o[3], const double d[3]);

#endif
