// ss_obscurance's obscurance pass (Toth, Szirmay-Kalos and Umenhoffer, ShaderX7 3.1): the twin of
// obs_sso_pixel in sso_pixel.h. Every value that feeds a comparison or the output is `precise`,
// so nothing is contracted to FMA or reassociated and the CPU twin repeats it bit for bit;
// fetches are texel-snapped imageLoads.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SSO_SHADER_AO
#include "layout.h"
#include "../../vulkan/shaders/include/frame.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = OBS_SSO_B_DEPTH, r32f) uniform readonly image2D depth_img;     // 0 = none
layout(binding = OBS_SSO_B_NORMAL, rgba32f) uniform readonly image2D normal_img; // view space
layout(binding = OBS_SSO_B_OFFSETS, rgba32f) uniform readonly image2D offset_img;
layout(binding = OBS_SSO_B_RAW, r32f) uniform writeonly image2D raw_img;

// floor(v) clamped to [0, n - 1], NaN to 0 (obs_sso_texel)
int texel(float v, int n) {
  precise float f = floor(v);
  f = f > 0.0 ? f : 0.0;
  f = f < float(n - 1) ? f : float(n - 1);
  return int(f);
}

// obs_sso_position
vec3 position(ivec2 q, float z) {
  precise float fx = float(q.x) + 0.5;
  precise float fy = float(q.y) + 0.5;
  precise float nx = fx * pc.two_inv_w - 1.0;
  precise float ny = 1.0 - fy * pc.two_inv_h;
  precise vec3 r;
  if ((pc.flags & OBS_SSO_FLAG_ORTHO) != 0) {
    r.x = nx * pc.half_w;
    r.y = ny * pc.half_h;
  } else {
    r.x = nx * pc.half_w * z;
    r.y = ny * pc.half_h * z;
  }
  r.z = z;
  return r;
}

void main() {
  ivec2 px = ivec2(gl_GlobalInvocationID.xy);
  if (px.x >= pc.width || px.y >= pc.height) return;
  float zp = imageLoad(depth_img, px).r;
  if (!(zp > 0.0)) {
    imageStore(raw_img, px, vec4(1.0));
    return;
  }
  bool ortho = (pc.flags & OBS_SSO_FLAG_ORTHO) != 0;
  vec3 p = position(px, zp);
  vec3 n = imageLoad(normal_img, px).xyz;
  vec3 t, b;
  obs_onb(n, t, b); // Duff et al.: the listing's T = N x (0, 1, 0) vanishes for N = +-y
  float R = pc.radius;
  precise vec3 tr = t * R;
  precise vec3 br = b * R;
  precise vec3 nr = n * R;
  int cell = (pc.flags & OBS_SSO_FLAG_INTERLEAVE) != 0 ? ((px.y & 3) << 2) | (px.x & 3) : 0;
  precise float hw = 0.5 * float(pc.width);
  precise float hh = 0.5 * float(pc.height);
  precise float closed = 0.0;
  for (int k = 0; k < pc.samples; k++) {
    vec4 o = imageLoad(offset_img, ivec2(k, cell));
    precise float sx = p.x + (o.x * tr.x + o.y * br.x + o.z * nr.x);
    precise float sy = p.y + (o.x * tr.y + o.y * br.y + o.z * nr.y);
    precise float sz = p.z + (o.x * tr.z + o.y * br.z + o.z * nr.z);
    precise float u, v;
    if (ortho) {
      u = sx * pc.inv_half_w;
      v = sy * pc.inv_half_h;
    } else {
      if (!(sz > 0.0)) continue; // behind the eye
      precise float rz = 1.0 / sz;
      u = sx * rz * pc.inv_half_w;
      v = sy * rz * pc.inv_half_h;
    }
    ivec2 q = ivec2(texel((u + 1.0) * hw, pc.width), texel((1.0 - v) * hh, pc.height));
    float zq = imageLoad(depth_img, q).r;
    if (!(zq > 0.0)) continue;          // background: free space
    precise float behind = sz - zq;
    if (behind > R) continue;           // more than R behind the stored surface
    vec3 s = position(q, zq);
    vec3 m = imageLoad(normal_img, q).xyz;
    precise float d = (sx - s.x) * m.x + (sy - s.y) * m.y + (sz - s.z) * m.z;
    precise float slack = float(OBS_SSO_SLACK) * (abs(s.x) + abs(s.y) + zq + R);
    if (d < -slack) closed += o.w;
  }
  float inv = imageLoad(offset_img, ivec2(pc.samples, cell)).x;
  precise float a = 1.0 - closed * inv;
  imageStore(raw_img, px, vec4(a < 0.0 ? 0.0 : a));
}
