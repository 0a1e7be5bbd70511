/* isosurface_mesh on Vulkan: each volume's isosurface extracted on the device in three compute
 * passes (the lattice's values; per point its crossed edges and its cell's triangles, which the
 * host sums into each point's first vertex and first triangle; the vertices and triangles written
 * at those places), so the mesh has the CPU's order and, from the same float field, its topology;
 * then read back, carried to the camera's frame and rasterised into depth, normal and coverage by
 * the device's G-buffer pass. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "driver.h"
#include "gbuffer.h"
#include "isosurface_mesh.h"
#include "layout.h"
#include "session_vk.h"
#include "shaders.h"
#include "vk.h"

_Static_assert(OBS_ISO_T_BINDING == OBS_VK_MAX_TEXTURES, "layout.h's buffer binding");
_Static_assert(OBS_ISO_SLOTS == 15, "the shaders' 15 edge slots");

static uint32_t rows(size_t n) { return n ? (uint32_t)((n + OBS_ISO_W - 1) / OBS_ISO_W) : 1; }

/* The table buffer: the lattice's axis tables, then the polygonisation table (layout.h). */
static uint32_t *pack_tables(const obs_iso_lattice *l, int refine, obs_iso_push *pc, size_t *n) {
  const obs_iso_table *tb = obs_iso_table_get(refine);
  size_t count = 0;
  for (int a = 0; a < 3; a++) count += 3 * (2 * (size_t)l->c[a] + 1);
  count += (size_t)tb->ntets * (4 + 16 + 16 * 12);
  uint32_t *d = malloc(count * sizeof *d);
  if (!d) return NULL;
  size_t at = 0;
  for (int a = 0; a < 3; a++) {
    size_t m = 2 * (size_t)l->c[a] + 1;
    pc->axis[a] = (int32_t)at;
    for (size_t i = 0; i < m; i++) d[at + i] = (uint32_t)l->i0[a][i];
    for (size_t i = 0; i < m; i++) d[at + m + i] = (uint32_t)l->i1[a][i];
    memcpy(d + at + 2 * m, l->w[a], m * sizeof(float));
    at += 3 * m;
  }
  pc->axis[3] = (int32_t)at;
  for (int t = 0; t < tb->ntets; t++)
    for (int q = 0; q < 4; q++) d[at++] = tb->tet[t][q];
  for (int t = 0; t < tb->ntets; t++)
    for (int cs = 0; cs < 16; cs++) d[at++] = tb->ntri[t][cs];
  for (int t = 0; t < tb->ntets; t++)
    for (int cs = 0; cs < 16; cs++)
      for (int r = 0; r < 2; r++)
        for (int e = 0; e < 3; e++)
          for (int end = 0; end < 2; end++) d[at++] = tb->edge[t][cs][r][e][end];
  *n = count;
  return d;
}

typedef struct dev {
  obs_vk_texture *vol;
  obs_vk_data *tables;
  obs_vk_image *img[OBS_ISO_IMAGES];
} dev;

static void dev_free(obs_vk *vk, dev *d) {
  obs_vk_texture_free(vk, d->vol);
  obs_vk_data_free(vk, d->tables);
  for (int i = 0; i < OBS_ISO_IMAGES; i++)
    if (d->img[i]) obs_vk_image_free(vk, d->img[i]);
  memset(d, 0, sizeof *d);
}

static obs_vk_pass make_pass(const char *name, const uint32_t *spv, size_t size, dev *d,
                             const obs_iso_push *pc) {
  obs_vk_pass p = {.name = name,
                   .spirv = spv,
                   .spirv_size = size,
                   .nimages = OBS_ISO_IMAGES,
                   .push = pc,
                   .push_size = sizeof *pc,
                   .groups_x = OBS_ISO_W / 64,
                   .groups_y = rows((size_t)pc->npoints),
                   .groups_z = 1,
                   .ntextures = 1,
                   .data = d->tables};
  p.textures[0] = d->vol;
  for (int i = 0; i < OBS_ISO_IMAGES; i++) p.images[i] = d->img[i];
  return p;
}

/* Replaces image slot i by a fresh one of n elements and `ch` channels (1 or 4). */
static int set_image(obs_vk *vk, dev *d, int i, size_t n, int ch, obs_err *err) {
  if (d->img[i]) obs_vk_image_free(vk, d->img[i]);
  d->img[i] = NULL;
  return obs_vk_image_create(vk, n ? OBS_ISO_W : 1, (int)rows(n), ch, &d->img[i], err);
}

/* The volume, its tables and the first passes' images on the device. */
static int upload(obs_vk *vk, const obs_volume *v, const obs_iso_lattice *l, int refine,
                  obs_iso_push *pc, dev *d, obs_err *err) {
  obs_vk_texture_desc td = {OBS_VK_TEXTURE_3D, v->n[0], v->n[1], v->n[2], 1, 0};
  static const int zero[3] = {0, 0, 0};
  int rc = obs_vk_texture_create(vk, &td, &d->vol, err);
  if (!rc) rc = obs_vk_texture_upload(vk, d->vol, zero, v->n, v->data, err);
  size_t nt = 0;
  uint32_t *t = pack_tables(l, refine, pc, &nt);
  if (!rc && !t) rc = obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  if (!rc) rc = obs_vk_data_create(vk, t, nt * sizeof *t, &d->tables, err);
  free(t);
  size_t cells = (size_t)l->c[0] * (size_t)l->c[1] * (size_t)l->c[2];
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_VALUES, (size_t)pc->npoints, 1, err);
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_CENTRE, refine ? cells : 0, 1, err);
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_COUNTS, (size_t)pc->npoints, 4, err);
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_BASES, (size_t)pc->npoints, 4, err);
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_VERTS, 0, 4, err);
  if (!rc) rc = set_image(vk, d, OBS_ISO_B_TRIS, 0, 4, err);
  return rc;
}

/* The counts into each point's first vertex and triangle (exclusive prefix sums in point order,
 * the CPU's), in place; the totals. Indices travel as floats: exact below 2^24. */
static int prefix(float *c, size_t npoints, size_t *nv, size_t *nt, obs_err *err) {
  double v = 0, t = 0;
  for (size_t i = 0; i < npoints; i++) {
    double cv = c[4 * i], ct = c[4 * i + 1];
    c[4 * i] = (float)v;
    c[4 * i + 1] = (float)t;
    v += cv;
    t += ct;
  }
  if (v >= 0x1p24 || t >= 0x1p24)
    return obs_err_set(err, OBS_EINVAL,
                       "isosurface_mesh: %.0f vertices and %.0f triangles; the Vulkan extractor "
                       "indexes at most 2^24 (lower grid)",
                       v, t);
  *nv = (size_t)v;
  *nt = (size_t)t;
  return 0;
}

/* The device's vertices and triangles into m (positions from each edge's key and t, in double,
 * as the CPU places them). */
static int read_mesh(obs_vk *vk, dev *d, size_t nv, size_t nt, obs_iso_mesh *m, obs_err *err) {
  float *vb = malloc((size_t)OBS_ISO_W * rows(nv) * 4 * sizeof(float));
  float *tb = malloc((size_t)OBS_ISO_W * rows(nt) * 4 * sizeof(float));
  m->pos = malloc((nv ? nv : 1) * 3 * sizeof(double));
  m->key = malloc((nv ? nv : 1) * sizeof *m->key);
  m->t = malloc((nv ? nv : 1) * sizeof(float));
  m->idx = malloc((nt ? nt : 1) * 3 * sizeof(uint32_t));
  int rc = vb && tb && m->pos && m->key && m->t && m->idx
               ? 0
               : obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  if (!rc && nv) rc = obs_vk_image_download(vk, d->img[OBS_ISO_B_VERTS], vb, err);
  if (!rc && nt) rc = obs_vk_image_download(vk, d->img[OBS_ISO_B_TRIS], tb, err);
  for (size_t i = 0; !rc && i < nv; i++) {
    uint32_t bits;
    memcpy(&bits, vb + 4 * i + 1, sizeof bits);
    m->key[i] = bits & ~OBS_ISO_KEY_BIAS;
    m->t[i] = vb[4 * i];
    obs_iso_key_point(&m->lat, (uint32_t)m->key[i], m->t[i], m->pos + 3 * i);
  }
  for (size_t i = 0; !rc && i < nt; i++)
    for (int k = 0; k < 3; k++) {
      float x = tb[4 * i + k];
      if (!(x >= 0 && x < (float)nv))
        rc = obs_err_set(err, OBS_EINTERNAL, "isosurface_mesh: triangle %zu's corner %g", i, x);
      else
        m->idx[3 * i + k] = (uint32_t)x;
    }
  m->nverts = nv;
  m->ntris = nt;
  free(vb);
  free(tb);
  return rc;
}

int obs_isosurface_mesh_vk_extract(obs_vk *vk, const obs_volume *v, float iso, int cells,
                                   int refine, obs_iso_mesh *m, double *ms, obs_err *err) {
  memset(m, 0, sizeof *m);
  if (refine < 0 || refine > 1)
    return obs_err_set(err, OBS_EINVAL,
                       "isosurface_mesh: refine %d, not 0 or 1 (the vulkan extractor bisects at "
                       "most 1 level)",
                       refine);
  int rc = obs_iso_lattice_init(v, cells, &m->lat, err);
  if (rc) return rc;
  const obs_iso_lattice *l = &m->lat;
  obs_iso_push pc = {.c = {l->c[0], l->c[1], l->c[2], refine}, .iso = iso};
  size_t npoints = (size_t)(l->c[0] + 1) * (size_t)(l->c[1] + 1) * (size_t)(l->c[2] + 1);
  pc.npoints = (int32_t)npoints;
  dev d;
  memset(&d, 0, sizeof d);
  double t[3] = {0, 0, 0};
  float *counts = malloc((size_t)OBS_ISO_W * rows(npoints) * 4 * sizeof(float));
  size_t nv = 0, nt = 0;
  rc = counts ? upload(vk, v, l, refine, &pc, &d, err)
              : obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  if (!rc) {
    obs_vk_pass p[2] = {make_pass("iso_values", obs_spv_isosurface_mesh_values_comp,
                                  obs_spv_isosurface_mesh_values_comp_size, &d, &pc),
                        make_pass("iso_count", obs_spv_isosurface_mesh_count_comp,
                                  obs_spv_isosurface_mesh_count_comp_size, &d, &pc)};
    rc = obs_vk_run(vk, p, 2, t, err);
  }
  if (!rc) rc = obs_vk_image_download(vk, d.img[OBS_ISO_B_COUNTS], counts, err);
  if (!rc) rc = prefix(counts, npoints, &nv, &nt, err);
  if (!rc) rc = obs_vk_image_upload(vk, d.img[OBS_ISO_B_BASES], counts, err);
  if (!rc) rc = set_image(vk, &d, OBS_ISO_B_VERTS, nv, 4, err);
  if (!rc) rc = set_image(vk, &d, OBS_ISO_B_TRIS, nt, 4, err);
  if (!rc) {
    obs_vk_pass p = make_pass("iso_emit", obs_spv_isosurface_mesh_emit_comp,
                              obs_spv_isosurface_mesh_emit_comp_size, &d, &pc);
    rc = obs_vk_run(vk, &p, 1, t + 2, err);
  }
  if (!rc) rc = read_mesh(vk, &d, nv, nt, m, err);
  free(counts);
  dev_free(vk, &d);
  if (ms) *ms = t[0] + t[1] + t[2];
  if (rc) obs_iso_mesh_free(m);
  return rc;
}

typedef struct vjob {
  obs_image *out;
} vjob;

/* The device's G-buffer of the meshes into the outputs: view depth, the face normal turned from
 * the view frame (right, up, forward) to the world, coverage. */
static int export_gbuffer(obs_render_ctx *ctx, const obs_camera_rig *rig, const obs_gbuffer *g,
                          obs_image *out, obs_err *err) {
  obs_region r;
  int rc = obs_driver_image(ctx, ISO_CH_COUNT, obs_isosurface_mesh_channels, out, &r, err);
  if (rc) return rc;
  size_t plane = (size_t)out->width * (size_t)out->height;
  for (int y = r.y0; y < r.y1; y++)
    for (int x = r.x0; x < r.x1; x++) {
      size_t i = (size_t)y * (size_t)out->width + (size_t)x;
      if (!(g->coverage[i] > 0)) continue;
      const float *nv = g->normal + 3 * i;
      for (int k = 0; k < 3; k++)
        out->data[(ISO_CH_NX + k) * plane + i] =
            (float)(nv[0] * rig->right[k] + nv[1] * rig->up[k] + nv[2] * rig->forward[k]);
      out->data[ISO_CH_DEPTH * plane + i] = g->depth[i];
      out->data[ISO_CH_ALPHA * plane + i] = 1.0f;
    }
  return 0;
}

static int render(obs_render_ctx *ctx, obs_vk *vk, void *user, obs_err *err) {
  vjob *j = user;
  const obs_scene *sc = ctx->scene;
  const obs_isosurface_mesh_params *p = ctx->bound;
  const obs_scene_volumes *vs = ctx->volumes;
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  double start = obs_now_ms();
  obs_geometry geo;
  memset(&geo, 0, sizeof geo);
  memcpy(geo.origin, rig.origin, sizeof geo.origin);
  geo.meshes = calloc(vs->n ? vs->n : 1, sizeof *geo.meshes);
  geo.spheres = calloc(1, sizeof *geo.spheres);
  int rc = geo.meshes && geo.spheres
               ? 0
               : obs_err_set(err, OBS_ENOMEM, "isosurface_mesh: out of memory");
  double extract_ms = 0;
  for (size_t i = 0; !rc && i < vs->n; i++) {
    const obs_scene_volume *sv = &vs->v[i];
    if (sv->brick) {
      rc = obs_err_set(err, OBS_EUNSUPPORTED,
                       "%s: /objects/%zu: isosurface_mesh extracts whole volumes, not one brick",
                       sc->name, sv->object);
      break;
    }
    obs_iso_mesh im;
    double t0 = obs_now_ms(), dev_ms = 0;
    rc = obs_isosurface_mesh_vk_extract(vk, &sv->v, sv->iso, p->grid, p->refine, &im, &dev_ms, err);
    if (rc) break;
    double ms = obs_now_ms() - t0;
    extract_ms += ms;
    rc = obs_iso_mesh_world(sv, &im, rig.origin, 1.0, 0, &geo.meshes[geo.nmeshes]);
    if (!rc) {
      obs_iso_mesh_record(ctx, sv, &im, ms);
      geo.ntris += im.ntris;
      geo.nmeshes++;
    } else {
      rc = obs_err_set(err, rc, "isosurface_mesh: out of memory");
    }
    obs_iso_mesh_free(&im);
  }
  obs_render_ctx_stage(ctx, "extract", extract_ms);
  obs_vk_gbuffer dev;
  memset(&dev, 0, sizeof dev);
  obs_gbuffer host;
  memset(&host, 0, sizeof host);
  double gb_ms = 0, t0 = obs_now_ms();
  if (!rc) rc = obs_vk_gbuffer_render(vk, sc, &geo, &dev, &gb_ms, err);
  if (!rc) rc = obs_gbuffer_alloc(&host, sc->width, sc->height, &rig, err);
  if (!rc) rc = obs_vk_gbuffer_download(vk, &dev, &host, 0, err);
  if (!rc) obs_render_ctx_stage(ctx, "gbuffer", obs_now_ms() - t0);
  if (!rc) rc = export_gbuffer(ctx, &rig, &host, j->out, err);
  obs_vk_gbuffer_free(vk, &dev);
  obs_gbuffer_free(&host);
  obs_geometry_free(&geo);
  ctx->render_ms = obs_now_ms() - start;
  return rc;
}

int obs_isosurface_mesh_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  if (!ctx->volumes)
    return obs_err_set(err, OBS_EINTERNAL, "%s: isosurface_mesh: the volumes were not read",
                       ctx->scene->name);
  vjob j = {out};
  memset(out, 0, sizeof *out);
  int rc = obs_vk_session_run(ctx, "isosurface_mesh", render, &j, err);
  if (rc) obs_image_free(out);
  return rc;
}
