// Test-only compute shader: image1 = image0 * factor, exercising bindings and push constants.
#version 450
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, rgba32f) uniform readonly image2D src;
layout(binding = 1, rgba32f) uniform writeonly image2D dst;
layout(push_constant) uniform Push {
  float factor;
  int width, height;
} pc;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  // Groups round the size up; the extra invocations must not write outside the image.
  if (p.x >= pc.width || p.y >= pc.height) return;
  imageStore(dst, p, imageLoad(src, p) * pc.factor);
}
