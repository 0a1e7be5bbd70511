// Depth-only orthographic maps (depth_maps.c), vertex stage: an affine map of positions relative
// to the maps' centre into clip space, one draw per map. No fragment stage: the depth test keeps
// the nearest depth.
#version 450
layout(location = 0) in vec3 a_pos;

layout(push_constant) uniform Push {
  vec4 row[3]; // x_ndc, y_ndc and depth, each row . (p, 1)
} pc;

void main() {
  vec4 p = vec4(a_pos, 1.0);
  gl_Position = vec4(dot(pc.row[0], p), dot(pc.row[1], p), dot(pc.row[2], p), 1.0);
}
