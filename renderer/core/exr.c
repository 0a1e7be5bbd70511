/* EXR output and input of obs_image through the C-only OpenEXRCore library. */
#include "obscura/image.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <openexr.h>

#include "parallel.h"

/* OpenEXRCore reports details only through a callback (stderr by default, which would spam test
 * logs and lose the text). Contexts are used by one thread at a time here, so a thread-local slot
 * holding the first message since the last reset is enough to put the library's reason into
 * obs_err. The first message is kept because later ones are usually consequences of it. */
static _Thread_local char exr_last_msg[512];

static void exr_capture(exr_const_context_t ctx, exr_result_t code, const char *msg) {
  (void)ctx;
  if (exr_last_msg[0]) return;
  snprintf(exr_last_msg, sizeof exr_last_msg, "%s",
           msg ? msg : exr_get_default_error_message(code));
}

static const char *exr_why(exr_result_t rc) {
  return exr_last_msg[0] ? exr_last_msg : exr_get_default_error_message(rc);
}

static exr_context_initializer_t exr_init_opts(int flags) {
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = exr_capture;
  init.flags = flags;
  exr_last_msg[0] = '\0';
  return init;
}

/* `fallback` is what an unclassified failure means: bad file content on read, a library fault on
 * write (where every input was validated first). A short read means the file opened fine but ends
 * too early (empty, truncated), which is bad content rather than an I/O failure, so READ_IO follows
 * the fallback too. */
static int exr_code(exr_result_t rc, int fallback) {
  switch (rc) {
    case EXR_ERR_OUT_OF_MEMORY: return OBS_ENOMEM;
    case EXR_ERR_FILE_ACCESS:
    case EXR_ERR_WRITE_IO: return OBS_EIO;
    case EXR_ERR_FEATURE_NOT_IMPLEMENTED: return OBS_EUNSUPPORTED;
    default: return fallback;
  }
}

/* ---------------------------------------------------------------------------------------------- */
/* Writing */

/* Fills the encoder's channel table for one chunk. The encoder lists channels in file order
 * (sorted by name), not in the image's order, so every entry is matched by name. */
static int exr_bind_encode(exr_encode_pipeline_t *enc, const obs_image *img, int y) {
  for (int i = 0; i < enc->channel_count; i++) {
    exr_coding_channel_info_t *ch = &enc->channels[i];
    const float *plane = obs_image_channel(img, ch->channel_name);
    if (!plane) return -1;
    ch->user_bytes_per_element = 4;
    ch->user_data_type = EXR_PIXEL_FLOAT;
    ch->user_pixel_stride = 4;
    ch->user_line_stride = 4 * img->width;
    ch->encode_from_ptr = (const uint8_t *)(plane + (size_t)y * (size_t)img->width);
  }
  return 0;
}

/* Forces the data to stable storage before the rename publishes it; otherwise a power loss could
 * leave the final name pointing at an empty file. */
static int exr_sync_file(const char *path) {
  int fd = open(path, O_RDONLY);
  if (fd < 0) return -1;
  int rc = fsync(fd);
  int saved = errno;
  close(fd);
  errno = saved;
  return rc;
}

/* One encoder per worker thread; chunks are compressed in any order on any thread, kept, and
 * written in file order afterwards, so the file's bytes never depend on the thread count. */
typedef struct exr_slot {
  exr_encode_pipeline_t enc;
  int alive, chosen;
  exr_result_t (*lib_compress)(exr_encode_pipeline_t *);
} exr_slot;

typedef struct exr_writer {
  exr_context_t ctx;
  const obs_image *img;
  exr_chunk_info_t *info; /* per chunk, gathered up front on the calling thread */
  uint8_t **data;         /* per chunk: the bytes to store */
  size_t *size;
  exr_slot *slots;
  atomic_int failed;
  exr_result_t fail_rc;   /* first failure, with the library's message */
  char fail_msg[512];
  atomic_int fail_layout; /* the encoder named a channel the image lacks (any thread sets it) */
  int base;               /* first chunk of the window being compressed */
} exr_writer;

/* The format's rule is that a chunk whose compressed form is not smaller than its packed pixels is
 * stored as the packed pixels: readers take "size == raw size" to mean "not compressed". OpenEXR
 * 3.1.5's ZIP and ZIPS encoders keep the compressed bytes when they come out exactly as large
 * (they only fall back when larger), so a reader decodes deflate bytes as pixels (values like 1e33
 * in an image of 0..1). Small chunks of nearly incompressible data hit it: a 1-pixel-wide image
 * with 7 float channels packs 448 bytes per 16-line chunk. Enforcing
 * the rule here after every compressor (RLE and PIZ already honour it; the check costs nothing)
 * makes every chunk readable whatever the library version. */
static exr_result_t exr_compress_checked(exr_encode_pipeline_t *enc) {
  const exr_slot *slot = enc->encoding_user_data;
  exr_result_t rc = slot->lib_compress(enc);
  if (rc == EXR_ERR_SUCCESS && enc->compressed_bytes >= enc->packed_bytes) {
    /* The compressed buffer is at least packed_bytes long: the library sizes it above that. */
    memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    enc->compressed_bytes = enc->packed_bytes;
  }
  return rc;
}

static int exr_encode_one(exr_writer *w, exr_slot *s, int idx) {
  const exr_chunk_info_t *ci = &w->info[idx];
  exr_result_t rc = s->alive ? exr_encoding_update(w->ctx, 0, ci, &s->enc)
                             : exr_encoding_initialize(w->ctx, 0, ci, &s->enc);
  if (rc == EXR_ERR_SUCCESS) s->alive = 1;
  if (rc == EXR_ERR_SUCCESS && exr_bind_encode(&s->enc, w->img, ci->start_y) != 0) {
    atomic_store(&w->fail_layout, 1);
    return -1;
  }
  if (rc == EXR_ERR_SUCCESS && !s->chosen) {
    rc = exr_encoding_choose_default_routines(w->ctx, 0, &s->enc);
    if (rc == EXR_ERR_SUCCESS) {
      s->chosen = 1;
      s->lib_compress = s->enc.compress_fn; /* NULL for uncompressed files */
      if (s->lib_compress) s->enc.compress_fn = exr_compress_checked;
      s->enc.encoding_user_data = s;
      /* The calling thread writes the chunks in order afterwards; the default yield would refuse
       * any chunk but the next one in file order. */
      s->enc.yield_until_ready_fn = NULL;
      s->enc.write_fn = NULL;
    }
  }
  if (rc == EXR_ERR_SUCCESS) rc = exr_encoding_run(w->ctx, 0, &s->enc);
  if (rc == EXR_ERR_SUCCESS) {
    size_t n = s->enc.compressed_bytes;
    w->data[idx] = malloc(n ? n : 1);
    if (!w->data[idx]) {
      rc = EXR_ERR_OUT_OF_MEMORY;
    } else {
      memcpy(w->data[idx], s->enc.compressed_buffer, n);
      w->size[idx] = n;
    }
  }
  if (rc != EXR_ERR_SUCCESS) {
    int expected = 0;
    if (atomic_compare_exchange_strong(&w->failed, &expected, 1)) {
      w->fail_rc = rc;
      snprintf(w->fail_msg, sizeof w->fail_msg, "%s", exr_why(rc));
    }
    return -1;
  }
  return 0;
}

/* obs_parallel_tiles hands out OBS_TILE-wide column tiles of a one-row strip: tile k is chunk k. */
static int exr_encode_tile(void *user, int thread, int x0, int y0, int x1, int y1) {
  (void)y0, (void)y1, (void)x1;
  exr_writer *w = user;
  if (atomic_load(&w->failed)) return OBS_EINTERNAL;
  return exr_encode_one(w, &w->slots[thread], w->base + x0 / OBS_TILE) ? OBS_EINTERNAL : 0;
}

static exr_compression_t exr_compression_of(int c) {
  switch (c) {
    case OBS_EXR_NONE: return EXR_COMPRESSION_NONE;
    case OBS_EXR_RLE: return EXR_COMPRESSION_RLE;
    case OBS_EXR_ZIPS: return EXR_COMPRESSION_ZIPS;
    case OBS_EXR_PIZ: return EXR_COMPRESSION_PIZ;
    default: return EXR_COMPRESSION_ZIP;
  }
}

/* Chunks are compressed a window at a time and each window is written before the next starts, so
 * the compressed copies held at once stay near this many raw bytes whatever the image's size. */
#define EXR_WINDOW_BYTES ((size_t)8 << 20)

/* Compresses chunks [k0, k1) on `threads` threads into w->data. */
static int exr_encode_window(exr_writer *w, int k0, int k1, int threads) {
  if (threads == 1 || k1 - k0 == 1) {
    for (int k = k0; k < k1; k++)
      if (exr_encode_one(w, &w->slots[0], k)) return OBS_EINTERNAL;
    return OBS_OK;
  }
  w->base = k0;
  return obs_parallel_tiles((k1 - k0) * OBS_TILE, 1, threads, exr_encode_tile, w, NULL, NULL,
                            NULL);
}

/* Encodes every chunk on `threads` threads and writes them in file order. */
static int exr_write_chunks(exr_writer *w, int lines, int threads, const char *path, obs_err *err,
                            exr_result_t *rcp, const char **stage) {
  int nchunks = (w->img->height + lines - 1) / lines;
  size_t chunk_raw = (size_t)w->img->width * (size_t)lines * (size_t)w->img->nchannels * 4;
  if (threads > nchunks) threads = nchunks;
  if (threads < 1) threads = 1;
  size_t win = EXR_WINDOW_BYTES / chunk_raw;
  if (win < (size_t)threads) win = (size_t)threads;
  if (win > (size_t)(INT_MAX / OBS_TILE)) win = (size_t)(INT_MAX / OBS_TILE);
  w->info = calloc((size_t)nchunks, sizeof *w->info);
  w->data = calloc((size_t)nchunks, sizeof *w->data);
  w->size = calloc((size_t)nchunks, sizeof *w->size);
  w->slots = calloc((size_t)threads, sizeof *w->slots);
  if (!w->info || !w->data || !w->size || !w->slots) {
    *rcp = EXR_ERR_OUT_OF_MEMORY;
    return OBS_ENOMEM;
  }
  exr_result_t rc = EXR_ERR_SUCCESS;
  for (int k = 0; k < nchunks && rc == EXR_ERR_SUCCESS; k++)
    rc = exr_write_scanline_chunk_info(w->ctx, 0, k * lines, &w->info[k]);
  for (int t = 0; t < threads; t++)
    w->slots[t].enc = (exr_encode_pipeline_t)EXR_ENCODE_PIPELINE_INITIALIZER;
  int code = OBS_OK;
  for (int k0 = 0; k0 < nchunks && rc == EXR_ERR_SUCCESS && !code; k0 += (int)win) {
    int k1 = nchunks - k0 < (int)win ? nchunks : k0 + (int)win;
    *stage = "encode pixels";
    code = exr_encode_window(w, k0, k1, threads);
    if (atomic_load(&w->fail_layout)) {
      code = obs_err_set(err, OBS_EINTERNAL,
                         "%s: cannot write EXR: encoder lists a channel the image lacks", path);
    } else if (atomic_load(&w->failed)) {
      snprintf(exr_last_msg, sizeof exr_last_msg, "%s", w->fail_msg);
      rc = w->fail_rc;
    } else if (code) { /* the threads could not be started */
      code = obs_err_set(err, code, "%s: cannot write EXR: %s", path, obs_strerror(code));
    }
    if (code || rc != EXR_ERR_SUCCESS) break;
    *stage = "write chunks";
    for (int k = k0; k < k1 && rc == EXR_ERR_SUCCESS; k++) {
      rc = exr_write_scanline_chunk(w->ctx, 0, w->info[k].start_y, w->data[k], w->size[k]);
      free(w->data[k]);
      w->data[k] = NULL;
    }
  }
  for (int t = 0; t < threads; t++)
    if (w->slots[t].alive) exr_encoding_destroy(w->ctx, &w->slots[t].enc);
  *rcp = rc;
  if (rc != EXR_ERR_SUCCESS) return exr_code(rc, !strcmp(*stage, "write chunks") ? OBS_EIO
                                                                                : OBS_EINTERNAL);
  return code;
}

/* RLE, chosen by measurement on a 512x512 render's 10 float channels (docs/performance.md,
 * "Writing outputs"): deflate (ZIP), even at level 1, costs several times the whole render budget
 * for writing on its 10 MB of mostly incompressible low mantissa bytes, and saves about half;
 * RLE still removes a quarter of the bytes (constant alpha, AO in steps of 1/samples, background)
 * at a small fraction of the cost. PIZ and ZIPS are both slower and larger than ZIP here. */
obs_exr_opts obs_exr_opts_default(void) {
  obs_exr_opts o = {OBS_EXR_RLE, 0, 1};
  return o;
}

int obs_image_write_exr_opts(const obs_image *img, const char *path, const obs_exr_opts *opts,
                             obs_err *err) {
  obs_exr_opts o = opts ? *opts : obs_exr_opts_default();
  if (!path || !path[0]) return obs_err_set(err, OBS_EINVAL, "EXR write: empty output path");
  if (!img || !img->data || img->width <= 0 || img->height <= 0 || img->nchannels <= 0 ||
      img->nchannels > OBS_IMAGE_MAX_CHANNELS)
    return obs_err_set(err, OBS_EINVAL, "%s: cannot write EXR: image is empty or uninitialised",
                       path);
  if (img->width > INT32_MAX / 4)
    return obs_err_set(err, OBS_EUNSUPPORTED, "%s: cannot write EXR: width %d is too large", path,
                       img->width);
  if (o.compression < 0 || o.compression >= OBS_EXR_NCOMPRESSIONS || o.zip_level < 0 ||
      o.zip_level > 9)
    return obs_err_set(err, OBS_EINVAL,
                       "%s: cannot write EXR: compression %d / zip level %d is not offered", path,
                       o.compression, o.zip_level);

  size_t plen = strlen(path);
  char *tmp = malloc(plen + 5);
  if (!tmp) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  memcpy(tmp, path, plen);
  memcpy(tmp + plen, ".tmp", 5);

  exr_context_initializer_t init = exr_init_opts(0);
  exr_writer w;
  memset(&w, 0, sizeof w);
  w.img = img;
  int part = 0, nchunks = 0;
  const char *stage = "create file";
  int code = OBS_OK;

  exr_result_t rc = exr_start_write(&w.ctx, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
  if (rc != EXR_ERR_SUCCESS) {
    w.ctx = NULL; /* the library already released it */
    code = exr_code(rc, OBS_EIO);
    goto fail;
  }
  stage = "define header";
  rc = exr_add_part(w.ctx, NULL, EXR_STORAGE_SCANLINE, &part);
  if (rc == EXR_ERR_SUCCESS)
    rc = exr_initialize_required_attr_simple(w.ctx, part, img->width, img->height,
                                             exr_compression_of(o.compression));
  if (rc == EXR_ERR_SUCCESS && o.zip_level > 0 &&
      (o.compression == OBS_EXR_ZIP || o.compression == OBS_EXR_ZIPS))
    rc = exr_set_zip_compression_level(w.ctx, part, o.zip_level);
  for (int c = 0; rc == EXR_ERR_SUCCESS && c < img->nchannels; c++)
    rc = exr_add_channel(w.ctx, part, img->names[c], EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1,
                         1);
  if (rc == EXR_ERR_SUCCESS) {
    stage = "write header";
    rc = exr_write_header(w.ctx);
  }
  int32_t lines = 0;
  if (rc == EXR_ERR_SUCCESS) rc = exr_get_scanlines_per_chunk(w.ctx, part, &lines);
  if (rc == EXR_ERR_SUCCESS && lines <= 0) rc = EXR_ERR_UNKNOWN;
  if (rc != EXR_ERR_SUCCESS) {
    code = exr_code(rc, OBS_EINTERNAL);
    goto fail;
  }
  nchunks = (img->height + lines - 1) / lines;

  code = exr_write_chunks(&w, lines, o.threads, path, err, &rc, &stage);
  if (code) {
    if (rc != EXR_ERR_SUCCESS) goto fail;
    goto cleanup;
  }

  /* exr_finish writes the chunk offset table, so its failure means a broken file. */
  stage = "finish file";
  rc = exr_finish(&w.ctx);
  w.ctx = NULL; /* released even when finishing failed */
  if (rc != EXR_ERR_SUCCESS) {
    code = exr_code(rc, OBS_EIO);
    goto fail;
  }
  if (exr_sync_file(tmp) != 0 || rename(tmp, path) != 0) {
    code = obs_err_set(err, OBS_EIO, "%s: cannot write EXR: publishing %s failed: %s", path, tmp,
                       strerror(errno));
    goto cleanup;
  }
  goto cleanup;

fail:
  obs_err_set(err, code, "%s: cannot write EXR (%s): %s", path, stage, exr_why(rc));
cleanup:
  if (w.ctx) exr_finish(&w.ctx);
  if (code) unlink(tmp); /* never leave a partial file behind; ENOENT is fine */
  free(tmp);
  for (int k = 0; w.data && k < nchunks; k++) free(w.data[k]);
  free(w.data);
  free(w.size);
  free(w.info);
  free(w.slots);
  return code;
}

int obs_image_write_exr(const obs_image *img, const char *path, obs_err *err) {
  return obs_image_write_exr_opts(img, path, NULL, err);
}

/* ---------------------------------------------------------------------------------------------- */
/* Reading */

static float exr_half_to_float(uint16_t h) {
  uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
  uint32_t exp = (h >> 10) & 0x1fu;
  uint32_t mant = h & 0x3ffu;
  uint32_t bits;
  if (exp == 0) {
    if (mant == 0) {
      bits = sign;
    } else { /* half denormals are normal floats: shift the leading 1 into the implicit bit */
      uint32_t e = 0;
      while (!(mant & 0x400u)) {
        mant <<= 1;
        e++;
      }
      bits = sign | ((113u - e) << 23) | ((mant & 0x3ffu) << 13);
    }
  } else if (exp == 31) {
    bits = sign | 0x7f800000u | (mant << 13); /* keeps NaN payloads */
  } else {
    bits = sign | ((exp + 112u) << 23) | (mant << 13);
  }
  float f;
  memcpy(&f, &bits, sizeof f);
  return f;
}

typedef struct exr_reader {
  exr_context_t ctx;
  exr_decode_pipeline_t dec;
  int dec_alive, routines_chosen;
  obs_image *img;
  float *planes[OBS_IMAGE_MAX_CHANNELS]; /* image plane for each decoder channel (file order) */
  uint8_t *scratch;                      /* 4 bytes per pixel per channel for the largest chunk */
  size_t slot;                           /* bytes per channel in scratch */
  int max_w, max_h;                      /* largest chunk the scratch holds */
  const char *path;
} exr_reader;

/* Decodes one chunk in the file's own pixel types into scratch, then converts to float and copies
 * it to pixel (x0, y0) of the image. Decoding natively and converting here keeps HALF/UINT handling
 * in one exact place instead of relying on the library's per-layout conversion paths. */
static int exr_read_chunk_into(exr_reader *r, const exr_chunk_info_t *ci, int x0, int y0,
                               obs_err *err) {
  obs_image *img = r->img;
  if (ci->width <= 0 || ci->height <= 0 || ci->width > r->max_w || ci->height > r->max_h ||
      x0 < 0 || y0 < 0 || ci->width > img->width - x0 || ci->height > img->height - y0)
    return obs_err_set(err, OBS_EINVAL, "%s: corrupt EXR: chunk %d is %dx%d at (%d,%d)", r->path,
                       ci->idx, ci->width, ci->height, x0, y0);
  exr_result_t rc = r->dec_alive ? exr_decoding_update(r->ctx, 0, ci, &r->dec)
                                 : exr_decoding_initialize(r->ctx, 0, ci, &r->dec);
  if (rc == EXR_ERR_SUCCESS) r->dec_alive = 1;
  if (rc == EXR_ERR_SUCCESS) {
    if (r->dec.channel_count != img->nchannels) {
      return obs_err_set(err, OBS_EINTERNAL, "%s: EXR decoder has %d channels, header has %d",
                         r->path, r->dec.channel_count, img->nchannels);
    }
    for (int i = 0; i < r->dec.channel_count; i++) {
      exr_coding_channel_info_t *ch = &r->dec.channels[i];
      float *plane = obs_image_channel(img, ch->channel_name);
      if (!plane || (ch->bytes_per_element != 2 && ch->bytes_per_element != 4))
        return obs_err_set(err, OBS_EINTERNAL, "%s: EXR decoder channel \"%s\" is unexpected",
                           r->path, ch->channel_name ? ch->channel_name : "(null)");
      r->planes[i] = plane;
      ch->user_bytes_per_element = ch->bytes_per_element;
      ch->user_data_type = ch->data_type;
      ch->user_pixel_stride = ch->bytes_per_element;
      ch->user_line_stride = ch->bytes_per_element * ci->width;
      ch->decode_to_ptr = r->scratch + (size_t)i * r->slot;
    }
    if (!r->routines_chosen) {
      rc = exr_decoding_choose_default_routines(r->ctx, 0, &r->dec);
      r->routines_chosen = rc == EXR_ERR_SUCCESS;
    }
  }
  if (rc == EXR_ERR_SUCCESS) rc = exr_decoding_run(r->ctx, 0, &r->dec);
  if (rc != EXR_ERR_SUCCESS) {
    return obs_err_set(err, exr_code(rc, OBS_EINVAL), "%s: cannot decode EXR chunk %d: %s",
                       r->path, ci->idx, exr_why(rc));
  }

  size_t w = (size_t)ci->width;
  for (int i = 0; i < r->dec.channel_count; i++) {
    const exr_coding_channel_info_t *ch = &r->dec.channels[i];
    const uint8_t *src = r->scratch + (size_t)i * r->slot;
    for (int row = 0; row < ci->height; row++) {
      float *dst = r->planes[i] + (size_t)(y0 + row) * (size_t)img->width + (size_t)x0;
      const uint8_t *s = src + (size_t)row * w * (size_t)ch->bytes_per_element;
      for (size_t x = 0; x < w; x++) {
        switch (ch->data_type) {
          case EXR_PIXEL_HALF: {
            uint16_t v;
            memcpy(&v, s + 2 * x, 2);
            dst[x] = exr_half_to_float(v);
            break;
          }
          case EXR_PIXEL_UINT: {
            uint32_t v;
            memcpy(&v, s + 4 * x, 4);
            dst[x] = (float)v;
            break;
          }
          default:
            memcpy(&dst[x], s + 4 * x, 4);
            break;
        }
      }
    }
  }
  return OBS_OK;
}

static int exr_read_scanlines(exr_reader *r, const exr_attr_box2i_t *dw, obs_err *err) {
  int32_t lines = 0;
  exr_result_t rc = exr_get_scanlines_per_chunk(r->ctx, 0, &lines);
  if (rc != EXR_ERR_SUCCESS || lines <= 0)
    return obs_err_set(err, OBS_EINVAL, "%s: EXR has no valid scanline chunk size", r->path);
  r->max_w = r->img->width;
  r->max_h = lines;
  if ((size_t)r->max_w > SIZE_MAX / 4 / (size_t)r->max_h)
    return obs_err_set(err, OBS_ENOMEM, "%s: EXR chunk too large", r->path);
  r->slot = (size_t)r->max_w * (size_t)r->max_h * 4;
  r->scratch = malloc(r->slot * (size_t)r->img->nchannels);
  if (!r->scratch) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", r->path);

  /* Chunks start at dataWindow.min.y; asking for any line inside one returns its true extent. */
  for (int64_t y = dw->min.y; y <= dw->max.y;) {
    exr_chunk_info_t ci;
    rc = exr_read_scanline_chunk_info(r->ctx, 0, (int)y, &ci);
    if (rc != EXR_ERR_SUCCESS)
      return obs_err_set(err, exr_code(rc, OBS_EINVAL), "%s: cannot read EXR chunk at line %d: %s",
                         r->path, (int)y, exr_why(rc));
    if (ci.start_y > y || ci.height <= 0 || ci.width != r->img->width)
      return obs_err_set(err, OBS_EINVAL, "%s: corrupt EXR: chunk for line %d is inconsistent",
                         r->path, (int)y);
    int rc2 = exr_read_chunk_into(r, &ci, 0, ci.start_y - dw->min.y, err);
    if (rc2) return rc2;
    y = (int64_t)ci.start_y + ci.height;
  }
  return OBS_OK;
}

static int exr_read_tiles(exr_reader *r, obs_err *err) {
  uint32_t tw = 0, th = 0;
  exr_tile_level_mode_t level_mode;
  exr_tile_round_mode_t round_mode;
  exr_result_t rc = exr_get_tile_descriptor(r->ctx, 0, &tw, &th, &level_mode, &round_mode);
  if (rc != EXR_ERR_SUCCESS || tw == 0 || th == 0 || tw > INT_MAX || th > INT_MAX)
    return obs_err_set(err, OBS_EINVAL, "%s: EXR has no valid tile description", r->path);
  /* Level (0,0) is the full-resolution image for one-level, mipmap and ripmap files alike. */
  r->max_w = (int)tw;
  r->max_h = (int)th;
  if ((size_t)r->max_w > SIZE_MAX / 4 / (size_t)r->max_h ||
      (size_t)r->max_w * (size_t)r->max_h * 4 > SIZE_MAX / (size_t)r->img->nchannels)
    return obs_err_set(err, OBS_ENOMEM, "%s: EXR tile %ux%u too large", r->path, tw, th);
  r->slot = (size_t)r->max_w * (size_t)r->max_h * 4;
  r->scratch = malloc(r->slot * (size_t)r->img->nchannels);
  if (!r->scratch) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", r->path);

  int ntx = (int)(((int64_t)r->img->width + tw - 1) / tw);
  int nty = (int)(((int64_t)r->img->height + th - 1) / th);
  for (int ty = 0; ty < nty; ty++) {
    for (int tx = 0; tx < ntx; tx++) {
      exr_chunk_info_t ci;
      rc = exr_read_tile_chunk_info(r->ctx, 0, tx, ty, 0, 0, &ci);
      if (rc != EXR_ERR_SUCCESS)
        return obs_err_set(err, exr_code(rc, OBS_EINVAL), "%s: cannot read EXR tile (%d,%d): %s",
                           r->path, tx, ty, exr_why(rc));
      int rc2 = exr_read_chunk_into(r, &ci, tx * (int)tw, ty * (int)th, err);
      if (rc2) return rc2;
    }
  }
  return OBS_OK;
}

int obs_image_read_exr(obs_image *img, const char *path, obs_err *err) {
  if (!img) return obs_err_set(err, OBS_EINVAL, "EXR read: NULL image pointer");
  memset(img, 0, sizeof *img);
  if (!path || !path[0]) return obs_err_set(err, OBS_EINVAL, "EXR read: empty input path");

  /* A truncated or damaged file must fail loudly rather than be silently patched up. */
  exr_context_initializer_t init = exr_init_opts(EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION);
  exr_reader r;
  memset(&r, 0, sizeof r);
  r.img = img;
  r.path = path;
  int code = OBS_OK;

  exr_result_t rc = exr_start_read(&r.ctx, path, &init);
  if (rc != EXR_ERR_SUCCESS) {
    r.ctx = NULL; /* the library already released it */
    code = obs_err_set(err, exr_code(rc, OBS_EINVAL), "%s: cannot read EXR: %s", path,
                       exr_why(rc));
    goto done;
  }

  /* Only the first part is read: obscura writes single-part files, and a multi-part file's
   * other parts (stereo views, AOV layers) do not map onto one obs_image. */
  exr_storage_t storage;
  exr_attr_box2i_t dw;
  const exr_attr_chlist_t *chl = NULL;
  rc = exr_get_storage(r.ctx, 0, &storage);
  if (rc == EXR_ERR_SUCCESS) rc = exr_get_data_window(r.ctx, 0, &dw);
  if (rc == EXR_ERR_SUCCESS) rc = exr_get_channels(r.ctx, 0, &chl);
  if (rc != EXR_ERR_SUCCESS || !chl) {
    code = obs_err_set(err, exr_code(rc, OBS_EINVAL), "%s: EXR header is incomplete: %s", path,
                       exr_why(rc));
    goto done;
  }
  if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
    code = obs_err_set(err, OBS_EUNSUPPORTED, "%s: deep EXR data is not supported", path);
    goto done;
  }
  int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
  if (w <= 0 || h <= 0 || w > INT_MAX || h > INT_MAX) {
    code = obs_err_set(err, OBS_EINVAL, "%s: EXR data window (%d,%d)-(%d,%d) is invalid", path,
                       dw.min.x, dw.min.y, dw.max.x, dw.max.y);
    goto done;
  }
  if (chl->num_channels <= 0 || chl->num_channels > OBS_IMAGE_MAX_CHANNELS) {
    code = obs_err_set(err, OBS_EUNSUPPORTED, "%s: EXR has %d channels, supported are 1..%d", path,
                       chl->num_channels, OBS_IMAGE_MAX_CHANNELS);
    goto done;
  }
  const char *names[OBS_IMAGE_MAX_CHANNELS];
  for (int c = 0; c < chl->num_channels; c++) {
    const exr_attr_chlist_entry_t *e = &chl->entries[c];
    names[c] = e->name.str;
    if (!e->name.str || e->name.length <= 0 || e->name.length >= OBS_CHANNEL_NAME_MAX) {
      code = obs_err_set(err, OBS_EUNSUPPORTED,
                         "%s: EXR channel name \"%s\" is empty or longer than %d bytes", path,
                         e->name.str ? e->name.str : "", OBS_CHANNEL_NAME_MAX - 1);
      goto done;
    }
    if (e->x_sampling != 1 || e->y_sampling != 1) {
      code = obs_err_set(err, OBS_EUNSUPPORTED, "%s: EXR channel \"%s\" is subsampled (%dx%d)",
                         path, e->name.str, e->x_sampling, e->y_sampling);
      goto done;
    }
    if (e->pixel_type != EXR_PIXEL_UINT && e->pixel_type != EXR_PIXEL_HALF &&
        e->pixel_type != EXR_PIXEL_FLOAT) {
      code = obs_err_set(err, OBS_EINVAL, "%s: EXR channel \"%s\" has unknown pixel type %d", path,
                         e->name.str, (int)e->pixel_type);
      goto done;
    }
  }
  code = obs_image_init(img, (int)w, (int)h, chl->num_channels, names, err);
  if (code) {
    obs_err_set(err, code, "%s: cannot hold the EXR image", path);
    goto done;
  }
  code = storage == EXR_STORAGE_TILED ? exr_read_tiles(&r, err) : exr_read_scanlines(&r, &dw, err);

done:
  if (r.dec_alive) exr_decoding_destroy(r.ctx, &r.dec);
  if (r.ctx) exr_finish(&r.ctx);
  free(r.scratch);
  if (code) obs_image_free(img);
  return code;
}
