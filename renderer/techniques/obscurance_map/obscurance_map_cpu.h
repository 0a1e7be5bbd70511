/* obscurance_map on the CPU: per-patch obscurances W (RGB with colour bleeding) by one of three
 * estimators, as values with their standard errors, for the technique's run, tests and benchmarks.
 * The estimators share the patches, the sample value and the accumulation (obscurance_map.c); the
 * line estimators (global lines, bundles) are in obscurance_map_lines.c. */
#ifndef OBS_OBSCURANCE_MAP_CPU_H
#define OBS_OBSCURANCE_MAP_CPU_H

#include <stdatomic.h>
#include <stdint.h>

#include "obscura/technique.h"
#include "obscurance.h"
#include "obscurance_lines.h"
#include "obscurance_map.h"
#include "patch_mesh.h"
#include "raytrace.h"

/* A map's values. Owns everything inside. */
typedef struct obs_omap {
  obs_patch_mesh pm;
  float *w;          /* count x 3, patch-major: W per channel (equal without colour bleeding) */
  float *se;         /* count x 3: standard error of a patch's W per channel (1: no sample;
                        docs/techniques/obscurance_map.md, "Standard errors") */
  uint64_t *n;       /* count: samples per patch */
  uint64_t rays;     /* Embree queries made */
  int64_t unsampled; /* patches of positive area that received no sample */
  double r_ave[3];   /* the scene's average reflectivity (the value of "nothing within d_max") */
} obs_omap;

/* Computes the map of `p` over rt's geometry (built from `scene`) on `threads` threads; the same
 * bits for any thread count. Patches without a sample take the value of "nothing within d_max"
 * (1, or R_ave with colour bleeding) and a standard error of 1. `cancel` and `progress` may be
 * NULL. */
int obs_omap_compute(const obs_rt *rt, const obs_scene *scene, const obs_obscurance_map_params *p,
                     int threads, const atomic_int *cancel, obs_progress_fn progress,
                     void *progress_user, obs_omap *out, obs_err *err);
void obs_omap_free(obs_omap *m);

/* ---- shared by the estimators' files ---- */

/* Fixed-point sums of one patch's samples: integer addition is associative, so per-thread sums
 * add up to the same bits whatever thread took which lines. */
typedef struct obs_omap_acc {
  uint64_t s[3]; /* sum of the sample's channels, OMAP_ONE = 1 */
  uint64_t q[3]; /* sum of the squares of the sample's channels */
  uint64_t n;    /* samples */
} obs_omap_acc;
#define OMAP_ONE 268435456.0 /* 2^28: 2^35 samples of value 1 fit in 63 bits */

typedef struct obs_omap_job {
  const obs_rt *rt;
  obs_obscurance_map_params p;
  obs_falloff f;
  const obs_patch_mesh *pm;
  float (*mesh_r)[3];   /* reflectivity of each mesh's object */
  float (*sphere_r)[3]; /* of each analytic sphere's object */
  double r_ave[3];
  obs_bound_sphere bs;
  int threads;
  obs_omap_acc *acc;    /* threads x count (lines); count (rays: a patch is one thread's) */
  int acc_sets;         /* the sets of count in acc: threads for lines, 1 for rays */
  /* rays: the patches to sample (NULL: all of them, in order) */
  const int64_t *list;
  int64_t nlist;
  /* rays, when set: per patch, whether one of its samples met a moving mesh (written by the
   * patch's thread); and, per patch, whether a sample of a moving mesh's patch met it. */
  unsigned char *hits_moving;
  atomic_uchar *seen;
  uint64_t *rays;       /* threads x 8 (one cache line each) */
  /* rays, bundles: per patch and channel, its samples' independent groups (replicates; groups of
   * directions, obs_bundle_groups), count x 3; NULL for global lines (independent samples) */
  struct obs_mcerr_ratio *groups;
  uint32_t dir0;        /* bundles: the first direction of the group being cast */
  obs_patch_err *errs;  /* count: what each patch knows of its error (patch_mesh.h) */
  float (*halton)[2];   /* rays: Halton points (bases 2, 3), unrotated, a power of two of them */
  uint32_t halton_mask; /* their count less one */
} obs_omap_job;

/* The value of a sample that sees a surface of reflectivity r at distance d (d = INFINITY or
 * r = NULL: nothing). */
static inline void obs_omap_value(const obs_omap_job *j, double d, const float *r, double v[3]) {
  if (!r || !(d < j->f.d_max)) {
    for (int c = 0; c < 3; c++) v[c] = j->p.color_bleeding ? j->r_ave[c] : 1.0;
    return;
  }
  double rho = obs_falloff_rho(&j->f, d);
  for (int c = 0; c < 3; c++) v[c] = j->p.color_bleeding ? rho * r[c] : rho;
}

static inline void obs_omap_add(obs_omap_acc *a, const double v[3]) {
  for (int c = 0; c < 3; c++) a->s[c] += (uint64_t)(v[c] * OMAP_ONE + 0.5);
  for (int c = 0; c < 3; c++) a->q[c] += (uint64_t)(v[c] * v[c] * OMAP_ONE + 0.5);
  a->n++;
}

/* The right-handed normal of mesh `geom`'s triangle `prim` (unnormalised): a patch's front side,
 * the one its obscurance is of. obs_rt_plane_normal's double cross product, the ray tracer's face
 * normal: a component whose products cancel is exactly 0 at every scale. */
static inline void obs_omap_tri_normal(const obs_rt *rt, unsigned geom, unsigned prim,
                                       double n[3]) {
  const obs_mesh *m = &rt->geo.meshes[geom];
  const uint32_t *t = m->idx + 3 * (size_t)prim;
  obs_rt_plane_normal(m->pos + 3 * t[0], m->pos + 3 * t[1], m->pos + 3 * t[2], n);
}

/* Tile functions for obs_parallel_tiles (x = chunk index, one row): */
int obs_omap_rays_tile(void *user, int thread, int x0, int y0, int x1, int y1);
int obs_omap_global_tile(void *user, int thread, int x0, int y0, int x1, int y1);
int obs_omap_bundle_tile(void *user, int thread, int x0, int y0, int x1, int y1);
/* Lines per chunk of the global-line estimator; patches per chunk of the ray estimator. */
#define OMAP_GLOBAL_CHUNK 1024
#define OMAP_RAYS_CHUNK 16
/* The number of global lines `p` asks for. */
uint64_t obs_omap_global_count(const obs_obscurance_map_params *p);

/* A job set up to compute maps of `p` over rt's geometry, again and again as objects move: the
 * patches (into out->pm), the scene's R_ave and the value arrays of `out`, all of frame 0. */
int obs_omap_job_init(obs_omap_job *j, const obs_rt *rt, const obs_scene *scene,
                      const obs_obscurance_map_params *p, int threads, obs_omap *out, obs_err *err);
/* Samples the patches j->list names (rays; NULL: every patch; the line estimators always do all)
 * and writes their values, errors and counts into `out` (the init's or one of the same size). */
int obs_omap_job_run(obs_omap_job *j, obs_omap *out, const atomic_int *cancel,
                     obs_progress_fn progress, void *progress_user);
void obs_omap_job_free(obs_omap_job *j);

/* The run of a scene with moving objects (obscurance_map_motion.c): every frame's map, updated
 * as `update` says, into the render's patches output; `out` is left holding the last frame. */
int obs_omap_frames(obs_render_ctx *ctx, obs_rt *rt, const obs_obscurance_map_params *p,
                    obs_omap *out, obs_err *err);

#endif
