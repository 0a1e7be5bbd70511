// hbao half-resolution input: the top-left texel of each 2x2 of the G-buffer's depth and normal.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_HBAO_DOWN_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth;
layout(binding = 1, rgba32f) uniform readonly image2D normal;
layout(binding = 2, r32f) uniform writeonly image2D half_depth;
layout(binding = 3, rgba32f) uniform writeonly image2D half_normal;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.lw || p.y >= pc.lh) return;
  // Not the minimum depth: depth and normal must stay those of one real surface point.
  imageStore(half_depth, p, imageLoad(depth, 2 * p));
  imageStore(half_normal, p, imageLoad(normal, 2 * p));
}
