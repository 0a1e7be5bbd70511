/* The polygonisation tables of the isosurface extractor (isosurface.h): the tetrahedra of a cube
 * and, per tetrahedron and sign case, its triangles as cell edges, built once from the corners'
 * integer positions. */
#include <pthread.h>
#include <string.h>

#include "isosurface.h"

/* Corner positions at four times the cube's side (the centre and edge midpoints are integers). */
static void corner4(int c, int p[3]) {
  for (int a = 0; a < 3; a++) p[a] = c == 8 ? 2 : 4 * ((c >> a) & 1);
}

int obs_iso_edge_slot(int u, int v) {
  if (u == 8) return 7 + v;
  if (v == 8) return 7 + u;
  /* The direction v - u has bits v ^ u (u's bits are a subset of v's): x, y, z, yz, xz, xy, xyz. */
  static const int slot[8] = {-1, 0, 1, 5, 2, 4, 3, 6};
  return slot[u ^ v];
}

/* Edge (a, b) as (lower, upper): the centre is lower than no corner in key terms, so it goes
 * first; of two corners, the one whose bits are a subset of the other's. */
static void set_edge(uint8_t e[2], int a, int b) {
  int lower = a == 8 ? 1 : b == 8 ? 0 : (a & b) == a;
  e[0] = (uint8_t)(lower ? a : b);
  e[1] = (uint8_t)(lower ? b : a);
}

static long det3(const int a[3], const int b[3], const int c[3]) {
  return (long)a[0] * (b[1] * c[2] - b[2] * c[1]) - (long)a[1] * (b[0] * c[2] - b[2] * c[0]) +
         (long)a[2] * (b[0] * c[1] - b[1] * c[0]);
}

int obs_iso_tet_case(const int p[4][3], int cs, uint8_t tri[2][3][2]) {
  int up[4], nup = 0, dn[4], ndn = 0;
  for (int v = 0; v < 4; v++) {
    if (cs >> v & 1)
      up[nup++] = v;
    else
      dn[ndn++] = v;
  }
  if (nup == 0 || nup == 4) return 0;
  if (nup == 1 || nup == 3) {
    int s = nup == 1 ? up[0] : dn[0], *o = nup == 1 ? dn : up;
    int d[3][3];
    for (int k = 0; k < 3; k++)
      for (int a = 0; a < 3; a++) d[k][a] = p[o[k]][a] - p[s][a];
    /* (e1, e2, e3) faces away from s when det(o1 - s, o2 - s, o3 - s) > 0; away is the low side
     * when s is the one corner above, toward s when it is the one below. */
    long dt = det3(d[0], d[1], d[2]);
    int flip = nup == 1 ? dt < 0 : dt > 0;
    int order[3] = {0, flip ? 2 : 1, flip ? 1 : 2};
    for (int k = 0; k < 3; k++) {
      tri[0][k][0] = (uint8_t)s;
      tri[0][k][1] = (uint8_t)o[order[k]];
    }
    return 1;
  }
  /* Two above (a, b), two below (c, d): the quad on edges ac, ad, bd, bc, cut along ac-bd. */
  int quad[4][2] = {{up[0], dn[0]}, {up[0], dn[1]}, {up[1], dn[1]}, {up[1], dn[0]}};
  int m[4][3];
  for (int k = 0; k < 4; k++)
    for (int a = 0; a < 3; a++) m[k][a] = p[quad[k][0]][a] + p[quad[k][1]][a];
  int e1[3], e2[3], toward[3];
  for (int a = 0; a < 3; a++) {
    e1[a] = m[1][a] - m[0][a];
    e2[a] = m[2][a] - m[0][a];
    toward[a] = p[dn[0]][a] + p[dn[1]][a] - p[up[0]][a] - p[up[1]][a];
  }
  long n[3] = {(long)e1[1] * e2[2] - (long)e1[2] * e2[1], (long)e1[2] * e2[0] - (long)e1[0] * e2[2],
               (long)e1[0] * e2[1] - (long)e1[1] * e2[0]};
  int flip = n[0] * toward[0] + n[1] * toward[1] + n[2] * toward[2] < 0;
  static const int tri3[2][3] = {{0, 1, 2}, {0, 2, 3}};
  for (int r = 0; r < 2; r++)
    for (int k = 0; k < 3; k++) {
      int qk = tri3[r][flip ? (3 - k) % 3 : k];
      tri[r][k][0] = (uint8_t)quad[qk][0];
      tri[r][k][1] = (uint8_t)quad[qk][1];
    }
  return 2;
}

/* The triangles of tetrahedron t for `cs`, into tb. */
static void table_case(obs_iso_table *tb, int t, int cs) {
  const uint8_t *q = tb->tet[t];
  int p[4][3];
  for (int v = 0; v < 4; v++) corner4(q[v], p[v]);
  uint8_t tri[2][3][2];
  int n = obs_iso_tet_case(p, cs, tri);
  for (int r = 0; r < n; r++)
    for (int k = 0; k < 3; k++) set_edge(tb->edge[t][cs][r][k], q[tri[r][k][0]], q[tri[r][k][1]]);
  tb->ntri[t][cs] = (uint8_t)n;
}

static obs_iso_table tables[2];
static pthread_once_t tables_once = PTHREAD_ONCE_INIT;

static void tables_build(void) {
  /* The six tetrahedra around the 0-7 diagonal: 0, one axis step, two axis steps, 7. */
  static const uint8_t kuhn[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7},
                                     {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};
  for (int r = 0; r < 2; r++) {
    obs_iso_table *tb = &tables[r];
    memset(tb, 0, sizeof *tb);
    tb->ntets = r ? 12 : 6;
    for (int t = 0; t < 6; t++) {
      if (!r) {
        memcpy(tb->tet[t], kuhn[t], 4);
        continue;
      }
      /* Longest-edge bisection: the diagonal 0-7 is every tetrahedron's longest edge, cut at the
       * centre (8), which no neighbouring cell shares, so the faces between cells are kept. */
      const uint8_t a[4] = {0, kuhn[t][1], kuhn[t][2], 8}, b[4] = {8, kuhn[t][1], kuhn[t][2], 7};
      memcpy(tb->tet[2 * t], a, 4);
      memcpy(tb->tet[2 * t + 1], b, 4);
    }
    for (int t = 0; t < tb->ntets; t++)
      for (int cs = 0; cs < 16; cs++) table_case(tb, t, cs);
  }
}

const obs_iso_table *obs_iso_table_get(int refine) {
  pthread_once(&tables_once, tables_build);
  return &tables[refine ? 1 : 0];
}
