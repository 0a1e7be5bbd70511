/* Environment cube maps: construction from lat-long images, face images and the procedural sky,
 * bilinear lookups, exact texel solid angles and the nine-coefficient diffuse environment
 * (environment.h). */
#include "environment.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/image.h"

#define PI 3.14159265358979323846

static const char *const face_names[OBS_ENV_FACE_COUNT] = {"+X", "-X", "+Y", "-Y", "+Z", "-Z"};
static const char channel_names[3] = {'R', 'G', 'B'};

/* ---- geometry ---------------------------------------------------------------------------- */

/* Scaling by the largest component first keeps huge finite vectors from overflowing to inf. */
static int normalise3(const double v[3], double out[3]) {
  double m = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
  if (!(m > 0) || !isfinite(m) || !isfinite(v[0] + v[1] + v[2])) return 0;
  double x = v[0] / m, y = v[1] / m, z = v[2] / m, l = sqrt(x * x + y * y + z * z);
  out[0] = x / l;
  out[1] = y / l;
  out[2] = z / l;
  return 1;
}

void obs_env_face_dir(int face, double s, double t, double dir[3]) {
  double sc = 2 * s - 1, tc = 2 * t - 1, d[3];
  switch (face) {
    case OBS_ENV_PX:
      d[0] = 1, d[1] = -tc, d[2] = -sc;
      break;
    case OBS_ENV_NX:
      d[0] = -1, d[1] = -tc, d[2] = sc;
      break;
    case OBS_ENV_PY:
      d[0] = sc, d[1] = 1, d[2] = tc;
      break;
    case OBS_ENV_NY:
      d[0] = sc, d[1] = -1, d[2] = -tc;
      break;
    case OBS_ENV_PZ:
      d[0] = sc, d[1] = -tc, d[2] = 1;
      break;
    default:
      d[0] = -sc, d[1] = -tc, d[2] = -1;
      break;
  }
  normalise3(d, dir);
}

static double clampd(double x, double lo, double hi) { return x < lo ? lo : x > hi ? hi : x; }

int obs_env_face_coords(const double dir[3], double *s, double *t) {
  double ax = fabs(dir[0]), ay = fabs(dir[1]), az = fabs(dir[2]);
  if (!isfinite(ax) || !isfinite(ay) || !isfinite(az) || (ax == 0 && ay == 0 && az == 0)) return -1;
  int f;
  double sc, tc, ma;
  if (ax >= ay && ax >= az) {
    f = dir[0] >= 0 ? OBS_ENV_PX : OBS_ENV_NX;
    ma = ax, sc = f == OBS_ENV_PX ? -dir[2] : dir[2], tc = -dir[1];
  } else if (ay >= az) {
    f = dir[1] >= 0 ? OBS_ENV_PY : OBS_ENV_NY;
    ma = ay, sc = dir[0], tc = f == OBS_ENV_PY ? dir[2] : -dir[2];
  } else {
    f = dir[2] >= 0 ? OBS_ENV_PZ : OBS_ENV_NZ;
    ma = az, sc = f == OBS_ENV_PZ ? dir[0] : -dir[0], tc = -dir[1];
  }
  /* |sc|, |tc| <= ma, so only rounding can leave [0, 1]. */
  *s = clampd(0.5 * (sc / ma + 1), 0, 1);
  *t = clampd(0.5 * (tc / ma + 1), 0, 1);
  return f;
}

static double area_element(double x, double y) { return atan2(x * y, sqrt(x * x + y * y + 1)); }

double obs_env_texel_solid_angle(int res, int i, int j) {
  if (res < 1 || i < 0 || j < 0 || i >= res || j >= res) return 0;
  double x0 = 2.0 * i / res - 1, x1 = 2.0 * (i + 1) / res - 1;
  double y0 = 2.0 * j / res - 1, y1 = 2.0 * (j + 1) / res - 1;
  return area_element(x0, y0) - area_element(x0, y1) - area_element(x1, y0) + area_element(x1, y1);
}

/* Calls fn for every texel with its centre direction and exact solid angle. The solid angle does
 * not depend on the face, so it is computed once for all six. */
typedef void (*env_texel_fn)(void *user, const double d[3], double omega, const float *rgb);
static void env_foreach(const obs_env *e, env_texel_fn fn, void *user) {
  int r = e->res;
  for (int j = 0; j < r; j++)
    for (int i = 0; i < r; i++) {
      double omega = obs_env_texel_solid_angle(r, i, j), d[3];
      for (int f = 0; f < OBS_ENV_FACE_COUNT; f++) {
        obs_env_face_dir(f, (i + 0.5) / r, (j + 0.5) / r, d);
        fn(user, d, omega, obs_env_texel(e, f, i, j));
      }
    }
}

/* ---- construction ------------------------------------------------------------------------ */

void obs_env_free(obs_env *e) {
  if (!e) return;
  free(e->data);
  memset(e, 0, sizeof *e);
}

static int env_alloc(obs_env *e, int res, const char *what, obs_err *err) {
  memset(e, 0, sizeof *e);
  if (res < 1 || res > OBS_ENV_MAX_RES)
    return obs_err_set(err, OBS_EINVAL, "%s: cube map resolution %d is outside [1, %d]", what, res,
                       OBS_ENV_MAX_RES);
  size_t n = (size_t)OBS_ENV_FACE_COUNT * (size_t)res * (size_t)res * 3;
  if (!(e->data = calloc(n, sizeof *e->data)))
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for a %d x %d cube map", what, res, res);
  e->res = res;
  return 0;
}

static void mean_add(void *user, const double d[3], double omega, const float *rgb) {
  (void)d;
  double *sum = user;
  for (int c = 0; c < 3; c++) sum[c] += rgb[c] * omega;
}

/* The solid-angle sum is 4 pi only up to rounding; dividing by the actual sum keeps a constant
 * environment's mean exactly its value. */
static void env_finish(obs_env *e) {
  double sum[3] = {0, 0, 0}, total = 0;
  env_foreach(e, mean_add, sum);
  for (int j = 0; j < e->res; j++)
    for (int i = 0; i < e->res; i++) total += obs_env_texel_solid_angle(e->res, i, j);
  total *= OBS_ENV_FACE_COUNT;
  for (int c = 0; c < 3; c++) e->mean[c] = sum[c] / total;
}

/* The index of the first value that is not finite and non-negative, or -1. */
static long long first_bad(const float *v, size_t n) {
  for (size_t k = 0; k < n; k++)
    if (!(v[k] >= 0) || !isfinite(v[k])) return (long long)k;
  return -1;
}

/* Fills every texel with the mean of n x n samples of fn at evenly spaced points of the texel,
 * each weighted by the solid angle it stands for (the Jacobian 1 / (1 + x^2 + y^2)^(3/2) of the
 * face at (x, y) = (2 s - 1, 2 t - 1)): the texel then holds its solid-angle mean, so its value
 * times its solid angle is the power it covers. Equal weights would err by up to ~20% for a small
 * source near a face corner at low resolution. */
typedef void (*env_sampler)(const void *user, const double d[3], double rgb[3]);
static void env_fill(obs_env *e, int n, env_sampler fn, const void *user) {
  int r = e->res;
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++)
    for (int j = 0; j < r; j++)
      for (int i = 0; i < r; i++) {
        double acc[3] = {0, 0, 0}, wsum = 0, d[3], v[3];
        for (int b = 0; b < n; b++)
          for (int a = 0; a < n; a++) {
            double s = (i + (a + 0.5) / n) / r, t = (j + (b + 0.5) / n) / r;
            double x = 2 * s - 1, y = 2 * t - 1, q = 1 + x * x + y * y, w = 1 / (q * sqrt(q));
            obs_env_face_dir(f, s, t, d);
            fn(user, d, v);
            for (int c = 0; c < 3; c++) acc[c] += w * v[c];
            wsum += w;
          }
        float *px = obs_env_texel(e, f, i, j);
        for (int c = 0; c < 3; c++) px[c] = (float)(acc[c] / wsum);
      }
  env_finish(e);
}

/* Supersamples per texel side so that samples lie no more than `spacing` radians apart (a texel
 * spans at most 2 / res radians, at the face centre), at least 2, and no more than
 * OBS_ENV_MAX_SAMPLES / res: a face never takes more than OBS_ENV_MAX_SAMPLES^2 samples. */
static int samples_for(int res, double spacing) {
  double n = ceil(2.0 / res / spacing), cap = OBS_ENV_MAX_SAMPLES / res;
  if (cap < 2) cap = 2;
  return !(n >= 2) ? 2 : n > cap ? (int)cap : (int)n;
}

int obs_env_constant(obs_env *e, const double rgb[3], obs_err *err) {
  for (int c = 0; c < 3; c++)
    if (!(rgb[c] >= 0) || !isfinite(rgb[c])) {
      memset(e, 0, sizeof *e);
      return obs_err_set(err, OBS_EINVAL,
                         "constant environment: rgb[%d] is %g (radiance must be finite and "
                         "non-negative)",
                         c, rgb[c]);
    }
  int rc = env_alloc(e, 1, "constant environment", err);
  if (rc) return rc;
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++)
    for (int c = 0; c < 3; c++) obs_env_texel(e, f, 0, 0)[c] = (float)rgb[c];
  env_finish(e);
  return 0;
}

/* ---- lat-long ---------------------------------------------------------------------------- */

typedef struct latlong {
  const float *rgb;
  int w, h;
} latlong;

static void latlong_sample(const void *user, const double d[3], double out[3]) {
  const latlong *ll = user;
  double u = 0.5 + atan2(d[0], -d[2]) / (2 * PI), v = acos(clampd(d[1], -1, 1)) / PI;
  double fx = u * ll->w - 0.5, fy = clampd(v * ll->h - 0.5, 0, ll->h - 1);
  double x0f = floor(fx), wx = fx - x0f, wy = fy - floor(fy);
  int x0 = (int)x0f % ll->w, y0 = (int)fy;
  if (x0 < 0) x0 += ll->w;
  int x1 = x0 + 1 == ll->w ? 0 : x0 + 1, y1 = y0 + 1 < ll->h ? y0 + 1 : y0;
  const float *p00 = ll->rgb + ((size_t)y0 * ll->w + x0) * 3;
  const float *p10 = ll->rgb + ((size_t)y0 * ll->w + x1) * 3;
  const float *p01 = ll->rgb + ((size_t)y1 * ll->w + x0) * 3;
  const float *p11 = ll->rgb + ((size_t)y1 * ll->w + x1) * 3;
  for (int c = 0; c < 3; c++) {
    double top = p00[c] + wx * ((double)p10[c] - p00[c]);
    double bot = p01[c] + wx * ((double)p11[c] - p01[c]);
    out[c] = top + wy * (bot - top);
  }
}

static int latlong_build(obs_env *e, const float *rgb, int w, int h, int res, const char *what,
                         obs_err *err) {
  memset(e, 0, sizeof *e);
  if (!rgb) return obs_err_set(err, OBS_EINVAL, "%s: no image", what);
  if (w < 2 || h < 1)
    return obs_err_set(err, OBS_EINVAL,
                       "%s: lat-long image of %d x %d pixels (needs width >= 2 "
                       "and height >= 1)",
                       what, w, h);
  long long bad = first_bad(rgb, (size_t)w * (size_t)h * 3);
  if (bad >= 0) {
    long long p = bad / 3;
    return obs_err_set(err, OBS_EINVAL,
                       "%s: pixel (%lld, %lld) channel %c is %g (radiance must be finite and "
                       "non-negative)",
                       what, p % w, p / w, channel_names[bad % 3], rgb[bad]);
  }
  int rc = env_alloc(e, res, what, err);
  if (rc) return rc;
  latlong ll = {rgb, w, h};
  /* Half a pixel apart: the bilinear tents then sum to nearly one wherever the samples fall, so a
   * source of a few pixels keeps its power (coarser sampling lost 1.3% of a 3 x 3 pixel spot). */
  env_fill(e, samples_for(res, 0.5 * fmin(2 * PI / w, PI / h)), latlong_sample, &ll);
  return 0;
}

int obs_env_from_latlong(obs_env *e, const float *rgb, int w, int h, int res, obs_err *err) {
  return latlong_build(e, rgb, w, h, res, "lat-long environment", err);
}

/* Reads the R, G, B planes of an EXR into one interleaved array the caller frees. */
static int read_rgb_exr(const char *path, float **rgb, int *w, int *h, obs_err *err) {
  *rgb = NULL;
  if (!path) return obs_err_set(err, OBS_EINVAL, "environment: no file name");
  obs_image img;
  int rc = obs_image_read_exr(&img, path, err);
  if (rc) return rc;
  const float *plane[3];
  for (int c = 0; c < 3; c++) {
    char name[2] = {channel_names[c], 0};
    if (!(plane[c] = obs_image_channel(&img, name))) {
      obs_image_free(&img);
      return obs_err_set(err, OBS_ENOTFOUND,
                         "%s: EXR has no channel \"%s\" (an environment needs R, G and B)", path,
                         name);
    }
  }
  size_t n = (size_t)img.width * (size_t)img.height;
  if (!(*rgb = malloc(n * 3 * sizeof **rgb))) {
    obs_image_free(&img);
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory for %d x %d pixels", path, img.width,
                       img.height);
  }
  for (size_t k = 0; k < n; k++)
    for (int c = 0; c < 3; c++) (*rgb)[k * 3 + c] = plane[c][k];
  *w = img.width;
  *h = img.height;
  obs_image_free(&img);
  return 0;
}

int obs_env_from_latlong_file(obs_env *e, const char *path, int res, obs_err *err) {
  memset(e, 0, sizeof *e);
  float *rgb;
  int w, h, rc = read_rgb_exr(path, &rgb, &w, &h, err);
  if (rc) return rc;
  rc = latlong_build(e, rgb, w, h, res, path, err);
  free(rgb);
  return rc;
}

/* ---- faces ------------------------------------------------------------------------------- */

/* names[f] names face f's source in messages (a file), or NULL for faces given in memory. */
static int faces_build(obs_env *e, const float *const faces[6], int res, const char *const names[6],
                       obs_err *err) {
  memset(e, 0, sizeof *e);
  const char *what = "environment faces";
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++) {
    const char *src = names ? names[f] : what;
    if (!faces || !faces[f])
      return obs_err_set(err, OBS_EINVAL, "%s: face %s is missing", src, face_names[f]);
    if (res < 1 || res > OBS_ENV_MAX_RES) continue; /* env_alloc says so */
    long long bad = first_bad(faces[f], (size_t)res * (size_t)res * 3);
    if (bad >= 0) {
      long long p = bad / 3;
      return obs_err_set(err, OBS_EINVAL,
                         "%s: face %s texel (%lld, %lld) channel %c is %g (radiance must be "
                         "finite and non-negative)",
                         src, face_names[f], p % res, p / res, channel_names[bad % 3],
                         faces[f][bad]);
    }
  }
  int rc = env_alloc(e, res, names ? names[0] : what, err);
  if (rc) return rc;
  size_t n = (size_t)res * (size_t)res * 3;
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++) memcpy(obs_env_texel(e, f, 0, 0), faces[f], n * 4);
  env_finish(e);
  return 0;
}

int obs_env_from_faces(obs_env *e, const float *const faces[6], int res, obs_err *err) {
  return faces_build(e, faces, res, NULL, err);
}

int obs_env_from_face_files(obs_env *e, const char *const paths[6], obs_err *err) {
  memset(e, 0, sizeof *e);
  if (!paths) return obs_err_set(err, OBS_EINVAL, "environment: no face files");
  float *faces[OBS_ENV_FACE_COUNT] = {0};
  int w0 = 0, rc = 0;
  for (int f = 0; f < OBS_ENV_FACE_COUNT && !rc; f++) {
    int w, h;
    if ((rc = read_rgb_exr(paths[f], &faces[f], &w, &h, err))) break;
    if (w != h)
      rc = obs_err_set(err, OBS_EINVAL, "%s: environment face %s is %d x %d pixels, not square",
                       paths[f], face_names[f], w, h);
    else if (f > 0 && w != w0)
      rc = obs_err_set(err, OBS_EINVAL,
                       "%s: environment face %s is %d x %d pixels, but face %s (%s) is %d x %d",
                       paths[f], face_names[f], w, h, face_names[0], paths[0], w0, w0);
    w0 = f == 0 ? w : w0;
  }
  if (!rc) rc = faces_build(e, (const float *const *)faces, w0, paths, err);
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++) free(faces[f]);
  return rc;
}

/* ---- procedural sky ---------------------------------------------------------------------- */

void obs_env_sky_default(obs_env_sky_params *p) {
  *p = (obs_env_sky_params){
      .zenith = {0.08, 0.20, 0.60},
      .horizon = {0.70, 0.75, 0.80},
      .ground = {0.10, 0.07, 0.04},
      .sun_dir = {0.5, 0.70710678118654752, -0.5},
      .sun_radius_deg = 2,
      .sun_radiance = {700, 650, 560},
  };
}

static double smoothstep(double a, double b, double x) {
  double t = clampd((x - a) / (b - a), 0, 1);
  return t * t * (3 - 2 * t);
}

void obs_env_sky_radiance(const obs_env_sky_params *p, const double dir[3], double rgb[3]) {
  double d[3], sun[3];
  if (!normalise3(dir, d)) {
    for (int c = 0; c < 3; c++) rgb[c] = p->horizon[c];
    return;
  }
  double h = d[1], g = h >= 0 ? h : smoothstep(0, 0.1, -h);
  for (int c = 0; c < 3; c++)
    rgb[c] = p->horizon[c] + ((h >= 0 ? p->zenith[c] : p->ground[c]) - p->horizon[c]) * g;
  if (!(p->sun_radius_deg > 0) || !normalise3(p->sun_dir, sun)) return;
  /* atan2 of the cross and dot products: acos loses the small angles the sun lives at. */
  double cx = d[1] * sun[2] - d[2] * sun[1], cy = d[2] * sun[0] - d[0] * sun[2],
         cz = d[0] * sun[1] - d[1] * sun[0];
  double a =
      atan2(sqrt(cx * cx + cy * cy + cz * cz), d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2]);
  double r = p->sun_radius_deg * PI / 180, w = 1 - smoothstep(0.9 * r, 1.1 * r, a);
  for (int c = 0; c < 3; c++) rgb[c] += p->sun_radiance[c] * w;
}

static void sky_sample(const void *user, const double d[3], double rgb[3]) {
  obs_env_sky_radiance(user, d, rgb);
}

static int sky_check(const obs_env_sky_params *p, obs_err *err) {
  const struct {
    const char *name;
    const double *v;
  } colours[] = {{"zenith", p->zenith},
                 {"horizon", p->horizon},
                 {"ground", p->ground},
                 {"sun_radiance", p->sun_radiance}};
  for (int k = 0; k < 4; k++)
    for (int c = 0; c < 3; c++)
      if (!(colours[k].v[c] >= 0) || !isfinite(colours[k].v[c]))
        return obs_err_set(err, OBS_EINVAL,
                           "sky: %s[%d] is %g (radiance must be finite and non-negative)",
                           colours[k].name, c, colours[k].v[c]);
  if (!(p->sun_radius_deg >= 0 && p->sun_radius_deg <= 45))
    return obs_err_set(err, OBS_EINVAL, "sky: sun_radius_deg is %g, must be in [0, 45]",
                       p->sun_radius_deg);
  double d[3];
  if (p->sun_radius_deg > 0 && !normalise3(p->sun_dir, d))
    return obs_err_set(err, OBS_EINVAL, "sky: sun_dir (%g, %g, %g) is zero or not finite",
                       p->sun_dir[0], p->sun_dir[1], p->sun_dir[2]);
  return 0;
}

int obs_env_sky(obs_env *e, const obs_env_sky_params *p, int res, obs_err *err) {
  memset(e, 0, sizeof *e);
  if (!p) return obs_err_set(err, OBS_EINVAL, "sky: no parameters");
  int rc = sky_check(p, err);
  if (!rc) rc = env_alloc(e, res, "sky", err);
  if (rc) return rc;
  /* Samples an eighth of the sun's radius apart, so a sun narrower than a few texels keeps its
   * power (within about 1%: a point-sampled disc). */
  double spacing = p->sun_radius_deg > 0 ? p->sun_radius_deg * PI / 180 / 8 : 1e9;
  env_fill(e, samples_for(res, spacing), sky_sample, p);
  return 0;
}

/* ---- lookup, mean ------------------------------------------------------------------------ */

void obs_env_lookup(const obs_env *e, const float dir[3], float rgb[3]) {
  double d[3] = {dir[0], dir[1], dir[2]}, s, t;
  int f = e->data ? obs_env_face_coords(d, &s, &t) : -1;
  if (f < 0) {
    for (int c = 0; c < 3; c++) rgb[c] = (float)e->mean[c];
    return;
  }
  int r = e->res;
  double fx = clampd(s * r - 0.5, 0, r - 1), fy = clampd(t * r - 0.5, 0, r - 1);
  int i0 = (int)fx, j0 = (int)fy;
  int i1 = i0 + 1 < r ? i0 + 1 : i0, j1 = j0 + 1 < r ? j0 + 1 : j0;
  float wx = (float)(fx - i0), wy = (float)(fy - j0);
  const float *p00 = obs_env_texel(e, f, i0, j0), *p10 = obs_env_texel(e, f, i1, j0);
  const float *p01 = obs_env_texel(e, f, i0, j1), *p11 = obs_env_texel(e, f, i1, j1);
  for (int c = 0; c < 3; c++) {
    float top = p00[c] + wx * (p10[c] - p00[c]), bot = p01[c] + wx * (p11[c] - p01[c]);
    rgb[c] = top + wy * (bot - top);
  }
}

void obs_env_mean(const obs_env *e, double rgb[3]) {
  for (int c = 0; c < 3; c++) rgb[c] = e->mean[c];
}

/* ---- spherical harmonics ----------------------------------------------------------------- */

void obs_sh_basis(int bands, const double d[3], double *y) {
  const double k0 = 0.5 * sqrt(1 / PI), k1 = sqrt(3 / (4 * PI)), k2 = sqrt(15 / (4 * PI));
  const double k20 = sqrt(5 / (16 * PI)), k22 = sqrt(15 / (16 * PI));
  double x = d[0], yy = d[1], z = d[2];
  y[0] = k0;
  if (bands < 2) return;
  y[1] = k1 * yy;
  y[2] = k1 * z;
  y[3] = k1 * x;
  if (bands < 3) return;
  y[4] = k2 * x * yy;
  y[5] = k2 * yy * z;
  y[6] = k20 * (3 * z * z - 1);
  y[7] = k2 * x * z;
  y[8] = k22 * (x * x - yy * yy);
  if (bands < 4) return;
  const double k33 = 0.25 * sqrt(35 / (2 * PI)), k32 = 0.5 * sqrt(105 / PI);
  const double k31 = 0.25 * sqrt(21 / (2 * PI)), k30 = 0.25 * sqrt(7 / PI);
  const double k32b = 0.25 * sqrt(105 / PI);
  y[9] = k33 * yy * (3 * x * x - yy * yy);
  y[10] = k32 * x * yy * z;
  y[11] = k31 * yy * (5 * z * z - 1);
  y[12] = k30 * z * (5 * z * z - 3);
  y[13] = k31 * x * (5 * z * z - 1);
  y[14] = k32b * z * (x * x - yy * yy);
  y[15] = k33 * x * (x * x - 3 * yy * yy);
}

typedef struct sh_sum {
  int bands;
  double (*coeffs)[3];
} sh_sum;

static void sh_add(void *user, const double d[3], double omega, const float *rgb) {
  const sh_sum *s = user;
  double y[OBS_SH_MAX_COEFFS];
  int n = s->bands * s->bands;
  obs_sh_basis(s->bands, d, y);
  for (int k = 0; k < n; k++)
    for (int c = 0; c < 3; c++) s->coeffs[k][c] += rgb[c] * y[k] * omega;
}

void obs_env_sh(const obs_env *e, int bands, double (*coeffs)[3]) {
  bands = bands < 1 ? 1 : bands > OBS_SH_MAX_BANDS ? OBS_SH_MAX_BANDS : bands;
  memset(coeffs, 0, sizeof(double[3]) * (size_t)(bands * bands));
  sh_sum s = {bands, coeffs};
  if (e->data) env_foreach(e, sh_add, &s);
}

void obs_env_sh9(const obs_env *e, double coeffs[9][3]) { obs_env_sh(e, 3, coeffs); }

void obs_env_sh_irradiance(const double coeffs[9][3], const float n[3], float rgb[3]) {
  /* A_l / pi for bands 0, 1, 2 (Ramamoorthi and Hanrahan 2001: pi, 2 pi / 3, pi / 4). */
  static const double band[9] = {1, 2.0 / 3, 2.0 / 3, 2.0 / 3, 0.25, 0.25, 0.25, 0.25, 0.25};
  double v[3] = {n[0], n[1], n[2]}, d[3], y[9];
  int terms = normalise3(v, d) ? 9 : 1;
  obs_sh_basis(3, terms == 9 ? d : v, y); /* y[0] does not depend on the direction */
  for (int c = 0; c < 3; c++) {
    double sum = 0;
    for (int k = 0; k < terms; k++) sum += band[k] * coeffs[k][c] * y[k];
    rgb[c] = sum > 0 ? (float)sum : 0.0f;
  }
}

/* The unit cube's point at face coordinates (s, t): the texel corners, whose straight edges on
 * the face project to great arcs, so a texel is a spherical quadrilateral. */
static void face_point(int face, double s, double t, double p[3]) {
  double d[3];
  obs_env_face_dir(face, s, t, d);
  double m = fmax(fabs(d[0]), fmax(fabs(d[1]), fabs(d[2])));
  for (int a = 0; a < 3; a++) p[a] = d[a] / m;
}

/* Clips the polygon v[0..n) (points on the cube) to the half-space n . p >= 0. A plane through
 * the origin cuts a great arc where it cuts the straight edge beneath it, so the clip is exact on
 * the sphere. Returns the new vertex count (at most n + 1). */
static int clip_polygon(const double v[][3], int n, const double nrm[3], double out[][3]) {
  int m = 0;
  for (int k = 0; k < n; k++) {
    const double *a = v[k], *b = v[(k + 1) % n];
    double da = nrm[0] * a[0] + nrm[1] * a[1] + nrm[2] * a[2];
    double db = nrm[0] * b[0] + nrm[1] * b[1] + nrm[2] * b[2];
    if (da >= 0) memcpy(out[m++], a, sizeof out[0]);
    if ((da >= 0) != (db >= 0)) {
      double t = da / (da - db);
      for (int c = 0; c < 3; c++) out[m][c] = a[c] + t * (b[c] - a[c]);
      m++;
    }
  }
  return m;
}

/* Lambert's formula: the integral of the unit direction over a spherical polygon is
 * (1/2) sum over edges of (edge angle) x (unit normal of the edge's plane). Its dot product with
 * the normal is the polygon's cosine-weighted solid angle. */
static double polygon_cosine(const double v[][3], int n, const double nrm[3]) {
  double sum[3] = {0, 0, 0}, centre[3] = {0, 0, 0};
  for (int k = 0; k < n; k++) {
    double a[3], b[3];
    normalise3(v[k], a);
    normalise3(v[(k + 1) % n], b);
    double g[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double sn = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    if (!(sn > 0)) continue; /* a clip point on a vertex: an empty edge */
    double theta = atan2(sn, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
    for (int c = 0; c < 3; c++) sum[c] += theta * g[c] / sn, centre[c] += a[c];
  }
  /* The faces' (s, t) frames differ in handedness; the integral points into the polygon. */
  double sign = sum[0] * centre[0] + sum[1] * centre[1] + sum[2] * centre[2] < 0 ? -0.5 : 0.5;
  return sign * (sum[0] * nrm[0] + sum[1] * nrm[1] + sum[2] * nrm[2]);
}

/* The integral of max(0, n . w) over texel (i, j) of face f. */
static double texel_cosine(int res, int f, int i, int j, const double nrm[3]) {
  double q[4][3], clipped[5][3];
  face_point(f, (double)i / res, (double)j / res, q[0]);
  face_point(f, (double)(i + 1) / res, (double)j / res, q[1]);
  face_point(f, (double)(i + 1) / res, (double)(j + 1) / res, q[2]);
  face_point(f, (double)i / res, (double)(j + 1) / res, q[3]);
  int above = 0;
  for (int k = 0; k < 4; k++) above += nrm[0] * q[k][0] + nrm[1] * q[k][1] + nrm[2] * q[k][2] >= 0;
  if (above == 0) return 0;
  if (above == 4) return polygon_cosine((const double(*)[3])q, 4, nrm);
  int m = clip_polygon((const double(*)[3])q, 4, nrm, clipped);
  return m >= 3 ? polygon_cosine((const double(*)[3])clipped, m, nrm) : 0;
}

void obs_env_irradiance_ref(const obs_env *e, const float n[3], float rgb[3]) {
  double v[3] = {n[0], n[1], n[2]}, nrm[3], sum[3] = {0, 0, 0};
  if (!e->data || !normalise3(v, nrm)) {
    for (int c = 0; c < 3; c++) rgb[c] = (float)e->mean[c];
    return;
  }
  int r = e->res;
  for (int f = 0; f < OBS_ENV_FACE_COUNT; f++)
    for (int j = 0; j < r; j++)
      for (int i = 0; i < r; i++) {
        double w = texel_cosine(r, f, i, j, nrm);
        if (w <= 0) continue;
        const float *px = obs_env_texel(e, f, i, j);
        for (int c = 0; c < 3; c++) sum[c] += px[c] * w;
      }
  for (int c = 0; c < 3; c++) rgb[c] = (float)(sum[c] / PI);
}
