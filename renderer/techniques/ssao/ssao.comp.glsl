// ssao AO pass (Kajalin, ShaderX7 6.1): the twin of ssao_pixel in cpu.c.
// Every value that feeds a comparison or the output is `precise`, so nothing is contracted to FMA
// or reassociated and the CPU twin can repeat it bit for bit; fetches are texel-snapped imageLoads.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SSAO_AO_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;     // linear view depth, 0 = none
layout(binding = 1, rgba32f) uniform readonly image2D normal_img; // view-space normal, coverage
layout(binding = 2, rgba32f) uniform readonly image2D rot_img;    // 4x4 unit reflection normals
layout(binding = 3, rgba32f) uniform readonly image2D offset_img; // samples x 1 offsets
layout(binding = 4, r32f) uniform writeonly image2D raw_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zp = imageLoad(depth_img, p).r;
  if (!(zp > 0.0)) {
    imageStore(raw_img, p, vec4(1.0));
    return;
  }
  vec3 rot = imageLoad(rot_img, ivec2(p.x & 3, p.y & 3)).xyz;
  vec3 n = imageLoad(normal_img, p).xyz;
  precise float fx = float(p.x) + 0.5;
  precise float fy = float(p.y) + 0.5;
  float fw = float(pc.width), fh = float(pc.height);
  float s = (pc.flags & OBS_SSAO_FLAG_ORTHO) != 0 ? 1.0 : zp;
  precise float kx = 2.0 * pc.half_w * s;
  precise float ky = -2.0 * pc.half_h * s;
  precise float kz = 2.0 * zp;
  precise float sum = 0.0;
  for (int k = 0; k < pc.samples; k++) {
    vec3 v = imageLoad(offset_img, ivec2(k, 0)).xyz;
    // reflect(v, rot), spelt out so its evaluation order is ours, not the compiler's
    precise float d = rot.x * v.x + rot.y * v.y + rot.z * v.z;
    precise float tt = 2.0 * d;
    precise float ox = v.x - tt * rot.x;
    precise float oy = v.y - tt * rot.y;
    precise float oz = v.z - tt * rot.z;
    if ((pc.flags & OBS_SSAO_FLAG_NORMAL_ORIENTED) != 0) {
      precise float dn = ox * kx * n.x + oy * ky * n.y + oz * kz * n.z;
      if (dn < 0.0) {
        ox = -ox;
        oy = -oy;
        oz = -oz;
      }
    }
    // clamp before the conversion: huge offsets must not overflow int
    precise float sxf = clamp(floor(fx + ox * fw), 0.0, float(pc.width - 1));
    precise float syf = clamp(floor(fy + oy * fh), 0.0, float(pc.height - 1));
    float zs = imageLoad(depth_img, ivec2(int(sxf), int(syf))).r;
    if (!(zs > 0.0)) {
      sum += 1.0; // background: infinitely far, so free space with a valid range
      continue;
    }
    precise float sz = zp + oz * zp * 2.0;
    precise float vis = zs > sz ? 1.0 : 0.0;
    precise float f = clamp((zp - zs) / zs, 0.0, 1.0);
    sum += vis + f * (0.5 - vis);
  }
  precise float a = sum * pc.inv_samples;
  precise float c = clamp(a * a + a, 0.0, 1.0);
  imageStore(raw_img, p, vec4(c));
}
