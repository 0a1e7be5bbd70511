/* Patches as regular sub-triangles of the scene's triangles (patch_mesh.h). */
#include "patch_mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double dist3(const float *a, const float *b) {
  double x = (double)a[0] - b[0], y = (double)a[1] - b[1], z = (double)a[2] - b[2];
  return sqrt(x * x + y * y + z * z);
}

int obs_patch_mesh_publish(obs_render_ctx *ctx, const char *name, const obs_patch_mesh *pm,
                           int components, const float *values, obs_err *err) {
  return obs_patch_mesh_publish_frames(ctx, name, pm, 1, components, values, err);
}

int obs_patch_mesh_publish_frames(obs_render_ctx *ctx, const char *name, const obs_patch_mesh *pm,
                                  int frames, int components, const float *values, obs_err *err) {
  if (ctx->npatches >= OBS_MAX_PATCH_OUTPUTS)
    return obs_err_set(err, OBS_EINTERNAL, "per-patch output \"%s\": more than %d of them", name,
                       OBS_MAX_PATCH_OUTPUTS);
  obs_patches *p = &ctx->patches[ctx->npatches];
  int rc = obs_patches_init_frames(p, name, frames, pm->count, components, 1, err);
  if (rc) return rc;
  memcpy(p->values, values, obs_patches_values(p) * sizeof(float));
  memcpy(p->area, pm->area, (size_t)pm->count * sizeof(float));
  ctx->npatches++;
  return 0;
}

/* Whether a patch's own error says nothing: no sample, or an exact value (its samples all agreed
 * and its floor is 0). */
static int pool_skips(const obs_patch_err *e) {
  return !(e->n > 0) || (e->floor == 0 && !(e->var[0] > 0 || e->var[1] > 0 || e->var[2] > 0));
}

/* The mean variance of one sample per channel over patches [a, b) with samples and not exact. */
static void pool_range(const obs_patch_err *e, int64_t a, int64_t b, double prior[3]) {
  int64_t k = 0;
  prior[0] = prior[1] = prior[2] = 0;
  for (int64_t i = a; i < b; i++) {
    if (pool_skips(&e[i])) continue;
    for (int c = 0; c < 3; c++) prior[c] += e[i].var[c] * e[i].n;
    k++;
  }
  for (int c = 0; c < 3 && k; c++) prior[c] /= (double)k;
}

void obs_patch_mesh_errors(const obs_patch_mesh *pm, const obs_patch_err *e, float *se) {
  size_t m = 0, cached = (size_t)-1;
  double mesh_prior[3] = {0, 0, 0};
  for (size_t t = 0; t < pm->ntris; t++) {
    while (pm->mesh_tri[m + 1] <= t) m++;
    int64_t a = pm->first[t], b = pm->first[t + 1];
    double prior[3];
    pool_range(e, a, b, prior);
    if (b - a == 1) { /* the mesh's, once per mesh */
      if (cached != m) {
        pool_range(e, pm->first[pm->mesh_tri[m]], pm->first[pm->mesh_tri[m + 1]], mesh_prior);
        cached = m;
      }
      memcpy(prior, mesh_prior, sizeof prior);
    }
    for (int64_t i = a; i < b; i++) {
      const obs_patch_err *p = &e[i];
      for (int c = 0; c < 3; c++) {
        float *out = &se[3 * i + c];
        if (!(p->n > 0)) {
          *out = 1.0f;
        } else if (pool_skips(p)) {
          *out = 0.0f;
        } else {
          double v = (p->df * p->var[c] + OBS_PATCH_PRIOR_WEIGHT * prior[c] / p->n) /
                     (p->df + OBS_PATCH_PRIOR_WEIGHT);
          *out = v > 0 ? (float)sqrt(v) : p->floor;
        }
      }
    }
  }
}

void obs_patch_mesh_warn_capped(obs_render_ctx *ctx, const obs_patch_mesh *pm) {
  if (pm->capped)
    obs_render_ctx_warn(ctx,
                        "patch_size split %zu triangles into more than %d x %d patches; they were "
                        "split %d x %d",
                        pm->capped, OBS_PATCH_SPLIT_MAX, OBS_PATCH_SPLIT_MAX, OBS_PATCH_SPLIT_MAX,
                        OBS_PATCH_SPLIT_MAX);
}

void obs_patch_mesh_free(obs_patch_mesh *pm) {
  if (!pm) return;
  free(pm->first);
  free(pm->mesh_tri);
  free(pm->split);
  free(pm->area);
  memset(pm, 0, sizeof *pm);
}

/* The split of one triangle: n from its longest edge, 1 for a zero-area one. */
static int tri_split(const float *v[3], double patch_size, double *area, int *capped) {
  *area = obs_geometry_tri_area(v[0], v[1], v[2]);
  *capped = 0;
  if (!(*area > 0) || isinf(patch_size)) return 1;
  double l = fmax(dist3(v[0], v[1]), fmax(dist3(v[1], v[2]), dist3(v[2], v[0])));
  double n = ceil(l / patch_size);
  if (!(n <= OBS_PATCH_SPLIT_MAX)) return *capped = 1, OBS_PATCH_SPLIT_MAX;
  return n < 1 ? 1 : (int)n;
}

int obs_patch_mesh_build(const obs_geometry *geo, double patch_size, const char *what,
                         obs_patch_mesh *pm, obs_err *err) {
  memset(pm, 0, sizeof *pm);
  pm->ntris = geo->ntris;
  pm->first = malloc((geo->ntris + 1) * sizeof *pm->first);
  pm->mesh_tri = malloc((geo->nmeshes + 1) * sizeof *pm->mesh_tri);
  pm->split = malloc((geo->ntris ? geo->ntris : 1) * sizeof *pm->split);
  if (!pm->first || !pm->mesh_tri || !pm->split) goto oom;
  size_t t = 0;
  int64_t count = 0;
  for (size_t m = 0; m < geo->nmeshes; m++) {
    const obs_mesh *me = &geo->meshes[m];
    pm->mesh_tri[m] = t;
    for (size_t k = 0; k < me->ntris; k++, t++) {
      const float *v[3];
      for (int j = 0; j < 3; j++) v[j] = me->pos + 3 * (size_t)me->idx[3 * k + (size_t)j];
      double a;
      int capped;
      int n = tri_split(v, patch_size, &a, &capped);
      pm->capped += (size_t)capped;
      pm->degenerate += !(a > 0);
      pm->split[t] = n;
      pm->first[t] = count;
      count += (int64_t)n * n;
      if (count > OBS_PATCH_COUNT_MAX) {
        obs_patch_mesh_free(pm);
        return obs_err_set(err, OBS_EINVAL,
                           "%s: the scene's triangles split into more than %lld patches; raise "
                           "the patch size",
                           what, (long long)OBS_PATCH_COUNT_MAX);
      }
    }
  }
  pm->mesh_tri[geo->nmeshes] = t;
  pm->first[t] = count;
  pm->count = count;
  pm->area = malloc((size_t)(count ? count : 1) * sizeof *pm->area);
  if (!pm->area) goto oom;
  t = 0;
  for (size_t m = 0; m < geo->nmeshes; m++) {
    const obs_mesh *me = &geo->meshes[m];
    for (size_t k = 0; k < me->ntris; k++, t++) {
      const float *v[3];
      for (int j = 0; j < 3; j++) v[j] = me->pos + 3 * (size_t)me->idx[3 * k + (size_t)j];
      /* The n^2 sub-triangles of a regular split are congruent: each has 1/n^2 of the area. */
      double n = pm->split[t], a = obs_geometry_tri_area(v[0], v[1], v[2]) / (n * n);
      for (int64_t p = pm->first[t]; p < pm->first[t + 1]; p++) pm->area[p] = (float)a;
    }
  }
  return 0;
oom:
  obs_patch_mesh_free(pm);
  return obs_err_set(err, OBS_ENOMEM, "patches: out of memory for %zu triangles", geo->ntris);
}

int64_t obs_patch_sub_index(int n, double u, double v) {
  if (n <= 1) return 0;
  double fu = u * n, fv = v * n;
  int i = fu > 0 ? (int)fu : 0, j = fv > 0 ? (int)fv : 0; /* NaN lands in the first row */
  if (i > n - 1) i = n - 1;
  if (j > n - 1) j = n - 1;
  if (i + j > n - 1) j = n - 1 - i;
  double a = fu - i, b = fv - j;
  int64_t N = n;
  if (a + b > 1.0 && i + j <= n - 2) /* inverted triangle (i, j) */
    return N * (N + 1) / 2 + (int64_t)i * (N - 1) - (int64_t)i * (i - 1) / 2 + j;
  return (int64_t)i * N - (int64_t)i * (i - 1) / 2 + j;
}

void obs_patch_sub_corners(int n, int64_t k, double uv[3][2]) {
  int64_t N = n, ups = N * (N + 1) / 2;
  int down = k >= ups;
  if (down) k -= ups;
  int64_t row = down ? N - 1 : N; /* entries in row 0; one fewer per row */
  int i = 0;
  while (k >= row && row > 0) k -= row--, i++;
  int j = (int)k;
  double s = 1.0 / n;
  if (down) {
    uv[0][0] = (i + 1) * s, uv[0][1] = j * s;
    uv[1][0] = (i + 1) * s, uv[1][1] = (j + 1) * s;
    uv[2][0] = i * s, uv[2][1] = (j + 1) * s;
  } else {
    uv[0][0] = i * s, uv[0][1] = j * s;
    uv[1][0] = (i + 1) * s, uv[1][1] = j * s;
    uv[2][0] = i * s, uv[2][1] = (j + 1) * s;
  }
}

size_t obs_patch_mesh_owner(const obs_patch_mesh *pm, int64_t patch, int64_t *sub) {
  size_t lo = 0, hi = pm->ntris; /* the last t with first[t] <= patch */
  while (hi - lo > 1) {
    size_t mid = lo + (hi - lo) / 2;
    if (pm->first[mid] <= patch)
      lo = mid;
    else
      hi = mid;
  }
  /* Empty ranges cannot hold it: every triangle has at least one patch. */
  *sub = patch - pm->first[lo];
  return lo;
}

void obs_patch_barycentric(const float a[3], const float b[3], const float c[3], const float p[3],
                           double *u, double *v) {
  double e1[3], e2[3], w[3];
  for (int k = 0; k < 3; k++) {
    e1[k] = (double)b[k] - a[k];
    e2[k] = (double)c[k] - a[k];
    w[k] = (double)p[k] - a[k];
  }
  double d00 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
  double d01 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
  double d11 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  double d20 = w[0] * e1[0] + w[1] * e1[1] + w[2] * e1[2];
  double d21 = w[0] * e2[0] + w[1] * e2[1] + w[2] * e2[2];
  double den = d00 * d11 - d01 * d01;
  if (!(den > 0) || !isfinite(den)) {
    *u = *v = 0;
    return;
  }
  *u = (d11 * d20 - d01 * d21) / den;
  *v = (d00 * d21 - d01 * d20) / den;
}
