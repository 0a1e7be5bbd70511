// G-buffer rasteriser, vertex stage: view-space positions to clip space.
#version 450
// View-space position (x right, y up, z forward, origin at the camera) and the triangle's unit
// face normal, both computed in double on the host (gbuffer_clip.c) and rounded to float once, so
// scenes far from the world origin, at any scale or field of view, keep their precision.
layout(location = 0) in vec3 a_view;
layout(location = 1) in vec3 a_normal;

layout(push_constant) uniform Push {
  vec4 proj;   // half_w, half_h, k, orthographic (1) or perspective (0)
  vec4 albedo; // fragment stage only
} pc;

layout(location = 0) out vec3 v_view;
layout(location = 1) flat out vec3 v_normal;

void main() {
  vec3 p = a_view;
  v_view = p;
  v_normal = a_normal;
  // x_ndc = x / (z half_w), y negated because Vulkan's framebuffer y points down (row 0 = top).
  if (pc.proj.w > 0.5) {
    // Orthographic, reversed depth 1 - z / far (k = 1 / far): z < 0 (behind) and z > far clip.
    gl_Position = vec4(p.x / pc.proj.x, -p.y / pc.proj.y, 1.0 - p.z * pc.proj.z, 1.0);
  } else {
    // Perspective, reversed infinite depth near / z (k = near): only z < near clips, and float
    // depth keeps ~1e-7 relative precision at any distance.
    gl_Position = vec4(p.x / pc.proj.x, -p.y / pc.proj.y, pc.proj.z, p.z);
  }
}
