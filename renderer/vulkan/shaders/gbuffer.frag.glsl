// G-buffer rasteriser, fragment stage: linear view depth, camera-facing face normal, albedo.
#version 450
layout(location = 0) in vec3 v_view;

layout(push_constant) uniform Push {
  vec4 right, up, forward;
  vec4 proj; // w: orthographic (1) or perspective (0)
  vec4 albedo;
} pc;

layout(location = 0) out float o_depth;
layout(location = 1) out vec4 o_normal; // xyz + coverage
layout(location = 2) out vec4 o_albedo;

void main() {
  // Differences of positions on the triangle's plane lie in that plane, so their cross product is
  // the face normal even though perspective makes v_view non-linear in screen space.
  // Each factor and the product are divided by their largest component first, so neither the
  // cross product nor the length's squares over- or underflow at any scene scale.
  vec3 a = dFdxFine(v_view), b = dFdyFine(v_view);
  float ma = max(max(abs(a.x), abs(a.y)), abs(a.z)), mb = max(max(abs(b.x), abs(b.y)), abs(b.z));
  vec3 c = ma > 0.0 && mb > 0.0 ? cross(a / ma, b / mb) : vec3(0.0);
  float mc = max(max(abs(c.x), abs(c.y)), abs(c.z));
  vec3 n = mc > 0.0 ? normalize(c / mc) : vec3(0.0, 0.0, -1.0);
  // Face the camera: against the ray through this pixel (the view axis when orthographic).
  vec3 ray = pc.proj.w > 0.5 ? vec3(0.0, 0.0, 1.0) : v_view;
  if (dot(n, ray) > 0.0) n = -n;
  o_depth = v_view.z;
  o_normal = vec4(n, 1.0);
  o_albedo = vec4(pc.albedo.rgb, 0.0);
}
