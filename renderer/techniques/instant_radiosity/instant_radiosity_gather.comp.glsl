// instant_radiosity gather pass (Szecsi, ShaderX7 6.6): each pixel sums the VPLs of its class of
// the 4x4 interleaving through the article's clamped form factor; the twin of gather_pixel in
// cpu.c. Every value that feeds a comparison or the output is `precise`, so nothing is contracted
// to FMA or reassociated and the CPU twin repeats it bit for bit.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_IRAD_GATHER
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;     // linear view depth, 0 = none
layout(binding = 1, rgba32f) uniform readonly image2D normal_img; // view-space normal, coverage
layout(binding = 2, rgba32f) uniform writeonly image2D raw_img;   // irradiance rgb, visibility
// The VPLs, OBS_IRAD_VPL_VEC4 vec4 each: view-space position; normal, two-sided flag; coefficient.
layout(set = 1, binding = 4, std430) readonly buffer Vpls { vec4 vpl[]; };

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zp = imageLoad(depth_img, p).r;
  if (!(zp > 0.0) || pc.classes < 1) {
    imageStore(raw_img, p, vec4(0.0, 0.0, 0.0, 1.0));
    return;
  }
  bool ortho = (pc.flags & OBS_IRAD_ORTHO) != 0;
  precise float fx = float(p.x) + 0.5;
  precise float fy = float(p.y) + 0.5;
  precise float ndx = 2.0 * fx / float(pc.width) - 1.0;
  precise float ndy = 1.0 - 2.0 * fy / float(pc.height);
  precise float px = ortho ? ndx * pc.half_w : ndx * pc.half_w * zp;
  precise float py = ortho ? ndy * pc.half_h : ndy * pc.half_h * zp;
  vec3 n = imageLoad(normal_img, p).xyz;
  int cls = ((p.y & 3) * 4 + (p.x & 3)) % pc.classes;
  precise float er = 0.0;
  precise float eg = 0.0;
  precise float eb = 0.0;
  precise float all_l = 0.0;
  precise float kept = 0.0;
  for (int k = pc.start[cls]; k < pc.start[cls + 1]; k++) {
    vec4 r0 = vpl[OBS_IRAD_VPL_VEC4 * k];
    vec4 r1 = vpl[OBS_IRAD_VPL_VEC4 * k + 1];
    vec4 r2 = vpl[OBS_IRAD_VPL_VEC4 * k + 2];
    precise float vx = r0.x - px;
    precise float vy = r0.y - py;
    precise float vz = r0.z - zp;
    precise float d2 = vx * vx + vy * vy + vz * vz;
    precise float nv = n.x * vx + n.y * vy + n.z * vz;
    precise float mv = -(r1.x * vx + r1.y * vy + r1.z * vz);
    if (r1.w > 0.5) mv = abs(mv);
    if (!(nv > 0.0) || !(mv >= 0.0)) continue;
    precise float n2 = mv * mv;
    precise float f;
    if (n2 < pc.nc2) {
      precise float dl2 = d2 - n2 + pc.nc2;
      f = nv / sqrt(d2) * sqrt(pc.nc2 / dl2) / dl2;
    } else {
      f = (nv / d2) * (mv / d2);
    }
    precise float cr = r2.x * f;
    precise float cg = r2.y * f;
    precise float cb = r2.z * f;
    precise float lum = 0.2126 * cr + 0.7152 * cg + 0.0722 * cb;
    all_l += lum;
    er += cr;
    eg += cg;
    eb += cb;
    kept += lum;
  }
  precise float vis = all_l > 0.0 ? kept / all_l : 1.0;
  imageStore(raw_img, p, vec4(er, eg, eb, vis));
}
