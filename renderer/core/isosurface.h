/* Isosurface extraction from a scalar volume (ShaderX7 1.1's hybrid marching cubes / marching
 * tetrahedra): the volume is resampled on a lattice of cubic cells, every cell is split into six
 * tetrahedra around its corner-0-to-corner-7 diagonal (optionally twelve, bisecting that diagonal
 * at a sample of the cell's centre: the article's adaptive refinement; two and three levels go on
 * bisecting every tetrahedron at its longest edge), and each tetrahedron is polygonised from the
 * 16 cases of its corners' sides. Shared by the geometry build (a volume
 * object becomes its mesh for every surface technique) and the isosurface_mesh technique, whose
 * Vulkan twin reads the same tables so both give the same topology. */
#ifndef OBS_ISOSURFACE_H
#define OBS_ISOSURFACE_H

#include <stddef.h>
#include <stdint.h>

#include "geometry.h"
#include "obscura/error.h"
#include "volume.h"

/* The most cells along the longest axis (lattice keys stay below 2^32). */
#define OBS_ISO_CELLS_MAX 512
/* The most bisection levels (three keep every vertex on the half lattice). */
#define OBS_ISO_REFINE_MAX 3
/* Per lattice point, the edges that may carry a vertex: 0..6 go to the point + (1,0,0), (0,1,0),
 * (0,0,1), (0,1,1), (1,0,1), (1,1,0), (1,1,1) (the tetrahedra's edges along the axes, the face
 * diagonals and the cell diagonal); 7..14 go from the centre of the cell whose lowest corner is
 * the point to that cell's corner 0..7 (refinement only). */
#define OBS_ISO_SLOTS 15
/* The guard of the edge parameter's denominator (the article's max(f_b - f_a, 1e-5)). */
#define OBS_ISO_EPS 1e-5f

/* The extraction lattice of a volume: c[a] cells per axis of side h[a] (data space), spanning the
 * voxel centres [s / 2, (n - 1/2) s] where the field is interpolated, not held (the whole box on
 * an axis of one voxel); lattice point (i, j, k) is at (o0 + i h0, o1 + j h1, o2 + k h2). The
 * longest axis has `cells` cells and the others as many as keep the cells nearest to cubes.
 * Starting at the first voxel centre, not at the box's face, also keeps the lattice's planes off
 * the round positions where scenes put boxes and pixel rays. The field there is the
 * volume's trilinear one (obs_volume_sample's), evaluated in float from per-axis tables: for the
 * 2 c[a] + 1 positions m h[a] / 2 (lattice points and cell centres), the lower voxel index, the
 * upper one and the upper one's weight. Owns its tables. */
typedef struct obs_iso_lattice {
  int c[3];
  double h[3], o[3];
  int32_t *i0[3], *i1[3];
  float *w[3];
} obs_iso_lattice;

int obs_iso_lattice_init(const obs_volume *v, int cells, obs_iso_lattice *l, obs_err *err);
void obs_iso_lattice_free(obs_iso_lattice *l);

/* The field minus `iso` at half-lattice position (mx, my, mz) (lattice point (i, j, k) is
 * (2i, 2j, 2k), a cell centre is odd on every axis), in float in a fixed order of operations
 * that the Vulkan extractor's shader repeats. */
float obs_iso_lattice_value(const obs_volume *v, const obs_iso_lattice *l, float iso, int mx,
                            int my, int mz);

/* The polygonisation table of one decomposition (refine 0: 6 tetrahedra, 1: 12): per
 * tetrahedron its 4 corners (0..7 cube corners, x | y << 1 | z << 2, 8 the centre), and per
 * tetrahedron and case (bit v set where corner v's value is >= 0, i.e. at or above the isovalue)
 * the triangles as cell edges: each edge is (lower corner, upper corner), wound so the face
 * normal points to the side below the isovalue. Built once; the same bytes for every caller. */
#define OBS_ISO_TETS_MAX 12
typedef struct obs_iso_table {
  int ntets;
  uint8_t tet[OBS_ISO_TETS_MAX][4];
  uint8_t ntri[OBS_ISO_TETS_MAX][16];
  uint8_t edge[OBS_ISO_TETS_MAX][16][2][3][2];
} obs_iso_table;
const obs_iso_table *obs_iso_table_get(int refine);
/* The lattice slot of cell edge (u, v), u the lower corner (0..8 as above). */
int obs_iso_edge_slot(int u, int v);
/* The triangles of a tetrahedron with corners at integer points p for `cs` (bit v: corner v at or
 * above), as pairs of its corners (0..3), wound so the face normal points to the side below;
 * returns their count (0..2). The tables' rule, which the bisection levels apply per
 * tetrahedron too. */
int obs_iso_tet_case(const int p[4][3], int cs, uint8_t tri[2][3][2]);

/* An extracted mesh in the volume's data space. Vertices are ordered by their edge's key
 * (refine 0 and 1: lattice point index, x fastest, times OBS_ISO_SLOTS plus the slot; 2 and 3:
 * the edge's lower end's half-lattice index times the half lattice's point count plus its upper
 * end's) and triangles by cell (x fastest), then tetrahedron, then the table's order, so the
 * topology is a function of the lattice values alone. Owns its arrays. */
typedef struct obs_iso_mesh {
  double *pos;   /* 3 per vertex */
  uint64_t *key; /* per vertex: the edge it lies on */
  float *t;      /* per vertex: its place on that edge from the edge's lower end, in [0, 1] */
  uint32_t *idx; /* 3 per triangle */
  size_t nverts, ntris;
  obs_iso_lattice lat;
} obs_iso_mesh;

/* Extracts v's isosurface of `iso` on a lattice of `cells` (1..OBS_ISO_CELLS_MAX) cells along its
 * longest axis, with `refine` 0..OBS_ISO_REFINE_MAX bisection levels. OBS_EINVAL for cells or
 * refine out of range; OBS_ENOMEM. */
int obs_iso_extract(const obs_volume *v, float iso, int cells, int refine, obs_iso_mesh *m,
                    obs_err *err);
/* As obs_iso_extract on `threads` threads over slabs of cell layers: the same mesh, bit for bit,
 * for any count (each point layer's vertices are numbered alone, then offset by the counts
 * before it). */
int obs_iso_extract_threads(const obs_volume *v, float iso, int cells, int refine, int threads,
                            obs_iso_mesh *m, obs_err *err);
void obs_iso_mesh_free(obs_iso_mesh *m);

/* The position of lattice edge `key` (refine 0 and 1) at parameter t (data space), as
 * obs_iso_extract places it. */
void obs_iso_key_point(const obs_iso_lattice *l, uint32_t key, float t, double p[3]);

/* The enclosed volume (divergence theorem) and the area of a closed mesh, in double. */
void obs_iso_mesh_measure(const obs_iso_mesh *m, double *area, double *volume);

/* Volume shape `s` as an object-space float mesh (its box centred on the origin), extracted on
 * its `mesh_cells` (0: the longest of its dims less one, a cell per voxel interval, at most
 * OBS_ISO_CELLS_MAX); the geometry build's
 * mesh of a volume object. */
int obs_iso_shape_mesh(const obs_shape *s, obs_mesh *m, obs_err *err, const char *where);

#endif
