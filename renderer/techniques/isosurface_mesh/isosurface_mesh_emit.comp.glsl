// isosurface_mesh, pass 3: each lattice point writes its vertices (edge parameter and key) from
// its first vertex on, and its cell's triangles from its first triangle on, as the CPU orders
// them; a triangle's corners are found as their edges' owners' first vertex plus the edge's rank
// among the owner's crossed edges (from the count pass's mask).
#version 450
#extension GL_GOOGLE_include_directive : require
#include "isosurface_mesh.inc.glsl"

int slot_of(int u, int v) {
  if (u == 8) return 7 + v;
  const int slot[8] = int[8](-1, 0, 1, 5, 2, 4, 3, 6);
  return slot[u ^ v];
}

int vertex_of(ivec3 cell, int u, int v) {
  ivec3 q = u == 8 ? cell : cell + corner_off(u);
  int s = slot_of(u, v), e = point_index(q);
  int mask = int(imageLoad(counts, at(e)).z);
  return int(imageLoad(bases, at(e)).x) + bitCount(mask & ((1 << s) - 1));
}

void main() {
  int e = element();
  if (e < 0) return;
  ivec3 p = point_of(e);
  vec4 b = imageLoad(bases, at(e));
  int vb = int(b.x), n = 0;
  for (int s = 0; s < 15; s++) {
    float fl, fh;
    if (!crossed(p, s, fl, fh)) continue;
    uint key = uint(e) * 15u + uint(s);
    imageStore(verts, at(vb + n), vec4(edge_t(fl, fh), uintBitsToFloat(key | OBS_ISO_KEY_BIAS), 0, 0));
    n++;
  }
  if (!is_cell(p)) return;
  int tri = int(b.y);
  for (int t = 0; t < ntets(); t++) {
    int cs = cell_case(p, t);
    for (int r = 0; r < tri_count(t, cs); r++) {
      ivec3 v;
      v.x = vertex_of(p, tri_edge(t, cs, r, 0, 0), tri_edge(t, cs, r, 0, 1));
      v.y = vertex_of(p, tri_edge(t, cs, r, 1, 0), tri_edge(t, cs, r, 1, 1));
      v.z = vertex_of(p, tri_edge(t, cs, r, 2, 0), tri_edge(t, cs, r, 2, 1));
      imageStore(tris, at(tri), vec4(vec3(v), 0));
      tri++;
    }
  }
}
