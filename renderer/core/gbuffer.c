/* G-buffer storage and its export into a technique's output channels. */
#include "gbuffer.h"

#include <stdlib.h>
#include <string.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

#include "obscura/backend.h"

const char *const obs_screen_channel_names[OBS_SCREEN_CHANNELS] = {
    "ao", "ao_raw", "depth.Z", "normal.X", "normal.Y", "normal.Z", "alpha"};

/* The outputs of every screen-space technique: the channels the screen-space drivers write
 * (obs_screen_channel_names), so every screen-space technique declares this one table. */
const obs_output obs_screen_outputs[] = {
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Ambient occlusion (white = open, black = fully occluded)",
     .flags = OBS_OUTPUT_PRIMARY | OBS_OUTPUT_UNIT},
    {.name = "ao_raw", .kind = OBS_OUTPUT_SCALAR,
     .description = "Ambient occlusion before the blur"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

/* n floats, not zeroed. Large ones on 2 MiB boundaries and marked for huge pages where the
 * system has them: a tile's rows reach 4 rows of pages per buffer, and with 4 KiB pages their
 * address translations miss far more than the stores do. */
static float *unset_floats(size_t n) {
  const size_t bytes = (n ? n : 1) * sizeof(float), huge = (size_t)2 << 20;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (bytes >= 2 * huge) {
    void *p = NULL;
    if (posix_memalign(&p, huge, bytes)) return NULL;
    madvise(p, bytes & ~(huge - 1), MADV_HUGEPAGE); /* advice only: failure is harmless */
    return p;
  }
#endif
  return malloc(bytes);
}

static int gbuffer_alloc(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig, int zero,
                         obs_err *err) {
  memset(g, 0, sizeof *g);
  size_t n = (size_t)width * (size_t)height;
  float *mem = zero ? calloc(n * 8, sizeof(float)) : unset_floats(n * 8);
  if (!mem) return obs_err_set(err, OBS_ENOMEM, "G-buffer %dx%d: out of memory", width, height);
  g->width = width;
  g->height = height;
  g->ortho = rig->ortho;
  g->half_w = (float)rig->half_w;
  g->half_h = (float)rig->half_h;
  g->depth = mem;
  g->normal = mem + n;
  g->albedo = mem + 4 * n;
  g->coverage = mem + 7 * n;
  return 0;
}

int obs_gbuffer_alloc(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig,
                      obs_err *err) {
  return gbuffer_alloc(g, width, height, rig, 1, err);
}

int obs_gbuffer_alloc_unset(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig,
                            obs_err *err) {
  return gbuffer_alloc(g, width, height, rig, 0, err);
}

void obs_gbuffer_free(obs_gbuffer *g) {
  free(g->depth);
  memset(g, 0, sizeof *g);
}

void obs_gbuffer_export(const obs_gbuffer *g, const obs_camera_rig *rig, obs_image *img) {
  size_t n = (size_t)g->width * (size_t)g->height;
  float *d = obs_image_channel(img, "depth.Z"), *a = obs_image_channel(img, "alpha");
  float *nx = obs_image_channel(img, "normal.X"), *ny = obs_image_channel(img, "normal.Y");
  float *nz = obs_image_channel(img, "normal.Z");
  for (size_t i = 0; i < n; i++) {
    const float *v = g->normal + 3 * i;
    float w[3];
    for (int k = 0; k < 3; k++)
      w[k] = (float)(v[0] * rig->right[k] + v[1] * rig->up[k] + v[2] * rig->forward[k]);
    if (d) d[i] = g->depth[i];
    if (a) a[i] = g->coverage[i];
    if (nx) nx[i] = w[0];
    if (ny) ny[i] = w[1];
    if (nz) nz[i] = w[2];
  }
}

static int cmp_float(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

int obs_gbuffer_median_depth(const obs_scene *scene, obs_backend_gbuffer_fn gbuffer, int max_side,
                             int threads, double *out, obs_err *err) {
  /* A shallow copy with a smaller image: the G-buffer only reads the camera, the size and the
   * geometry, and the aspect ratio (hence the camera rig) is kept. */
  obs_scene coarse = *scene;
  int side = scene->width > scene->height ? scene->width : scene->height;
  if (max_side > 0 && side > max_side) {
    double s = (double)max_side / side;
    coarse.width = (int)(scene->width * s + 0.5);
    coarse.height = (int)(scene->height * s + 0.5);
    if (coarse.width < 1) coarse.width = 1;
    if (coarse.height < 1) coarse.height = 1;
  }
  if (!gbuffer)
    return obs_err_set(err, OBS_EUNSUPPORTED, "%s: no backend makes a host G-buffer",
                       scene->name ? scene->name : "scene");
  obs_gbuffer g;
  double build_ms = 0, render_ms = 0;
  int rc = gbuffer(&coarse, &g, threads > 0 ? threads : 1, &build_ms, &render_ms, err);
  if (rc) return rc;
  size_t n = (size_t)g.width * (size_t)g.height, k = 0;
  for (size_t i = 0; i < n; i++)
    if (g.coverage[i] > 0.0f) g.depth[k++] = g.depth[i]; /* compacted in place */
  if (k == 0) {
    obs_gbuffer_free(&g);
    return obs_err_set(err, OBS_EINVAL, "%s: no surface covers the image, so there is no median "
                       "view depth", scene->name ? scene->name : "scene");
  }
  qsort(g.depth, k, sizeof *g.depth, cmp_float);
  *out = k % 2 ? g.depth[k / 2] : 0.5 * ((double)g.depth[k / 2 - 1] + g.depth[k / 2]);
  obs_gbuffer_free(&g);
  return 0;
}
