// ibl_shadows fit pass: per G-buffer pixel, the shadow test against every map, b_j = V_j max(0,
// n . w_j), and the coefficients w = Y+ b into four rgba images; the twin of fit_pixel in cpu.c
// (the same float operations in the same order).
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_IBL_FIT
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, rgba32f) uniform readonly image2D normal_img;
layout(binding = 2, rgba32f) uniform writeonly image2D c0_img;
layout(binding = 3, rgba32f) uniform writeonly image2D c1_img;
layout(binding = 4, rgba32f) uniform writeonly image2D c2_img;
layout(binding = 5, rgba32f) uniform writeonly image2D c3_img;
// The shadow maps, one layer each (nearest, read with texelFetch): distances from the maps' plane
// in units of depth_scale (1 for the host's ray-cast maps; the depth range of rasterised ones).
layout(set = 1, binding = 0) uniform sampler2DArray maps_tex;
layout(set = 1, binding = 4, std430) readonly buffer table_buf {
  vec4 dir[OBS_IBL_MAX_MAPS];
  vec4 tax[OBS_IBL_MAX_MAPS];
  vec4 bax[OBS_IBL_MAX_MAPS];
  float yplus[16 * OBS_IBL_MAX_MAPS];
} tb;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float w[16];
  for (int k = 0; k < 16; k++) w[k] = 0.0;
  float z = imageLoad(depth_img, p).r;
  if (z > 0.0) {
    bool ortho = (pc.flags & OBS_IBL_ORTHO) != 0;
    precise float fx = float(p.x) + 0.5;
    precise float fy = float(p.y) + 0.5;
    precise float nx = 2.0 * fx / float(pc.width) - 1.0;
    precise float ny = 1.0 - 2.0 * fy / float(pc.height);
    precise float pv0 = ortho ? nx * pc.half_w : nx * pc.half_w * z;
    precise float pv1 = ortho ? ny * pc.half_h : ny * pc.half_h * z;
    vec3 nv = imageLoad(normal_img, p).xyz;
    precise float q[3];
    precise float nw[3];
    for (int k = 0; k < 3; k++) {
      q[k] = pc.eye[k] + pv0 * pc.right[k] + pv1 * pc.up[k] + z * pc.fwd[k];
      nw[k] = nv.x * pc.right[k] + nv.y * pc.up[k] + nv.z * pc.fwd[k];
    }
    float b[OBS_IBL_MAX_MAPS];
    float S = float(pc.size);
    for (int m = 0; m < pc.maps; m++) {
      vec4 d = tb.dir[m];
      precise float c = nw[0] * d.x + nw[1] * d.y + nw[2] * d.z;
      b[m] = 0.0;
      if (!(c > 0.0)) continue;
      vec4 t = tb.tax[m], bb = tb.bax[m];
      precise float du = q[0] * t.x + q[1] * t.y + q[2] * t.z;
      precise float dv = q[0] * bb.x + q[1] * bb.y + q[2] * bb.z;
      precise float u = (du / pc.radius + 1.0) * 0.5 * S;
      precise float v = (dv / pc.radius + 1.0) * 0.5 * S;
      bool lit = true;
      if (u >= 0.0 && u < S && v >= 0.0 && v < S) {
        precise float occ = texelFetch(maps_tex, ivec3(int(u), int(v), m), 0).r * pc.depth_scale;
        precise float zz = pc.start - (q[0] * d.x + q[1] * d.y + q[2] * d.z);
        precise float slope = c < float(OBS_IBL_MIN_COS) ? float(OBS_IBL_MAX_SLOPE)
                                                         : sqrt(1.0 - c * c) / c;
        precise float thr = occ + pc.texel_bias * (1.0 + slope);
        lit = zz <= thr;
      }
      b[m] = lit ? c : 0.0;
    }
    for (int k = 0; k < pc.coeffs; k++) {
      precise float acc = 0.0;
      for (int m = 0; m < pc.maps; m++) acc += tb.yplus[k * OBS_IBL_MAX_MAPS + m] * b[m];
      w[k] = acc;
    }
  }
  imageStore(c0_img, p, vec4(w[0], w[1], w[2], w[3]));
  imageStore(c1_img, p, vec4(w[4], w[5], w[6], w[7]));
  imageStore(c2_img, p, vec4(w[8], w[9], w[10], w[11]));
  imageStore(c3_img, p, vec4(w[12], w[13], w[14], w[15]));
}
