// ibl_shadows blur pass: one axis of the article's 9 x 9 normal-weighted Gaussian over one image
// of four coefficients; the twin of blur_pixel in cpu.c (same weights, same order).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_IBL_BLUR
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, rgba32f) uniform readonly image2D normal_img;
layout(binding = 2, rgba32f) uniform readonly image2D src_img;
layout(binding = 3, rgba32f) uniform writeonly image2D dst_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  if (!(imageLoad(depth_img, p).r > 0.0)) {
    imageStore(dst_img, p, vec4(0.0));
    return;
  }
  vec3 nc = imageLoad(normal_img, p).xyz;
  precise vec4 acc = vec4(0.0);
  precise float total = 0.0;
  for (int t = -4; t <= 4; t++) {
    ivec2 q = pc.horizontal != 0 ? ivec2(p.x + t, p.y) : ivec2(p.x, p.y + t);
    if (q.x < 0 || q.y < 0 || q.x >= pc.width || q.y >= pc.height) continue;
    if (!(imageLoad(depth_img, q).r > 0.0)) continue;
    vec3 nq = imageLoad(normal_img, q).xyz;
    precise float a = nq.x * nc.x + nq.y * nc.y + nq.z * nc.z;
    precise float wt = pc.weights[t + 4] * (a > 0.0 ? a : 0.0);
    if (!(wt > 0.0)) continue;
    acc += wt * imageLoad(src_img, q);
    total += wt;
  }
  imageStore(dst_img, p, total > 0.0 ? acc / total : vec4(0.0));
}
