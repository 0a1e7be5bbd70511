// G-buffer rasteriser, fragment stage: linear view depth, camera-facing face normal, albedo and
// the object's index + 1 (in the albedo target's alpha).
#version 450
layout(location = 0) in vec3 v_view;
// The triangle's unit face normal, computed on the host in double (screen-space derivatives of
// float positions lose it at tiny fields of view and over- or underflow at extreme scales).
layout(location = 1) flat in vec3 v_normal;

layout(push_constant) uniform Push {
  vec4 proj; // w: orthographic (1) or perspective (0)
  vec4 albedo; // rgb; a: the object's index + 1
} pc;

layout(location = 0) out float o_depth;
layout(location = 1) out vec4 o_normal; // xyz + coverage
layout(location = 2) out vec4 o_albedo;

void main() {
  vec3 n = v_normal;
  // A triangle degenerate in double covers no pixel; keep the output a unit vector regardless.
  if (!(dot(n, n) > 0.5)) n = vec3(0.0, 0.0, -1.0);
  // Face the camera: against the ray through this pixel (the view axis when orthographic).
  vec3 ray = pc.proj.w > 0.5 ? vec3(0.0, 0.0, 1.0) : v_view;
  if (dot(n, ray) > 0.0) n = -n;
  o_depth = v_view.z;
  o_normal = vec4(n, 1.0);
  o_albedo = pc.albedo;
}
