// analytic_ao's proxies (Shopf et al., ShaderX7 6.3): at each G-buffer pixel its occluder's cube
// covers, that occluder's closed form (analytic_ao_closed.inc.glsl, as the compute pass evaluates
// it) behind the same bounding-cube test, written as 1 - occlusion; the blend multiplies it into
// the target cleared to 1, in instance order, which is the compute pass's order.
#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#define OBS_AAO_RASTER_PASS
#include "layout.h"
layout(binding = OBS_AAO_RB_DEPTH, r32f) uniform readonly image2D depth_img;
layout(binding = OBS_AAO_RB_NORMAL, rgba32f) uniform readonly image2D normal_img;
layout(binding = OBS_AAO_RB_OCC, std430) readonly buffer Occluders { vec4 occ[]; };
layout(location = 0) flat in int f_occ;
layout(location = 0) out vec4 o;

#include "analytic_ao_closed.inc.glsl"

void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  float z = imageLoad(depth_img, px).r;
  o = vec4(1.0);
  if (!(z > 0.0)) return;
  precise vec3 p = aao_receiver(px, z, pc.width, pc.height, pc.ortho, pc.half_w, pc.half_h);
  int base = OBS_AAO_VEC4S * f_occ;
  vec4 c = occ[base];
  precise vec3 clo = c.xyz - vec3(c.w);
  precise vec3 chi = c.xyz + vec3(c.w);
  if (!(all(lessThanEqual(clo, p)) && all(lessThanEqual(p, chi)))) return;
  vec3 nrm = imageLoad(normal_img, px).xyz;
  precise float r = 1.0 - occlusion(base, p, nrm);
  o = vec4(r);
}
