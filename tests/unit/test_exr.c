/* Unit tests for the integrity of written files: every EXR reads back bit-identical to the image in
 * memory for every compression, size, content and thread count (including the chunks whose deflate
 * output is exactly as large as the raw pixels), an independent reader agrees, the bytes do not
 * depend on the thread count, and obs_result_write leaves no partial outputs. */
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <zlib.h>

static float from_bits(uint32_t u) {
  float f;
  memcpy(&f, &u, sizeof f);
  return f;
}

/* Compares every plane bit for bit (NaN payloads, signed zeros, infinities included). */
static void assert_same_bits(const obs_image *a, const obs_image *b, const char *what) {
  assert_int_equal(a->width, b->width);
  assert_int_equal(a->height, b->height);
  assert_int_equal(a->nchannels, b->nchannels);
  size_t n = (size_t)a->width * (size_t)a->height;
  for (int c = 0; c < a->nchannels; c++) {
    const uint32_t *pa = (const uint32_t *)obs_image_channel(a, a->names[c]);
    const uint32_t *pb = (const uint32_t *)obs_image_channel(b, a->names[c]);
    assert_non_null(pb);
    for (size_t i = 0; i < n; i++) {
      if (pa[i] != pb[i]) {
        fprintf(stderr, "%s: channel %s pixel %zu: wrote 0x%08x, read 0x%08x\n", what, a->names[c],
                i, pa[i], pb[i]);
        fail();
      }
    }
  }
}

/* Channel names whose sorted (file) order is their index order. */
static const char *const chan10[10] = {
    "alpha",         "ao",      "ao_stderr", "bent_normal.X", "bent_normal.Y",
    "bent_normal.Z", "depth.Z", "normal.X",  "normal.Y",      "normal.Z"};

enum { K_CONST, K_RANDOM, K_SMOOTH, K_AO, K_SPECIAL, NKINDS };
static const char *const kind_names[NKINDS] = {"constant", "random bits", "smooth", "ao-like",
                                               "specials"};

/* Contents that compress well (constant, smooth, AO in steps of 1/16) and badly (random bits), and
 * the special values (NaN payloads, infinities, denormals, -0). */
static void fill(obs_image *img, int kind, uint32_t seed) {
  size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->nchannels;
  uint32_t s = seed | 1u;
  static const uint32_t specials[] = {0x7fc00000u, 0xffc00001u, 0x7f800001u, 0x7f800000u,
                                      0xff800000u, 0x80000000u, 0x00000001u, 0x007fffffu,
                                      0x3f800000u, 0x00000000u};
  for (size_t i = 0; i < n; i++) {
    size_t x = i % (size_t)img->width, y = (i / (size_t)img->width) % (size_t)img->height;
    switch (kind) {
      case K_CONST:
        img->data[i] = 0.25f;
        break;
      case K_RANDOM:
        img->data[i] = from_bits(obs_test_rand(&s));
        break;
      case K_SMOOTH:
        img->data[i] = (float)(0.001 * (double)x + 0.01 * (double)y + 1.0);
        break;
      case K_AO:
        img->data[i] = (float)(obs_test_rand(&s) % 17u) / 16.0f;
        break;
      default:
        img->data[i] = from_bits(specials[obs_test_rand(&s) % 10u]);
        break;
    }
  }
}

static void make(obs_image *img, int w, int h, int nch) {
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(img, w, h, nch, chan10, &err), 0);
}

static void write_read_check(const obs_image *img, const char *path, const obs_exr_opts *eo,
                             const char *what) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_image_write_exr_opts(img, path, eo, &err);
  if (rc) fprintf(stderr, "%s: %s\n", what, obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_image back;
  rc = obs_image_read_exr(&back, path, &err);
  if (rc) fprintf(stderr, "%s: %s\n", what, obs_err_message(&err));
  assert_int_equal(rc, 0);
  assert_same_bits(img, &back, what);
  obs_image_free(&back);
  obs_err_free(&err);
}

/* The compressions and levels the writer can be asked for. */
static const obs_exr_opts every_compression[] = {
    {OBS_EXR_NONE, 0, 1}, {OBS_EXR_RLE, 0, 1}, {OBS_EXR_ZIPS, 0, 1}, {OBS_EXR_ZIP, 0, 1},
    {OBS_EXR_ZIP, 1, 1},  {OBS_EXR_ZIP, 9, 1}, {OBS_EXR_PIZ, 0, 1}};
#define NCOMP (int)(sizeof every_compression / sizeof every_compression[0])

static void test_exr_roundtrip_sizes_contents_compressions(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("exr_sweep");
  static const int sizes[][2] = {{1, 1},  {1, 2},   {1, 15},   {1, 16},   {1, 17},
                                 {1, 33}, {1, 100}, {1, 4096}, {2, 1},    {15, 1},
                                 {16, 1}, {17, 1},  {100, 1},  {4096, 1}, {3, 5},
                                 {7, 31}, {33, 17}, {64, 64},  {129, 47}};
  int nsizes = (int)(sizeof sizes / sizeof sizes[0]), cases = 0;
  for (int si = 0; si < nsizes; si++) {
    for (int kind = 0; kind < NKINDS; kind++) {
      int nch = (si + kind) % 3 == 0 ? 1 : ((si + kind) % 3 == 1 ? 7 : 10);
      obs_image img;
      make(&img, sizes[si][0], sizes[si][1], nch);
      fill(&img, kind, 0x9e3779b9u * (uint32_t)(si * NKINDS + kind + 1));
      for (int c = 0; c < NCOMP; c++) {
        obs_exr_opts eo = every_compression[c];
        eo.threads = 1 + (si + c) % 3; /* 1..3 threads, chunks compressed out of order */
        char what[160];
        snprintf(what, sizeof what, "%dx%d %d channels %s, compression %d level %d, %d threads",
                 img.width, img.height, nch, kind_names[kind], eo.compression, eo.zip_level,
                 eo.threads);
        write_read_check(&img, obs_test_path(dir, "sweep.exr"), &eo, what);
        cases++;
      }
      obs_image_free(&img);
    }
  }
  assert_int_equal(cases, nsizes * NKINDS * NCOMP);
  unlink(obs_test_path(dir, "sweep.exr"));
}

/* ---- chunks whose deflate output is exactly as large as the raw pixels ------------------------
 */

/* OpenEXR's ZIP pre-pass: bytes split into even and odd halves, then delta-coded. */
static void zip_forward(const uint8_t *raw, uint8_t *out, size_t n) {
  size_t h = (n + 1) / 2;
  for (size_t i = 0; i < n; i++) out[(i % 2 ? h : 0) + i / 2] = raw[i];
  int p = out[0];
  for (size_t i = 1; i < n; i++) {
    int d = (int)out[i] - p + 384;
    p = out[i];
    out[i] = (uint8_t)d;
  }
}

static void zip_inverse(const uint8_t *pre, uint8_t *raw, size_t n) {
  uint8_t *t = malloc(n);
  assert_non_null(t);
  t[0] = pre[0];
  for (size_t i = 1; i < n; i++) t[i] = (uint8_t)(pre[i] + t[i - 1] - 384 + 512);
  size_t h = (n + 1) / 2;
  for (size_t i = 0; i < n; i++) raw[i] = t[(i % 2 ? h : 0) + i / 2];
  free(t);
}

/* Size of OpenEXR's ZIP encoding of one packed chunk at deflate `level`. */
static size_t zip_size(const uint8_t *raw, size_t n, int level) {
  uint8_t *pre = malloc(n);
  uLongf cap = compressBound((uLong)n);
  uint8_t *out = malloc(cap);
  assert_true(pre && out);
  zip_forward(raw, pre, n);
  assert_int_equal(compress2(out, &cap, pre, (uLong)n, level), Z_OK);
  free(pre);
  free(out);
  return (size_t)cap;
}

/* A 1x4096 image of 7 float channels (448 packed bytes per 16-line ZIP chunk, as an ssao render of
 * that size has) whose chunks sweep from incompressible to slightly compressible: the deflate size
 * crosses the raw size, and at about one chunk in forty it lands exactly on it. The pre-pass output
 * is drawn first (random bytes, a share of them 128) and inverted into pixels. */
static void test_exr_zip_equal_size_chunks(void **state) {
  (void)state;
  const int w = 1, h = 4096, nch = 7, lines = 16;
  obs_image img;
  make(&img, w, h, nch);
  size_t n = (size_t)w * lines * nch * 4;
  uint8_t *pre = malloc(n), *raw = malloc(n);
  assert_true(pre && raw);
  uint32_t s = 12345u;
  for (int c = 0; c < h / lines; c++) {
    uint32_t share = 240u + (uint32_t)(c * 80 / (h / lines)); /* per mille of 128s */
    for (size_t i = 0; i < n; i++) {
      uint32_t v = obs_test_rand(&s);
      pre[i] = (v >> 8) % 1000u < share ? 128 : (uint8_t)v;
    }
    zip_inverse(pre, raw, n);
    /* Packed order: line by line, channels in file (name) order, pixels little-endian. */
    size_t k = 0;
    for (int y = c * lines; y < (c + 1) * lines; y++)
      for (int ch = 0; ch < nch; ch++, k += 4)
        memcpy(obs_image_channel(&img, chan10[ch]) + y, raw + k, 4);
  }
  const char *dir = obs_test_tmpdir("exr_equal");
  static const int levels[] = {0, 1, 9};
  for (int li = 0; li < 3; li++) {
    int level = levels[li] ? levels[li] : 6, equal = 0;
    for (int c = 0; c < h / lines; c++) {
      size_t k = 0;
      for (int y = c * lines; y < (c + 1) * lines; y++)
        for (int ch = 0; ch < nch; ch++, k += 4)
          memcpy(raw + k, obs_image_channel(&img, chan10[ch]) + y, 4);
      equal += zip_size(raw, n, level) == n;
    }
    /* The case the test exists for must really be in the file. */
    if (levels[li] == 0) assert_true(equal >= 3);
    for (int t = 1; t <= 2; t++) {
      obs_exr_opts eo = {OBS_EXR_ZIP, levels[li], t};
      char what[96];
      snprintf(what, sizeof what, "1x4096 ZIP level %d (%d equal-size chunks), %d threads", level,
               equal, t);
      write_read_check(&img, obs_test_path(dir, "equal.exr"), &eo, what);
    }
  }
  free(pre);
  free(raw);
  obs_image_free(&img);
  unlink(obs_test_path(dir, "equal.exr"));
}

/* ---- determinism and the independent reader ---------------------------------------------------
 */

static uint8_t *slurp(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  assert_non_null(f);
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  uint8_t *b = malloc(n > 0 ? (size_t)n : 1);
  assert_non_null(b);
  assert_int_equal(fread(b, 1, (size_t)n, f), (size_t)n);
  fclose(f);
  *len = (size_t)n;
  return b;
}

static void assert_same_file(const char *a, const char *b) {
  size_t la, lb;
  uint8_t *ba = slurp(a, &la), *bb = slurp(b, &lb);
  if (la != lb || memcmp(ba, bb, la)) {
    fprintf(stderr, "%s and %s differ\n", a, b);
    fail();
  }
  free(ba);
  free(bb);
}

static void test_exr_bytes_independent_of_threads(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("exr_threads");
  obs_image img;
  make(&img, 77, 301, 10);
  fill(&img, K_AO, 7u);
  uint32_t s = 9u; /* half the planes random bits: chunks of very different sizes */
  for (size_t i = 5u * 77u * 301u; i < 10u * 77u * 301u; i++)
    img.data[i] = from_bits(obs_test_rand(&s));
  for (int c = 0; c < NCOMP; c++) {
    char ref[2200];
    static const int counts[] = {1, 3, 5, 0, -2}; /* 0 and below mean the calling thread */
    for (int ti = 0; ti < 5; ti++) {
      int t = counts[ti];
      obs_exr_opts eo = every_compression[c];
      eo.threads = t;
      char name[32];
      snprintf(name, sizeof name, "t%d.exr", ti);
      obs_err err = OBS_ERR_INIT;
      assert_int_equal(obs_image_write_exr_opts(&img, obs_test_path(dir, name), &eo, &err), 0);
      if (ti == 0)
        snprintf(ref, sizeof ref, "%s", obs_test_path(dir, name));
      else
        assert_same_file(ref, obs_test_path(dir, name));
    }
  }
  obs_image_free(&img);
}

/* An image larger than the writer's window of chunks held at once (8 MB of raw pixels): chunks are
 * compressed and written window by window, and the bytes still do not depend on the threads. */
static void test_exr_large_image_windows(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("exr_large");
  obs_image img;
  make(&img, 1024, 300, 10);
  fill(&img, K_AO, 11u);
  uint32_t s = 5u;
  for (size_t i = 0; i < 3u * 1024u * 300u; i++) img.data[i] = from_bits(obs_test_rand(&s));
  static const obs_exr_opts which[] = {{OBS_EXR_RLE, 0, 1}, {OBS_EXR_ZIP, 1, 1}};
  for (int c = 0; c < 2; c++) {
    obs_exr_opts eo = which[c];
    write_read_check(&img, obs_test_path(dir, "t1.exr"), &eo, "1024x300 one thread");
    eo.threads = 3;
    write_read_check(&img, obs_test_path(dir, "t3.exr"), &eo, "1024x300 three threads");
    char a[2200];
    snprintf(a, sizeof a, "%s", obs_test_path(dir, "t1.exr"));
    assert_same_file(a, obs_test_path(dir, "t3.exr"));
  }
  obs_image_free(&img);
}

/* OpenImageIO reads EXR through the C++ OpenEXR library, whose decompressors are separate code
 * from OpenEXRCore's: it rewrites each file uncompressed and the result must hold the same bits. */
static void test_exr_independent_reader(void **state) {
  (void)state;
  if (system("command -v oiiotool >/dev/null 2>&1") != 0) skip();
  const char *dir = obs_test_tmpdir("exr_oiio");
  obs_image img;
  make(&img, 1, 4096, 7);
  fill(&img, K_RANDOM, 3u);
  for (size_t i = 0; i < 4096u * 7u; i++) /* finite values: the copy must not depend on NaN care */
    if (!isfinite(img.data[i])) img.data[i] = 0.5f;
  for (int c = 0; c < NCOMP; c++) {
    obs_exr_opts eo = every_compression[c];
    eo.threads = 2;
    char src[1024], dst[1024], cmd[3000];
    snprintf(src, sizeof src, "%s/in%d.exr", dir, c);
    snprintf(dst, sizeof dst, "%s/out%d.exr", dir, c);
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_image_write_exr_opts(&img, src, &eo, &err), 0);
    snprintf(cmd, sizeof cmd, "oiiotool '%s' --compression none -o '%s' >/dev/null 2>&1", src, dst);
    assert_int_equal(system(cmd), 0);
    obs_image back;
    assert_int_equal(obs_image_read_exr(&back, dst, &err), 0);
    assert_same_bits(&img, &back, "oiiotool copy");
    obs_image_free(&back);
  }
  obs_image_free(&img);
}

/* ---- obs_result_write ---------------------------------------------------------------------------
 */

static const char *scene_json =
    "{\"camera\":{\"type\":\"perspective\",\"position\":[0,3,-4],\"look_at\":[0,0.3,0],"
    "\"up\":[0,1,0],\"fov_y\":45},\"image\":{\"width\":37,\"height\":29,\"spp\":1},"
    "\"objects\":[{\"name\":\"ground\",\"shape\":{\"type\":\"quad\",\"vertices\":[[-20,0,-20],"
    "[-20,0,20],[20,0,20],[20,0,-20]]}},{\"name\":\"ball\",\"shape\":{\"type\":\"sphere\","
    "\"center\":[0,1,0],\"radius\":0.5}}],\"technique\":{\"name\":\"rt_ao\",\"backend\":\"cpu\","
    "\"params\":{\"samples\":8}}}";

static void write_result(const char *json, int threads, const char *dir) {
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_scene_load_string(&sc, json, "t.json", NULL, NULL, 0, &err), 0);
  obs_result res;
  obs_render_opts ro = {.threads = 2};
  assert_int_equal(obs_render(&sc, &ro, &res, &err), 0);
  res.threads = threads; /* the writer's thread count */
  int rc = obs_result_write(&res, &sc, dir, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_image back;
  assert_int_equal(obs_image_read_exr(&back, obs_test_path(dir, "ao.exr"), &err), 0);
  assert_same_bits(&res.image, &back, "ao.exr");
  obs_image_free(&back);
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static void test_result_write_threads_and_readback(void **state) {
  (void)state;
  char a[1024], b[1024];
  snprintf(a, sizeof a, "%s", obs_test_tmpdir("result_t1"));
  snprintf(b, sizeof b, "%s", obs_test_tmpdir("result_t4"));
  write_result(scene_json, 1, a);
  write_result(scene_json, 4, b);
  static const char *const files[] = {"ao.exr", "ao.png", "bent_normal.png", "depth.png"};
  for (int i = 0; i < 4; i++) {
    char pa[2200], pb[2200];
    snprintf(pa, sizeof pa, "%s/%s", a, files[i]);
    snprintf(pb, sizeof pb, "%s/%s", b, files[i]);
    assert_same_file(pa, pb);
  }
}

/* The render that exposed the equal-size chunks: ssao at 1x4096 on sphere_on_plane (7 channels,
 * 448 packed bytes per 16-line chunk). Its ao.exr must hold exactly the image rendered, at every
 * compression, and the written file must also pass through the independent reader. */
static void test_result_write_ssao_1x4096(void **state) {
  (void)state;
  obs_override ov[] = {{"/technique/name", "\"ssao\""},
                       {"/technique/params", "{}"},
                       {"/image/width", "1"},
                       {"/image/height", "4096"}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src("scenes/sphere_on_plane.json"), ov, 4, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_result res;
  obs_render_opts ro = {.threads = 2};
  assert_int_equal(obs_render(&sc, &ro, &res, &err), 0);
  char dir[1024];
  snprintf(dir, sizeof dir, "%s", obs_test_tmpdir("ssao_1x4096"));
  assert_int_equal(obs_result_write(&res, &sc, dir, &err), 0);
  obs_image back;
  assert_int_equal(obs_image_read_exr(&back, obs_test_path(dir, "ao.exr"), &err), 0);
  assert_same_bits(&res.image, &back, "ssao 1x4096 ao.exr");
  const float *ao = obs_image_channel(&back, "ao");
  for (int i = 0; i < 4096; i++) assert_true(ao[i] >= 0.0f && ao[i] <= 1.0f);
  obs_image_free(&back);
  for (int c = 0; c < NCOMP; c++) {
    char what[64];
    snprintf(what, sizeof what, "ssao 1x4096, compression %d level %d",
             every_compression[c].compression, every_compression[c].zip_level);
    write_read_check(&res.image, obs_test_path(dir, "again.exr"), &every_compression[c], what);
  }
  if (system("command -v oiiotool >/dev/null 2>&1") == 0) {
    char cmd[3000];
    snprintf(cmd, sizeof cmd, "oiiotool '%s/ao.exr' --compression none -o '%s/copy.exr'", dir, dir);
    assert_int_equal(system(cmd), 0);
    assert_int_equal(obs_image_read_exr(&back, obs_test_path(dir, "copy.exr"), &err), 0);
    assert_same_bits(&res.image, &back, "oiiotool copy of ssao 1x4096");
    obs_image_free(&back);
  }
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* A PNG that cannot be created (its temporary name is taken by a directory) fails the whole write
 * while the other files are written on other threads: nothing new is published, no staging file
 * stays, and the earlier outputs are untouched. */
static void test_result_write_failure_leaves_nothing(void **state) {
  (void)state;
  char dir[1024];
  snprintf(dir, sizeof dir, "%s", obs_test_tmpdir("result_fail"));
  write_result(scene_json, 3, dir);
  size_t before_len;
  uint8_t *before = slurp(obs_test_path(dir, "ao.exr"), &before_len);
  char blocker[2200];
  snprintf(blocker, sizeof blocker, "%s/.depth.png.new.tmp", dir);
  assert_int_equal(mkdir(blocker, 0755), 0);

  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_scene_load_string(&sc, scene_json, "t.json", NULL, NULL, 0, &err), 0);
  obs_result res;
  obs_render_opts ro = {.threads = 3};
  assert_int_equal(obs_render(&sc, &ro, &res, &err), 0);
  res.image.data[0] = 0.123f; /* a different ao.exr, were it published */
  assert_int_not_equal(obs_result_write(&res, &sc, dir, &err), 0);
  assert_non_null(strstr(obs_err_message(&err), "depth.png"));
  static const char *const staged[] = {
      ".ao.exr.new",       ".ao.png.new",     ".bent_normal.png.new", ".depth.png.new",
      ".summary.json.new", ".ao.exr.new.tmp", ".ao.png.new.tmp",      ".bent_normal.png.new.tmp"};
  for (size_t i = 0; i < sizeof staged / sizeof staged[0]; i++)
    assert_false(obs_test_file_exists(obs_test_path(dir, staged[i])));
  size_t after_len;
  uint8_t *after = slurp(obs_test_path(dir, "ao.exr"), &after_len);
  assert_true(before_len == after_len && !memcmp(before, after, before_len));
  free(before);
  free(after);
  rmdir(blocker);
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Every PNG setting the writer offers stores the same 8-bit pixels (grey and RGB, odd sizes). */
static void test_png_every_option_reads_back(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("png_opts");
  static const char *const names[3] = {"R", "G", "B"};
  static const int sizes[][2] = {{1, 1}, {1, 300}, {300, 1}, {37, 29}};
  for (int si = 0; si < 4; si++) {
    obs_image img;
    obs_err err = OBS_ERR_INIT;
    assert_int_equal(obs_image_init(&img, sizes[si][0], sizes[si][1], 3, names, &err), 0);
    uint32_t s = 77u + (uint32_t)si;
    size_t n = (size_t)img.width * (size_t)img.height;
    for (size_t i = 0; i < 3 * n; i++) /* steps of 1/255 with runs, noise and out-of-range */
      img.data[i] = i % 7 < 3 ? 0.5f : (float)(obs_test_rand(&s) % 300u) / 255.0f - 0.1f;
    for (int level = -1; level <= 9; level += 5)
      for (int f = 0; f < OBS_PNG_NFILTERS; f++)
        for (int st = 0; st < OBS_PNG_NSTRATEGIES; st++)
          for (int nch = 1; nch <= 3; nch += 2) {
            obs_png_opts po = {level, f, st};
            assert_int_equal(obs_image_write_png_opts(&img, names, nch, 0,
                                                      obs_test_path(dir, "p.png"), &po, &err),
                             0);
            obs_image back;
            assert_int_equal(obs_image_read_png(&back, obs_test_path(dir, "p.png"), &err), 0);
            for (int c = 0; c < nch; c++) {
              const float *src = obs_image_channel(&img, names[c]);
              const float *got = nch == 1 ? back.data : obs_image_channel(&back, names[c]);
              for (size_t i = 0; i < n; i++) {
                float v = src[i] < 0.0f ? 0.0f : (src[i] > 1.0f ? 1.0f : src[i]);
                assert_true(fabs(got[i] * 255.0 - floor((double)v * 255.0 + 0.5)) < 1e-3);
              }
            }
            obs_image_free(&back);
          }
    obs_image_free(&img);
    obs_err_free(&err);
  }
}

/* The rejected options name themselves. */
static void test_writer_rejects_unknown_options(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("exr_opts");
  obs_image img;
  make(&img, 2, 2, 1);
  obs_err err = OBS_ERR_INIT;
  obs_exr_opts bad = {OBS_EXR_NCOMPRESSIONS, 0, 1};
  assert_int_equal(obs_image_write_exr_opts(&img, obs_test_path(dir, "x.exr"), &bad, &err),
                   OBS_EINVAL);
  assert_false(obs_test_file_exists(obs_test_path(dir, "x.exr")));
  bad = (obs_exr_opts){OBS_EXR_ZIP, 10, 1};
  assert_int_equal(obs_image_write_exr_opts(&img, obs_test_path(dir, "x.exr"), &bad, &err),
                   OBS_EINVAL);
  const char *ch[] = {"alpha"};
  obs_png_opts pbad = {10, OBS_PNG_FILTER_NONE, OBS_PNG_STRATEGY_DEFAULT};
  assert_int_equal(
      obs_image_write_png_opts(&img, ch, 1, 0, obs_test_path(dir, "x.png"), &pbad, &err),
      OBS_EINVAL);
  pbad = (obs_png_opts){1, OBS_PNG_NFILTERS, OBS_PNG_STRATEGY_DEFAULT};
  assert_int_equal(
      obs_image_write_png_opts(&img, ch, 1, 0, obs_test_path(dir, "x.png"), &pbad, &err),
      OBS_EINVAL);
  pbad = (obs_png_opts){1, OBS_PNG_FILTER_UP, OBS_PNG_NSTRATEGIES};
  assert_int_equal(
      obs_image_write_png_opts(&img, ch, 1, 0, obs_test_path(dir, "x.png"), &pbad, &err),
      OBS_EINVAL);
  assert_false(obs_test_file_exists(obs_test_path(dir, "x.png")));
  obs_image_free(&img);
  obs_err_free(&err);
}

/* An argument runs only the tests whose names match it (cmocka's pattern, e.g. "*windows*"). */
int main(int argc, char **argv) {
  if (argc > 1) cmocka_set_test_filter(argv[1]);
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_exr_roundtrip_sizes_contents_compressions),
      cmocka_unit_test(test_exr_zip_equal_size_chunks),
      cmocka_unit_test(test_exr_bytes_independent_of_threads),
      cmocka_unit_test(test_exr_large_image_windows),
      cmocka_unit_test(test_exr_independent_reader),
      cmocka_unit_test(test_result_write_threads_and_readback),
      cmocka_unit_test(test_result_write_ssao_1x4096),
      cmocka_unit_test(test_result_write_failure_leaves_nothing),
      cmocka_unit_test(test_png_every_option_reads_back),
      cmocka_unit_test(test_writer_rejects_unknown_options),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
