// G-buffer rasteriser, vertex stage: camera-relative world positions to view space and clip space.
#version 450
// World position minus the camera origin, subtracted in double on the host so scenes far from the
// origin keep their precision near the camera.
layout(location = 0) in vec3 a_rel;

layout(push_constant) uniform Push {
  vec4 right, up, forward; // camera axes (xyz)
  vec4 proj;               // half_w, half_h, k, orthographic (1) or perspective (0)
  vec4 albedo;             // fragment stage only
} pc;

layout(location = 0) out vec3 v_view;

void main() {
  vec3 p = vec3(dot(a_rel, pc.right.xyz), dot(a_rel, pc.up.xyz), dot(a_rel, pc.forward.xyz));
  v_view = p;
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
