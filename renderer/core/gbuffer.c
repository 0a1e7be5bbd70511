/* G-buffer storage and its export into a technique's output channels. */
#include "gbuffer.h"

#include <stdlib.h>
#include <string.h>

const char *const obs_screen_channel_names[OBS_SCREEN_CHANNELS] = {
    "ao", "ao_raw", "depth.Z", "normal.X", "normal.Y", "normal.Z", "alpha"};

int obs_gbuffer_alloc(obs_gbuffer *g, int width, int height, const obs_camera_rig *rig,
                      obs_err *err) {
  memset(g, 0, sizeof *g);
  size_t n = (size_t)width * (size_t)height;
  float *mem = calloc(n * 8, sizeof(float));
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
