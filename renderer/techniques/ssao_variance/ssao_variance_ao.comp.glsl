// ssao_variance AO pass: the column part of each pixel's box, its mean and variance relative to
// the pixel's depth, and the estimator; the twin of ao_tile_body and svar_estimate in cpu.c.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SVAR_AO_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = OBS_SVAR_A_DEPTH, r32f) uniform readonly image2D depth_img;
layout(binding = OBS_SVAR_A_MOMENTS, rgba32f) uniform readonly image2D moments_img;
layout(binding = OBS_SVAR_A_INV, r32f) uniform readonly image2D inv_img; // 1/N, N = 0..1089
layout(binding = OBS_SVAR_A_AO, r32f) uniform writeonly image2D ao_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  precise float z0 = imageLoad(depth_img, p).r * pc.zscale;
  if (!(z0 > 0.0)) {
    imageStore(ao_img, p, vec4(1.0));
    return;
  }
  int s = pc.stride, K = pc.taps;
  int m = min(p.y, pc.height - 1 - p.y);
  precise float nn = 0.0, t1 = 0.0, t2 = 0.0;
  for (int k = -K; k <= K; k++) {
    if (abs(k) * s > m) continue;
    vec4 a = imageLoad(moments_img, ivec2(p.x, p.y + k * s));
    precise float dl = a.w - z0;
    precise float an_d = a.x * dl;
    t1 = t1 + (a.y + an_d);
    precise float tw = 2.0 * dl;
    t2 = t2 + ((a.z + tw * a.y) + an_d * dl);
    nn = nn + a.x;
  }
  float iv = imageLoad(inv_img, ivec2(int(nn), 0)).r;
  // the covered share of the box's taps: uncovered taps are open sky, behind every pixel
  int mx = min(p.x, pc.width - 1 - p.x);
  precise float ntot = float(2 * min(K, mx / s) + 1) * float(2 * min(K, m / s) + 1);
  precise float share = nn * imageLoad(inv_img, ivec2(int(ntot), 0)).r;
  precise float mo = t1 * iv;
  precise float e2 = t2 * iv;
  precise float var = e2 - mo * mo;
  if (!(var > 0.0)) var = 0.0;
  precise float tz = pc.tol * z0;
  precise float dd = (0.0 - mo) - tz;
  precise float R = pc.ortho != 0 ? pc.rw : pc.rw * z0;
  precise float v = 1.0;
  if (dd > 0.0) {
    if (pc.method == 0) {
      precise float den = var + dd * dd;
      precise float vis = den > 0.0 ? var / den : 1.0;
      precise float q = var / (R * R);
      precise float ov = 1.0 - vis;
      v = (1.0 - share * ov) + pc.weight * q;
    } else {
      precise float u = dd / R;
      v = 1.0 - share * (pc.strength * u);
    }
  }
  float ao = v > 0.0 ? (v < 1.0 ? v : 1.0) : 0.0;
  imageStore(ao_img, p, vec4(ao));
}
