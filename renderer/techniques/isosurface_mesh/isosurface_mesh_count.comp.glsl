// isosurface_mesh, pass 2: per lattice point, how many of its edges carry a vertex (and which: a
// mask of its 15 slots, for the emit pass's ranks), and how many triangles its cell makes; the
// host turns the counts into prefix sums (the vertices' and triangles' places in the CPU's
// order).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "isosurface_mesh.inc.glsl"

void main() {
  int e = element();
  if (e < 0) return;
  ivec3 p = point_of(e);
  int nv = 0, nt = 0, mask = 0;
  for (int s = 0; s < 15; s++) {
    float fl, fh;
    if (crossed(p, s, fl, fh)) {
      nv++;
      mask |= 1 << s;
    }
  }
  if (is_cell(p))
    for (int t = 0; t < ntets(); t++) nt += tri_count(t, cell_case(p, t));
  imageStore(counts, at(e), vec4(float(nv), float(nt), float(mask), 0));
}
