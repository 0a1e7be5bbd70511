// Depth peeling of obscurance_map: the transfers between two consecutive layers A (nearer) and B
// of one bundle direction, accumulated per patch in 64-bit fixed point (two 32-bit words with an
// explicit carry: integer sums do not depend on the order the atomics land in, so a map has the
// same bits on every run). Layers are (patch id, b, window depth, reflectivity index); id -1 is
// background (the virtual layers before the first and after the last), -2 a surface without
// patches. b is the cosine of the front normal with the direction towards the viewer.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_PEEL_TRANSFER_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = OBS_PEEL_B_LAYER_A, rgba32f) uniform readonly image2D la;
layout(binding = OBS_PEEL_B_LAYER_B, rgba32f) uniform readonly image2D lb;
// Per patch OBS_PEEL_ACC_WORDS words (layout.h).
layout(std430, binding = OBS_PEEL_B_ACC) buffer Acc { uint acc[]; };
layout(std430, binding = OBS_PEEL_B_REFL) readonly buffer Refl { vec4 refl[]; };
layout(std430, binding = OBS_PEEL_B_COVERED) buffer Count { uint covered[]; }; // per layer

void add64(uint at, uint x) {
  uint old = atomicAdd(acc[at], x);
  if (old + x < old) atomicAdd(acc[at + 1u], 1u);
}

void add_bg(int pid) {
  uint base = uint(pid) * uint(OBS_PEEL_ACC_WORDS);
  for (int c = 0; c < 3; c++) {
    add64(base + uint(OBS_PEEL_ACC_SUM + 2 * c), pc.bg_s[c]);
    add64(base + uint(OBS_PEEL_ACC_SQ + 2 * c), pc.bg_q[c]);
  }
  add64(base + uint(OBS_PEEL_ACC_SAMPLES), 1u);
}

// Patch `pid` sees a surface of reflectivity index `r` at window distance d.
void add_seen(int pid, float d, int r) {
  if (!(d < pc.dmax)) {
    add_bg(pid);
    return;
  }
  float rho = pc.falloff == 0 ? 0.0 : pc.falloff == 1 ? sqrt(d / pc.dmax) : 1.0 - exp(-pc.tau * d);
  vec3 v = pc.bleed != 0 ? rho * refl[r].rgb : vec3(rho);
  uint base = uint(pid) * uint(OBS_PEEL_ACC_WORDS);
  for (int c = 0; c < 3; c++) {
    add64(base + uint(OBS_PEEL_ACC_SUM + 2 * c), uint(v[c] * OBS_PEEL_FIXED_ONE + 0.5));
    add64(base + uint(OBS_PEEL_ACC_SQ + 2 * c), uint(v[c] * v[c] * OBS_PEEL_FIXED_ONE + 0.5));
  }
  add64(base + uint(OBS_PEEL_ACC_SAMPLES), 1u);
}

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= pc.res || px.y >= pc.res) return;
  vec4 a = imageLoad(la, px), b = imageLoad(lb, px);
  bool ha = a.x != -1.0, hb = b.x != -1.0;
  if (hb) atomicAdd(covered[pc.layer], 1u);
  int ia = int(a.x), ib = int(b.x);
  if (ha && hb) {
    // Pass 0 and pass 1 of the article at once: A faces away from the viewer (towards B) and B
    // faces the viewer (towards A); any other pair does not face and records nothing.
    if (a.y < 0.0 && b.y > 0.0) {
      float d = b.z - a.z;
      if (ia >= 0) add_seen(ia, d, int(b.w));
      if (ib >= 0) add_seen(ib, d, int(a.w));
    }
  } else if (ha) {
    if (a.y < 0.0 && ia >= 0) add_bg(ia); // the last layer, facing away: nothing behind it
  } else if (hb) {
    if (b.y > 0.0 && ib >= 0) add_bg(ib); // the first layer, facing the viewer: nothing in front
  }
}
