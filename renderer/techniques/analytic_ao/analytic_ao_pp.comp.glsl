// analytic_ao's push-pull upsampling (the twin of aao_pp_* in cpu.c, operation for operation):
// the evaluated pixels (the half grid and those the bilateral test marked) with weight 1, pushed
// down a pyramid of weighted 2x2 means and pulled back up from the bilinear of the parents; one dispatch
// per level, the levels side by side in one atlas (value in r, weight in g).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_AAO_PP_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, r32f) uniform readonly image2D mask_img;
layout(binding = 2, r32f) uniform readonly image2D low_img;
layout(binding = 3, r32f) uniform image2D ao_img;
layout(binding = 4, rgba32f) uniform image2D atlas_img;

// Level 0 at pixel q: (AO, 1) where evaluated, else (0, 0).
vec2 sample0(ivec2 q) {
  if (!(imageLoad(depth_img, q).r > 0.0)) return vec2(0.0);
  if (imageLoad(mask_img, q).r != 0.0) return vec2(imageLoad(ao_img, q).r, 1.0);
  if ((q.x & 1) == 0 && (q.y & 1) == 0) return vec2(imageLoad(low_img, q >> 1).r, 1.0);
  return vec2(0.0);
}

// The parents' value at child c: bilinear over the 2x2 parents around it (weights 3/4 and 1/4 on
// each axis, clamped at the level's edges).
float parent(ivec2 c) {
  int x = c.x >> 1, y = c.y >> 1;
  int x2 = clamp((c.x & 1) != 0 ? x + 1 : x - 1, 0, pc.sw - 1);
  int y2 = clamp((c.y & 1) != 0 ? y + 1 : y - 1, 0, pc.sh - 1);
  precise float a = 0.75 * imageLoad(atlas_img, ivec2(pc.sx + x, y)).r +
                    0.25 * imageLoad(atlas_img, ivec2(pc.sx + x2, y)).r;
  precise float b = 0.75 * imageLoad(atlas_img, ivec2(pc.sx + x, y2)).r +
                    0.25 * imageLoad(atlas_img, ivec2(pc.sx + x2, y2)).r;
  precise float r = 0.75 * a + 0.25 * b;
  return r;
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (pc.mode == OBS_AAO_PP_PULL0) {
    if (p.x >= pc.width || p.y >= pc.height) return;
    if (!(imageLoad(depth_img, p).r > 0.0)) {
      imageStore(ao_img, p, vec4(1.0));
      return;
    }
    vec2 s = sample0(p);
    float par = parent(p);
    precise float v = s.y * s.x + (1.0 - s.y) * par;
    imageStore(ao_img, p, vec4(v));
    return;
  }
  if (p.x >= pc.dw || p.y >= pc.dh) return;
  ivec2 d = ivec2(pc.dx + p.x, p.y);
  if (pc.mode == OBS_AAO_PP_PULL) {
    vec2 s = imageLoad(atlas_img, d).rg;
    float par = parent(p);
    precise float v = s.y * s.x + (1.0 - s.y) * par;
    imageStore(atlas_img, d, vec4(v, 1.0, 0.0, 0.0));
    return;
  }
  precise float acc = 0.0;
  precise float sum = 0.0;
  for (int s = 0; s < 4; s++) {
    ivec2 c = ivec2(2 * p.x + (s & 1), 2 * p.y + (s >> 1));
    if (c.x >= pc.sw || c.y >= pc.sh) continue;
    vec2 t = pc.mode == OBS_AAO_PP_PUSH0 ? sample0(c)
                                         : imageLoad(atlas_img, ivec2(pc.sx + c.x, c.y)).rg;
    acc += t.y * t.x;
    sum += t.y;
  }
  precise float v = sum > 0.0 ? acc / sum : 1.0;
  precise float w = min(sum, 1.0);
  imageStore(atlas_img, d, vec4(v, w, 0.0, 0.0));
}
