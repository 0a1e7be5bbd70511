/* Patches as sub-triangles: each scene triangle split regularly into n x n congruent triangles so
 * that no patch edge exceeds a length, numbered in scene triangle order, then sub-triangle order;
 * and the way back from a point on a triangle to its patch. */
#ifndef OBS_PATCH_MESH_H
#define OBS_PATCH_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "geometry.h"
#include "obscura/error.h"
#include "obscura/technique.h"

/* A triangle is split into at most OBS_PATCH_SPLIT_MAX^2 patches; a smaller patch_size is capped
 * there (obs_patch_mesh.capped counts the triangles it caps), so any length renders. */
#define OBS_PATCH_SPLIT_MAX 128
/* Scenes whose split would exceed this many patches are refused. */
#define OBS_PATCH_COUNT_MAX ((int64_t)1 << 24)

typedef struct obs_patch_mesh {
  int64_t count;     /* patches */
  size_t ntris;      /* scene triangles */
  int64_t *first;    /* ntris + 1: the first patch of each triangle, then count */
  size_t *mesh_tri;  /* nmeshes + 1: the first triangle of each mesh */
  int32_t *split;    /* ntris: n, the triangle's split into n^2 patches */
  float *area;       /* count: patch areas in scene units squared */
  size_t capped;     /* triangles whose split OBS_PATCH_SPLIT_MAX capped */
  size_t degenerate; /* triangles of zero area (one patch each, area 0) */
} obs_patch_mesh;

/* Splits every triangle of `geo` with n = ceil(longest edge / patch_size) (at least 1;
 * patch_size INFINITY: no split). A zero-area triangle stays one patch of area 0. OBS_EINVAL
 * naming `what` (the parameter's JSON pointer) past OBS_PATCH_COUNT_MAX patches. */
int obs_patch_mesh_build(const obs_geometry *geo, double patch_size, const char *what,
                         obs_patch_mesh *pm, obs_err *err);
void obs_patch_mesh_free(obs_patch_mesh *pm);

/* Sub-triangle k of a triangle split n times, for a point with barycentric weights u (vertex 1)
 * and v (vertex 2), clamped into the triangle. Sub-triangles are numbered row by row: the n(n+1)/2
 * upright ones (lattice corners (i,j), (i+1,j), (i,j+1) in units of 1/n), then the n(n-1)/2
 * inverted ones ((i+1,j), (i+1,j+1), (i,j+1)); all keep the triangle's winding. */
int64_t obs_patch_sub_index(int n, double u, double v);
/* The corners of sub-triangle k as (u, v) weights, in the triangle's winding. */
void obs_patch_sub_corners(int n, int64_t k, double uv[3][2]);

/* The scene triangle (index over all meshes) of a mesh primitive. */
static inline size_t obs_patch_mesh_tri(const obs_patch_mesh *pm, unsigned geom, unsigned prim) {
  return pm->mesh_tri[geom] + prim;
}
/* The patch of the point with weights (u, v) on mesh `geom`'s triangle `prim`. */
static inline int64_t obs_patch_mesh_find(const obs_patch_mesh *pm, unsigned geom, unsigned prim,
                                          double u, double v) {
  size_t t = obs_patch_mesh_tri(pm, geom, prim);
  return pm->first[t] + obs_patch_sub_index(pm->split[t], u, v);
}
/* Hands a map of `components` values per patch (pm->count x components: 3 for RGB, 1 for a
 * scalar) to the render as its next per-patch output `name` (ctx->patches[ctx->npatches]), with
 * the patches' areas (both copied). */
int obs_patch_mesh_publish(obs_render_ctx *ctx, const char *name, const obs_patch_mesh *pm,
                           int components, const float *values, obs_err *err);
/* The same for `frames` maps one after the other (frames x pm->count x components values). */
int obs_patch_mesh_publish_frames(obs_render_ctx *ctx, const char *name, const obs_patch_mesh *pm,
                                  int frames, int components, const float *values, obs_err *err);
/* What a map's patch knows of its own error: the variance of its mean from its samples (0 when
 * they all agreed), their number n (0: none reached it) and the variance's degrees of freedom,
 * and the floor it reports when they agreed (mcerr.h; 0: its value is exact). */
typedef struct obs_patch_err {
  double var[3], n, df; /* var per channel */
  float floor;
} obs_patch_err;
/* The patches' standard errors (docs/techniques/obscurance_map.md, "Standard errors"): each
 * patch's variance in each channel pooled with a prior, the mean variance of one sample over the
 * patches of its triangle (or, for a triangle of one patch, of its mesh) with samples and not
 * exact, over its own n, with OBS_PATCH_PRIOR_WEIGHT degrees of freedom:
 * (df var + w p / n) / (df + w). Like the
 * per-pixel prior (driver.h) it makes up for events too rare for a patch's few samples: where they
 * were missed, mean and spread are both low. 1 where no sample reached a patch (its value is a
 * convention); the floor where the pooled variance is 0 (0 where exact). */
#define OBS_PATCH_PRIOR_WEIGHT 8.0
void obs_patch_mesh_errors(const obs_patch_mesh *pm, const obs_patch_err *e, float *se);
/* (se: count x 3, patch-major, one per channel) */
/* Warns the render when the split of some triangles was capped at OBS_PATCH_SPLIT_MAX. */
void obs_patch_mesh_warn_capped(obs_render_ctx *ctx, const obs_patch_mesh *pm);
/* The triangle holding `patch` and its sub-triangle index there. */
size_t obs_patch_mesh_owner(const obs_patch_mesh *pm, int64_t patch, int64_t *sub);
/* Barycentric weights (u, v) of p on triangle (a, b, c), in double; (0, 0) when degenerate. */
void obs_patch_barycentric(const float a[3], const float b[3], const float c[3], const float p[3],
                           double *u, double *v);

#endif
