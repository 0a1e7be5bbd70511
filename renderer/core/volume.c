/* Scalar volumes: allocation, trilinear reconstruction, procedural volumes and the min/max
 * macrocell grid (volume.h). */
#include "volume.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sampling.h"

#define PI 3.14159265358979323846

const char *const obs_volume_procedural_names[] = {"sphere", "torus", "marschner_lobb", "noise",
                                                   NULL};

int obs_volume_init(obs_volume *v, const int n[3], const double spacing[3], obs_err *err) {
  memset(v, 0, sizeof *v);
  int64_t count = 1;
  for (int a = 0; a < 3; a++) {
    if (n[a] < 1)
      return obs_err_set(err, OBS_EINVAL, "volume: dims must be at least 1 (got %d on axis %d)",
                         n[a], a);
    if (!(spacing[a] > 0) || !isfinite(spacing[a]))
      return obs_err_set(err, OBS_EINVAL,
                         "volume: spacing must be finite and positive (got %g on axis %d)",
                         spacing[a], a);
    count *= n[a];
    if (count > OBS_VOLUME_MAX_VOXELS)
      return obs_err_set(err, OBS_EINVAL, "volume: more than %lld voxels",
                         (long long)OBS_VOLUME_MAX_VOXELS);
  }
  if (!(v->data = calloc((size_t)count, sizeof *v->data)))
    return obs_err_set(err, OBS_ENOMEM, "volume: out of memory for %lld voxels", (long long)count);
  memcpy(v->n, n, sizeof v->n);
  memcpy(v->spacing, spacing, sizeof v->spacing);
  return 0;
}

void obs_volume_free(obs_volume *v) {
  if (!v) return;
  free(v->data);
  memset(v, 0, sizeof *v);
}

/* The continuous index of p along axis a, clamped to the voxel centres: the lower sample and the
 * weight of the upper one. */
static inline void axis_index(const obs_volume *v, int a, double p, int *i0, float *w) {
  double u = p / v->spacing[a] - 0.5;
  double hi = v->n[a] - 1;
  if (!(u > 0)) u = 0; /* NaN too */
  if (u > hi) u = hi;
  int i = (int)u;
  if (i > v->n[a] - 2) i = v->n[a] > 1 ? v->n[a] - 2 : 0;
  *i0 = i;
  *w = v->n[a] > 1 ? (float)(u - i) : 0.0f;
}

float obs_volume_sample(const obs_volume *v, const double p[3]) {
  int i, j, k;
  float wx, wy, wz;
  axis_index(v, 0, p[0], &i, &wx);
  axis_index(v, 1, p[1], &j, &wy);
  axis_index(v, 2, p[2], &k, &wz);
  int i1 = i + (v->n[0] > 1), j1 = j + (v->n[1] > 1), k1 = k + (v->n[2] > 1);
  return obs_volume_lerp3(v, i, i1, j, j1, k, k1, wx, wy, wz);
}

float obs_volume_sample_sided(const obs_volume *v, const obs_volume_sides *s, const double p[3]) {
  int c[3];
  float w[3];
  for (int a = 0; a < 3; a++) axis_index(v, a, p[a], &c[a], &w[a]);
  int side = obs_volume_side(s, c[0], c[1], c[2]);
  if (side) return side == OBS_VOLUME_BELOW ? -INFINITY : INFINITY;
  return obs_volume_sample(v, p);
}

static double clamp01(double x) { return x < 0 ? 0 : x > 1 ? 1 : x; }

/* The lattice value at (x, y, z) of noise `seed`: the shared sampling hashes. */
static uint32_t hash3(uint32_t seed, int x, int y, int z) {
  return obs_hash32(obs_hash_combine(
      obs_hash_combine(obs_hash_combine(seed, (uint32_t)x), (uint32_t)y), (uint32_t)z));
}

/* Value noise on a lattice of 8 cells across [-1, 1], smoothstep-weighted: in [0, 1]. */
static double value_noise(uint32_t seed, const double x[3]) {
  double u[3], w[3];
  int c[3];
  for (int a = 0; a < 3; a++) {
    u[a] = (x[a] + 1) * 4;
    c[a] = (int)floor(u[a]);
    double f = u[a] - c[a];
    w[a] = f * f * (3 - 2 * f);
  }
  double r = 0;
  for (int k = 0; k < 8; k++) {
    int dx = k & 1, dy = (k >> 1) & 1, dz = (k >> 2) & 1;
    double wt = (dx ? w[0] : 1 - w[0]) * (dy ? w[1] : 1 - w[1]) * (dz ? w[2] : 1 - w[2]);
    r += wt * (hash3(seed, c[0] + dx, c[1] + dy, c[2] + dz) >> 8) * 0x1p-24;
  }
  return clamp01(r);
}

/* The Marschner-Lobb signal is a sum of a term in z and a term in r = |(x, y)|: a fill computes
 * each once per slice and per column and combines them per voxel, with the same bits as the
 * direct formula (these three functions are that formula). */
#define ML_FM 6.0
#define ML_ALPHA 0.25
static double ml_axial(double z) { return 1 - sin(PI * z / 2); }
static double ml_radial(double x, double y) {
  double r = sqrt(x * x + y * y);
  return ML_ALPHA * (1 + cos(2 * PI * ML_FM * cos(PI * r / 2)));
}
static double ml_combine(double axial, double radial) {
  return clamp01((axial + radial) / (2 * (1 + ML_ALPHA)));
}

double obs_volume_procedural_value(obs_volume_procedural kind, uint32_t seed, const double x[3]) {
  switch (kind) {
    case OBS_VOLUME_SPHERE: {
      double d = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) - 0.6;
      return clamp01(0.5 - d / 2);
    }
    case OBS_VOLUME_TORUS: {
      double q = sqrt(x[0] * x[0] + x[1] * x[1]) - 0.6;
      double d = sqrt(q * q + x[2] * x[2]) - 0.25;
      return clamp01(0.5 - d / 2);
    }
    case OBS_VOLUME_MARSCHNER_LOBB:
      return ml_combine(ml_axial(x[2]), ml_radial(x[0], x[1]));
    default:
      return value_noise(seed, x);
  }
}

/* The lattice coordinate of voxel index i of n across [-1, 1]. */
static double lattice(int i, int n) { return -1 + (i + 0.5) * (2.0 / n); }

/* Marschner-Lobb by its separable terms: the radial term per column (x, y), the axial per slice. */
static int fill_marschner_lobb(const int full[3], const int off[3], obs_volume *v, obs_err *err) {
  const int *n = v->n;
  double *radial = malloc((size_t)n[0] * (size_t)n[1] * sizeof *radial);
  if (!radial) return obs_err_set(err, OBS_ENOMEM, "volume: out of memory");
  for (int j = 0; j < n[1]; j++)
    for (int i = 0; i < n[0]; i++)
      radial[(size_t)j * (size_t)n[0] + (size_t)i] =
          ml_radial(lattice(i + off[0], full[0]), lattice(j + off[1], full[1]));
  float *out = v->data;
  for (int k = 0; k < n[2]; k++) {
    double axial = ml_axial(lattice(k + off[2], full[2]));
    for (size_t c = 0; c < (size_t)n[0] * (size_t)n[1]; c++)
      *out++ = (float)ml_combine(axial, radial[c]);
  }
  free(radial);
  return 0;
}

int obs_volume_procedural_fill_part(obs_volume_procedural kind, uint32_t seed, const int full[3],
                                    const int off[3], const int n[3], obs_volume *v,
                                    obs_err *err) {
  memset(v, 0, sizeof *v);
  if ((int)kind < 0 || kind >= OBS_VOLUME_PROCEDURAL_COUNT)
    return obs_err_set(err, OBS_EINVAL, "volume: unknown procedural kind %d", (int)kind);
  for (int a = 0; a < 3; a++)
    if (full[a] < 1 || off[a] < 0 || n[a] < 1 || off[a] + n[a] > full[a])
      return obs_err_set(err, OBS_EINVAL,
                         "volume: part [%d, %d) of %d voxels on axis %d is not inside the volume",
                         off[a], off[a] + n[a], full[a], a);
  double s[3] = {2.0 / full[0], 2.0 / full[1], 2.0 / full[2]};
  int rc = obs_volume_init(v, n, s, err);
  if (rc) return rc;
  if (kind == OBS_VOLUME_MARSCHNER_LOBB) {
    if ((rc = fill_marschner_lobb(full, off, v, err))) obs_volume_free(v);
    return rc;
  }
  for (int k = 0; k < n[2]; k++)
    for (int j = 0; j < n[1]; j++)
      for (int i = 0; i < n[0]; i++) {
        double x[3] = {lattice(i + off[0], full[0]), lattice(j + off[1], full[1]),
                       lattice(k + off[2], full[2])};
        v->data[((size_t)k * (size_t)n[1] + (size_t)j) * (size_t)n[0] + (size_t)i] =
            (float)obs_volume_procedural_value(kind, seed, x);
      }
  return 0;
}

int obs_volume_procedural_fill(obs_volume_procedural kind, uint32_t seed, const int n[3],
                               obs_volume *v, obs_err *err) {
  const int zero[3] = {0, 0, 0};
  return obs_volume_procedural_fill_part(kind, seed, n, zero, n, v, err);
}

int obs_volume_cells_build(const obs_volume *v, int cell, obs_volume_cells *c, obs_err *err) {
  memset(c, 0, sizeof *c);
  if (cell < 1) return obs_err_set(err, OBS_EINVAL, "volume: cell size must be at least 1");
  c->cell = cell;
  size_t count = 1;
  for (int a = 0; a < 3; a++) {
    /* n - 1 intervals between centres, at least one cell (a 1-voxel axis has none). */
    int intervals = v->n[a] > 1 ? v->n[a] - 1 : 1;
    c->n[a] = intervals / cell + (intervals % cell != 0);
    count *= (size_t)c->n[a];
  }
  c->min = malloc(count * sizeof *c->min);
  c->max = malloc(count * sizeof *c->max);
  if (!c->min || !c->max) {
    obs_volume_cells_free(c);
    return obs_err_set(err, OBS_ENOMEM, "volume: out of memory for %zu cells", count);
  }
  for (int ck = 0; ck < c->n[2]; ck++)
    for (int cj = 0; cj < c->n[1]; cj++)
      for (int ci = 0; ci < c->n[0]; ci++) {
        int lo[3] = {ci * cell, cj * cell, ck * cell}, hi[3];
        for (int a = 0; a < 3; a++) {
          hi[a] = lo[a] + cell;
          if (hi[a] > v->n[a] - 1) hi[a] = v->n[a] - 1;
        }
        float mn = INFINITY, mx = -INFINITY;
        for (int k = lo[2]; k <= hi[2]; k++)
          for (int j = lo[1]; j <= hi[1]; j++)
            for (int i = lo[0]; i <= hi[0]; i++) {
              float x = obs_volume_at(v, i, j, k);
              mn = x < mn ? x : mn;
              mx = x > mx ? x : mx;
            }
        size_t at = ((size_t)ck * (size_t)c->n[1] + (size_t)cj) * (size_t)c->n[0] + (size_t)ci;
        c->min[at] = mn;
        c->max[at] = mx;
      }
  return 0;
}

void obs_volume_cells_free(obs_volume_cells *c) {
  if (!c) return;
  free(c->min);
  free(c->max);
  memset(c, 0, sizeof *c);
}

/* The min and max of the 2 x 2 corners of every x position of row (j, k) across y and z: a cell's
 * bounds are then those of two neighbouring columns. */
static void column_bounds(const obs_volume *v, int j, int k, float *mn, float *mx) {
  int j1 = v->n[1] > 1 ? j + 1 : j, k1 = v->n[2] > 1 ? k + 1 : k;
  const float *r[4] = {&v->data[((size_t)k * v->n[1] + j) * v->n[0]],
                       &v->data[((size_t)k * v->n[1] + j1) * v->n[0]],
                       &v->data[((size_t)k1 * v->n[1] + j) * v->n[0]],
                       &v->data[((size_t)k1 * v->n[1] + j1) * v->n[0]]};
  for (int i = 0; i < v->n[0]; i++) {
    float a = r[0][i], b = a;
    for (int q = 1; q < 4; q++) {
      a = r[q][i] < a ? r[q][i] : a;
      b = r[q][i] > b ? r[q][i] : b;
    }
    mn[i] = a;
    mx[i] = b;
  }
}

/* One pass of the separable Chebyshev distance transform along axis a of the brick grid (dims
 * n): d[x] = min over |e| <= OBS_VOLUME_FAR_MAX of max(|e|, d[x + e e_a]) (the first pass starts
 * from 0 at the feature bricks and the cap elsewhere, so it is the 1-D distance). */
static void far_pass(uint8_t *d, uint8_t *line, const int n[3], int a) {
  size_t stride[3] = {1, (size_t)n[0], (size_t)n[0] * n[1]};
  int b = a == 0 ? 1 : 0, c = a == 2 ? 1 : 2;
  for (int y = 0; y < n[c]; y++)
    for (int x = 0; x < n[b]; x++) {
      uint8_t *p = d + (size_t)x * stride[b] + (size_t)y * stride[c];
      for (int i = 0; i < n[a]; i++) line[i] = p[(size_t)i * stride[a]];
      for (int i = 0; i < n[a]; i++) {
        int best = line[i];
        for (int e = 1; e < best && e <= OBS_VOLUME_FAR_MAX; e++) {
          int lo = i - e >= 0 ? line[i - e] : OBS_VOLUME_FAR_MAX;
          int hi = i + e < n[a] ? line[i + e] : OBS_VOLUME_FAR_MAX;
          int m = lo < hi ? lo : hi;
          m = m > e ? m : e;
          best = m < best ? m : best;
        }
        p[(size_t)i * stride[a]] = (uint8_t)best;
      }
    }
}

/* Fills the distances of s->far, whose bytes hold each brick's side. */
static int far_distances(obs_volume_sides *s, obs_err *err) {
  size_t count = (size_t)s->bricks[0] * s->bricks[1] * s->bricks[2];
  int most = s->bricks[0] > s->bricks[1] ? s->bricks[0] : s->bricks[1];
  most = most > s->bricks[2] ? most : s->bricks[2];
  uint8_t *d = malloc(2 * count), *line = malloc((size_t)most);
  if (!d || !line) {
    free(d);
    free(line);
    obs_volume_sides_free(s);
    return obs_err_set(err, OBS_ENOMEM, "volume: out of memory for %zu bricks", count);
  }
  /* One transform per side: the distance to the nearest brick not wholly on it. */
  for (int side = 1; side <= 2; side++) {
    uint8_t *ds = d + (size_t)(side - 1) * count;
    for (size_t b = 0; b < count; b++) ds[b] = s->far[b] == side ? OBS_VOLUME_FAR_MAX : 0;
    for (int a = 0; a < 3; a++) far_pass(ds, line, s->bricks, a);
  }
  for (size_t b = 0; b < count; b++) {
    int side = s->far[b] & 3;
    s->far[b] = (uint8_t)(side ? side | d[(size_t)(side - 1) * count + b] << 2 : 0);
  }
  free(d);
  free(line);
  return 0;
}

int obs_volume_sides_build(const obs_volume *v, float iso, obs_volume_sides *s, obs_err *err) {
  memset(s, 0, sizeof *s);
  size_t count = 512;
  for (int a = 0; a < 3; a++) {
    s->n[a] = v->n[a] > 1 ? v->n[a] - 1 : 1;
    s->bricks[a] = (s->n[a] + 7) / 8;
    count *= (size_t)s->bricks[a];
  }
  s->bits = calloc(count / 4 + 4, 1); /* the slack: 4-byte gathers of the last cells */
  s->far = malloc(count / 512);
  float *mn = malloc((size_t)v->n[0] * sizeof *mn), *mx = malloc((size_t)v->n[0] * sizeof *mx);
  if (s->far) memset(s->far, 3, count / 512);
  if (!s->bits || !s->far || !mn || !mx) {
    free(mn);
    free(mx);
    obs_volume_sides_free(s);
    return obs_err_set(err, OBS_ENOMEM, "volume: out of memory for %zu cell sides", count);
  }
  int up = v->n[0] > 1;
  for (int k = 0; k < s->n[2]; k++)
    for (int j = 0; j < s->n[1]; j++) {
      column_bounds(v, j, k, mn, mx);
      for (int i = 0; i < s->n[0]; i++) {
        float lo = mn[i + up] < mn[i] ? mn[i + up] : mn[i];
        float hi = mx[i + up] > mx[i] ? mx[i + up] : mx[i];
        /* A float lerp chain strays from its corners' hull by a few roundings of their size. */
        float size = fabsf(lo) > fabsf(hi) ? fabsf(lo) : fabsf(hi);
        size = size > fabsf(iso) ? size : fabsf(iso);
        float margin = 64 * FLT_EPSILON * size;
        int side = hi < iso - margin ? OBS_VOLUME_BELOW : lo > iso + margin ? OBS_VOLUME_ABOVE : 0;
        size_t c = obs_volume_side_index(s, i, j, k);
        s->bits[c >> 2] |= (uint8_t)(side << ((c & 3) * 2));
        /* The brick's side so far: every cell's, or none (3 & 1 = 1, 3 & 2 = 2, 1 & 2 = 0). */
        size_t b = c >> 9;
        s->far[b] = (uint8_t)(s->far[b] & side);
      }
    }
  free(mn);
  free(mx);
  return far_distances(s, err);
}

void obs_volume_sides_free(obs_volume_sides *s) {
  if (!s) return;
  free(s->bits);
  free(s->far);
  memset(s, 0, sizeof *s);
}
