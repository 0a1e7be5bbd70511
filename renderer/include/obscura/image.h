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
/* Renames the channels of output `from` to those of output `to` ("radiance" or "radiance.R" to
 * "final" / "final.R"): a reference technique may declare the quantity a candidate's output
 * estimates under another name (path_trace's `radiance` for obscurance's `final`). */
void obs_image_rename_output(obs_image *img, const char *from, const char *to);

/* EXR compressions the writer offers (all lossless). */
enum { OBS_EXR_NONE, OBS_EXR_RLE, OBS_EXR_ZIPS, OBS_EXR_ZIP, OBS_EXR_PIZ, OBS_EXR_NCOMPRESSIONS };

typedef struct obs_exr_opts {
  int compression; /* OBS_EXR_* */
  int zip_level;   /* deflate level 1..9 for ZIP/ZIPS; 0 = the library's default (6) */
  int threads;     /* chunks are compressed on this many threads (<= 1: the calling thread) */
} obs_exr_opts;

/* The writer's choice for every EXR obscura writes (RLE, one thread; see docs/performance.md,
 * "Writing outputs"). */
obs_exr_opts obs_exr_opts_default(void);

/* Writes every channel as 32-bit float in one scanline EXR, to `path` via `path`.tmp (removed on
 * failure). Channels are written in the order EXR requires (sorted by name); reading back by name
 * restores them. The file's bytes do not depend on opts->threads. NULL opts = the default. */
int obs_image_write_exr_opts(const obs_image *img, const char *path, const obs_exr_opts *opts,
                             obs_err *err);
/* obs_image_write_exr_opts with the default options, one thread. */
int obs_image_write_exr(const obs_image *img, const char *path, obs_err *err);
/* Reads every channel of a scanline or tiled EXR as float. `img` is initialised by the call and owned
 * by the caller afterwards. */
int obs_image_read_exr(obs_image *img, const char *path, obs_err *err);


/* PNG row filters the writer offers: ADAPTIVE lets every row try all five (libspng's default). */
enum { OBS_PNG_FILTER_ADAPTIVE, OBS_PNG_FILTER_NONE, OBS_PNG_FILTER_SUB, OBS_PNG_FILTER_UP,
       OBS_PNG_FILTER_PAETH, OBS_PNG_NFILTERS };

/* How deflate looks for repeats: DEFAULT is libspng's choice (zlib's Z_FILTERED for filtered rows,
 * Z_DEFAULT_STRATEGY for unfiltered); RLE only matches runs of one byte value (zlib's Z_RLE);
 * HUFFMAN matches nothing (Z_HUFFMAN_ONLY). */
enum { OBS_PNG_STRATEGY_DEFAULT, OBS_PNG_STRATEGY_RLE, OBS_PNG_STRATEGY_HUFFMAN,
       OBS_PNG_NSTRATEGIES };

typedef struct obs_png_opts {
  int level;    /* deflate level 0..9 (0 = stored); -1 = libspng's default (6) */
  int filter;   /* OBS_PNG_FILTER_* */
  int strategy; /* OBS_PNG_STRATEGY_* */
} obs_png_opts;

/* The writer's choice for every PNG obscura writes (the up filter, run-length deflate; see
 * docs/performance.md, "Writing outputs"). */
obs_png_opts obs_png_opts_default(void);

/* Writes 8-bit PNG. With one channel name: greyscale; with three: RGB. Values are clamped to [0,1]
 * and mapped to 0..255 with round-to-nearest; NaN maps to 0. `gamma_encode` applies the sRGB
 * transfer curve first (use 0 for data such as AO that is shown linearly). NULL opts = default. */
int obs_image_write_png_opts(const obs_image *img, const char *const *channels, int nchannels,
                             int gamma_encode, const char *path, const obs_png_opts *opts,
                             obs_err *err);
/* obs_image_write_png_opts with the default options. */
int obs_image_write_png(const obs_image *img, const char *const *channels, int nchannels,
                        int gamma_encode, const char *path, obs_err *err);
/* Reads an 8-bit greyscale or RGB(A) PNG into channels "R","G","B" (or "Y" for grey) in [0,1]. */
int obs_image_read_png(obs_image *img, const char *path, obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
