/* ss_obscurance's per-pixel estimator in C, the formula ss_obscurance.comp.glsl repeats
 * operation for operation (float32, the same order, no contraction): W of one pixel from the
 * G-buffer's depth and view-space normals and the offset table (layout.h). */
#ifndef OBS_SSO_PIXEL_H
#define OBS_SSO_PIXEL_H

#include <stddef.h>

#include "layout.h"
#include "parallel.h"
#include "sampling.h"

/* floor(v) clamped to [0, n - 1], NaN to 0: the texel a sample lands on (clamp to edge). The
 * clamp comes before the conversion, so a huge or infinite coordinate never overflows an int. */
OBS_HOT_INLINE int obs_sso_texel(float v, int n) {
  float f = floorf(v);
  f = f > 0.0f ? f : 0.0f;
  f = f < (float)(n - 1) ? f : (float)(n - 1);
  return (int)f;
}

/* View-space position of texel (x, y) at depth z (gbuffer.h's definition, with 2/W and 2/H
 * rounded once so that no backend divides). */
OBS_HOT_INLINE void obs_sso_position(const obs_sso_push *pc, int x, int y, float z, float out[3]) {
  const float fx = (float)x + 0.5f, fy = (float)y + 0.5f;
  const float nx = fx * pc->two_inv_w - 1.0f, ny = 1.0f - fy * pc->two_inv_h;
  if (pc->flags & OBS_SSO_FLAG_ORTHO) {
    out[0] = nx * pc->half_w;
    out[1] = ny * pc->half_h;
  } else {
    out[0] = nx * pc->half_w * z;
    out[1] = ny * pc->half_h * z;
  }
  out[2] = z;
}

/* W of pixel (x, y): 1 - (sum of the closed samples' weights) / (sum of all weights). `offsets`
 * is the table of obs_sso_tables (cells x (OBS_SSO_MAX_SAMPLES + 1) x 4 floats). */
OBS_HOT_INLINE float obs_sso_pixel(const obs_sso_push *pc, const float *depth, const float *normal,
                                   const float *offsets, int x, int y) {
  const int w = pc->width, h = pc->height;
  const size_t i = (size_t)y * (size_t)w + (size_t)x;
  const float zp = depth[i];
  if (!(zp > 0.0f)) return 1.0f;
  const int ortho = pc->flags & OBS_SSO_FLAG_ORTHO;
  float p[3], t[3], b[3];
  obs_sso_position(pc, x, y, zp, p);
  const float *n = normal + 3 * i;
  /* Duff et al.'s basis (sampling.h): the listing's T = N x (0, 1, 0) vanishes for N = +-y. */
  obs_onb(n, t, b);
  const float R = pc->radius;
  const float tx = t[0] * R, ty = t[1] * R, tz = t[2] * R;
  const float bx = b[0] * R, by = b[1] * R, bz = b[2] * R;
  const float nx = n[0] * R, ny = n[1] * R, nz = n[2] * R;
  const int cell = (pc->flags & OBS_SSO_FLAG_INTERLEAVE) ? ((y & 3) << 2) | (x & 3) : 0;
  const float *o = offsets + (size_t)cell * (OBS_SSO_MAX_SAMPLES + 1) * 4;
  const float hw = 0.5f * (float)w, hh = 0.5f * (float)h;
  float closed = 0.0f;
  for (int k = 0; k < pc->samples; k++, o += 4) {
    const float sx = p[0] + (o[0] * tx + o[1] * bx + o[2] * nx);
    const float sy = p[1] + (o[0] * ty + o[1] * by + o[2] * ny);
    const float sz = p[2] + (o[0] * tz + o[1] * bz + o[2] * nz);
    float u, v;
    if (ortho) {
      u = sx * pc->inv_half_w;
      v = sy * pc->inv_half_h;
    } else {
      /* Behind the eye: outside every view of the depth buffer, and the eye is in free space. */
      if (!(sz > 0.0f)) continue;
      const float rz = 1.0f / sz;
      u = sx * rz * pc->inv_half_w;
      v = sy * rz * pc->inv_half_h;
    }
    const int qx = obs_sso_texel((u + 1.0f) * hw, w), qy = obs_sso_texel((1.0f - v) * hh, h);
    const size_t q = (size_t)qy * (size_t)w + (size_t)qx;
    const float zq = depth[q];
    /* Background: infinitely far, so the sample is in free space. */
    if (!(zq > 0.0f)) continue;
    /* More than R behind the stored surface: that surface is no occluder within R. */
    if (sz - zq > R) continue;
    /* In front of the stored surface along the sample's own line of sight: in front of the plane
     * of the texel it lands on. */
    float s[3];
    obs_sso_position(pc, qx, qy, zq, s);
    const float *m = normal + 3 * q;
    const float d = (sx - s[0]) * m[0] + (sy - s[1]) * m[1] + (sz - s[2]) * m[2];
    const float slack = (float)OBS_SSO_SLACK * (fabsf(s[0]) + fabsf(s[1]) + zq + R);
    if (d < -slack) closed += o[3];
  }
  const float inv = offsets[(size_t)cell * (OBS_SSO_MAX_SAMPLES + 1) * 4 +
                            (size_t)pc->samples * 4];
  const float a = 1.0f - closed * inv;
  return a < 0.0f ? 0.0f : a;
}

#endif
