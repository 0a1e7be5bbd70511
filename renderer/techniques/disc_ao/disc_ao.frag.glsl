// disc_ao's occlusion of one receiver by one disc: the twin of obs_disc_occlusion (disc_ao.h),
// the same expression in the same order, `precise` so nothing is contracted or reassociated. The
// additive blend sums it (red) and counts the fragments (green).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "layout.h"
layout(binding = OBS_DISC_B_DEPTH, r32f) uniform readonly image2D depth_img;
layout(binding = OBS_DISC_B_NORMAL, rgba32f) uniform readonly image2D normal_img;
layout(location = 0) flat in vec4 f_c; // centroid, area in the form factor
layout(location = 1) flat in vec4 f_n; // unit normal, squared reach
layout(location = 0) out vec4 o;

float occlusion(ivec2 px, float z) {
  precise float fx = float(px.x) + 0.5;
  precise float fy = float(px.y) + 0.5;
  precise float nx = 2.0 * fx / float(pc.width) - 1.0;
  precise float ny = 1.0 - 2.0 * fy / float(pc.height);
  precise vec3 p;
  if ((pc.flags & OBS_DISC_FLAG_ORTHO) != 0)
    p = vec3(nx * pc.half_w, ny * pc.half_h, z);
  else
    p = vec3(nx * pc.half_w * z, ny * pc.half_h * z, z);
  vec3 nr = imageLoad(normal_img, px).xyz;
  precise float vx = f_c.x - p.x;
  precise float vy = f_c.y - p.y;
  precise float vz = f_c.z - p.z;
  precise float d2 = vx * vx + vy * vy + vz * vz;
  if (!(d2 > 0.0) || d2 > f_n.w) return 0.0;
  precise float len = sqrt(d2);
  precise float ce = (f_n.x * vx + f_n.y * vy + f_n.z * vz) / len;
  if ((pc.flags & OBS_DISC_FLAG_BACK) == 0) ce = -ce;
  precise float cr = 4.0 * ((nr.x * vx + nr.y * vy + nr.z * vz) / len);
  if (!(ce > 0.0) || !(cr > 0.0)) return 0.0;
  precise float x = f_c.w / d2;
  precise float s = sqrt(x + 1.0);
  precise float ff = x / (s * (s + 1.0));
  return ff * min(ce, 1.0) * min(cr, 1.0);
}

void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  float z = imageLoad(depth_img, px).r;
  o = vec4(z > 0.0 ? occlusion(px, z) : 0.0, 1.0, 0.0, 0.0);
}
