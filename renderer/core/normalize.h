/* Scale-safe normalisation of 3-vectors. Squaring the components overflows for lengths beyond
 * sqrt(FLT_MAX) (~1.8e19 in float, ~1.3e154 in double) and underflows below sqrt(FLT_MIN), so a
 * plain v / |v| turns huge or tiny normals into infinities, NaNs or zero. Where the squared length
 * is comfortably inside the normal range the plain arithmetic is used; outside it the vector is
 * first scaled by the power of two that brings its largest |component| into [0.5, 1). A power of
 * two scales exactly, so both ways give the same bits wherever both can be computed. */
#ifndef OBS_NORMALIZE_H
#define OBS_NORMALIZE_H

#include <math.h>

/* Normalises v in place; returns 0, or -1 (v unchanged) when v is zero or not finite. */
static inline int obs_normalize3f(float v[3]) {
  float l2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  float w[3] = {v[0], v[1], v[2]};
  if (!(l2 >= 0x1p-100f && l2 <= 0x1p100f)) {
    float a = fabsf(v[0]), b = fabsf(v[1]), c = fabsf(v[2]);
    float m = a > b ? a : b;
    m = m > c ? m : c;
    if (!(m > 0.0f) || !isfinite(m)) return -1;
    int e;
    frexpf(m, &e);
    for (int k = 0; k < 3; k++) w[k] = ldexpf(v[k], -e);
    l2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if (!isfinite(l2)) return -1;
  }
  float l = sqrtf(l2);
  for (int k = 0; k < 3; k++) v[k] = w[k] / l;
  return 0;
}

static inline int obs_normalize3d(double v[3]) {
  double l2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
  double w[3] = {v[0], v[1], v[2]};
  if (!(l2 >= 0x1p-900 && l2 <= 0x1p900)) {
    double a = fabs(v[0]), b = fabs(v[1]), c = fabs(v[2]);
    double m = a > b ? a : b;
    m = m > c ? m : c;
    if (!(m > 0.0) || !isfinite(m)) return -1;
    int e;
    frexp(m, &e);
    for (int k = 0; k < 3; k++) w[k] = ldexp(v[k], -e);
    l2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    if (!isfinite(l2)) return -1;
  }
  double l = sqrt(l2);
  for (int k = 0; k < 3; k++) v[k] = w[k] / l;
  return 0;
}

/* v scaled in place by the power of two that brings its largest |component| into [0.5, 1) (exact;
 * left alone when zero or not finite), so products of such vectors neither overflow nor
 * underflow. */
static inline void obs_prescale3d(double v[3]) {
  double a = fabs(v[0]), b = fabs(v[1]), c = fabs(v[2]);
  double m = a > b ? a : b;
  m = m > c ? m : c;
  if (!(m > 0.0) || !isfinite(m)) return;
  int e;
  frexp(m, &e);
  for (int k = 0; k < 3; k++) v[k] = ldexp(v[k], -e);
}

#endif
