// ssao_variance moments pass: the row part of each pixel's box, (n, sum d, sum d^2, shift) with
// d = z - shift, the twin of moments_tile_body in cpu.c (same taps, same order, `precise`).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SVAR_MOMENTS_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = OBS_SVAR_M_DEPTH, r32f) uniform readonly image2D depth_img;
layout(binding = OBS_SVAR_M_MOMENTS, rgba32f) uniform writeonly image2D moments_img;

float zat(int x, int y) { return imageLoad(depth_img, ivec2(x, y)).r * pc.zscale; }

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  int s = pc.stride, K = pc.taps;
  int m = min(p.x, pc.width - 1 - p.x);
  precise float c = zat(p.x, p.y);
  if (!(c > 0.0)) {
    // uncovered: the nearest covered tap's depth, left before right (cpu.c, shift_of_uncovered)
    c = 0.0;
    for (int j = 1; j <= K; j++) {
      if (j * s > m) break;
      float zl = zat(p.x - j * s, p.y);
      if (zl > 0.0) {
        c = zl;
        break;
      }
      float zr = zat(p.x + j * s, p.y);
      if (zr > 0.0) {
        c = zr;
        break;
      }
    }
  }
  precise float n = 0.0, h1 = 0.0, h2 = 0.0;
  for (int k = -K; k <= K; k++) {
    if (abs(k) * s > m) continue;
    float zt = zat(p.x + k * s, p.y);
    if (zt > 0.0) {
      precise float d = zt - c;
      n += 1.0;
      h1 += d;
      h2 += d * d;
    }
  }
  imageStore(moments_img, p, vec4(n, h1, h2, c));
}
