// analytic_ao's bilateral upsampling (the twin of aao_up_tile in cpu.c, operation for operation):
// each pixel averages the up to four half-resolution cells around it, weighted bilinearly, by the
// agreement of normals (cos^8) and of depths; a pixel no cell agrees with is marked for the AO
// pass to evaluate at full resolution.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_AAO_UP_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;
layout(binding = 1, rgba32f) uniform readonly image2D normal_img;
layout(binding = 2, r32f) uniform readonly image2D low_img;
layout(binding = 3, r32f) uniform writeonly image2D ao_img;
layout(binding = 4, r32f) uniform writeonly image2D mask_img;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  float zp = imageLoad(depth_img, p).r;
  if (!(zp > 0.0)) {
    imageStore(ao_img, p, vec4(1.0));
    imageStore(mask_img, p, vec4(0.0));
    return;
  }
  vec3 np = imageLoad(normal_img, p).xyz;
  precise float acc = 0.0;
  precise float sum = 0.0;
  for (int s = 0; s < 4; s++) {
    int cx = (p.x >> 1) + (s & 1), cy = (p.y >> 1) + (s >> 1);
    if (((s & 1) != 0 && (p.x & 1) == 0) || ((s >> 1) != 0 && (p.y & 1) == 0) || cx >= pc.lw ||
        cy >= pc.lh)
      continue;
    precise float b = ((p.x & 1) != 0 ? 0.5 : 1.0) * ((p.y & 1) != 0 ? 0.5 : 1.0);
    ivec2 q = ivec2(2 * cx, 2 * cy);
    float zs = imageLoad(depth_img, q).r;
    if (!(zs > 0.0)) continue;
    vec3 ns = imageLoad(normal_img, q).xyz;
    precise float dn = ns.x * np.x + ns.y * np.y + ns.z * np.z;
    if (!(dn > 0.0)) continue;
    precise float dn2 = dn * dn;
    precise float dn4 = dn2 * dn2;
    precise float dz = abs(zs - zp) / zp;
    if (!(dz < pc.depth_limit)) continue;
    precise float w = b * (dn4 * dn4) * (1.0 - dz / pc.depth_limit);
    acc += w * imageLoad(low_img, ivec2(cx, cy)).r;
    sum += w;
  }
  bool filled = sum > 0.0;
  precise float ao = filled ? acc / sum : 1.0;
  imageStore(ao_img, p, vec4(ao));
  imageStore(mask_img, p, vec4(filled ? 0.0 : 1.0));
}
