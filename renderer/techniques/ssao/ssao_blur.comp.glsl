// ssao blur pass: 4x4 box over pixels of similar depth; the twin of blur_pixel in
// cpu.c (same window, same summation order, same reciprocal table).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SSAO_BLUR_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, r32f) uniform readonly image2D raw_img;
layout(binding = 2, r32f) uniform writeonly image2D ao_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zc = imageLoad(depth_img, p).r;
  if (!(zc > 0.0)) {
    imageStore(ao_img, p, vec4(1.0));
    return;
  }
  precise float lim = pc.threshold * zc;
  precise float sum = 0.0;
  int cnt = 0;
  // The window is [-2, 1]^2 (OBS_SSAO_BLUR_LO/HI): even, so it covers the 4x4 rotation tile.
  for (int dy = -2; dy <= 1; dy++)
    for (int dx = -2; dx <= 1; dx++) {
      ivec2 q = p + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= pc.width || q.y >= pc.height) continue;
      float zn = imageLoad(depth_img, q).r;
      precise float dz = abs(zn - zc);
      if (zn > 0.0 && dz <= lim) {
        sum += imageLoad(raw_img, q).r;
        cnt++;
      }
    }
  precise float r = min(sum * pc.inv_count[cnt], 1.0);
  imageStore(ao_img, p, vec4(r));
}
