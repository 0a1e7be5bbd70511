// Depth peeling of obscurance_map: scene triangles in coordinates normalised to the bounding
// sphere, projected by one matrix (a bundle's orthographic grid, or the camera for the display
// of patch ids); the patch and the facing cosine travel to the fragment shader.
#version 450

layout(location = 0) in vec3 pos;   // (p - centre) / radius
layout(location = 1) in vec2 bary;  // weights of vertices 1 and 2
layout(location = 2) in vec3 nrm;   // unit face normal (front side)
layout(location = 3) in int first;  // first patch of the triangle; -2: a surface without patches
layout(location = 4) in int split;  // the triangle's split n (n x n patches)
layout(location = 5) in int robj;   // index into the reflectivity table

layout(push_constant) uniform Push {
  mat4 m;    // normalised coordinates to clip space
  vec4 dir;  // the view direction (into the scene), normalised coordinates
  float eps; // peel: keep fragments this far behind the previous layer; < 0: no previous layer
} pc;

layout(location = 0) out vec2 o_bary;
layout(location = 1) flat out int o_first;
layout(location = 2) flat out int o_split;
layout(location = 3) flat out int o_robj;
layout(location = 4) flat out float o_b;

void main() {
  gl_Position = pc.m * vec4(pos, 1.0);
  o_bary = bary;
  o_first = first;
  o_split = split;
  o_robj = robj;
  o_b = -dot(nrm, pc.dir.xyz);
}
