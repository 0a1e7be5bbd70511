// ss_obscurance's 4x4 average of the interleaved pattern over neighbours within R in depth, as
// the mean of the closed shares; the twin of avg_pixel in cpu.c (same window, same order, same
// reciprocal table).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SSO_SHADER_AVG
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = OBS_SSO_A_DEPTH, r32f) uniform readonly image2D depth_img;
layout(binding = OBS_SSO_A_RAW, r32f) uniform readonly image2D raw_img;
layout(binding = OBS_SSO_A_OUT, r32f) uniform writeonly image2D ao_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zc = imageLoad(depth_img, p).r;
  if (!(zc > 0.0)) {
    imageStore(ao_img, p, vec4(1.0));
    return;
  }
  precise float sum = 0.0;
  int cnt = 0;
  for (int dy = OBS_SSO_AVG_LO; dy <= OBS_SSO_AVG_HI; dy++)
    for (int dx = OBS_SSO_AVG_LO; dx <= OBS_SSO_AVG_HI; dx++) {
      ivec2 q = p + ivec2(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= pc.width || q.y >= pc.height) continue;
      float zn = imageLoad(depth_img, q).r;
      precise float dz = abs(zn - zc);
      if (zn > 0.0 && dz <= pc.radius) {
        precise float c = 1.0 - imageLoad(raw_img, q).r;
        sum += c;
        cnt++;
      }
    }
  precise float r = 1.0 - sum * pc.inv_count[cnt];
  imageStore(ao_img, p, vec4(r < 0.0 ? 0.0 : r));
}
