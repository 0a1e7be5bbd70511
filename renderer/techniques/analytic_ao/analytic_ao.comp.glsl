// analytic_ao's compute pass (Shopf et al., ShaderX7 6.3): the twin of cpu.c, its closed forms
// shared with the rasterised proxies (analytic_ao_closed.inc.glsl, the twin of occluders.c). Each
// 8x8 work group first takes the box of its receivers, and its invocations loop over the
// occluders whose bounding cubes reach that box. Loops with a data-dependent trip count stay
// loops (the host splits the occluders over dispatches so that an invocation stays under
// lavapipe's loop limit, vulkan.c).
#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#define OBS_AAO_AO_PASS
#include "layout.h"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32f) uniform readonly image2D depth_img;     // linear view depth, 0 = none
layout(binding = 1, rgba32f) uniform readonly image2D normal_img; // view-space normal, coverage
layout(binding = 2, r32f) uniform image2D ao_img;                 // the grid's AO
layout(binding = 3, r32f) uniform readonly image2D mask_img;      // EDGES: 1 = evaluate
layout(set = 1, binding = 4, std430) readonly buffer Occluders { vec4 occ[]; };

shared vec3 s_lo[64];
shared vec3 s_hi[64];

#include "analytic_ao_closed.inc.glsl"

void main() {
  // The grid cell (the AO image's texel) and the G-buffer pixel it evaluates.
  ivec2 cell = ivec2(gl_GlobalInvocationID.xy);
  ivec2 grid = imageSize(ao_img);
  ivec2 px = pc.mode == OBS_AAO_MODE_LOW ? 2 * cell : cell;
  uint li = gl_LocalInvocationIndex;
  bool inside = cell.x < grid.x && cell.y < grid.y;
  float z = inside ? imageLoad(depth_img, px).r : 0.0;
  bool evaluated = z > 0.0;
  if (pc.mode == OBS_AAO_MODE_EDGES && inside) evaluated = evaluated && imageLoad(mask_img, px).r != 0.0;
  precise vec3 p = aao_receiver(px, z, pc.width, pc.height, pc.ortho, pc.half_w, pc.half_h);
  // The box of the group's receivers (empty where none is evaluated): min and max are exact.
  const float INF = uintBitsToFloat(0x7f800000u);
  s_lo[li] = evaluated ? p : vec3(INF);
  s_hi[li] = evaluated ? p : vec3(-INF);
  barrier();
  for (uint stride = 32u; stride > 0u; stride >>= 1) {
    if (li < stride) {
      s_lo[li] = min(s_lo[li], s_lo[li + stride]);
      s_hi[li] = max(s_hi[li], s_hi[li + stride]);
    }
    barrier();
  }
  vec3 lo = s_lo[0], hi = s_hi[0];
  vec3 nrm = inside ? imageLoad(normal_img, px).xyz : vec3(0.0);
  precise float ao = pc.accumulate != 0 && evaluated ? imageLoad(ao_img, cell).r : 1.0;
  for (int i = pc.first; i < pc.first + pc.count; i++) {
    int base = OBS_AAO_VEC4S * i;
    vec4 c = occ[base];
    precise vec3 clo = c.xyz - vec3(c.w);
    precise vec3 chi = c.xyz + vec3(c.w);
    // The group's test: uniform across it, so no invocation idles in a divergent branch.
    if (!(all(lessThanEqual(clo, hi)) && all(lessThanEqual(lo, chi)))) continue;
    if (!evaluated) continue;
    if (!(all(lessThanEqual(clo, p)) && all(lessThanEqual(p, chi)))) continue;
    ao *= 1.0 - occlusion(base, p, nrm);
  }
  // EDGES leaves the pixels it does not evaluate as the upsampling wrote them.
  if (inside && (evaluated || pc.mode != OBS_AAO_MODE_EDGES)) imageStore(ao_img, cell, vec4(ao));
}
