// analytic_ao's proxies (Shopf et al., ShaderX7 6.3): one instance per occluder, 36 vertices per
// instance, the faces of its bounding cube (obs_aao_in_bound, enlarged by the margin of layout.h)
// of which only those facing away from the camera are kept; the others collapse to a point. A
// ray from the camera through a receiver inside the cube leaves it through such a face beyond the
// receiver, so every receiver inside is covered once, the camera inside the cube included. An
// unbounded occluder, or one whose cube holds the camera, is a full-screen triangle instead.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_AAO_RASTER_PASS
#include "layout.h"
layout(binding = OBS_AAO_RB_OCC, std430) readonly buffer Occluders { vec4 occ[]; };
layout(location = 0) flat out int f_occ;

// View space (gbuffer.h: x right, y up, z forward) to clip space. The near plane sits a hair in
// front of the camera (near, relative to the cube's depth), so no clipped vertex has w = 0.
vec4 clip(vec3 q, float near) {
  if (pc.ortho != 0) return vec4(q.x / pc.half_w, -q.y / pc.half_h, 0.5, 1.0);
  return vec4(q.x / pc.half_w, -q.y / pc.half_h, 0.5 * (q.z - near), q.z);
}

void main() {
  const vec2 SQUARE[6] = vec2[6](vec2(-1, -1), vec2(1, -1), vec2(1, 1), vec2(-1, -1), vec2(1, 1),
                                 vec2(-1, 1));
  const vec2 FULL[3] = vec2[3](vec2(-1, -1), vec2(3, -1), vec2(-1, 3));
  int v = gl_VertexIndex;
  f_occ = gl_InstanceIndex;
  vec4 c = occ[OBS_AAO_VEC4S * gl_InstanceIndex];
  gl_Position = vec4(0.0, 0.0, 0.5, 1.0);
  bool ortho = pc.ortho != 0;
  // Two pixels at the cube's far side, in view units.
  float pixel = 2.0 * max(pc.half_w / float(pc.width), pc.half_h / float(pc.height));
  float far = ortho ? 1.0 : max(c.z + c.w * (1.0 + OBS_AAO_PROXY_MARGIN), 0.0);
  float b = c.w * (1.0 + OBS_AAO_PROXY_MARGIN) + 2.0 * pixel * far;
  bool holds_camera = !ortho && all(lessThanEqual(abs(c.xyz), vec3(b)));
  if (isinf(c.w) || holds_camera) {
    if (v < 3) gl_Position = vec4(FULL[v], 0.5, 1.0);
    return;
  }
  int f = v / 6, k = f >> 1, u = (k + 1) % 3, w = (k + 2) % 3;
  float s = (f & 1) != 0 ? 1.0 : -1.0;
  // Facing away: the camera (perspective: the origin; orthographic: looking along +z) is on the
  // cube's side of the face's plane.
  bool away = ortho ? (k == 2 && s > 0.0) : (s * c[k] + b > 0.0);
  if (!away) return;
  vec3 q = c.xyz;
  q[k] += s * b;
  q[u] += SQUARE[v % 6].x * b;
  q[w] += SQUARE[v % 6].y * b;
  gl_Position = clip(q, 1e-6 * (abs(c.z) + b));
}
