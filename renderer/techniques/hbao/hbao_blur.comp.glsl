// hbao cross-bilateral blur, one direction per dispatch: the twin of blur_tile in
// cpu.c (exp here and libm's expf may differ in the last bits).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_HBAO_BLUR_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth;
layout(binding = 1, r32f) uniform readonly image2D ao_in;
layout(binding = 2, r32f) uniform writeonly image2D ao_out;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  precise float zc = imageLoad(depth, p).x;
  if (!(zc > 0.0)) {
    imageStore(ao_out, p, imageLoad(ao_in, p));
    return;
  }
  ivec2 step = pc.axis != 0 ? ivec2(0, 1) : ivec2(1, 0);
  precise float sw = 0.0;
  precise float sa = 0.0;
  for (int k = -pc.radius; k <= pc.radius; k++) {
    ivec2 q = p + k * step;
    if (q.x < 0 || q.x >= pc.width || q.y < 0 || q.y >= pc.height) continue;
    precise float z = imageLoad(depth, q).x;
    if (!(z > 0.0)) continue;
    precise float rq = abs(z - zc) / zc;
    if (!(rq < pc.max_rel_dz)) rq = pc.max_rel_dz;
    precise float w = exp(-(float(k * k) * pc.falloff + pc.sharpness * (rq * rq)));
    sw += w;
    sa += w * imageLoad(ao_in, q).x;
  }
  precise float v = sa / sw;
  imageStore(ao_out, p, vec4(v > 1.0 ? 1.0 : v > 0.0 ? v : 0.0));
}
