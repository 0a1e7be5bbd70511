/* Isosurface extraction by marching tetrahedra over a cube lattice (isosurface.h): the lattice
 * and its float field, the extractor, and a volume object's mesh for the geometry build (the
 * polygonisation tables are isosurface_table.c's). */
#include "isosurface.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "parallel.h"
#include "volume_scene.h"

/* ---- the lattice ----------------------------------------------------------------------------- */

/* obs_volume_sample's index and weight along axis a at data coordinate p (volume.c's rule). */
static void axis_entry(const obs_volume *v, int a, double p, int32_t *i0, int32_t *i1, float *w) {
  double u = p / v->spacing[a] - 0.5;
  double hi = v->n[a] - 1;
  if (!(u > 0)) u = 0;
  if (u > hi) u = hi;
  int i = (int)u;
  if (i > v->n[a] - 2) i = v->n[a] > 1 ? v->n[a] - 2 : 0;
  *i0 = i;
  *i1 = i + (v->n[a] > 1);
  *w = v->n[a] > 1 ? (float)(u - i) : 0.0f;
}

void obs_iso_lattice_free(obs_iso_lattice *l) {
  for (int a = 0; a < 3; a++) {
    free(l->i0[a]);
    free(l->i1[a]);
    free(l->w[a]);
  }
  memset(l, 0, sizeof *l);
}

int obs_iso_lattice_init(const obs_volume *v, int cells, obs_iso_lattice *l, obs_err *err) {
  memset(l, 0, sizeof *l);
  if (cells < 1 || cells > OBS_ISO_CELLS_MAX)
    return obs_err_set(err, OBS_EINVAL, "isosurface: %d cells along the longest axis, not in 1..%d",
                       cells, OBS_ISO_CELLS_MAX);
  double side[3], longest = 0;
  for (int a = 0; a < 3; a++) {
    side[a] = (v->n[a] > 1 ? v->n[a] - 1 : 1) * v->spacing[a];
    l->o[a] = v->n[a] > 1 ? 0.5 * v->spacing[a] : 0;
    longest = fmax(longest, side[a]);
  }
  for (int a = 0; a < 3; a++) {
    /* Cells as near to cubes as whole counts allow: the longest axis's side over `cells`. */
    int c = (int)lround(cells * side[a] / longest);
    l->c[a] = c < 1 ? 1 : c > OBS_ISO_CELLS_MAX ? OBS_ISO_CELLS_MAX : c;
    l->h[a] = side[a] / l->c[a];
    size_t n = 2 * (size_t)l->c[a] + 1;
    l->i0[a] = malloc(n * sizeof(int32_t));
    l->i1[a] = malloc(n * sizeof(int32_t));
    l->w[a] = malloc(n * sizeof(float));
    if (!l->i0[a] || !l->i1[a] || !l->w[a]) {
      obs_iso_lattice_free(l);
      return obs_err_set(err, OBS_ENOMEM, "isosurface: out of memory for the lattice");
    }
    for (size_t m = 0; m < n; m++)
      axis_entry(v, a, l->o[a] + (double)m * 0.5 * l->h[a], &l->i0[a][m], &l->i1[a][m],
                 &l->w[a][m]);
  }
  return 0;
}

float obs_iso_lattice_value(const obs_volume *v, const obs_iso_lattice *l, float iso, int mx,
                            int my, int mz) {
  int i = l->i0[0][mx], i1 = l->i1[0][mx], j = l->i0[1][my], j1 = l->i1[1][my];
  int k = l->i0[2][mz], k1 = l->i1[2][mz];
  return obs_volume_lerp3(v, i, i1, j, j1, k, k1, l->w[0][mx], l->w[1][my], l->w[2][mz]) - iso;
}

/* ---- the extractor --------------------------------------------------------------------------- */

static const int slot_dir[7][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 1, 1},
                                   {1, 0, 1}, {1, 1, 0}, {1, 1, 1}};

void obs_iso_key_point(const obs_iso_lattice *l, uint32_t key, float t, double p[3]) {
  uint32_t s = key % OBS_ISO_SLOTS, pt = key / OBS_ISO_SLOTS;
  int q[3] = {(int)(pt % (uint32_t)(l->c[0] + 1)),
              (int)(pt / (uint32_t)(l->c[0] + 1) % (uint32_t)(l->c[1] + 1)),
              (int)(pt / ((uint32_t)(l->c[0] + 1) * (uint32_t)(l->c[1] + 1)))};
  for (int a = 0; a < 3; a++) {
    double lo, d;
    if (s < 7) {
      lo = q[a];
      d = slot_dir[s][a];
    } else { /* from the cell's centre to its corner s - 7 */
      lo = q[a] + 0.5;
      d = (double)((s - 7) >> a & 1) - 0.5;
    }
    p[a] = l->o[a] + (lo + (double)t * d) * l->h[a];
  }
}

typedef struct grow {
  obs_iso_mesh *m;
  size_t vcap, tcap;
} grow;

static int add_vertex(grow *g, uint32_t key, float t) {
  obs_iso_mesh *m = g->m;
  if (m->nverts == g->vcap) {
    size_t cap = g->vcap ? 2 * g->vcap : 1024;
    double *p = realloc(m->pos, cap * 3 * sizeof *p);
    if (p) m->pos = p;
    uint64_t *k = realloc(m->key, cap * sizeof *k);
    if (k) m->key = k;
    float *tt = realloc(m->t, cap * sizeof *tt);
    if (tt) m->t = tt;
    if (!p || !k || !tt) return OBS_ENOMEM;
    g->vcap = cap;
  }
  m->key[m->nverts] = key;
  m->t[m->nverts] = t;
  obs_iso_key_point(&m->lat, key, t, m->pos + 3 * m->nverts);
  m->nverts++;
  return 0;
}

static int add_triangle(grow *g, const uint32_t v[3]) {
  obs_iso_mesh *m = g->m;
  if (m->ntris == g->tcap) {
    size_t cap = g->tcap ? 2 * g->tcap : 1024;
    uint32_t *i = realloc(m->idx, cap * 3 * sizeof *i);
    if (!i) return OBS_ENOMEM;
    m->idx = i;
    g->tcap = cap;
  }
  memcpy(m->idx + 3 * m->ntris++, v, 3 * sizeof *v);
  return 0;
}

/* The edge parameter from the lower end, with f_lo and f_hi on opposite sides: the article's
 * t = -f_a / max(f_b - f_a, eps) from the end below the isovalue (a), so the denominator is
 * positive and t lies in [0, 1]. */
static float edge_t(float f_lo, float f_hi) {
  int lo_below = f_lo < 0;
  float fa = lo_below ? f_lo : f_hi, fb = lo_below ? f_hi : f_lo;
  float d = fb - fa;
  float t = -fa / (d > OBS_ISO_EPS ? d : OBS_ISO_EPS);
  return lo_below ? t : 1.0f - t;
}

typedef struct extract {
  const obs_volume *v;
  float iso;
  int refine;
  const obs_iso_lattice *l;
  float *f;      /* lattice values, x fastest */
  float *centre; /* cell centre values (refine), x fastest; NULL */
  int nslabs;
  size_t *layer_verts; /* per point layer: its crossed edges */
  size_t *tri_end;     /* per cell layer: its slab's triangles up to its end */
  struct bisect *bis;  /* refine 2 and 3: per slab */
} extract;

/* The cell layers [k0, k1) of one thread's share: their triangles, and the vertices of the point
 * layers it owns (k0..k1 - 1, and the last layer in the last slab). Triangle corners are held as
 * (index within its point layer) | ISO_UPPER for the cell layer's upper point layer until the
 * layers' vertex counts are summed. */
#define ISO_UPPER 0x80000000u
typedef struct slab {
  obs_iso_mesh m;
  grow g;
  uint32_t *ids[2]; /* vertex index within the layer of two point layers, OBS_ISO_SLOTS a point */
  int k0, k1;
} slab;

static float point_f(const extract *x, int i, int j, int k) {
  const int *c = x->l->c;
  return x->f[((size_t)k * (size_t)(c[1] + 1) + (size_t)j) * (size_t)(c[0] + 1) + (size_t)i];
}

/* Numbers the crossed edges of point layer k into ids (in key order, from 0) and, with `store`,
 * adds their vertices; *count gets how many. */
static int number_layer(const extract *x, grow *g, int k, uint32_t *ids, int store, size_t *count) {
  const int *c = x->l->c;
  uint32_t n = 0;
  for (int j = 0; j <= c[1]; j++)
    for (int i = 0; i <= c[0]; i++) {
      uint32_t pt =
          ((uint32_t)k * (uint32_t)(c[1] + 1) + (uint32_t)j) * (uint32_t)(c[0] + 1) + (uint32_t)i;
      uint32_t *id = ids + ((size_t)j * (size_t)(c[0] + 1) + (size_t)i) * OBS_ISO_SLOTS;
      float f0 = point_f(x, i, j, k);
      for (int s = 0; s < OBS_ISO_SLOTS; s++) {
        id[s] = UINT32_MAX;
        float fl, fh;
        if (s < 7) {
          const int *d = slot_dir[s];
          if ((s == 6 && x->refine) || i + d[0] > c[0] || j + d[1] > c[1] || k + d[2] > c[2])
            continue;
          fl = f0;
          fh = point_f(x, i + d[0], j + d[1], k + d[2]);
        } else {
          if (!x->refine || i == c[0] || j == c[1] || k == c[2]) continue;
          int cc = s - 7;
          fl = x->centre[((size_t)k * (size_t)c[1] + (size_t)j) * (size_t)c[0] + (size_t)i];
          fh = point_f(x, i + (cc & 1), j + (cc >> 1 & 1), k + (cc >> 2 & 1));
        }
        if ((fl >= 0) == (fh >= 0)) continue;
        id[s] = n++;
        if (store && add_vertex(g, pt * OBS_ISO_SLOTS + (uint32_t)s, edge_t(fl, fh)))
          return OBS_ENOMEM;
      }
    }
  *count = n;
  return 0;
}

/* The vertex of cell (i, j)'s edge (u, v) of the current layer pair, as a slab holds it. */
static uint32_t edge_id(const extract *x, uint32_t *const ids[2], int i, int j, int u, int v) {
  const int *c = x->l->c;
  int s = obs_iso_edge_slot(u, v), lo = u == 8 ? 0 : u;
  int pi = i + (lo & 1), pj = j + (lo >> 1 & 1), pk = lo >> 2 & 1;
  return ids[pk][((size_t)pj * (size_t)(c[0] + 1) + (size_t)pi) * OBS_ISO_SLOTS + (size_t)s] |
         (pk ? ISO_UPPER : 0);
}

static int cells_layer(const extract *x, slab *sl, int k) {
  const int *c = x->l->c;
  const obs_iso_table *tb = obs_iso_table_get(x->refine);
  for (int j = 0; j < c[1]; j++)
    for (int i = 0; i < c[0]; i++) {
      float f[9];
      for (int q = 0; q < 8; q++) f[q] = point_f(x, i + (q & 1), j + (q >> 1 & 1), k + (q >> 2));
      f[8] = x->refine
                 ? x->centre[((size_t)k * (size_t)c[1] + (size_t)j) * (size_t)c[0] + (size_t)i]
                 : 0;
      for (int t = 0; t < tb->ntets; t++) {
        int cs = 0;
        for (int v = 0; v < 4; v++) cs |= (f[tb->tet[t][v]] >= 0) << v;
        for (int r = 0; r < tb->ntri[t][cs]; r++) {
          uint32_t tri[3];
          for (int e = 0; e < 3; e++)
            tri[e] = edge_id(x, sl->ids, i, j, tb->edge[t][cs][r][e][0], tb->edge[t][cs][r][e][1]);
          if (add_triangle(&sl->g, tri)) return OBS_ENOMEM;
        }
      }
    }
  return 0;
}

/* Point layers [k0, k1) of the lattice values and cell layers [k0, min(k1, c2)) of the centres. */
static void sample_layers(extract *x, int k0, int k1) {
  const int *c = x->l->c;
  for (int k = k0; k < k1; k++) {
    size_t n = (size_t)k * (size_t)(c[1] + 1) * (size_t)(c[0] + 1);
    for (int j = 0; j <= c[1]; j++)
      for (int i = 0; i <= c[0]; i++)
        x->f[n++] = obs_iso_lattice_value(x->v, x->l, x->iso, 2 * i, 2 * j, 2 * k);
    if (!x->refine || k == c[2]) continue;
    n = (size_t)k * (size_t)c[1] * (size_t)c[0];
    for (int j = 0; j < c[1]; j++)
      for (int i = 0; i < c[0]; i++)
        x->centre[n++] = obs_iso_lattice_value(x->v, x->l, x->iso, 2 * i + 1, 2 * j + 1, 2 * k + 1);
  }
}

/* Slab s's share of the cell layers: an even split, fixed by the slab count alone. */
static void slab_range(const extract *x, int s, int *k0, int *k1) {
  int c2 = x->l->c[2];
  *k0 = (int)((long)c2 * s / x->nslabs);
  *k1 = (int)((long)c2 * (s + 1) / x->nslabs);
}

typedef struct slab_loop {
  extract *x;
  slab *sl;
  int (*fn)(extract *x, slab *sl, int s);
  atomic_int next;
} slab_loop;

static int slab_next(void *user, int *x0, int *y0, int *x1, int *y1) {
  slab_loop *lp = user;
  int s = atomic_fetch_add(&lp->next, 1);
  if (s >= lp->x->nslabs) return 0;
  *x0 = s;
  *x1 = s + 1;
  *y0 = 0;
  *y1 = 1;
  return 1;
}

static int slab_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)thread, (void)y0, (void)y1, (void)x1;
  slab_loop *lp = user;
  return lp->fn(lp->x, lp->sl, x0);
}

/* Runs fn(x, sl, s) for every slab s on `threads` threads. */
static int slabs_run(extract *x, slab *sl, int threads, int (*fn)(extract *, slab *, int)) {
  slab_loop lp = {.x = x, .sl = sl, .fn = fn};
  atomic_init(&lp.next, 0);
  if (threads <= 1 || x->nslabs == 1) {
    for (int s = 0; s < x->nslabs; s++)
      if (fn(x, sl, s)) return OBS_ENOMEM;
    return 0;
  }
  return obs_parallel_tiles_from(slab_next, &lp, threads, slab_tile, &lp, NULL);
}

static int slab_sample(extract *x, slab *sl, int s) {
  (void)sl;
  int k0, k1;
  slab_range(x, s, &k0, &k1);
  sample_layers(x, k0, s == x->nslabs - 1 ? x->l->c[2] + 1 : k1);
  return 0;
}

static int slab_extract(extract *x, slab *all, int s) {
  slab *sl = &all[s];
  const int *c = x->l->c;
  size_t layer = (size_t)(c[0] + 1) * (size_t)(c[1] + 1) * OBS_ISO_SLOTS, count;
  sl->m.lat = *x->l; /* borrowed for obs_iso_key_point; never freed here */
  sl->g.m = &sl->m;
  sl->ids[0] = malloc(layer * sizeof(uint32_t));
  sl->ids[1] = malloc(layer * sizeof(uint32_t));
  if (!sl->ids[0] || !sl->ids[1]) return OBS_ENOMEM;
  int last = s == x->nslabs - 1;
  slab_range(x, s, &sl->k0, &sl->k1);
  /* Layer k's edges are numbered before k + 1's, and both before the cells between them emit,
   * so vertices come in key order. */
  int rc = number_layer(x, &sl->g, sl->k0, sl->ids[0], 1, &x->layer_verts[sl->k0]);
  for (int k = sl->k0; !rc && k < sl->k1; k++) {
    int own = k + 1 < sl->k1 || last;
    rc = number_layer(x, &sl->g, k + 1, sl->ids[1], own, &count);
    if (own) x->layer_verts[k + 1] = count;
    if (!rc) rc = cells_layer(x, sl, k);
    x->tri_end[k] = sl->m.ntris;
    uint32_t *tmp = sl->ids[0];
    sl->ids[0] = sl->ids[1];
    sl->ids[1] = tmp;
  }
  return rc;
}

/* The slabs' vertices and triangles joined in slab order, the corners made global. */
static int slabs_join(extract *x, slab *sl, obs_iso_mesh *m) {
  int c2 = x->l->c[2];
  size_t *base = malloc((size_t)(c2 + 1) * sizeof *base), nv = 0, nt = 0;
  if (!base) return OBS_ENOMEM;
  for (int k = 0; k <= c2; k++) {
    base[k] = nv;
    nv += x->layer_verts[k];
  }
  for (int s = 0; s < x->nslabs; s++) nt += sl[s].m.ntris;
  m->pos = malloc((nv ? nv : 1) * 3 * sizeof *m->pos);
  m->key = malloc((nv ? nv : 1) * sizeof *m->key);
  m->t = malloc((nv ? nv : 1) * sizeof *m->t);
  m->idx = malloc((nt ? nt : 1) * 3 * sizeof *m->idx);
  if (!m->pos || !m->key || !m->t || !m->idx || nv > UINT32_MAX) {
    free(base);
    return OBS_ENOMEM;
  }
  for (int s = 0; s < x->nslabs; s++) {
    const obs_iso_mesh *q = &sl[s].m;
    if (q->nverts) {
      memcpy(m->pos + 3 * m->nverts, q->pos, 3 * q->nverts * sizeof *q->pos);
      memcpy(m->key + m->nverts, q->key, q->nverts * sizeof *q->key);
      memcpy(m->t + m->nverts, q->t, q->nverts * sizeof *q->t);
    }
    m->nverts += q->nverts;
    size_t t0 = 0;
    for (int k = sl[s].k0; k < sl[s].k1; k++) {
      for (size_t t = t0; t < x->tri_end[k]; t++)
        for (int e = 0; e < 3; e++) {
          uint32_t id = q->idx[3 * t + e];
          m->idx[3 * (m->ntris + t) + e] =
              (uint32_t)base[k + ((id & ISO_UPPER) != 0)] + (id & ~ISO_UPPER);
        }
      t0 = x->tri_end[k];
    }
    m->ntris += q->ntris;
  }
  free(base);
  return 0;
}

static int run_extract(extract *x, obs_iso_mesh *m, int threads) {
  const int *c = x->l->c;
  size_t np = (size_t)(c[0] + 1) * (size_t)(c[1] + 1) * (size_t)(c[2] + 1);
  size_t nc = (size_t)c[0] * (size_t)c[1] * (size_t)c[2];
  x->f = malloc(np * sizeof(float));
  x->centre = x->refine ? malloc(nc * sizeof(float)) : NULL;
  x->layer_verts = calloc((size_t)c[2] + 1, sizeof *x->layer_verts);
  x->tri_end = calloc((size_t)c[2], sizeof *x->tri_end);
  slab *sl = calloc((size_t)x->nslabs, sizeof *sl);
  int rc = x->f && (!x->refine || x->centre) && x->layer_verts && x->tri_end && sl ? 0 : OBS_ENOMEM;
  if (!rc) rc = slabs_run(x, sl, threads, slab_sample);
  if (!rc) rc = slabs_run(x, sl, threads, slab_extract);
  if (!rc) rc = slabs_join(x, sl, m);
  for (int s = 0; sl && s < x->nslabs; s++) {
    free(sl[s].m.pos);
    free(sl[s].m.key);
    free(sl[s].m.t);
    free(sl[s].m.idx);
    free(sl[s].ids[0]);
    free(sl[s].ids[1]);
  }
  free(sl);
  return rc ? OBS_ENOMEM : 0;
}

/* ---- refinement beyond one level: longest-edge bisection ------------------------------------ */

/* Levels 2 and 3 bisect every tetrahedron of a cell that many times at its longest edge (in
 * lattice units, the cell taken as a cube). The Kuhn tetrahedra keep a unique longest edge for
 * three generations (the cell diagonal, then a face diagonal, then a cell edge), so every vertex
 * is one of the cell's 27 half-lattice points and the bisection is the same on both sides of
 * every face: applied to every cell, it is conforming. A cell whose 27 values share one sign has
 * no crossed sub-tetrahedron, so only crossed cells are subdivided, and the result is the
 * uniform refinement's surface, closed. Edges are welded by the pair of their ends' half-lattice
 * indices (key = lower * points + upper), vertices ordered by that key. */
typedef struct bis_edge {
  uint64_t key;
  float t;
} bis_edge;

typedef struct bisect {
  const extract *x;
  uint64_t np[3], npts; /* half-lattice points per axis, in all */
  bis_edge *e;          /* 3 per triangle, in emission order */
  size_t ne, cap;
} bisect;

static int bis_push(bisect *b, uint64_t key, float t) {
  if (b->ne == b->cap) {
    size_t cap = b->cap ? 2 * b->cap : 3072;
    bis_edge *e = realloc(b->e, cap * sizeof *e);
    if (!e) return OBS_ENOMEM;
    b->e = e;
    b->cap = cap;
  }
  b->e[b->ne++] = (bis_edge){key, t};
  return 0;
}

static int bis_len2(const int8_t p[3], const int8_t q[3]) {
  int d0 = p[0] - q[0], d1 = p[1] - q[1], d2 = p[2] - q[2];
  return d0 * d0 + d1 * d1 + d2 * d2;
}

/* Tetrahedron q (cell-local half-lattice points 0..2 per axis) of the cell at half-lattice
 * origin o, with the cell's 27 values f (x fastest): its triangles, or its two children. */
static int bis_tet(bisect *b, const int o[3], const float f[27], int8_t q[4][3], int left) {
  if (left) {
    int bu = 0, bv = 1, best = -1;
    for (int u = 0; u < 4; u++)
      for (int v = u + 1; v < 4; v++)
        if (bis_len2(q[u], q[v]) > best) best = bis_len2(q[u], q[v]), bu = u, bv = v;
    int8_t m[3], c[4][3];
    for (int a = 0; a < 3; a++) m[a] = (int8_t)((q[bu][a] + q[bv][a]) / 2);
    for (int side = 0; side < 2; side++) {
      memcpy(c, q, sizeof c);
      memcpy(c[side ? bu : bv], m, 3);
      if (bis_tet(b, o, f, c, left - 1)) return OBS_ENOMEM;
    }
    return 0;
  }
  int p[4][3], cs = 0;
  float fv[4];
  uint64_t id[4];
  for (int v = 0; v < 4; v++) {
    for (int a = 0; a < 3; a++) p[v][a] = q[v][a];
    fv[v] = f[q[v][0] + 3 * q[v][1] + 9 * q[v][2]];
    cs |= (fv[v] >= 0) << v;
    id[v] = ((uint64_t)(o[2] + q[v][2]) * b->np[1] + (uint64_t)(o[1] + q[v][1])) * b->np[0] +
            (uint64_t)(o[0] + q[v][0]);
  }
  uint8_t tri[2][3][2];
  int n = obs_iso_tet_case(p, cs, tri);
  for (int r = 0; r < n; r++)
    for (int k = 0; k < 3; k++) {
      int u = tri[r][k][0], v = tri[r][k][1];
      if (id[u] > id[v]) u = tri[r][k][1], v = tri[r][k][0];
      if (bis_push(b, id[u] * b->npts + id[v], edge_t(fv[u], fv[v]))) return OBS_ENOMEM;
    }
  return 0;
}

static int bis_cells(bisect *b, int levels, int k0, int k1) {
  const extract *x = b->x;
  const int *c = x->l->c;
  static const uint8_t kuhn[6][4] = {{0, 1, 3, 7}, {0, 1, 5, 7}, {0, 2, 3, 7},
                                     {0, 2, 6, 7}, {0, 4, 5, 7}, {0, 4, 6, 7}};
  for (int k = k0; k < k1; k++)
    for (int j = 0; j < c[1]; j++)
      for (int i = 0; i < c[0]; i++) {
        int o[3] = {2 * i, 2 * j, 2 * k}, pos = 0, neg = 0;
        float f[27];
        for (int n = 0; n < 27; n++) {
          f[n] = obs_iso_lattice_value(x->v, x->l, x->iso, o[0] + n % 3, o[1] + n / 3 % 3,
                                       o[2] + n / 9);
          pos += f[n] >= 0;
          neg += f[n] < 0;
        }
        if (!pos || !neg) continue;
        for (int t = 0; t < 6; t++) {
          int8_t q[4][3];
          for (int v = 0; v < 4; v++)
            for (int a = 0; a < 3; a++) q[v][a] = (int8_t)(2 * (kuhn[t][v] >> a & 1));
          if (bis_tet(b, o, f, q, levels)) return OBS_ENOMEM;
        }
      }
  return 0;
}

static int cmp_edge(const void *a, const void *b) {
  uint64_t x = ((const bis_edge *)a)->key, y = ((const bis_edge *)b)->key;
  return x < y ? -1 : x > y;
}

/* The welded mesh of the emitted edges: unique keys in order become the vertices. */
static int bis_weld(bisect *b, obs_iso_mesh *m) {
  bis_edge *u = malloc((b->ne ? b->ne : 1) * sizeof *u);
  m->idx = malloc((b->ne ? b->ne : 1) * sizeof *m->idx);
  if (!u || !m->idx) {
    free(u);
    return OBS_ENOMEM;
  }
  if (b->ne) memcpy(u, b->e, b->ne * sizeof *u);
  qsort(u, b->ne, sizeof *u, cmp_edge);
  size_t nv = 0;
  for (size_t i = 0; i < b->ne; i++)
    if (!nv || u[i].key != u[nv - 1].key) u[nv++] = u[i];
  m->pos = malloc((nv ? nv : 1) * 3 * sizeof *m->pos);
  m->key = malloc((nv ? nv : 1) * sizeof *m->key);
  m->t = malloc((nv ? nv : 1) * sizeof *m->t);
  if (!m->pos || !m->key || !m->t) {
    free(u);
    return OBS_ENOMEM;
  }
  for (size_t i = 0; i < nv; i++) {
    uint64_t lo = u[i].key / b->npts, hi = u[i].key % b->npts;
    uint64_t pl[3] = {lo % b->np[0], lo / b->np[0] % b->np[1], lo / (b->np[0] * b->np[1])};
    uint64_t ph[3] = {hi % b->np[0], hi / b->np[0] % b->np[1], hi / (b->np[0] * b->np[1])};
    m->key[i] = u[i].key;
    m->t[i] = u[i].t;
    for (int a = 0; a < 3; a++)
      m->pos[3 * i + a] =
          m->lat.o[a] +
          0.5 * ((double)pl[a] + (double)u[i].t * ((double)ph[a] - (double)pl[a])) * m->lat.h[a];
  }
  for (size_t i = 0; i < b->ne; i++) {
    size_t lo = 0, hi = nv;
    while (hi - lo > 1) {
      size_t mid = (lo + hi) / 2;
      if (u[mid].key <= b->e[i].key)
        lo = mid;
      else
        hi = mid;
    }
    m->idx[i] = (uint32_t)lo;
  }
  m->nverts = nv;
  m->ntris = b->ne / 3;
  free(u);
  return 0;
}

static int slab_bisect(extract *x, slab *sl, int s) {
  (void)sl;
  int k0, k1;
  slab_range(x, s, &k0, &k1);
  return bis_cells(&x->bis[s], x->refine, k0, k1);
}

/* Each slab's edges in its cells' order, joined in slab order and welded. */
static int run_bisect(extract *x, obs_iso_mesh *m, int levels, int threads) {
  bisect *b = calloc((size_t)x->nslabs, sizeof *b);
  if (!b) return OBS_ENOMEM;
  x->bis = b;
  x->refine = levels;
  for (int s = 0; s < x->nslabs; s++) {
    b[s].x = x;
    for (int a = 0; a < 3; a++) b[s].np[a] = 2 * (uint64_t)x->l->c[a] + 1;
    b[s].npts = b[s].np[0] * b[s].np[1] * b[s].np[2];
  }
  int rc = slabs_run(x, NULL, threads, slab_bisect);
  for (int s = 1; !rc && s < x->nslabs; s++)
    for (size_t i = 0; !rc && i < b[s].ne; i++) rc = bis_push(&b[0], b[s].e[i].key, b[s].e[i].t);
  if (!rc) rc = bis_weld(&b[0], m);
  for (int s = 0; s < x->nslabs; s++) free(b[s].e);
  free(b);
  return rc;
}

int obs_iso_extract(const obs_volume *v, float iso, int cells, int refine, obs_iso_mesh *m,
                    obs_err *err) {
  return obs_iso_extract_threads(v, iso, cells, refine, 1, m, err);
}

int obs_iso_extract_threads(const obs_volume *v, float iso, int cells, int refine, int threads,
                            obs_iso_mesh *m, obs_err *err) {
  memset(m, 0, sizeof *m);
  if (refine < 0 || refine > OBS_ISO_REFINE_MAX)
    return obs_err_set(err, OBS_EINVAL, "isosurface: refine %d, not in 0..%d", refine,
                       OBS_ISO_REFINE_MAX);
  int rc = obs_iso_lattice_init(v, cells, &m->lat, err);
  if (rc) return rc;
  /* More slabs than threads evens out their shares of the surface; the output does not depend
   * on the count. */
  int slabs = threads > 1 ? 4 * threads : 1;
  extract x = {.v = v,
               .iso = iso,
               .refine = refine > 0,
               .l = &m->lat,
               .nslabs = slabs < m->lat.c[2] ? slabs : m->lat.c[2]};
  rc = refine > 1 ? run_bisect(&x, m, refine, threads) : run_extract(&x, m, threads);
  free(x.f);
  free(x.centre);
  free(x.layer_verts);
  free(x.tri_end);
  if (rc) {
    obs_iso_mesh_free(m);
    return obs_err_set(err, OBS_ENOMEM, "isosurface: out of memory extracting %d cells", cells);
  }
  return 0;
}

void obs_iso_mesh_free(obs_iso_mesh *m) {
  free(m->pos);
  free(m->key);
  free(m->t);
  free(m->idx);
  obs_iso_lattice_free(&m->lat);
  memset(m, 0, sizeof *m);
}

void obs_iso_mesh_measure(const obs_iso_mesh *m, double *area, double *volume) {
  double A = 0, V = 0;
  for (size_t t = 0; t < m->ntris; t++) {
    const double *a = m->pos + 3 * m->idx[3 * t], *b = m->pos + 3 * m->idx[3 * t + 1],
                 *c = m->pos + 3 * m->idx[3 * t + 2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                   e1[0] * e2[1] - e1[1] * e2[0]};
    A += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    /* Outward normals enclose the region above the isovalue with a positive signed volume. */
    V += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
          a[2] * (b[0] * c[1] - b[1] * c[0])) /
         6.0;
  }
  *area = A;
  *volume = V;
}

/* ---- a volume object's mesh ------------------------------------------------------------------ */

int obs_iso_shape_mesh(const obs_shape *s, obs_mesh *m, obs_err *err, const char *where) {
  memset(m, 0, sizeof *m);
  obs_volume v;
  obs_err e = OBS_ERR_INIT;
  int rc = obs_scene_volume_read_shape(s, &v, &e);
  int cells = s->volume.mesh_cells;
  if (cells <= 0) {
    cells = v.n[0] > v.n[1] ? v.n[0] : v.n[1];
    cells = (cells > v.n[2] ? cells : v.n[2]) - 1; /* one cell per voxel interval */
    if (cells < 1) cells = 1;
    if (cells > OBS_ISO_CELLS_MAX) cells = OBS_ISO_CELLS_MAX;
  }
  obs_iso_mesh im;
  memset(&im, 0, sizeof im);
  if (!rc) rc = obs_iso_extract(&v, (float)s->volume.isovalue, cells, 0, &im, &e);
  obs_volume_free(&v);
  if (!rc && im.nverts > UINT32_MAX) rc = obs_err_set(&e, OBS_EINVAL, "too many vertices");
  if (!rc) {
    m->pos = malloc((im.nverts ? im.nverts : 1) * 3 * sizeof(float));
    m->idx = malloc((im.ntris ? im.ntris : 1) * 3 * sizeof(uint32_t));
    if (!m->pos || !m->idx) rc = obs_err_set(&e, OBS_ENOMEM, "out of memory");
  }
  if (!rc) {
    /* Object space: the data box [0, extent] centred on the origin. */
    for (size_t i = 0; i < im.nverts; i++)
      for (int a = 0; a < 3; a++)
        m->pos[3 * i + a] = (float)(im.pos[3 * i + a] - 0.5 * s->volume.extent[a]);
    if (im.ntris) memcpy(m->idx, im.idx, im.ntris * 3 * sizeof(uint32_t));
    m->nverts = im.nverts;
    m->ntris = im.ntris;
  }
  obs_iso_mesh_free(&im);
  if (rc) {
    obs_geometry_mesh_free(m);
    rc = obs_err_set(err, rc, "%s: isosurface: %s", where, obs_err_message(&e));
  }
  obs_err_free(&e);
  return rc;
}
