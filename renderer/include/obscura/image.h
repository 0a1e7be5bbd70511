/* Float images with named channels, and their EXR (OpenEXRCore) and PNG (libspng) files. */
#ifndef OBSCURA_IMAGE_H
#define OBSCURA_IMAGE_H

#include <stdint.h>
#include "obscura/error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OBS_IMAGE_MAX_CHANNELS 32
#define OBS_CHANNEL_NAME_MAX 32

/* A width x height image of `nchannels` float planes. Row 0 is the top row. The image owns `data`
 * (one allocation, plane c starts at data + c*width*height); names are stored inline. */
typedef struct obs_image {
  int width;
  int height;
  int nchannels;
  char names[OBS_IMAGE_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  float *data;
} obs_image;

/* Allocates a zero-filled image with the given channel names (copied). */
int obs_image_init(obs_image *img, int width, int height, int nchannels, const char *const *names,
                   obs_err *err);
void obs_image_free(obs_image *img);
/* Pointer to plane `name`, or NULL when absent. Borrowed. */
float *obs_image_channel(const obs_image *img, const char *name);

/* Writes every channel as 32-bit float in one scanline EXR (ZIP compression). Channels are written
 * in the order EXR requires (sorted by name); reading back by name restores them. */
int obs_image_write_exr(const obs_image *img, const char *path, obs_err *err);
/* Reads every channel of a scanline or tiled EXR as float. `img` is initialised by the call and owned
 * by the caller afterwards. */
int obs_image_read_exr(obs_image *img, const char *path, obs_err *err);

/* Creates `dir` and any missing parents (like mkdir -p), so images can be written into it; an
 * existing directory is fine, an existing non-directory is an error naming it. */
int obs_image_make_dirs(const char *dir, obs_err *err);

/* Writes 8-bit PNG. With one channel name: greyscale; with three: RGB. Values are clamped to [0,1]
 * and mapped to 0..255 with round-to-nearest; NaN maps to 0. `gamma_encode` applies the sRGB
 * transfer curve first (use 0 for data such as AO that is shown linearly). */
int obs_image_write_png(const obs_image *img, const char *const *channels, int nchannels,
                        int gamma_encode, const char *path, obs_err *err);
/* Reads an 8-bit greyscale or RGB(A) PNG into channels "R","G","B" (or "Y" for grey) in [0,1]. */
int obs_image_read_png(obs_image *img, const char *path, obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
