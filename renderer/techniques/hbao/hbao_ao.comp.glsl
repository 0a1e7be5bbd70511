// hbao horizon search, one AO texel per invocation: the twin of ao_texel in cpu.c,
// written operation for operation in the same order; `precise` stops FMA contraction so the bits
// match the C code's.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_HBAO_AO_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_l;
layout(binding = 1, rgba32f) uniform readonly image2D normal_l;
layout(binding = 2, rgba32f) uniform readonly image2D dirs; // directions x 16: (dx, dy, jitter, 0)
layout(binding = 3, r32f) uniform writeonly image2D ao_out;

// obs_gbuffer_position (renderer/core/gbuffer.h).
vec3 position(float fx, float fy, float z) {
  precise float nx = 2.0 * fx / float(pc.width) - 1.0;
  precise float ny = 1.0 - 2.0 * fy / float(pc.height);
  precise vec3 o;
  if (pc.ortho != 0) {
    o.x = nx * pc.half_w;
    o.y = ny * pc.half_h;
  } else {
    o.x = nx * pc.half_w * z;
    o.y = ny * pc.half_h * z;
  }
  o.z = z;
  return o;
}

// Elevation (sin, cos) of the tangent line along view-space direction (dx, dy); see tangent() in
// cpu.c.
vec2 tangent(vec3 n, vec3 r, float nr, float dx, float dy) {
  precise float nd = n.x * dx + n.y * dy;
  precise float lx = nd * r.x - nr * dx;
  precise float ly = nd * r.y - nr * dy;
  precise float lz = nd;
  if (!(nr < 0.0)) {
    lx = -lx;
    ly = -ly;
    lz = -lz;
  }
  precise float h2 = lx * lx + ly * ly;
  precise float l = sqrt(h2 + lz * lz);
  if (!(l > 0.0)) return vec2(0.0, 1.0);
  precise float st = -lz / l;
  precise float ct = sqrt(h2) / l;
  return vec2(st, ct);
}

float ao_texel(ivec2 a) {
  precise float z = imageLoad(depth_l, a).x;
  if (!(z > 0.0)) return 1.0;
  precise float R = pc.radius;
  if (!(R > 0.0)) return 1.0;
  precise float fx = float(pc.s * a.x) + 0.5;
  precise float fy = float(pc.s * a.y) + 0.5;
  precise vec3 P = position(fx, fy, z);
  precise vec3 r = vec3(0.0, 0.0, 1.0);
  if (pc.ortho == 0) {
    r.x = (2.0 * fx / float(pc.width) - 1.0) * pc.half_w;
    r.y = (1.0 - 2.0 * fy / float(pc.height)) * pc.half_h;
  }
  precise float num = R * (0.5 * float(pc.width));
  precise float rpx = pc.ortho != 0 ? num / pc.half_w : num / (pc.half_w * z);
  precise float rl = rpx / float(pc.s);
  if (!(rl >= 1.0)) return 1.0;
  precise float cap = float(max(pc.lw, pc.lh));
  if (rl > cap) rl = cap;
  precise float st = rl / float(pc.steps + 1);
  precise vec3 n = imageLoad(normal_l, a).xyz;
  precise float nr = n.x * r.x + n.y * r.y + n.z * r.z;
  int cell = (a.y & 3) * 4 + (a.x & 3);
  precise float cx = float(a.x) + 0.5;
  precise float cy = float(a.y) + 0.5;
  // pow2_scale in cpu.c: 2^-e and 2^e for the binary exponent e of z.
  uint be = clamp((floatBitsToUint(z) >> 23) & 0xffu, 1u, 253u);
  precise float down = uintBitsToFloat((254u - be) << 23);
  precise float rscale = uintBitsToFloat(be << 23) * pc.inv_r;
  precise float sum = 0.0;
  for (int i = 0; i < pc.directions; i++) {
    precise vec4 d = imageLoad(dirs, ivec2(i, cell));
    precise vec2 t = tangent(n, r, nr, d.x, -d.y);
    precise float sin_t = t.x;
    precise float cos_t = t.y;
    precise float c = cos_t * pc.cos_b - sin_t * pc.sin_b;
    if (!(c > 0.0)) continue;
    precise float sin_h = sin_t * pc.cos_b + cos_t * pc.sin_b;
    for (int k = 1; k <= pc.steps; k++) {
      precise float o = (float(k) + d.z) * st;
      precise float sx = cx + o * d.x;
      precise float sy = cy + o * d.y;
      int ix = clamp(int(floor(sx)), 0, pc.lw - 1);
      int iy = clamp(int(floor(sy)), 0, pc.lh - 1);
      if (ix == a.x && iy == a.y) continue;
      precise float zs = imageLoad(depth_l, ivec2(ix, iy)).x;
      if (!(zs > 0.0)) continue;
      precise vec3 S = position(float(pc.s * ix) + 0.5, float(pc.s * iy) + 0.5, zs);
      // Moved away by the depths' uncertainty, scaled by the pixel's power of two (see ao_texel).
      precise float dx = S.x - P.x;
      precise float dy = S.y - P.y;
      precise float dz = (S.z - P.z) + pc.depth_eps * (zs + z);
      precise float qx = dx * down;
      precise float qy = dy * down;
      precise float qz = dz * down;
      precise float len = sqrt(qx * qx + qy * qy + qz * qz);
      if (!(len > 0.0)) continue;
      precise float dist = len * rscale;
      if (!(dist < 1.0)) continue;
      precise float d2 = dist * dist;
      precise float sin_s = -qz / len;
      precise vec2 ts = tangent(n, r, nr, float(ix - a.x), -float(iy - a.y));
      precise float e = sin_s - ts.x + sin_t;
      if (e > 1.0) e = 1.0;
      if (e > sin_h) {
        sum += (1.0 - d2) * (e - sin_h);
        sin_h = e;
      }
    }
  }
  precise float ao = 1.0 - pc.scale * sum / float(pc.directions);
  return ao > 1.0 ? 1.0 : ao > 0.0 ? ao : 0.0;
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.lw || p.y >= pc.lh) return;
  imageStore(ao_out, p, vec4(ao_texel(p), 0.0, 0.0, 0.0));
}
