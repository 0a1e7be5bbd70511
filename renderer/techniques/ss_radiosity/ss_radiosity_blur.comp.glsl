// ss_radiosity blur pass: 4x4 box over pixels of similar depth of the bounce and its ao; the twin
// of blur_pixel in cpu.c (same window, same summation order, same reciprocal table).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SRAD_BLUR
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, rgba32f) uniform readonly image2D raw_img;
layout(binding = 2, rgba32f) uniform writeonly image2D out_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zc = imageLoad(depth_img, p).r;
  if (!(zc > 0.0)) {
    imageStore(out_img, p, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  precise float lim = pc.threshold * zc;
  precise vec4 s = vec4(0.0);
  int cnt = 0;
  for (int dy = OBS_SRAD_BLUR_LO; dy <= OBS_SRAD_BLUR_HI; dy++)
    for (int dx = OBS_SRAD_BLUR_LO; dx <= OBS_SRAD_BLUR_HI; dx++) {
      ivec2 q = p + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= pc.width || q.y >= pc.height) continue;
      float zn = imageLoad(depth_img, q).r;
      precise float dz = abs(zn - zc);
      if (zn > 0.0 && dz <= lim) {
        s += imageLoad(raw_img, q);
        cnt++;
      }
    }
  precise vec4 r = s * pc.inv_count[cnt];
  r.w = min(r.w, 1.0);
  imageStore(out_img, p, r);
}
