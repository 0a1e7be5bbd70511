// Depth peeling of obscurance_map: scene triangles in coordinates normalised to the bounding
// sphere, projected by one matrix (a bundle's orthographic grid, or the camera for the display
// of patch ids); the patch and the facing cosine travel to the fragment shader. The push block
// (layout.h) is the fragment shader's too.
#version 450
#extension GL_GOOGLE_include_directive : require
#define OBS_PEEL_DRAW_PASS
#include "layout.h"

layout(location = 0) in vec3 pos;   // (p - centre) / radius
layout(location = 1) in vec2 bary;  // weights of vertices 1 and 2
layout(location = 2) in vec3 nrm;   // unit face normal (front side)
layout(location = 3) in int first;  // first patch of the triangle; -2: a surface without patches
layout(location = 4) in int split;  // the triangle's split n (n x n patches)
layout(location = 5) in int robj;   // index into the reflectivity table


layout(location = 0) out vec2 o_bary;
layout(location = 1) flat out int o_first;
layout(location = 2) flat out int o_split;
layout(location = 3) flat out int o_robj;
layout(location = 4) flat out float o_b;

void main() {
  mat4 m = mat4(pc.m[0], pc.m[1], pc.m[2], pc.m[3], pc.m[4], pc.m[5], pc.m[6], pc.m[7], pc.m[8],
                pc.m[9], pc.m[10], pc.m[11], pc.m[12], pc.m[13], pc.m[14], pc.m[15]);
  gl_Position = m * vec4(pos, 1.0);
  o_bary = bary;
  o_first = first;
  o_split = split;
  o_robj = robj;
  o_b = -dot(nrm, vec3(pc.dir[0], pc.dir[1], pc.dir[2]));
}
