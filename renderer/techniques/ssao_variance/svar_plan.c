/* ssao_variance's per-frame plan (ssao_variance.h): the median depth, the box it gives the world
 * radius, the depth scale and the reciprocal table, computed once on the host for both backends. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ssao_variance.h"

/* Samples the median reads at most: enough for a stable median, a fraction of a millisecond. */
#define SVAR_MEDIAN_SAMPLES (1 << 18)

static uint32_t float_bits(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u;
}

double obs_svar_median_depth(const float *depth, int width, int height) {
  if (!depth || width < 1 || height < 1) return 0.0;
  int g = 1;
  while ((double)((width + g - 1) / g) * (double)((height + g - 1) / g) > SVAR_MEDIAN_SAMPLES) g++;
  /* Positive floats order as their bits do: select the rank's high 16 bits, then its low 16. */
  uint32_t *hist = calloc(65536, sizeof *hist);
  if (!hist) return 0.0;
  size_t count = 0;
  for (int y = 0; y < height; y += g)
    for (int x = 0; x < width; x += g) {
      float z = depth[(size_t)y * (size_t)width + (size_t)x];
      if (z > 0.0f) {
        hist[float_bits(z) >> 16]++;
        count++;
      }
    }
  double out = 0.0;
  if (count) {
    size_t rank = (count - 1) / 2, below = 0;
    uint32_t hi = 0;
    while (below + hist[hi] <= rank) below += hist[hi++];
    rank -= below;
    memset(hist, 0, 65536 * sizeof *hist);
    for (int y = 0; y < height; y += g)
      for (int x = 0; x < width; x += g) {
        float z = depth[(size_t)y * (size_t)width + (size_t)x];
        if (z > 0.0f && float_bits(z) >> 16 == hi) hist[float_bits(z) & 0xffffu]++;
      }
    uint32_t lo = 0;
    below = 0;
    while (below + hist[lo] <= rank) below += hist[lo++];
    uint32_t bits = hi << 16 | lo;
    float z;
    memcpy(&z, &bits, sizeof z);
    out = z;
  }
  free(hist);
  return out;
}

void obs_svar_plan_make(const obs_ssao_variance_params *p, const float *depth, int width,
                        int height, const obs_svar_projection *proj, obs_svar_plan *out) {
  memset(out, 0, sizeof *out);
  out->zscale = 1.0f;
  out->stride = 1;
  out->z_median = obs_svar_median_depth(depth, width, height);
  for (int n = 1; n < OBS_SVAR_INV_COUNT; n++) out->inv_count[n] = 1.0f / (float)n;
  if (!(out->z_median > 0.0)) return;
  /* A pixel spans 2 half_w / W at unit depth (perspective) or in all (orthographic). */
  double pixel = 2.0 * (double)proj->half_w / (double)width;
  double at = proj->ortho ? pixel : pixel * out->z_median;
  double px = p->radius / at;
  /* The symmetric box never reaches past half the image (docs: edges), so a longer radius reads
   * the same as half the image's longer side. */
  int half = ((width > height ? width : height) - 1) / 2;
  int r = px < (double)half ? (int)floor(px + 0.5) : half;
  if (r < 0) r = 0;
  out->radius_px = r;
  if (r > 0) {
    const int t = p->taps < 1 ? 1 : p->taps > OBS_SVAR_MAX_TAPS ? OBS_SVAR_MAX_TAPS : p->taps;
    out->stride = (r + t - 1) / t;
    out->taps = r / out->stride;
  }
  int e;
  frexp(out->z_median, &e); /* z_median = f 2^e, f in [0.5, 1) */
  out->zscale = (float)ldexp(1.0, 1 - e);
  double reach = (double)out->taps * (double)out->stride * pixel;
  out->rw = (float)(proj->ortho ? reach * (double)out->zscale : reach);
}

void obs_svar_ao_push_make(const obs_ssao_variance_params *p, const obs_svar_plan *plan, int width,
                           int height, int ortho, obs_svar_ao_push *out) {
  memset(out, 0, sizeof *out);
  out->width = width;
  out->height = height;
  out->stride = plan->stride;
  out->taps = plan->taps;
  out->method = p->method;
  out->ortho = ortho ? 1 : 0;
  out->zscale = plan->zscale;
  out->rw = plan->rw;
  out->tol = (float)OBS_SVAR_DEPTH_TOL;
  out->weight = p->variance_weight;
  out->strength = p->strength;
}
