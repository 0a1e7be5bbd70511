/* 8-bit PNG output (previews, AO maps) and input (reference images) of obs_image via libspng. */
#include "obscura/image.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <spng.h>
#include <zlib.h>

static double png_srgb_encode(double v) {
  return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

static uint8_t png_quantize(float f, int gamma_encode) {
  if (isnan(f)) return 0;
  double v = f < 0.0f ? 0.0 : (f > 1.0f ? 1.0 : (double)f);
  if (gamma_encode) v = png_srgb_encode(v);
  /* Round half up (not lrint's half-to-even) so 0.5 -> 128 as documented; double keeps the
   * product exact for every float input. */
  int q = (int)floor(v * 255.0 + 0.5);
  return (uint8_t)(q < 0 ? 0 : (q > 255 ? 255 : q));
}

/* The "up" filter and deflate matching only runs of one byte (zlib's Z_RLE), chosen by measurement
 * on every image obs_result_write writes (docs/performance.md, "Writing outputs"): against
 * libspng's default (level 6, Z_FILTERED, every row trying all five filters) a fifth to a quarter
 * of the time for files within 3 % of its size (ao.png even 23 % smaller). Longer matches find
 * little in noisy AO and normals, and with run-length matching the level makes no difference. */
obs_png_opts obs_png_opts_default(void) {
  obs_png_opts o = {6, OBS_PNG_FILTER_UP, OBS_PNG_STRATEGY_RLE};
  return o;
}



static int png_filter_choice(int f) {
  switch (f) {
    case OBS_PNG_FILTER_NONE: return SPNG_FILTER_CHOICE_NONE;
    case OBS_PNG_FILTER_SUB: return SPNG_FILTER_CHOICE_SUB;
    case OBS_PNG_FILTER_UP: return SPNG_FILTER_CHOICE_UP;
    case OBS_PNG_FILTER_PAETH: return SPNG_FILTER_CHOICE_PAETH;
    default: return SPNG_FILTER_CHOICE_ALL;
  }
}

int obs_image_write_png(const obs_image *img, const char *const *channels, int nchannels,
                        int gamma_encode, const char *path, obs_err *err) {
  return obs_image_write_png_opts(img, channels, nchannels, gamma_encode, path, NULL, err);
}

int obs_image_write_png_opts(const obs_image *img, const char *const *channels, int nchannels,
                             int gamma_encode, const char *path, const obs_png_opts *opts,
                             obs_err *err) {
  obs_png_opts o = opts ? *opts : obs_png_opts_default();
  if (!path || !path[0]) return obs_err_set(err, OBS_EINVAL, "PNG write: empty output path");
  if (!img || !img->data || img->width <= 0 || img->height <= 0)
    return obs_err_set(err, OBS_EINVAL, "%s: cannot write PNG: image is empty or uninitialised",
                       path);
  if (!channels || (nchannels != 1 && nchannels != 3))
    return obs_err_set(err, OBS_EINVAL,
                       "%s: cannot write PNG: need 1 (grey) or 3 (RGB) channels, got %d", path,
                       nchannels);
  if (o.level < -1 || o.level > 9 || o.filter < 0 || o.filter >= OBS_PNG_NFILTERS ||
      o.strategy < 0 || o.strategy >= OBS_PNG_NSTRATEGIES)
    return obs_err_set(err, OBS_EINVAL,
                       "%s: cannot write PNG: level %d / filter %d / strategy %d is not offered",
                       path, o.level, o.filter, o.strategy);
  const float *planes[3];
  for (int c = 0; c < nchannels; c++) {
    planes[c] = obs_image_channel(img, channels[c]);
    if (!planes[c])
      return obs_err_set(err, OBS_ENOTFOUND, "%s: cannot write PNG: image has no channel \"%s\"",
                         path, channels[c] ? channels[c] : "(null)");
  }

  size_t npix = (size_t)img->width * (size_t)img->height;
  if (npix > SIZE_MAX / (size_t)nchannels)
    return obs_err_set(err, OBS_ENOMEM, "%s: image too large for PNG", path);
  uint8_t *buf = malloc(npix * (size_t)nchannels);
  if (!buf) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  for (size_t i = 0; i < npix; i++)
    for (int c = 0; c < nchannels; c++)
      buf[i * (size_t)nchannels + (size_t)c] = png_quantize(planes[c][i], gamma_encode);

  size_t plen = strlen(path);
  char *tmp = malloc(plen + 5);
  if (!tmp) {
    free(buf);
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  }
  memcpy(tmp, path, plen);
  memcpy(tmp + plen, ".tmp", 5);

  int code = OBS_OK;
  spng_ctx *ctx = NULL;
  FILE *fp = fopen(tmp, "wb");
  if (!fp) {
    code = obs_err_set(err, OBS_EIO, "%s: cannot write PNG: cannot create %s: %s", path, tmp,
                       strerror(errno));
    goto done;
  }
  ctx = spng_ctx_new(SPNG_CTX_ENCODER);
  if (!ctx) {
    code = obs_err_set(err, OBS_ENOMEM, "%s: cannot write PNG: out of memory", path);
    goto done;
  }
  struct spng_ihdr ihdr = {
      .width = (uint32_t)img->width,
      .height = (uint32_t)img->height,
      .bit_depth = 8,
      .color_type = nchannels == 1 ? SPNG_COLOR_TYPE_GRAYSCALE : SPNG_COLOR_TYPE_TRUECOLOR,
  };
  int rc = spng_set_png_file(ctx, fp);
  if (!rc) rc = spng_set_ihdr(ctx, &ihdr);
  /* Tag gamma-encoded output as sRGB so viewers do not guess; linear data stays untagged. */
  if (!rc && gamma_encode) rc = spng_set_srgb(ctx, 0);
  if (!rc) rc = spng_set_option(ctx, SPNG_FILTER_CHOICE, png_filter_choice(o.filter));
  if (!rc && o.level >= 0) rc = spng_set_option(ctx, SPNG_IMG_COMPRESSION_LEVEL, o.level);
  if (!rc && o.strategy != OBS_PNG_STRATEGY_DEFAULT)
    rc = spng_set_option(ctx, SPNG_IMG_COMPRESSION_STRATEGY,
                         o.strategy == OBS_PNG_STRATEGY_RLE ? Z_RLE : Z_HUFFMAN_ONLY);
  if (!rc)
    rc = spng_encode_image(ctx, buf, npix * (size_t)nchannels, SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE);
  if (rc) {
    code = obs_err_set(err, OBS_EIO, "%s: cannot write PNG: %s", path, spng_strerror(rc));
    goto done;
  }
  spng_ctx_free(ctx);
  ctx = NULL;
  /* fsync before rename so a crash or power loss never publishes a truncated file. */
  int bad = fflush(fp) != 0 || fsync(fileno(fp)) != 0;
  bad |= fclose(fp) != 0;
  fp = NULL;
  if (bad || rename(tmp, path) != 0) {
    code = obs_err_set(err, OBS_EIO, "%s: cannot write PNG: finishing %s failed: %s", path, tmp,
                       strerror(errno));
    goto done;
  }

done:
  spng_ctx_free(ctx);
  if (fp) fclose(fp);
  if (code) unlink(tmp);
  free(tmp);
  free(buf);
  return code;
}

int obs_image_read_png(obs_image *img, const char *path, obs_err *err) {
  if (!img) return obs_err_set(err, OBS_EINVAL, "PNG read: NULL image pointer");
  memset(img, 0, sizeof *img);
  if (!path || !path[0]) return obs_err_set(err, OBS_EINVAL, "PNG read: empty input path");

  int code = OBS_OK;
  uint8_t *buf = NULL;
  spng_ctx *ctx = NULL;
  FILE *fp = fopen(path, "rb");
  if (!fp) {
    code = obs_err_set(err, OBS_EIO, "%s: cannot read PNG: %s", path, strerror(errno));
    goto done;
  }
  ctx = spng_ctx_new(0);
  if (!ctx) {
    code = obs_err_set(err, OBS_ENOMEM, "%s: cannot read PNG: out of memory", path);
    goto done;
  }
  struct spng_ihdr ihdr;
  int rc = spng_set_png_file(ctx, fp);
  if (!rc) rc = spng_get_ihdr(ctx, &ihdr);
  if (rc) {
    code = obs_err_set(err, OBS_EINVAL, "%s: not a readable PNG: %s", path, spng_strerror(rc));
    goto done;
  }
  if (ihdr.width > INT32_MAX || ihdr.height > INT32_MAX) {
    code = obs_err_set(err, OBS_EUNSUPPORTED, "%s: PNG is too large (%ux%u)", path, ihdr.width,
                       ihdr.height);
    goto done;
  }
  int grey = ihdr.color_type == SPNG_COLOR_TYPE_GRAYSCALE ||
             ihdr.color_type == SPNG_COLOR_TYPE_GRAYSCALE_ALPHA;
  /* G8 only exists for plain greyscale of depth <= 8; everything else goes through RGBA8, which
   * libspng can produce from every colour type and depth (16-bit is scaled down). */
  int fmt = (ihdr.color_type == SPNG_COLOR_TYPE_GRAYSCALE && ihdr.bit_depth <= 8) ? SPNG_FMT_G8
                                                                                  : SPNG_FMT_RGBA8;
  size_t len = 0;
  rc = spng_decoded_image_size(ctx, fmt, &len);
  if (!rc) {
    buf = malloc(len ? len : 1);
    if (!buf) {
      code = obs_err_set(err, OBS_ENOMEM, "%s: cannot read PNG: out of memory", path);
      goto done;
    }
    rc = spng_decode_image(ctx, buf, len, fmt, 0);
  }
  if (rc) {
    code = obs_err_set(err, OBS_EINVAL, "%s: cannot decode PNG: %s", path, spng_strerror(rc));
    goto done;
  }

  static const char *const grey_names[] = {"Y"};
  static const char *const rgb_names[] = {"R", "G", "B"};
  int nch = grey ? 1 : 3;
  code = obs_image_init(img, (int)ihdr.width, (int)ihdr.height, nch, grey ? grey_names : rgb_names,
                        err);
  if (code) {
    obs_err_set(err, code, "%s: cannot hold the PNG image", path);
    goto done;
  }
  size_t npix = (size_t)img->width * (size_t)img->height;
  size_t stride = fmt == SPNG_FMT_G8 ? 1 : 4;
  for (int c = 0; c < nch; c++) {
    float *dst = img->data + (size_t)c * npix;
    for (size_t i = 0; i < npix; i++) dst[i] = (float)buf[i * stride + (size_t)c] / 255.0f;
  }

done:
  spng_ctx_free(ctx);
  if (fp) fclose(fp);
  free(buf);
  return code;
}
