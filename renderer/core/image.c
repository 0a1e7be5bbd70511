/* Float image with named planes: allocation, release and channel lookup shared by EXR/PNG I/O,
 * and the output directories images are written into. */
#include "obscura/image.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int obs_image_init(obs_image *img, int width, int height, int nchannels, const char *const *names,
                   obs_err *err) {
  if (!img) return obs_err_set(err, OBS_EINVAL, "image: NULL image pointer");
  /* Zero first so obs_image_free is safe on every failure path below. */
  memset(img, 0, sizeof *img);
  if (width <= 0 || height <= 0)
    return obs_err_set(err, OBS_EINVAL, "image: invalid size %dx%d (both must be positive)", width,
                       height);
  if (nchannels <= 0 || nchannels > OBS_IMAGE_MAX_CHANNELS)
    return obs_err_set(err, OBS_EINVAL, "image: %d channels requested, must be 1..%d", nchannels,
                       OBS_IMAGE_MAX_CHANNELS);
  if (!names) return obs_err_set(err, OBS_EINVAL, "image: NULL channel name list");
  for (int c = 0; c < nchannels; c++) {
    const char *n = names[c];
    if (!n || !n[0]) return obs_err_set(err, OBS_EINVAL, "image: channel %d has no name", c);
    if (strlen(n) >= OBS_CHANNEL_NAME_MAX)
      return obs_err_set(err, OBS_EINVAL, "image: channel name \"%s\" is longer than %d bytes", n,
                         OBS_CHANNEL_NAME_MAX - 1);
    /* Channels are addressed by name, so a duplicate would silently shadow a plane. */
    for (int d = 0; d < c; d++)
      if (strcmp(names[d], n) == 0)
        return obs_err_set(err, OBS_EINVAL, "image: duplicate channel name \"%s\"", n);
  }
  size_t plane = (size_t)width * (size_t)height;
  if (plane / (size_t)width != (size_t)height ||
      plane > SIZE_MAX / sizeof(float) / (size_t)nchannels)
    return obs_err_set(err, OBS_ENOMEM, "image: %dx%d with %d channels overflows memory size",
                       width, height, nchannels);
  float *data = calloc(plane * (size_t)nchannels, sizeof(float));
  if (!data)
    return obs_err_set(err, OBS_ENOMEM, "image: cannot allocate %dx%d with %d channels", width,
                       height, nchannels);
  img->width = width;
  img->height = height;
  img->nchannels = nchannels;
  for (int c = 0; c < nchannels; c++) memcpy(img->names[c], names[c], strlen(names[c]) + 1);
  img->data = data;
  return OBS_OK;
}

void obs_image_free(obs_image *img) {
  if (!img) return;
  free(img->data);
  memset(img, 0, sizeof *img);
}

float *obs_image_channel(const obs_image *img, const char *name) {
  if (!img || !name || !img->data) return NULL;
  size_t plane = (size_t)img->width * (size_t)img->height;
  for (int c = 0; c < img->nchannels; c++)
    if (strcmp(img->names[c], name) == 0) return img->data + (size_t)c * plane;
  return NULL;
}

void obs_image_rename_output(obs_image *img, const char *from, const char *to) {
  size_t n = strlen(from);
  for (int c = 0; c < img->nchannels; c++) {
    char *name = img->names[c];
    if (strncmp(name, from, n) || (name[n] && name[n] != '.')) continue;
    char renamed[OBS_CHANNEL_NAME_MAX];
    snprintf(renamed, sizeof renamed, "%s%s", to, name + n);
    snprintf(name, OBS_CHANNEL_NAME_MAX, "%s", renamed);
  }
}
