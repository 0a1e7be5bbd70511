/* Unit tests for obs_image: allocation, EXR round trips, foreign EXR layouts, PNG quantisation. */
#include "testutil.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The library itself only exposes float EXR output; these headers let the tests author files with
 * HALF/UINT channels, tiles and offset data windows that real-world inputs have. */
#include <OpenEXR/openexr.h>
#include <spng.h>

static void assert_msg_has(const obs_err *err, const char *needle) {
  const char *msg = obs_err_message(err);
  if (!strstr(msg, needle)) {
    fprintf(stderr, "message \"%s\" lacks \"%s\"\n", msg, needle);
    fail();
  }
}

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static uint32_t float_bits(float f) {
  uint32_t u;
  memcpy(&u, &f, sizeof u);
  return u;
}

/* xorshift32: deterministic "random" bit patterns cover NaN payloads, denormals and both zeros. */
/* ---------------------------------------------------------------------------------------------- */

static void test_image_init_and_lookup(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  const char *names[] = {"ao", "alpha"};
  assert_int_equal(obs_image_init(&img, 3, 2, 2, names, &err), 0);
  assert_int_equal(img.width, 3);
  assert_int_equal(img.height, 2);
  assert_int_equal(img.nchannels, 2);
  assert_string_equal(img.names[1], "alpha");
  float *ao = obs_image_channel(&img, "ao");
  float *alpha = obs_image_channel(&img, "alpha");
  assert_ptr_equal(ao, img.data);
  assert_ptr_equal(alpha, img.data + 6);
  for (int i = 0; i < 12; i++) assert_true(img.data[i] == 0.0f);
  assert_null(obs_image_channel(&img, "depth.Z"));
  assert_null(obs_image_channel(&img, NULL));
  assert_null(obs_image_channel(NULL, "ao"));
  obs_image_free(&img);
  assert_null(img.data);
  obs_image_free(&img); /* second free of a released image is harmless */
  obs_err_free(&err);
}

static void test_image_init_rejects_bad_input(void **state) {
  (void)state;
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  const char *one[] = {"ao"};
  const char *dup[] = {"ao", "ao"};
  const char *empty[] = {""};
  const char *null_name[] = {NULL};
  const char *longname[] = {"this_channel_name_is_way_too_long_for_obscura"};
  assert_int_equal(obs_image_init(&img, 0, 4, 1, one, &err), OBS_EINVAL);
  assert_null(img.data);
  assert_int_equal(obs_image_init(&img, 4, -1, 1, one, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, 0, one, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, OBS_IMAGE_MAX_CHANNELS + 1, one, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, 1, NULL, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, 2, dup, &err), OBS_EINVAL);
  assert_msg_has(&err, "duplicate channel name \"ao\"");
  assert_int_equal(obs_image_init(&img, 4, 4, 1, empty, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, 1, null_name, &err), OBS_EINVAL);
  assert_int_equal(obs_image_init(&img, 4, 4, 1, longname, &err), OBS_EINVAL);
  assert_msg_has(&err, longname[0]);
  /* The byte count overflows size_t; this must be caught before any allocation is tried. */
  char many[OBS_IMAGE_MAX_CHANNELS][16];
  const char *many_names[OBS_IMAGE_MAX_CHANNELS];
  for (int c = 0; c < OBS_IMAGE_MAX_CHANNELS; c++) {
    snprintf(many[c], sizeof many[c], "c%d", c);
    many_names[c] = many[c];
  }
  assert_int_equal(
      obs_image_init(&img, INT32_MAX, INT32_MAX, OBS_IMAGE_MAX_CHANNELS, many_names, &err),
      OBS_ENOMEM);
  assert_null(img.data);
  obs_image_free(&img);
  obs_err_free(&err);
}

/* ---------------------------------------------------------------------------------------------- */
/* EXR round trips through obs_image_write_exr / obs_image_read_exr */

/* Deliberately not in sorted order: the file stores channels sorted, the image keeps this order. */
static const char *const k_aov_names[] = {"ao",       "ao_stderr", "bent_normal.X", "bent_normal.Y",
                                          "normal.X", "depth.Z",   "bent_normal.Z", "alpha"};
enum { K_AOV_COUNT = 8 };

static const uint32_t k_special_bits[] = {
    0x0DA24260u, /* 1e-30f */
    0x7149F2CAu, /* 1e30f */
    0x80000000u, /* -0.0f */
    0x00000001u, /* smallest denormal */
    0x807FFFFFu, /* largest negative denormal */
    0x7F7FFFFFu, /* FLT_MAX */
    0x7F800000u, /* +Inf */
    0xFF800000u, /* -Inf */
    0x7FC12345u, /* quiet NaN with payload */
    0xFFA00001u, /* signalling NaN, negative */
    0x3F800000u, /* 1.0f */
};
enum { K_SPECIALS = sizeof k_special_bits / sizeof k_special_bits[0] };

enum { FILL_SMOOTH, FILL_RANDOM, FILL_MIXED };

/* Every channel gets different content so a channel swapped with another is caught. */
static void fill_distinctive(obs_image *img, int mode) {
  size_t n = (size_t)img->width * (size_t)img->height;
  uint32_t seed = 0x9E3779B9u;
  for (int c = 0; c < img->nchannels; c++) {
    float *p = img->data + (size_t)c * n;
    int random = mode == FILL_RANDOM || (mode == FILL_MIXED && (c & 1));
    for (size_t i = 0; i < n; i++) {
      if (random) {
        uint32_t bits = obs_test_rand(&seed);
        memcpy(&p[i], &bits, sizeof bits);
      } else {
        p[i] = (float)c * 1000.0f + (float)(i % 4099) * 0.25f - 7.0f;
      }
    }
    /* Specials rotate per channel, so each lands in a different pixel of each channel. */
    for (size_t k = 0; k < K_SPECIALS && k < n; k++) {
      uint32_t bits = k_special_bits[(k + (size_t)c) % K_SPECIALS];
      memcpy(&p[(k * 7 + (size_t)c) % n], &bits, sizeof bits);
    }
  }
}

static void assert_same_by_name(const obs_image *want, const obs_image *got) {
  assert_int_equal(got->width, want->width);
  assert_int_equal(got->height, want->height);
  assert_int_equal(got->nchannels, want->nchannels);
  size_t n = (size_t)want->width * (size_t)want->height;
  for (int c = 0; c < want->nchannels; c++) {
    const float *a = want->data + (size_t)c * n;
    const float *b = obs_image_channel(got, want->names[c]);
    if (!b) {
      fprintf(stderr, "channel %s missing after read\n", want->names[c]);
      fail();
    }
    if (memcmp(a, b, n * sizeof(float)) != 0) {
      for (size_t i = 0; i < n; i++) {
        if (float_bits(a[i]) != float_bits(b[i])) {
          fprintf(stderr, "channel %s pixel %zu: wrote 0x%08x read 0x%08x\n", want->names[c], i,
                  (unsigned)float_bits(a[i]), (unsigned)float_bits(b[i]));
          break;
        }
      }
      fail();
    }
  }
}

static void roundtrip_case(const char *dir, int w, int h, int mode) {
  obs_err err = OBS_ERR_INIT;
  obs_image img, back;
  assert_int_equal(obs_image_init(&img, w, h, K_AOV_COUNT, k_aov_names, &err), 0);
  fill_distinctive(&img, mode);
  char name[64];
  snprintf(name, sizeof name, "rt_%dx%d_%d.exr", w, h, mode);
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, name));
  int rc = obs_image_write_exr(&img, path, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  char tmp[1100];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  assert_false(obs_test_file_exists(tmp));
  rc = obs_image_read_exr(&back, path, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  assert_same_by_name(&img, &back);
  /* The file's channel list is sorted by name, and reading follows the file. */
  for (int c = 1; c < back.nchannels; c++)
    assert_true(strcmp(back.names[c - 1], back.names[c]) < 0);
  assert_int_equal(err.count, 0);
  obs_image_free(&back);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_exr_roundtrip_bit_exact(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_rt");
  roundtrip_case(dir, 1, 1, FILL_MIXED);
  roundtrip_case(dir, 37, 13, FILL_RANDOM);    /* one partial 16-line ZIP chunk, incompressible */
  roundtrip_case(dir, 4096, 16, FILL_SMOOTH);  /* exactly one full chunk, compressible */
  roundtrip_case(dir, 5, 37, FILL_MIXED);      /* chunks of 16, 16 and 5 lines */
  roundtrip_case(dir, 300, 100, FILL_MIXED);
}

static void test_exr_single_channel_and_overwrite(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_ow");
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "ao.exr"));
  obs_err err = OBS_ERR_INIT;
  obs_image a, b, back;
  const char *n1[] = {"ao"};
  const char *n2[] = {"Y", "A"};
  assert_int_equal(obs_image_init(&a, 2, 2, 1, n1, &err), 0);
  for (int i = 0; i < 4; i++) a.data[i] = 0.25f * (float)i;
  assert_int_equal(obs_image_write_exr(&a, path, &err), 0);
  assert_int_equal(obs_image_init(&b, 3, 1, 2, n2, &err), 0);
  for (int i = 0; i < 6; i++) b.data[i] = -(float)i;
  assert_int_equal(obs_image_write_exr(&b, path, &err), 0); /* replaces the first file */
  assert_int_equal(obs_image_read_exr(&back, path, &err), 0);
  assert_same_by_name(&b, &back);
  assert_string_equal(back.names[0], "A"); /* sorted: "A" < "Y" */
  obs_image_free(&back);
  obs_image_free(&b);
  obs_image_free(&a);
  obs_err_free(&err);
}

static void test_exr_write_errors(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_werr");
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  const char *n1[] = {"ao"};
  assert_int_equal(obs_image_init(&img, 4, 4, 1, n1, &err), 0);
  char path[1024];
  snprintf(path, sizeof path, "%s/no/such/dir/out.exr", dir);
  assert_int_equal(obs_image_write_exr(&img, path, &err), OBS_EIO);
  assert_msg_has(&err, path);
  assert_false(obs_test_file_exists(path));
  obs_err_clear(&err);

  obs_image empty;
  memset(&empty, 0, sizeof empty);
  assert_int_equal(obs_image_write_exr(&empty, obs_test_path(dir, "e.exr"), &err), OBS_EINVAL);
  assert_int_equal(obs_image_write_exr(&img, "", &err), OBS_EINVAL);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_exr_read_errors(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_rerr");
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  char path[1024];

  snprintf(path, sizeof path, "%s", obs_test_path(dir, "missing.exr"));
  assert_int_equal(obs_image_read_exr(&img, path, &err), OBS_EIO);
  assert_msg_has(&err, path);
  assert_null(img.data);
  obs_image_free(&img);
  obs_err_clear(&err);

  snprintf(path, sizeof path, "%s", obs_test_path(dir, "text.exr"));
  write_text(path, "this is plainly not an OpenEXR file, just some text that is long enough\n");
  assert_int_equal(obs_image_read_exr(&img, path, &err), OBS_EINVAL);
  assert_msg_has(&err, path);
  assert_null(img.data);
  obs_err_clear(&err);

  snprintf(path, sizeof path, "%s", obs_test_path(dir, "empty.exr"));
  write_text(path, "");
  assert_int_equal(obs_image_read_exr(&img, path, &err), OBS_EINVAL);
  assert_msg_has(&err, path);
  obs_err_clear(&err);

  /* A file cut short after its header must fail, not come back half-filled. */
  obs_image src;
  const char *n1[] = {"ao"};
  assert_int_equal(obs_image_init(&src, 64, 64, 1, n1, &err), 0);
  fill_distinctive(&src, FILL_RANDOM);
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "trunc.exr"));
  assert_int_equal(obs_image_write_exr(&src, path, &err), 0);
  struct stat st;
  assert_int_equal(stat(path, &st), 0);
  assert_int_equal(truncate(path, st.st_size / 2), 0);
  assert_int_equal(obs_image_read_exr(&img, path, &err), OBS_EINVAL);
  assert_msg_has(&err, path);
  assert_null(img.data);
  obs_image_free(&src);
  obs_err_free(&err);
}

/* ---------------------------------------------------------------------------------------------- */
/* Foreign EXR layouts written directly with OpenEXRCore */

typedef struct raw_chan {
  const char *name;
  exr_pixel_type_t type;
  const void *data; /* w*h tightly packed values of `type` */
} raw_chan;

static int raw_bpe(exr_pixel_type_t t) { return t == EXR_PIXEL_HALF ? 2 : 4; }

static void raw_bind(exr_encode_pipeline_t *enc, const raw_chan *ch, int nch, int w, int px,
                     int py) {
  for (int i = 0; i < enc->channel_count; i++) {
    exr_coding_channel_info_t *c = &enc->channels[i];
    const raw_chan *src = NULL;
    for (int k = 0; k < nch; k++)
      if (strcmp(ch[k].name, c->channel_name) == 0) src = &ch[k];
    assert_non_null(src);
    int bpe = raw_bpe(src->type);
    c->user_bytes_per_element = (int16_t)bpe;
    c->user_data_type = (uint16_t)src->type;
    c->user_pixel_stride = bpe;
    c->user_line_stride = bpe * w;
    size_t offset = ((size_t)py * (size_t)w + (size_t)px) * (size_t)bpe;
    c->encode_from_ptr = (const uint8_t *)src->data + offset;
  }
}

/* tile_w == 0 writes scanlines. The data window starts at (x0, y0) so offsets get exercised. */
static void write_raw_exr(const char *path, int tile_w, int tile_h, exr_compression_t comp, int x0,
                          int y0, int w, int h, const raw_chan *ch, int nch) {
  exr_context_t ctx = NULL;
  int part = 0;
  assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, NULL), EXR_ERR_SUCCESS);
  assert_int_equal(
      exr_add_part(ctx, "raw", tile_w ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE, &part),
      EXR_ERR_SUCCESS);
  exr_attr_box2i_t dw;
  dw.min.x = x0;
  dw.min.y = y0;
  dw.max.x = x0 + w - 1;
  dw.max.y = y0 + h - 1;
  exr_attr_v2f_t center;
  center.x = 0.0f;
  center.y = 0.0f;
  assert_int_equal(exr_initialize_required_attr(ctx, part, &dw, &dw, 1.0f, &center, 1.0f,
                                                EXR_LINEORDER_INCREASING_Y, comp),
                   EXR_ERR_SUCCESS);
  if (tile_w)
    assert_int_equal(exr_set_tile_descriptor(ctx, part, (uint32_t)tile_w, (uint32_t)tile_h,
                                             EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN),
                     EXR_ERR_SUCCESS);
  for (int k = 0; k < nch; k++)
    assert_int_equal(
        exr_add_channel(ctx, part, ch[k].name, ch[k].type, EXR_PERCEPTUALLY_LINEAR, 1, 1),
        EXR_ERR_SUCCESS);
  assert_int_equal(exr_write_header(ctx), EXR_ERR_SUCCESS);

  exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
  int started = 0;
  exr_chunk_info_t ci;
  if (tile_w) {
    for (int ty = 0; ty * tile_h < h; ty++) {
      for (int tx = 0; tx * tile_w < w; tx++) {
        assert_int_equal(exr_write_tile_chunk_info(ctx, part, tx, ty, 0, 0, &ci), EXR_ERR_SUCCESS);
        assert_int_equal(started ? exr_encoding_update(ctx, part, &ci, &enc)
                                 : exr_encoding_initialize(ctx, part, &ci, &enc),
                         EXR_ERR_SUCCESS);
        raw_bind(&enc, ch, nch, w, tx * tile_w, ty * tile_h);
        if (!started)
          assert_int_equal(exr_encoding_choose_default_routines(ctx, part, &enc), EXR_ERR_SUCCESS);
        started = 1;
        assert_int_equal(exr_encoding_run(ctx, part, &enc), EXR_ERR_SUCCESS);
      }
    }
  } else {
    int32_t lines = 0;
    assert_int_equal(exr_get_scanlines_per_chunk(ctx, part, &lines), EXR_ERR_SUCCESS);
    for (int y = y0; y < y0 + h; y += lines) {
      assert_int_equal(exr_write_scanline_chunk_info(ctx, part, y, &ci), EXR_ERR_SUCCESS);
      assert_int_equal(started ? exr_encoding_update(ctx, part, &ci, &enc)
                               : exr_encoding_initialize(ctx, part, &ci, &enc),
                       EXR_ERR_SUCCESS);
      raw_bind(&enc, ch, nch, w, 0, ci.start_y - y0);
      if (!started)
        assert_int_equal(exr_encoding_choose_default_routines(ctx, part, &enc), EXR_ERR_SUCCESS);
      started = 1;
      assert_int_equal(exr_encoding_run(ctx, part, &enc), EXR_ERR_SUCCESS);
    }
  }
  exr_encoding_destroy(ctx, &enc);
  assert_int_equal(exr_finish(&ctx), EXR_ERR_SUCCESS);
}

/* Half bit patterns with their exact float values; the reader must not round or flush any. */
static const uint16_t k_half_bits[] = {0x0000, 0x8000, 0x3C00, 0xC000, 0x7BFF, 0x0001, 0x03FF,
                                       0x0400, 0x3555, 0x7C00, 0xFC00, 0x7E00, 0x8001, 0x5640};
static const uint32_t k_half_as_float[] = {
    0x00000000u, 0x80000000u, 0x3F800000u, 0xC0000000u, 0x477FE000u, 0x33800000u, 0x387FC000u,
    0x38800000u, 0x3EAAA000u, 0x7F800000u, 0xFF800000u, 0x7FC00000u, 0xB3800000u, 0x42C80000u};
enum { K_HALFS = sizeof k_half_bits / sizeof k_half_bits[0] };

typedef struct mixed_data {
  int w, h;
  uint16_t *half;
  uint32_t *uint;
  float *flt;
} mixed_data;

static void mixed_make(mixed_data *m, int w, int h) {
  size_t n = (size_t)w * (size_t)h;
  m->w = w;
  m->h = h;
  m->half = malloc(n * sizeof *m->half);
  m->uint = malloc(n * sizeof *m->uint);
  m->flt = malloc(n * sizeof *m->flt);
  assert_non_null(m->half);
  assert_non_null(m->uint);
  assert_non_null(m->flt);
  uint32_t seed = 12345u;
  for (size_t i = 0; i < n; i++) {
    m->half[i] = k_half_bits[i % K_HALFS];
    m->uint[i] = i % 3 == 0 ? (uint32_t)i : (i % 3 == 1 ? 0xFFFFFFFFu : 16777217u);
    uint32_t bits = obs_test_rand(&seed);
    memcpy(&m->flt[i], &bits, sizeof bits);
  }
}

static void mixed_check(const mixed_data *m, const obs_image *img) {
  assert_int_equal(img->width, m->w);
  assert_int_equal(img->height, m->h);
  assert_int_equal(img->nchannels, 3);
  const float *h = obs_image_channel(img, "h");
  const float *u = obs_image_channel(img, "u");
  const float *f = obs_image_channel(img, "f");
  assert_non_null(h);
  assert_non_null(u);
  assert_non_null(f);
  size_t n = (size_t)m->w * (size_t)m->h;
  for (size_t i = 0; i < n; i++) {
    if (float_bits(h[i]) != k_half_as_float[i % K_HALFS]) {
      fprintf(stderr, "half 0x%04x read as 0x%08x\n", m->half[i], (unsigned)float_bits(h[i]));
      fail();
    }
    assert_true(u[i] == (float)m->uint[i]);
    assert_int_equal(float_bits(f[i]), float_bits(m->flt[i]));
  }
}

static void mixed_free(mixed_data *m) {
  free(m->half);
  free(m->uint);
  free(m->flt);
}

static void test_exr_read_half_uint_scanlines(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_mixed");
  mixed_data m;
  mixed_make(&m, 7, 45);
  /* Declared unsorted; the library sorts them ("f" < "h" < "u"). */
  raw_chan ch[] = {{"u", EXR_PIXEL_UINT, m.uint}, {"h", EXR_PIXEL_HALF, m.half},
                   {"f", EXR_PIXEL_FLOAT, m.flt}};
  const exr_compression_t comps[] = {EXR_COMPRESSION_NONE, EXR_COMPRESSION_RLE,
                                     EXR_COMPRESSION_ZIPS, EXR_COMPRESSION_ZIP,
                                     EXR_COMPRESSION_PIZ};
  for (size_t k = 0; k < sizeof comps / sizeof comps[0]; k++) {
    char name[64];
    snprintf(name, sizeof name, "mixed_%d.exr", (int)comps[k]);
    char path[1024];
    snprintf(path, sizeof path, "%s", obs_test_path(dir, name));
    write_raw_exr(path, 0, 0, comps[k], -3, 11, m.w, m.h, ch, 3);
    obs_err err = OBS_ERR_INIT;
    obs_image img;
    int rc = obs_image_read_exr(&img, path, &err);
    if (rc) fprintf(stderr, "compression %d: %s\n", (int)comps[k], obs_err_message(&err));
    assert_int_equal(rc, 0);
    mixed_check(&m, &img);
    obs_image_free(&img);
    obs_err_free(&err);
  }
  mixed_free(&m);
}

static void test_exr_read_tiled(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_exr_tiled");
  mixed_data m;
  mixed_make(&m, 37, 13); /* 16x8 tiles leave partial tiles on the right and bottom */
  raw_chan ch[] = {{"h", EXR_PIXEL_HALF, m.half}, {"f", EXR_PIXEL_FLOAT, m.flt},
                   {"u", EXR_PIXEL_UINT, m.uint}};
  const exr_compression_t comps[] = {EXR_COMPRESSION_NONE, EXR_COMPRESSION_ZIP};
  for (size_t k = 0; k < sizeof comps / sizeof comps[0]; k++) {
    char name[64];
    snprintf(name, sizeof name, "tiled_%d.exr", (int)comps[k]);
    char path[1024];
    snprintf(path, sizeof path, "%s", obs_test_path(dir, name));
    write_raw_exr(path, 16, 8, comps[k], 5, -2, m.w, m.h, ch, 3);
    obs_err err = OBS_ERR_INIT;
    obs_image img;
    int rc = obs_image_read_exr(&img, path, &err);
    if (rc) fprintf(stderr, "tiled compression %d: %s\n", (int)comps[k], obs_err_message(&err));
    assert_int_equal(rc, 0);
    mixed_check(&m, &img);
    obs_image_free(&img);
    obs_err_free(&err);
  }
  mixed_free(&m);
}

/* ---------------------------------------------------------------------------------------------- */
/* PNG */

/* Input, expected byte: clamping, NaN and round-half-up at 0.5 (127.5 -> 128). */
static const float k_png_in[] = {0.0f, 0.5f, 1.0f, -1.0f, 2.0f, NAN, 0.25f, 1.0f / 255.0f,
                                 INFINITY, -INFINITY, 0.998f, 0.0019f};
static const uint8_t k_png_out[] = {0, 128, 255, 0, 255, 0, 64, 1, 255, 0, 254, 0};
enum { K_PNG_N = sizeof k_png_in / sizeof k_png_in[0] };

/* Reads the file through libspng independently of the code under test. */
static uint8_t *png_raw_decode(const char *path, int fmt, struct spng_ihdr *ihdr, size_t *len) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  spng_ctx *ctx = spng_ctx_new(0);
  assert_non_null(ctx);
  assert_int_equal(spng_set_png_file(ctx, f), 0);
  assert_int_equal(spng_get_ihdr(ctx, ihdr), 0);
  assert_int_equal(spng_decoded_image_size(ctx, fmt, len), 0);
  uint8_t *buf = malloc(*len);
  assert_non_null(buf);
  assert_int_equal(spng_decode_image(ctx, buf, *len, fmt, 0), 0);
  spng_ctx_free(ctx);
  fclose(f);
  return buf;
}

static void test_png_grey_roundtrip(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_png_grey");
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "ao.png"));
  obs_err err = OBS_ERR_INIT;
  obs_image img, back;
  const char *names[] = {"alpha", "ao"};
  assert_int_equal(obs_image_init(&img, 4, 3, 2, names, &err), 0);
  float *ao = obs_image_channel(&img, "ao");
  for (int i = 0; i < K_PNG_N; i++) ao[i] = k_png_in[i];
  const char *sel[] = {"ao"};
  assert_int_equal(obs_image_write_png(&img, sel, 1, 0, path, &err), 0);
  char tmp[1100];
  snprintf(tmp, sizeof tmp, "%s.tmp", path);
  assert_false(obs_test_file_exists(tmp));

  struct spng_ihdr ihdr;
  size_t len;
  uint8_t *raw = png_raw_decode(path, SPNG_FMT_G8, &ihdr, &len);
  assert_int_equal(ihdr.width, 4);
  assert_int_equal(ihdr.height, 3);
  assert_int_equal(ihdr.bit_depth, 8);
  assert_int_equal(ihdr.color_type, SPNG_COLOR_TYPE_GRAYSCALE);
  assert_int_equal(len, K_PNG_N);
  assert_memory_equal(raw, k_png_out, K_PNG_N);
  free(raw);

  assert_int_equal(obs_image_read_png(&back, path, &err), 0);
  assert_int_equal(back.nchannels, 1);
  assert_string_equal(back.names[0], "Y");
  for (int i = 0; i < K_PNG_N; i++) assert_true(back.data[i] == (float)k_png_out[i] / 255.0f);
  assert_true(back.data[2] == 1.0f);
  obs_image_free(&back);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_png_rgb_roundtrip(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_png_rgb");
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "normal.png"));
  obs_err err = OBS_ERR_INIT;
  obs_image img, back;
  const char *names[] = {"normal.X", "normal.Y", "normal.Z"};
  assert_int_equal(obs_image_init(&img, 3, 4, 3, names, &err), 0);
  size_t n = 12;
  for (size_t i = 0; i < n; i++) {
    img.data[i] = k_png_in[i];                      /* X -> R */
    img.data[n + i] = k_png_in[(i + 1) % K_PNG_N];  /* Y -> G */
    img.data[2 * n + i] = k_png_in[(i + 2) % K_PNG_N]; /* Z -> B */
  }
  /* Channel order comes from the argument, not the image: write Z as red. */
  const char *sel[] = {"normal.Z", "normal.Y", "normal.X"};
  assert_int_equal(obs_image_write_png(&img, sel, 3, 0, path, &err), 0);

  struct spng_ihdr ihdr;
  size_t len;
  uint8_t *raw = png_raw_decode(path, SPNG_FMT_RGB8, &ihdr, &len);
  assert_int_equal(ihdr.color_type, SPNG_COLOR_TYPE_TRUECOLOR);
  assert_int_equal(len, 3 * n);
  for (size_t i = 0; i < n; i++) {
    assert_int_equal(raw[3 * i + 0], k_png_out[(i + 2) % K_PNG_N]);
    assert_int_equal(raw[3 * i + 1], k_png_out[(i + 1) % K_PNG_N]);
    assert_int_equal(raw[3 * i + 2], k_png_out[i]);
  }
  free(raw);

  assert_int_equal(obs_image_read_png(&back, path, &err), 0);
  assert_int_equal(back.nchannels, 3);
  const float *r = obs_image_channel(&back, "R");
  const float *g = obs_image_channel(&back, "G");
  const float *b = obs_image_channel(&back, "B");
  assert_non_null(r);
  assert_non_null(g);
  assert_non_null(b);
  for (size_t i = 0; i < n; i++) {
    assert_true(r[i] == (float)k_png_out[(i + 2) % K_PNG_N] / 255.0f);
    assert_true(g[i] == (float)k_png_out[(i + 1) % K_PNG_N] / 255.0f);
    assert_true(b[i] == (float)k_png_out[i] / 255.0f);
  }
  obs_image_free(&back);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_png_gamma_encode(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_png_gamma");
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "srgb.png"));
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  const char *names[] = {"v"};
  assert_int_equal(obs_image_init(&img, 5, 1, 1, names, &err), 0);
  /* sRGB: 0.5 -> 0.73536 -> 187.52 -> 188; 0.001 (linear toe) -> 0.01292 -> 3.29 -> 3;
   * 0.2 -> 0.48453 -> 123.56 -> 124. */
  const float in[] = {0.0f, 0.5f, 1.0f, 0.001f, 0.2f};
  const uint8_t want[] = {0, 188, 255, 3, 124};
  memcpy(img.data, in, sizeof in);
  assert_int_equal(obs_image_write_png(&img, names, 1, 1, path, &err), 0);
  struct spng_ihdr ihdr;
  size_t len;
  uint8_t *raw = png_raw_decode(path, SPNG_FMT_G8, &ihdr, &len);
  assert_int_equal(len, 5);
  assert_memory_equal(raw, want, 5);
  free(raw);
  obs_image_free(&img);
  obs_err_free(&err);
}

/* Files the writer never produces (alpha, 16-bit) must still read as 8-bit values. */
static void write_spng(const char *path, int color_type, int depth, const void *px, size_t len,
                       int w, int h) {
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  spng_ctx *ctx = spng_ctx_new(SPNG_CTX_ENCODER);
  assert_non_null(ctx);
  struct spng_ihdr ihdr = {.width = (uint32_t)w, .height = (uint32_t)h,
                           .bit_depth = (uint8_t)depth, .color_type = (uint8_t)color_type};
  assert_int_equal(spng_set_png_file(ctx, f), 0);
  assert_int_equal(spng_set_ihdr(ctx, &ihdr), 0);
  assert_int_equal(spng_encode_image(ctx, px, len, SPNG_FMT_PNG, SPNG_ENCODE_FINALIZE), 0);
  spng_ctx_free(ctx);
  fclose(f);
}

static void test_png_read_alpha_and_16bit(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_png_foreign");
  obs_err err = OBS_ERR_INIT;
  obs_image img;
  char path[1024];

  const uint8_t rgba[] = {10, 20, 30, 0, 255, 128, 0, 255};
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "rgba.png"));
  write_spng(path, SPNG_COLOR_TYPE_TRUECOLOR_ALPHA, 8, rgba, sizeof rgba, 2, 1);
  assert_int_equal(obs_image_read_png(&img, path, &err), 0);
  assert_int_equal(img.nchannels, 3);
  assert_true(obs_image_channel(&img, "R")[0] == 10.0f / 255.0f);
  assert_true(obs_image_channel(&img, "G")[0] == 20.0f / 255.0f);
  assert_true(obs_image_channel(&img, "B")[1] == 0.0f);
  assert_true(obs_image_channel(&img, "G")[1] == 128.0f / 255.0f);
  obs_image_free(&img);

  /* 16-bit PNG samples are big-endian in the file format. */
  const uint8_t ga16[] = {0xFF, 0xFF, 0x12, 0x34, 0x00, 0x00, 0xFF, 0xFF};
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "ga16.png"));
  write_spng(path, SPNG_COLOR_TYPE_GRAYSCALE_ALPHA, 16, ga16, sizeof ga16, 2, 1);
  assert_int_equal(obs_image_read_png(&img, path, &err), 0);
  assert_int_equal(img.nchannels, 1);
  assert_string_equal(img.names[0], "Y");
  assert_true(img.data[0] == 1.0f);
  assert_true(img.data[1] == 0.0f);
  obs_image_free(&img);
  obs_err_free(&err);
}

static void test_png_errors(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("image_png_err");
  obs_err err = OBS_ERR_INIT;
  obs_image img, back;
  const char *names[] = {"ao", "alpha"};
  assert_int_equal(obs_image_init(&img, 2, 2, 2, names, &err), 0);
  char path[1024];
  snprintf(path, sizeof path, "%s", obs_test_path(dir, "x.png"));

  const char *missing[] = {"bent_normal.X"};
  assert_int_equal(obs_image_write_png(&img, missing, 1, 0, path, &err), OBS_ENOTFOUND);
  assert_msg_has(&err, "bent_normal.X");
  assert_false(obs_test_file_exists(path));
  obs_err_clear(&err);
  assert_int_equal(obs_image_write_png(&img, names, 2, 0, path, &err), OBS_EINVAL);
  assert_false(obs_test_file_exists(path));

  char bad[1024];
  snprintf(bad, sizeof bad, "%s/missing_dir/x.png", dir);
  assert_int_equal(obs_image_write_png(&img, names, 1, 0, bad, &err), OBS_EIO);
  assert_msg_has(&err, bad);
  obs_err_clear(&err);

  snprintf(path, sizeof path, "%s", obs_test_path(dir, "missing.png"));
  assert_int_equal(obs_image_read_png(&back, path, &err), OBS_EIO);
  assert_msg_has(&err, path);
  assert_null(back.data);
  obs_err_clear(&err);

  snprintf(path, sizeof path, "%s", obs_test_path(dir, "text.png"));
  write_text(path, "definitely not a PNG file, only text in here\n");
  assert_int_equal(obs_image_read_png(&back, path, &err), OBS_EINVAL);
  assert_msg_has(&err, path);
  assert_null(back.data);
  obs_image_free(&img);
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_image_init_and_lookup),
      cmocka_unit_test(test_image_init_rejects_bad_input),
      cmocka_unit_test(test_exr_roundtrip_bit_exact),
      cmocka_unit_test(test_exr_single_channel_and_overwrite),
      cmocka_unit_test(test_exr_write_errors),
      cmocka_unit_test(test_exr_read_errors),
      cmocka_unit_test(test_exr_read_half_uint_scanlines),
      cmocka_unit_test(test_exr_read_tiled),
      cmocka_unit_test(test_png_grey_roundtrip),
      cmocka_unit_test(test_png_rgb_roundtrip),
      cmocka_unit_test(test_png_gamma_encode),
      cmocka_unit_test(test_png_read_alpha_and_16bit),
      cmocka_unit_test(test_png_errors),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
