/* Proximity fields (proximity.h): the grids' layout per object, the build that
 * voxelises and floods them, the world-to-grid maps and the reconstruction of occlusion. */
#include "proximity.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "parallel.h"
#include "sampling.h"
#include "shapes.h"
#include "simd.h"

#define PI 3.14159265358979323846

/* What one object contributes before its grid is laid out. */
typedef struct prox_src {
  size_t object;
  int sphere;           /* analytic sphere: centre and radius, no mesh */
  double centre[3], radius;
  obs_mesh mesh;        /* object space */
  double box[2][3];     /* object-space box of the surface */
  double scale[3];      /* |transform scale| per axis: object lengths to world */
} prox_src;

static void src_free(prox_src *s, size_t n) {
  for (size_t i = 0; i < n; i++) obs_geometry_mesh_free(&s[i].mesh);
  free(s);
}

static int has_surface(const obs_object *o) {
  const obs_shape_kind *k = obs_shape_kind_of(o->shape.type);
  return k->vertices || k->mesh || k->sphere;
}

/* The world box of object `o` in frame 0, from the points its shape kind declares. */
static void world_box(const obs_object *o, double w[2][3]) {
  memset(w, 0, sizeof(double[2][3]));
  double pts[8][3], r;
  int n = obs_geometry_object_points(o, 0, NULL, pts, &r);
  for (int c = 0; c < n; c++)
    for (int i = 0; i < 3; i++) {
      if (c == 0 || pts[c][i] - r < w[0][i]) w[0][i] = pts[c][i] - r;
      if (c == 0 || pts[c][i] + r > w[1][i]) w[1][i] = pts[c][i] + r;
    }
}

static double diag(const double b[2][3]) {
  double d[3] = {b[1][0] - b[0][0], b[1][1] - b[0][1], b[1][2] - b[0][2]};
  return sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}

static int src_read(const obs_scene *sc, size_t oi, prox_src *s, obs_err *err) {
  const obs_object *o = &sc->objects[oi];
  s->object = oi;
  s->scale[0] = fabs(o->transform.scale.x);
  s->scale[1] = fabs(o->transform.scale.y);
  s->scale[2] = fabs(o->transform.scale.z);
  if (obs_shape_is_analytic(&o->shape)) {
    s->sphere = 1;
    obs_shape_kind_of(o->shape.type)->sphere(&o->shape, s->centre, &s->radius);
    for (int k = 0; k < 3; k++) {
      s->box[0][k] = s->centre[k] - s->radius;
      s->box[1][k] = s->centre[k] + s->radius;
    }
  } else {
    int rc = obs_geometry_object_mesh(sc, oi, &s->mesh, err);
    if (rc) return rc;
    obs_geometry_mesh_bounds(&s->mesh, s->box);
  }
  return 0;
}

double obs_prox_radius(const obs_scene *sc, const obs_prox_layout *lay) {
  double largest = 0, ubox[2][3] = {{0}}, w[2][3] = {{0}}, extent[3] = {0, 0, 0};
  int first = 1;
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (!has_surface(&sc->objects[i])) continue;
    world_box(&sc->objects[i], w);
    largest = fmax(largest, diag(w));
    for (int k = 0; k < 3; k++) {
      extent[k] = fmax(extent[k], w[1][k] - w[0][k]);
      if (first || w[0][k] < ubox[0][k]) ubox[0][k] = w[0][k];
      if (first || w[1][k] > ubox[1][k]) ubox[1][k] = w[1][k];
    }
    first = 0;
  }
  double ref = largest;
  if (lay->box == OBS_PROX_BOX_UNION && !first) ref = diag(ubox);
  if (lay->box == OBS_PROX_BOX_MAXIMAL)
    ref = sqrt(extent[0] * extent[0] + extent[1] * extent[1] + extent[2] * extent[2]);
  return lay->fraction * ref;
}

/* The power of two nearest to x (in the log), clamped to [lo, hi]. */
static int pow2_near(double x, int lo, int hi) {
  double e = x > 0 ? round(log2(x)) : -1e9;
  double v = e < 0 ? 1 : e > 30 ? 1e9 : ldexp(1.0, (int)e);
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return (int)v;
}

/* Lays out s's grid: the box grown by r_p (world) in object units per axis, voxels per axis the
 * nearest power of two to res x (the side / the longest side of every grid). */
static void layout_grid(const prox_src *s, double rp, double longest, const obs_prox_layout *lay,
                        obs_prox_field *f) {
  int lo = lay->min_res < lay->res ? lay->min_res : lay->res;
  double d2 = 0;
  f->count = 1;
  for (int k = 0; k < 3; k++) {
    double grow = s->scale[k] > 0 ? rp / s->scale[k] : 0;
    double side = (s->box[1][k] - s->box[0][k]) + 2 * grow;
    if (!(side > 0)) side = s->scale[k] > 0 ? longest / s->scale[k] : 1; /* a flat box, r_p 0 */
    if (!(side > 0) || !isfinite(side)) side = 1;
    double centre = 0.5 * (s->box[0][k] + s->box[1][k]);
    double wside = side * s->scale[k];
    f->dims[k] = pow2_near(longest > 0 ? lay->res * wside / longest : 1, lo, lay->res);
    f->lo[k] = centre - 0.5 * side;
    f->voxel[k] = side / f->dims[k];
    double wv = f->voxel[k] * s->scale[k];
    d2 += wv * wv;
    f->count *= (size_t)f->dims[k];
  }
  double dv = sqrt(d2);
  double it = dv > 0 ? ceil(rp / dv) : 0;
  f->iterations = it > 1e6 ? 1000000 : (int)it;
  f->object = s->object;
}

void obs_prox_fields_free(obs_prox_fields *fs) {
  for (size_t i = 0; i < fs->n; i++) {
    free(fs->f[i].occupied);
    free(fs->f[i].value);
  }
  free(fs->f);
  memset(fs, 0, sizeof *fs);
}

void obs_prox_fields_built(const obs_prox_fields *fs, json_t *built) {
  for (size_t i = 0; i < fs->n; i++) {
    const obs_prox_field *f = &fs->f[i];
    json_array_append_new(
        built, json_pack("{s:s, s:I, s:[i,i,i], s:I, s:i, s:I}", "name", "proximity_field",
                         "object", (json_int_t)f->object, "dims", f->dims[0], f->dims[1],
                         f->dims[2], "occupied", (json_int_t)f->occupied_count, "iterations",
                         f->iterations, "bytes", (json_int_t)(OBS_PROX_VOXEL_BYTES * f->count)));
  }
}

/* Every field together must stay within this many bytes (values, occupancy and the CPU walk's
 * read copy, plus the flood's two working copies of the largest). */
#define PROX_MAX_BYTES ((double)(6ull << 30))

int obs_prox_build(const obs_scene *sc, const obs_prox_layout *lay, int threads,
                   obs_prox_flood_fn flood, void *flood_user, obs_prox_fields *out,
                   obs_err *err) {
  memset(out, 0, sizeof *out);
  size_t n = 0;
  for (size_t i = 0; i < sc->nobjects; i++) n += has_surface(&sc->objects[i]);
  prox_src *src = calloc(n ? n : 1, sizeof *src);
  out->f = calloc(n ? n : 1, sizeof *out->f);
  if (!src || !out->f) {
    free(src);
    obs_prox_fields_free(out);
    return obs_err_set(err, OBS_ENOMEM, "%s: proximity fields: out of memory", sc->name);
  }
  double t0 = obs_now_ms();
  int rc = 0;
  size_t m = 0;
  for (size_t i = 0; i < sc->nobjects && !rc; i++)
    if (has_surface(&sc->objects[i])) rc = src_read(sc, i, &src[m++], err);
  out->rp = obs_prox_radius(sc, lay);
  double longest = 0;
  for (size_t i = 0; i < m; i++)
    for (int k = 0; k < 3; k++)
      longest =
          fmax(longest, (src[i].box[1][k] - src[i].box[0][k]) * src[i].scale[k] + 2 * out->rp);
  double bytes = 0, biggest = 0;
  for (size_t i = 0; i < m && !rc; i++) {
    layout_grid(&src[i], out->rp, longest, lay, &out->f[i]);
    bytes += (double)OBS_PROX_VOXEL_BYTES * (double)out->f[i].count +
             sizeof(float) * (double)obs_prox_corners_count(&out->f[i]);
    biggest = fmax(biggest, 8.0 * (double)out->f[i].count);
  }
  if (!rc && bytes + biggest > PROX_MAX_BYTES)
    rc = obs_err_set(err, OBS_EINVAL, "%s: /technique/params/volume_res: the proximity fields "
                     "would take %.1f GiB, more than %.0f GiB; lower volume_res",
                     sc->name, (bytes + biggest) / (1 << 30), PROX_MAX_BYTES / (1 << 30));
  for (size_t i = 0; i < m && !rc; i++) {
    obs_prox_field *f = &out->f[i];
    f->occupied = calloc(f->count, 1);
    f->value = malloc(f->count * sizeof *f->value);
    out->n++;
    if (!f->occupied || !f->value) {
      rc = obs_err_set(err, OBS_ENOMEM, "%s: /objects/%zu: out of memory for its proximity field "
                       "(%zu voxels)", sc->name, f->object, f->count);
      break;
    }
    if (src[i].sphere) obs_prox_voxelise_sphere(f, src[i].centre, src[i].radius, threads);
    else obs_prox_voxelise_mesh(f, &src[i].mesh, threads);
    for (size_t v = 0; v < f->count; v++) {
      f->value[v] = f->occupied[v] ? 1.0f : 0.0f;
      f->occupied_count += f->occupied[v];
    }
    out->bytes += OBS_PROX_VOXEL_BYTES * f->count;
  }
  src_free(src, n);
  double t1 = obs_now_ms();
  out->voxelise_ms = t1 - t0;
  for (size_t i = 0; i < out->n && !rc; i++)
    rc = (flood ? flood : obs_prox_flood_cpu)(flood_user, &out->f[i], threads, err);
  out->flood_ms = obs_now_ms() - t1;
  if (rc) obs_prox_fields_free(out);
  return rc;
}

void obs_prox_world_to_grid(const obs_prox_field *f, const obs_object *o, int frame,
                            double g[3][4]) {
  double m[3][4];
  obs_geometry_transform_matrix(obs_object_transform_at(o, frame), m);
  /* A singular transform maps every point to the grid's far outside, where nothing is read. */
  double lin[3][3], inv[3][3];
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) lin[i][j] = m[i][j];
  if (!obs_geometry_invert3(lin, inv)) {
    memset(g, 0, sizeof(double[3][4]));
    for (int i = 0; i < 3; i++) g[i][3] = -1e30;
    return;
  }
  for (int i = 0; i < 3; i++) {
    double t = 0;
    for (int j = 0; j < 3; j++) t -= inv[i][j] * m[j][3];
    /* object = inv (w) + t; grid = (object - lo) / voxel */
    for (int j = 0; j < 3; j++) g[i][j] = inv[i][j] / f->voxel[i];
    g[i][3] = (t - f->lo[i]) / f->voxel[i];
  }
}

/* The trilinear read: the one definition, shared by the scalar and the eight-lane paths (which
 * take the same float operations in the same order, lane by lane). */
float obs_prox_sample(const obs_prox_field *f, const float g[3]) {
  int i0[3], i1[3];
  float w[3];
  for (int k = 0; k < 3; k++) {
    float u = g[k] - 0.5f, hi = (float)(f->dims[k] - 1);
    if (!(u > 0.0f)) u = 0.0f;
    if (u > hi) u = hi;
    int i = (int)u;
    i0[k] = i;
    i1[k] = i + 1 < f->dims[k] ? i + 1 : i;
    w[k] = u - (float)i;
  }
  size_t sx = (size_t)f->dims[0], sxy = sx * (size_t)f->dims[1];
  const float *v = f->value;
  float c[2][2];
  for (int dz = 0; dz < 2; dz++)
    for (int dy = 0; dy < 2; dy++) {
      size_t r = (size_t)(dz ? i1[2] : i0[2]) * sxy + (size_t)(dy ? i1[1] : i0[1]) * sx;
      float a = v[r + (size_t)i0[0]], b = v[r + (size_t)i1[0]];
      c[dz][dy] = a + (b - a) * w[0];
    }
  float y0 = c[0][0] + (c[0][1] - c[0][0]) * w[1];
  float y1 = c[1][0] + (c[1][1] - c[1][0]) * w[1];
  return y0 + (y1 - y0) * w[2];
}

void obs_prox_recon_init(obs_prox_recon *r, int steps, int mode, float stop_value,
                         float scale_before, float scale_after, uint32_t seed) {
  memset(r, 0, sizeof *r);
  if (steps > OBS_PROX_MAX_STEPS) steps = OBS_PROX_MAX_STEPS;
  r->steps = steps;
  r->mode = mode;
  r->stop_value = stop_value;
  r->scale_before = scale_before;
  r->scale_after = scale_after;
  r->isa = obs_simd_isa();
  /* The thesis's code advances one step before its loop and again at the top of each: step i
   * samples at p + (i + 2) step. The corrected walk samples at p + i step. */
  float base = mode == OBS_PROX_THESIS_CODE ? 2.0f : 0.0f;
  int at = 0;
  for (int i = 0; i < steps; i++) {
    r->first[i] = at;
    int m = i / 2;
    for (int k = 0; k < m; k++, at++) {
      uint32_t h = obs_hash_combine(obs_hash_combine(seed, (uint32_t)i), (uint32_t)k);
      double u = obs_u32_to_unit(obs_hash_combine(h, 0));
      double v = obs_u32_to_unit(obs_hash_combine(h, 1));
      double phi = 2 * PI * (k + u) / m, rad = sqrt(v);
      r->disc[at][0] = (float)(rad * cos(phi));
      r->disc[at][1] = (float)(rad * sin(phi));
      /* The disc's radius is R i / N: i steps. */
      r->along[at] = base + (float)i;
      r->across_t[at] = r->disc[at][0] * (float)i;
      r->across_b[at] = r->disc[at][1] * (float)i;
    }
  }
  r->first[steps] = at;
}

/* The walk's points read into val[] (+0 where a point lies outside the field's box, and
 * inside[] 0 there when counted). */
typedef struct prox_walk {
  const obs_prox_field *f;
  const float *corners;
  const obs_prox_recon *r;
  float gp[3], gs[3], gt[3], gb[3];
#if OBS_SIMD_AVX2
  /* The eight-lane walk's per-point constants, once per walk: the grid's sides, its last voxel
   * centres' cells (dims - 1) and the corner copy's strides, as lanes. */
  __m256 dim[3], top[3];
  __m256i stride[3];
#endif
  float val[OBS_PROX_DISC_POINTS + 8];
  unsigned char inside[OBS_PROX_DISC_POINTS + 8];
} prox_walk;

static void walk_point(prox_walk *w, int k) {
  const obs_prox_field *f = w->f;
  float q[3];
  for (int c = 0; c < 3; c++)
    q[c] = ((w->gp[c] + w->r->along[k] * w->gs[c]) + w->r->across_t[k] * w->gt[c]) +
           w->r->across_b[k] * w->gb[c];
  int in = obs_prox_inside(f, q);
  w->inside[k] = (unsigned char)in;
  w->val[k] = in ? obs_prox_sample(f, q) : 0.0f;
}

size_t obs_prox_corners_count(const obs_prox_field *f) {
  return 2 * (size_t)(f->dims[0] + 1) * (size_t)f->dims[1] * (size_t)(f->dims[2] + 1);
}

typedef struct corners_job {
  const obs_prox_field *f;
  float *c;
} corners_job;

static int corners_slab(void *user, int thread, int z0, int y0, int z1, int y1) {
  (void)thread, (void)y0, (void)y1;
  const corners_job *j = user;
  const int dx = j->f->dims[0], dy = j->f->dims[1], dz = j->f->dims[2];
  const size_t row = 2 * (size_t)(dx + 1);
  for (int z = z0; z < z1; z++) {
    const float *slice = j->f->value + (size_t)(z < dz ? z : dz - 1) * (size_t)dy * (size_t)dx;
    for (int y = 0; y < dy; y++) {
      const float *v0 = slice + (size_t)y * dx, *v1 = slice + (size_t)(y + 1 < dy ? y + 1 : y) * dx;
      float *c = j->c + ((size_t)z * (size_t)dy + (size_t)y) * row;
      for (int x = 0; x <= dx; x++) {
        int xs = x < dx ? x : dx - 1;
        c[2 * x] = v0[xs];
        c[2 * x + 1] = v1[xs];
      }
    }
  }
  return 0;
}

float *obs_prox_corners(const obs_prox_field *f, const obs_prox_recon *r, int threads) {
  if (r->isa < OBS_ISA_AVX2) return NULL;
  corners_job j = {f, malloc(obs_prox_corners_count(f) * sizeof(float))};
  if (j.c) obs_parallel_tiles(f->dims[2] + 1, 1, threads, corners_slab, &j, NULL, NULL, NULL);
  return j.c;
}

#if OBS_SIMD_AVX2
/* Eight points k0..k0+7 at once: walk_point's operations lane by lane, each lane's corners in
 * two 16-byte reads of w->corners (obs_prox_corners). */
OBS_AVX2_INLINE void walk_points8(prox_walk *w, int k0) {
  const obs_prox_recon *r = w->r;
  __m256 al = _mm256_loadu_ps(r->along + k0), at = _mm256_loadu_ps(r->across_t + k0),
         ab = _mm256_loadu_ps(r->across_b + k0);
  __m256 in = _mm256_castsi256_ps(_mm256_set1_epi32(-1)), wt[3];
  __m256i base = _mm256_setzero_si256();
  for (int c = 0; c < 3; c++) {
    __m256 q = _mm256_add_ps(
        _mm256_add_ps(_mm256_add_ps(_mm256_set1_ps(w->gp[c]),
                                    _mm256_mul_ps(al, _mm256_set1_ps(w->gs[c]))),
                      _mm256_mul_ps(at, _mm256_set1_ps(w->gt[c]))),
        _mm256_mul_ps(ab, _mm256_set1_ps(w->gb[c])));
    in = _mm256_and_ps(in, _mm256_and_ps(_mm256_cmp_ps(q, _mm256_setzero_ps(), _CMP_GE_OQ),
                                         _mm256_cmp_ps(q, w->dim[c], _CMP_LE_OQ)));
    __m256 u = _mm256_sub_ps(q, _mm256_set1_ps(0.5f));
    u = _mm256_max_ps(u, _mm256_setzero_ps()); /* NaN and below 0: 0, as !(u > 0) */
    u = _mm256_min_ps(u, w->top[c]);
    __m256i i = _mm256_cvttps_epi32(u);
    wt[c] = _mm256_sub_ps(u, _mm256_cvtepi32_ps(i));
    base = _mm256_add_epi32(base, _mm256_mullo_epi32(i, w->stride[c]));
  }
  const size_t slice = (size_t)_mm256_cvtsi256_si32(w->stride[2]);
  int ix[8];
  _mm256_storeu_si256((__m256i *)ix, base);
  __m256 cz[2];
  for (int dz = 0; dz < 2; dz++) {
    const float *v = w->corners + (dz ? slice : 0);
    __m256 q[4];
    for (int l = 0; l < 4; l++)
      q[l] = _mm256_setr_m128(_mm_loadu_ps(v + ix[l]), _mm_loadu_ps(v + ix[l + 4]));
    /* q[l] = a(y0) a(y1) b(y0) b(y1) of lanes l | l + 4; transposed to one vector each. */
    __m256 t0 = _mm256_unpacklo_ps(q[0], q[1]), t1 = _mm256_unpackhi_ps(q[0], q[1]);
    __m256 t2 = _mm256_unpacklo_ps(q[2], q[3]), t3 = _mm256_unpackhi_ps(q[2], q[3]);
    __m256 a0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
    __m256 a1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
    __m256 b0 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
    __m256 b1 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
    __m256 c0 = _mm256_add_ps(a0, _mm256_mul_ps(_mm256_sub_ps(b0, a0), wt[0]));
    __m256 c1 = _mm256_add_ps(a1, _mm256_mul_ps(_mm256_sub_ps(b1, a1), wt[0]));
    cz[dz] = _mm256_add_ps(c0, _mm256_mul_ps(_mm256_sub_ps(c1, c0), wt[1]));
  }
  __m256 v = _mm256_add_ps(cz[0], _mm256_mul_ps(_mm256_sub_ps(cz[1], cz[0]), wt[2]));
  _mm256_storeu_ps(w->val + k0, _mm256_and_ps(v, in));
  if (r->mode == OBS_PROX_THESIS_CODE) return; /* inside[] only for the corrected average */
  /* The lane masks (all ones or zero) narrowed to bytes 1 or 0. */
  __m128i m32 = _mm_packs_epi32(_mm256_castsi256_si128(_mm256_castps_si256(in)),
                                _mm256_extracti128_si256(_mm256_castps_si256(in), 1));
  __m128i m8 = _mm_and_si128(_mm_packs_epi16(m32, m32), _mm_set1_epi8(1));
  _mm_storel_epi64((__m128i_u *)(void *)(w->inside + k0), m8);
}
#endif

typedef void (*walk_read_fn)(prox_walk *w, int *done, int upto);

/* Reads the points up to `upto` (exclusive) that are not read yet. */
static inline __attribute__((always_inline)) void walk_read(prox_walk *w, int *done, int upto) {
  for (; *done < upto; ++*done) walk_point(w, *done);
}

#if OBS_SIMD_AVX2
OBS_AVX2_INLINE void walk_read8(prox_walk *w, int *done, int upto) {
  for (; *done < upto; *done += 8) walk_points8(w, *done);
}
#endif

/* The walk's steps over points read by `read` (inlined into each instruction-set level). */
static inline __attribute__((always_inline)) float walk_steps(prox_walk *w, walk_read_fn read) {
  const obs_prox_recon *r = w->r;
  const int n = r->steps, code = r->mode == OBS_PROX_THESIS_CODE;
  float ao = 0.0f, prev = 0.0f;
  int done = r->first[0];
  for (int i = 0; i < n; i++) {
    read(w, &done, r->first[i + 1]);
    float sum = 0.0f, value;
    /* Points outside the box read +0: the thesis's sum skips them without a test. */
    if (code) {
      for (int k = r->first[i]; k < r->first[i + 1]; k++) sum += w->val[k];
      value = sum;
    } else {
      int count = 0;
      for (int k = r->first[i]; k < r->first[i + 1]; k++)
        if (w->inside[k]) sum += w->val[k], count++;
      value = count ? sum / (float)count : 0.0f;
    }
    /* A step below the last kept one moves away from what occludes: dropped, prev kept.
     * Selected rather than branched on: which steps drop is the data's, not a pattern. */
    int keep = !(value < prev);
    /* The listing's (1 - i / N) is integer division: 1 for every i < N. */
    float weight = code ? 1.0f : 1.0f - (float)i / (float)n;
    float more = ao + value * weight;
    ao = keep ? more : ao;
    if (keep && value > r->stop_value) break;
    prev = keep ? value : prev;
  }
  ao *= r->scale_before;
  ao /= (float)n;
  if (!(ao > 0.0f)) ao = 0.0f;
  if (ao > 1.0f) ao = 1.0f;
  return ao * r->scale_after;
}

#if OBS_SIMD_AVX2
OBS_AVX2_FN static float walk_steps8(prox_walk *w) {
  const int *d = w->f->dims;
  /* int indices: the copy holds at most 2 x 513 x 512 x 513 < 2^31 floats (volume_res <= 512). */
  const int stride[3] = {2, 2 * (d[0] + 1), 2 * (d[0] + 1) * d[1]};
  for (int c = 0; c < 3; c++) {
    w->dim[c] = _mm256_set1_ps((float)d[c]);
    w->top[c] = _mm256_set1_ps((float)(d[c] - 1));
    w->stride[c] = _mm256_set1_epi32(stride[c]);
  }
  return walk_steps(w, walk_read8);
}
#endif

float obs_prox_occlusion(const obs_prox_field *f, const float *corners, const obs_prox_recon *r,
                         const float gp[3], const float gs[3], const float gt[3],
                         const float gb[3]) {
  prox_walk w;
  w.f = f;
  w.r = r;
  w.corners = corners;
  for (int c = 0; c < 3; c++) w.gp[c] = gp[c], w.gs[c] = gs[c], w.gt[c] = gt[c], w.gb[c] = gb[c];
#if OBS_SIMD_AVX2
  if (r->isa >= OBS_ISA_AVX2 && corners) return walk_steps8(&w);
#endif
  return walk_steps(&w, walk_read);
}
