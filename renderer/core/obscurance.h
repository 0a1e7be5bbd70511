/* The obscurance model (Méndez-Feliu and Sbert) shared by every obscurance estimator, per pixel or
 * per patch, on every backend: the distance falloff rho(d), the scene's area-weighted average
 * reflectivity R_ave and the ambient intensity I_A of a closed environment.
 *
 * Radiometry: scene emission is radiance, so I_A below is a radiance and the indirect term
 * I(P) = R(P) I_A W(P) is one too, comparable with path_trace's output (the radiosity form of the
 * article, B = pi L, has the same pi on both sides). */
#ifndef OBS_OBSCURANCE_H
#define OBS_OBSCURANCE_H

#include <math.h>
#include "geometry.h"
#include "obscura/error.h"
#include "obscura/scene.h"

/* The falloffs in the order rt_ao's and the obscurance techniques' `falloff` choices list them. */
typedef enum obs_falloff_kind {
  OBS_FALLOFF_BINARY = 0, /* 0 for any surface within d_max */
  OBS_FALLOFF_SQRT = 1,   /* sqrt(d / d_max), the article's */
  OBS_FALLOFF_EXP = 2     /* 1 - exp(-tau d) */
} obs_falloff_kind;

/* The falloffs' names, indexed by obs_falloff_kind, NULL-terminated: the `falloff` choices of
 * every technique that has one. */
extern const char *const obs_falloff_names[4];

typedef struct obs_falloff {
  int kind;     /* obs_falloff_kind */
  double d_max; /* > 0; INFINITY: unbounded (not with SQRT) */
  double tau;   /* EXP only, > 0 */
} obs_falloff;

/* rho(d) in [0, 1] for the nearest surface at distance d (d = INFINITY: none); 1 from d_max on. */
static inline double obs_falloff_rho(const obs_falloff *f, double d) {
  if (!(d < f->d_max)) return 1.0;
  switch (f->kind) {
    case OBS_FALLOFF_BINARY: return 0.0;
    case OBS_FALLOFF_SQRT: return sqrt(d / f->d_max);
    default: return isinf(d) ? 1.0 : -expm1(-f->tau * d);
  }
}

/* Area-weighted facts of a scene's surfaces (the objects' geometry: triangles after tessellation
 * and analytic spheres, each counted once; quad lights are emitters, not surfaces). */
typedef struct obs_obscurance_env {
  double area;        /* A_total, scene units squared */
  double r_ave[3];    /* sum A_i R_i / A_total (0 for an object without material) */
  double emitted[3];  /* sum A_i E_i / A_total: emissive objects (area once) and quad lights */
} obs_obscurance_env;

/* Computes `env` from `geo` (built from `scene`). Refuses a scene without surface area and one
 * whose R_ave reaches 1 in any channel (the closed-environment series 1 / (1 - R_ave) diverges),
 * naming the scene. */
int obs_obscurance_env_compute(const obs_scene *scene, const obs_geometry *geo,
                               obs_obscurance_env *env, obs_err *err);

/* The ambient intensity of a closed environment, per channel:
 *   without colour bleeding  I_A = R_ave / (1 - R_ave) * sum A_i E_i / A_total
 *   with colour bleeding     I_A =     1 / (1 - R_ave) * sum A_i E_i / A_total
 * (with bleeding W already carries the reflectivity of the surfaces seen). */
void obs_obscurance_ambient(const obs_obscurance_env *env, int color_bleeding, double ia[3]);

#endif
