// isosurface_mesh, pass 1: the field minus the isovalue at every lattice point and, refining, at
// every cell's centre (one invocation per lattice point).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "isosurface_mesh.inc.glsl"

void main() {
  int e = element();
  if (e < 0) return;
  ivec3 p = point_of(e);
  imageStore(values, at(e), vec4(lattice_value(2 * p), 0, 0, 0));
  if (pc.c[3] != 0 && is_cell(p))
    imageStore(centre, at(cell_index(p)), vec4(lattice_value(2 * p + 1), 0, 0, 0));
}
