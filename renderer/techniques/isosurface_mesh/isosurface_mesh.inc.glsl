// isosurface_mesh's extraction on the device, shared by its three passes: the lattice and its
// float field in renderer/core/isosurface.c's order of operations (so the sides of the isovalue,
// and with them the topology, are the CPU's bits), which edges a lattice point owns and whether
// the isovalue crosses them, and the polygonisation table the host uploads (obs_iso_table_get).
#extension GL_GOOGLE_include_directive : require
#include "layout.h"

layout(local_size_x = 64) in;

layout(set = 0, binding = OBS_ISO_B_VALUES, r32f) uniform image2D values;
layout(set = 0, binding = OBS_ISO_B_CENTRE, r32f) uniform image2D centre;
layout(set = 0, binding = OBS_ISO_B_COUNTS, rgba32f) uniform image2D counts;
layout(set = 0, binding = OBS_ISO_B_BASES, rgba32f) uniform image2D bases;
layout(set = 0, binding = OBS_ISO_B_VERTS, rgba32f) uniform image2D verts;
layout(set = 0, binding = OBS_ISO_B_TRIS, rgba32f) uniform image2D tris;
layout(set = 1, binding = 0) uniform sampler3D vol;
layout(set = 1, binding = OBS_ISO_T_BINDING, std430) readonly buffer tables { uint tb[]; };

ivec2 at(int e) { return ivec2(e % OBS_ISO_W, e / OBS_ISO_W); }

// This invocation's element (one per lattice point), or -1 past the end.
int element() {
  int e = int(gl_GlobalInvocationID.y) * OBS_ISO_W + int(gl_GlobalInvocationID.x);
  return e < pc.npoints ? e : -1;
}

ivec3 point_of(int e) {
  int nx = pc.c[0] + 1, ny = pc.c[1] + 1;
  return ivec3(e % nx, (e / nx) % ny, e / (nx * ny));
}
int point_index(ivec3 p) { return (p.z * (pc.c[1] + 1) + p.y) * (pc.c[0] + 1) + p.x; }
int cell_index(ivec3 p) { return (p.z * pc.c[1] + p.y) * pc.c[0] + p.x; }
bool is_cell(ivec3 p) { return p.x < pc.c[0] && p.y < pc.c[1] && p.z < pc.c[2]; }

float vox(int i, int j, int k) { return texelFetch(vol, ivec3(i, j, k), 0).r; }

// obs_iso_lattice_value: the trilinear field at half-lattice position m, minus the isovalue.
float lattice_value(ivec3 m) {
  int n0 = 2 * pc.c[0] + 1, n1 = 2 * pc.c[1] + 1, n2 = 2 * pc.c[2] + 1;
  int i = int(tb[pc.axis[0] + m.x]), i1 = int(tb[pc.axis[0] + n0 + m.x]);
  int j = int(tb[pc.axis[1] + m.y]), j1 = int(tb[pc.axis[1] + n1 + m.y]);
  int k = int(tb[pc.axis[2] + m.z]), k1 = int(tb[pc.axis[2] + n2 + m.z]);
  precise float wx = uintBitsToFloat(tb[pc.axis[0] + 2 * n0 + m.x]);
  precise float wy = uintBitsToFloat(tb[pc.axis[1] + 2 * n1 + m.y]);
  precise float wz = uintBitsToFloat(tb[pc.axis[2] + 2 * n2 + m.z]);
  precise float c00 = vox(i, j, k) + wx * (vox(i1, j, k) - vox(i, j, k));
  precise float c10 = vox(i, j1, k) + wx * (vox(i1, j1, k) - vox(i, j1, k));
  precise float c01 = vox(i, j, k1) + wx * (vox(i1, j, k1) - vox(i, j, k1));
  precise float c11 = vox(i, j1, k1) + wx * (vox(i1, j1, k1) - vox(i, j1, k1));
  precise float c0 = c00 + wy * (c10 - c00);
  precise float c1 = c01 + wy * (c11 - c01);
  precise float f = (c0 + wz * (c1 - c0)) - pc.iso;
  return f;
}

float point_f(ivec3 p) { return imageLoad(values, at(point_index(p))).r; }
float centre_f(ivec3 p) { return imageLoad(centre, at(cell_index(p))).r; }

const ivec3 slot_dir[7] = ivec3[7](ivec3(1, 0, 0), ivec3(0, 1, 0), ivec3(0, 0, 1), ivec3(0, 1, 1),
                                   ivec3(1, 0, 1), ivec3(1, 1, 0), ivec3(1, 1, 1));
ivec3 corner_off(int c) { return ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1); }

// Whether edge slot s of point p exists and carries a vertex; its ends' values (lower end first).
bool crossed(ivec3 p, int s, out float fl, out float fh) {
  fl = 0.0;
  fh = 0.0;
  bool refine = pc.c[3] != 0;
  if (s < 7) {
    ivec3 q = p + slot_dir[s];
    if ((s == 6 && refine) || q.x > pc.c[0] || q.y > pc.c[1] || q.z > pc.c[2]) return false;
    fl = point_f(p);
    fh = point_f(q);
  } else {
    if (!refine || !is_cell(p)) return false;
    fl = centre_f(p);
    fh = point_f(p + corner_off(s - 7));
  }
  return (fl >= 0.0) != (fh >= 0.0);
}

// The edge parameter from the lower end (isosurface.c's edge_t).
float edge_t(float f_lo, float f_hi) {
  bool lo_below = f_lo < 0.0;
  float fa = lo_below ? f_lo : f_hi, fb = lo_below ? f_hi : f_lo;
  precise float d = fb - fa;
  precise float t = -fa / (d > 1e-5 ? d : 1e-5);
  precise float r = lo_below ? t : 1.0 - t;
  return r;
}

// The table: tetrahedra, triangle counts, edges (layout.h).
int ntets() { return pc.c[3] != 0 ? 12 : 6; }
int tet_corner(int t, int q) { return int(tb[pc.axis[3] + t * 4 + q]); }
int tri_count(int t, int cs) { return int(tb[pc.axis[3] + ntets() * 4 + t * 16 + cs]); }
int tri_edge(int t, int cs, int r, int e, int end) {
  return int(tb[pc.axis[3] + ntets() * 20 + ((t * 16 + cs) * 2 + r) * 6 + e * 2 + end]);
}

// The value at cell corner q (0..7) or its centre (8).
float cell_f(ivec3 p, int q) { return q == 8 ? centre_f(p) : point_f(p + corner_off(q)); }

int cell_case(ivec3 p, int t) {
  int cs = 0;
  for (int v = 0; v < 4; v++) cs |= (cell_f(p, tet_corner(t, v)) >= 0.0 ? 1 : 0) << v;
  return cs;
}
