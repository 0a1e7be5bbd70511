// Test-only compute shader: the sampling frame (include/frame.glsl) of every normal in image 0,
// t into image 1 and b into image 2, for a comparison of bits with the CPU's obs_onb.
#version 450
#extension GL_GOOGLE_include_directive : require
#include "include/frame.glsl"
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, rgba32f) uniform readonly image2D normals;
layout(binding = 1, rgba32f) uniform writeonly image2D tangents;
layout(binding = 2, rgba32f) uniform writeonly image2D bitangents;
layout(push_constant) uniform Push {
  int width, height;
} pc;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= pc.width || p.y >= pc.height) return;
  vec3 t, b;
  obs_onb(imageLoad(normals, p).xyz, t, b);
  imageStore(tangents, p, vec4(t, 0.0));
  imageStore(bitangents, p, vec4(b, 0.0));
}
