/* Importance sampling of an environment map by luminance x sin theta over a lat-long grid, with
 * the folded Hammersley points that spread the samples (environment.h): ibl_shadows picks its
 * shadow-map directions with it and path_trace its environment light samples. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "environment.h"

#define PI 3.14159265358979323846

void obs_env_latlong_dir(double u, double v, double dir[3]) {
  double th = PI * v, ph = 2 * PI * (u - 0.5), st = sin(th);
  dir[0] = st * sin(ph);
  dir[1] = cos(th);
  dir[2] = -st * cos(ph);
}

int obs_env_dist_build(obs_env_dist *d, const obs_env *e, int w, int h, obs_err *err) {
  memset(d, 0, sizeof *d);
  if (!e || !e->data)
    return obs_err_set(err, OBS_EINVAL, "environment sampler: no environment map");
  if (w < 2 || w > 4096 || h < 1 || h > 2048)
    return obs_err_set(err, OBS_EINVAL,
                       "environment sampler: grid %dx%d out of range (w 2..4096, h 1..2048)", w, h);
  d->row = malloc((size_t)(h + 1) * sizeof *d->row);
  d->col = malloc((size_t)h * (size_t)(w + 1) * sizeof *d->col);
  if (!d->row || !d->col) {
    obs_env_dist_free(d);
    return obs_err_set(err, OBS_ENOMEM, "environment sampler: grid %dx%d: out of memory", w, h);
  }
  d->w = w, d->h = h;
  d->row[0] = 0;
  for (int y = 0; y < h; y++) {
    double v = (y + 0.5) / h, st = sin(PI * v), *c = d->col + (size_t)y * (size_t)(w + 1);
    c[0] = 0;
    for (int x = 0; x < w; x++) {
      double dir[3];
      float fd[3], rgb[3];
      obs_env_latlong_dir((x + 0.5) / w, v, dir);
      for (int k = 0; k < 3; k++) fd[k] = (float)dir[k];
      obs_env_lookup(e, fd, rgb);
      double lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
      c[x + 1] = c[x] + lum * st;
    }
    d->row[y + 1] = d->row[y] + c[w];
  }
  d->total = d->row[h];
  return 0;
}

void obs_env_dist_grid(int res, int *w, int *h) {
  int ww = 4 * res;
  ww = ww < 16 ? 16 : ww > 1024 ? 1024 : ww;
  *w = ww;
  *h = ww / 2;
}

void obs_env_dist_free(obs_env_dist *d) {
  free(d->row);
  free(d->col);
  memset(d, 0, sizeof *d);
}

double obs_env_dist_pmf(const obs_env_dist *d, int x, int y) {
  if (!(d->total > 0) || x < 0 || y < 0 || x >= d->w || y >= d->h) return 0;
  const double *c = d->col + (size_t)y * (size_t)(d->w + 1);
  return (c[x + 1] - c[x]) / d->total;
}

/* The first index i in [0, n) with cdf[i + 1] > t (cdf[0] = 0, non-decreasing, cdf[n] > t),
 * skipping empty entries. */
static int find(const double *cdf, int n, double t) {
  int lo = 0, hi = n - 1;
  while (lo < hi) {
    int mid = (lo + hi) / 2;
    if (cdf[mid + 1] > t)
      hi = mid;
    else
      lo = mid + 1;
  }
  return lo;
}

/* The density in solid angle of pixel (x, y) at polar angle theta of sine st. */
static double density(const obs_env_dist *d, int x, int y, double st) {
  double p = obs_env_dist_pmf(d, x, y);
  if (!(p > 0) || !(st > 0)) return 0;
  return p * d->w * d->h / (2 * PI * PI * st);
}

double obs_env_dist_sample(const obs_env_dist *d, double u0, double u1, double dir[3]) {
  if (!(d->total > 0)) {
    dir[0] = 0, dir[1] = 1, dir[2] = 0;
    return 0;
  }
  u0 = u0 < 0 ? 0 : u0 >= 1 ? 0x1.fffffffffffffp-1 : u0;
  u1 = u1 < 0 ? 0 : u1 >= 1 ? 0x1.fffffffffffffp-1 : u1;
  double t = u0 * d->total;
  int y = find(d->row, d->h, t);
  double fy = (t - d->row[y]) / (d->row[y + 1] - d->row[y]);
  const double *c = d->col + (size_t)y * (size_t)(d->w + 1);
  double s = u1 * c[d->w];
  int x = find(c, d->w, s);
  double fx = (s - c[x]) / (c[x + 1] - c[x]);
  fx = fx < 0 ? 0 : fx > 1 ? 1 : fx;
  fy = fy < 0 ? 0 : fy > 1 ? 1 : fy;
  double u = (x + fx) / d->w, v = (y + fy) / d->h;
  obs_env_latlong_dir(u, v, dir);
  return density(d, x, y, sin(PI * v));
}

double obs_env_dist_pdf(const obs_env_dist *d, const double dir[3]) {
  if (!(d->total > 0)) return 0;
  double cy = dir[1] < -1 ? -1 : dir[1] > 1 ? 1 : dir[1];
  double u = 0.5 + atan2(dir[0], -dir[2]) / (2 * PI), v = acos(cy) / PI;
  int x = (int)floor(u * d->w), y = (int)floor(v * d->h);
  x = x < 0 ? 0 : x >= d->w ? d->w - 1 : x;
  y = y < 0 ? 0 : y >= d->h ? d->h - 1 : y;
  return density(d, x, y, sqrt(fmax(0, 1 - cy * cy)));
}

void obs_folded_hammersley(uint32_t i, uint32_t n, double *u0, double *u1) {
  *u0 = (i + 0.5) / (n ? n : 1);
  /* Folded radical inverse in base 2: digit k is (a_k + k) mod 2, over 32 digits. */
  double val = 0, inv = 0.5;
  uint32_t m = i;
  for (int k = 0; k < 32; k++, m >>= 1, inv *= 0.5) val += (double)((m + (uint32_t)k) & 1u) * inv;
  *u1 = val;
}
