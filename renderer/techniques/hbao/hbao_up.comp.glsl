// hbao depth-aware bilinear upsampling of the half-resolution AO: the twin of up_tile in
// cpu.c.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_HBAO_UP_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth;
layout(binding = 1, r32f) uniform readonly image2D half_depth;
layout(binding = 2, r32f) uniform readonly image2D half_ao;
layout(binding = 3, r32f) uniform writeonly image2D ao_out;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  precise float zc = imageLoad(depth, p).x;
  if (!(zc > 0.0)) {
    imageStore(ao_out, p, vec4(1.0));
    return;
  }
  ivec2 h0 = p >> 1;
  ivec2 h1 = min(h0 + (p & 1), ivec2(pc.lw - 1, pc.lh - 1));
  vec2 b1 = vec2((p.x & 1) != 0 ? 0.5 : 0.0, (p.y & 1) != 0 ? 0.5 : 0.0);
  vec2 b0 = vec2((p.x & 1) != 0 ? 0.5 : 1.0, (p.y & 1) != 0 ? 0.5 : 1.0);
  precise float sw = 0.0;
  precise float sa = 0.0;
  for (int c = 0; c < 4; c++) {
    int a = c & 1, b = c >> 1;
    precise float wb = (a != 0 ? b1.x : b0.x) * (b != 0 ? b1.y : b0.y);
    if (!(wb > 0.0)) continue;
    ivec2 q = ivec2(a != 0 ? h1.x : h0.x, b != 0 ? h1.y : h0.y);
    precise float z = imageLoad(half_depth, q).x;
    if (!(z > 0.0)) continue;
    precise float rq = abs(z - zc) / zc;
    if (!(rq < pc.max_rel_dz)) rq = pc.max_rel_dz;
    precise float w = wb / (1.0 + pc.upsample_k * (rq * rq));
    sw += w;
    sa += w * imageLoad(half_ao, q).x;
  }
  precise float v = sw > 0.0 ? sa / sw : 1.0;
  imageStore(ao_out, p, vec4(v > 1.0 ? 1.0 : v > 0.0 ? v : 0.0));
}
