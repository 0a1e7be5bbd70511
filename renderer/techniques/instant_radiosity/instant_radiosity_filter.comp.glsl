// instant_radiosity filter pass: the geometry-aware 4x4 box over the interleaved image, each VPL
// class taken once from the window or, where rejected, from the extended neighbourhood (the
// article's adaptive filter); the twin of filter_pixel in cpu.c (same candidates, same order, same
// reciprocal table).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_IRAD_FILTER
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, rgba32f) uniform readonly image2D normal_img;
layout(binding = 2, rgba32f) uniform readonly image2D raw_img;
layout(binding = 3, rgba32f) uniform writeonly image2D out_img;

// The gather's view-space reconstruction of pixel q at depth z.
vec3 view_pos(ivec2 q, float z) {
  bool ortho = (pc.flags & OBS_IRAD_ORTHO) != 0;
  precise float fx = float(q.x) + 0.5;
  precise float fy = float(q.y) + 0.5;
  precise float ndx = 2.0 * fx / float(pc.width) - 1.0;
  precise float ndy = 1.0 - 2.0 * fy / float(pc.height);
  precise float px = ortho ? ndx * pc.half_w : ndx * pc.half_w * z;
  precise float py = ortho ? ndy * pc.half_h : ndy * pc.half_h * z;
  return vec3(px, py, z);
}

// Whether pixel q may join the filter of the centre at view-space position c, normal nc: near the
// centre's tangent plane and facing the same way.
bool filter_ok(ivec2 q, vec3 c, vec3 nc) {
  if (q.x < 0 || q.y < 0 || q.x >= pc.width || q.y >= pc.height) return false;
  float zq = imageLoad(depth_img, q).r;
  if (!(zq > 0.0)) return false;
  vec3 nq = imageLoad(normal_img, q).xyz;
  vec3 pq = view_pos(q, zq);
  precise float ex = pq.x - c.x;
  precise float ey = pq.y - c.y;
  precise float ez = pq.z - c.z;
  precise float dp = abs(nc.x * ex + nc.y * ey + nc.z * ez);
  precise float dn = nq.x * nc.x + nq.y * nc.y + nq.z * nc.z;
  precise float lim = pc.depth_tol * c.z;
  return dp <= lim && dn >= pc.normal_min;
}

int alt(int o) { return o < 0 ? o + 4 : o - 4; }

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zc = imageLoad(depth_img, p).r;
  if (!(zc > 0.0)) {
    imageStore(out_img, p, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  vec3 nc = imageLoad(normal_img, p).xyz;
  vec3 cp = view_pos(p, zc);
  precise vec4 s = vec4(0.0);
  int cnt = 0;
  for (int dy = OBS_IRAD_FILTER_LO; dy < OBS_IRAD_FILTER_LO + 4; dy++)
    for (int dx = OBS_IRAD_FILTER_LO; dx < OBS_IRAD_FILTER_LO + 4; dx++) {
      ivec2 cand[4] = ivec2[4](ivec2(dx, dy), ivec2(alt(dx), dy), ivec2(dx, alt(dy)),
                               ivec2(alt(dx), alt(dy)));
      for (int c = 0; c < 4; c++) {
        ivec2 q = p + cand[c];
        if (!filter_ok(q, cp, nc)) continue;
        s += imageLoad(raw_img, q);
        cnt++;
        break;
      }
    }
  precise vec4 r = s * pc.inv_count[cnt];
  imageStore(out_img, p, r);
}
