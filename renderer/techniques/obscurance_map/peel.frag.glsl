// Depth peeling of obscurance_map: the nearest fragment strictly behind the previous layer, as
// (patch id, facing cosine b, window depth, reflectivity index). The patch is the sub-triangle of
// the scene triangle at the fragment's barycentric weights, numbered as the CPU's patch mesh
// (patch_mesh.c, obs_patch_sub_index).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_PEEL_DRAW_PASS
#include "layout.h"

layout(location = 0) in vec2 bary;
layout(location = 1) flat in int first;
layout(location = 2) flat in int split;
layout(location = 3) flat in int robj;
layout(location = 4) flat in float b;

layout(binding = OBS_PEEL_B_LAYER_A, rgba32f) uniform readonly image2D prev;

layout(location = 0) out vec4 layer;

int sub_index(int n, float u, float v) {
  if (n <= 1) return 0;
  float fu = u * float(n), fv = v * float(n);
  int i = fu > 0.0 ? int(fu) : 0, j = fv > 0.0 ? int(fv) : 0;
  i = min(i, n - 1);
  j = min(j, n - 1);
  if (i + j > n - 1) j = n - 1 - i;
  float a = fu - float(i), c = fv - float(j);
  if (a + c > 1.0 && i + j <= n - 2) return n * (n + 1) / 2 + i * (n - 1) - i * (i - 1) / 2 + j;
  return i * n - i * (i - 1) / 2 + j;
}

void main() {
  if (pc.eps >= 0.0) {
    vec4 p = imageLoad(prev, ivec2(gl_FragCoord.xy));
    if (gl_FragCoord.z <= p.z + pc.eps) discard;
  }
  float id = first < 0 ? float(first) : float(first + sub_index(split, bary.x, bary.y));
  layer = vec4(id, b, gl_FragCoord.z, float(robj));
}
