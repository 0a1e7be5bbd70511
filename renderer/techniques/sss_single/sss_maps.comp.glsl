// sss_single's light-view maps on Vulkan, one invocation per texel of one light's maps: the
// G-buffer rasterised from the light's camera (orthographic along a directional light,
// perspective from a point light: the projection the CPU casts its texel rays with, sss_maps.c)
// becomes the three maps the walk reads (layout.h): the first surface's position in the ray
// tracer's frame and its object, its outward normal, and the transmitted irradiance E_t of
// Eq. 6.5.4 with Schlick's transmittance (0 on objects without a medium), as fill_tile computes
// them from a ray hit.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_SSS_MAPS_PASS
#include "layout.h"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = OBS_SSS_M_DEPTH, r32f) uniform readonly image2D gdepth;
layout(set = 0, binding = OBS_SSS_M_NORMAL, rgba32f) uniform readonly image2D gnormal;
layout(set = 0, binding = OBS_SSS_M_ALBEDO, rgba32f) uniform readonly image2D galbedo;
layout(set = 0, binding = OBS_SSS_M_POS, rgba32f) uniform writeonly image2D mpos;
layout(set = 0, binding = OBS_SSS_M_NRM, rgba32f) uniform writeonly image2D mnrm;
layout(set = 0, binding = OBS_SSS_M_IRR, rgba32f) uniform writeonly image2D mirr;
layout(set = 1, binding = 4, std430) readonly buffer Table { vec4 rows[]; };

#include "sss_fresnel.inc.glsl"

void main() {
  ivec2 q = ivec2(gl_GlobalInvocationID.xy);
  if (q.x >= pc.size || q.y >= pc.size) return;
  int lr = pc.nobjects * OBS_SSS_OBJ_ROWS + pc.light * OBS_SSS_LIGHT_ROWS;
  vec4 p0 = rows[lr], p1 = rows[lr + 1], cb = rows[lr + 3];
  vec3 power = rows[lr + 2].xyz, right = rows[lr + 4].xyz, up = rows[lr + 5].xyz;
  vec3 fwd = rows[lr + 6].xyz;
  float z = imageLoad(gdepth, q).x;
  int id = int(imageLoad(galbedo, q).w + 0.5) - 1;
  vec4 pos = vec4(0.0, 0.0, 0.0, -1.0), nrm = vec4(0.0), irr = vec4(0.0);
  if (z > 0.0 && id >= 0) {
    // the texel centre's offsets in the map's plane, as fill_tile's u and v
    float half_ = p1.w;
    float u = ((float(q.x) + 0.5) / float(pc.size) * 2.0 - 1.0) * half_;
    float v = ((float(q.y) + 0.5) / float(pc.size) * 2.0 - 1.0) * half_;
    vec3 x, dir;
    if (p0.w > 0.5) {
      vec3 ray = fwd + u * right + v * up; // linear depth z along fwd: the point is z * ray
      x = p0.xyz + z * ray;
      dir = normalize(ray);
    } else {
      x = cb.xyz + (z - cb.w) * fwd + u * right + v * up;
      dir = fwd;
    }
    // the G-buffer's axes are (right, -up, fwd): its rows run down, the maps' up
    vec3 nv = imageLoad(gnormal, q).xyz;
    vec3 n = normalize(nv.x * right - nv.y * up + nv.z * fwd);
    pos = vec4(x, float(id));
    nrm = vec4(n, 0.0);
    int orow = id * OBS_SSS_OBJ_ROWS;
    float c = -dot(dir, n);
    if (rows[orow].w > 0.5 && c > 0.0) {
      float e = 1.0;
      if (p0.w > 0.5) {
        vec3 d = x - p0.xyz;
        e = 1.0 / dot(d, d);
      }
      irr = vec4(power * (e * schlick_t(c, rows[orow + 2].y) * c), 0.0);
    }
  }
  imageStore(mpos, q, pos);
  imageStore(mnrm, q, nrm);
  imageStore(mirr, q, irr);
}
