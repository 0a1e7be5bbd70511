/* Volume files (renderer/core/volume_io.h): raw bricks of each sample type, .den files in both
 * byte orders, NRRD headers read through teem, normalisation, and the refusals; and VolPack's
 * MRI head from Debian's libvolpack1-dev when it is installed. */
#include <stdio.h>
#include <string.h>

#include "testutil.h"
#include "volume_io.h"

static const char *write_file(const char *dir, const char *name, const void *head, size_t hn,
                              const void *data, size_t n) {
  const char *path = obs_test_path(dir, name);
  FILE *f = fopen(path, "wb");
  assert_non_null(f);
  if (hn) assert_int_equal(fwrite(head, 1, hn, f), hn);
  if (n) assert_int_equal(fwrite(data, 1, n, f), n);
  assert_int_equal(fclose(f), 0);
  return path;
}

/* Raw bricks: little-endian samples, x fastest, normalised by the type's range, the data's for
 * float32, or the given range; a size that does not match is refused. */
static void test_raw(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("volume-raw");
  obs_err err = OBS_ERR_INIT;
  obs_volume v;
  const unsigned char u8[12] = {0, 51, 102, 153, 204, 255, 0, 0, 0, 0, 0, 255};
  obs_volume_source s = {OBS_VOLUME_FILE_RAW, NULL, {3, 2, 2}, OBS_VOLUME_UINT8, {1, 2, 3}, {0, 0}};
  s.path = write_file(dir, "a.raw", NULL, 0, u8, sizeof u8);
  assert_int_equal(obs_volume_read(&s, &v, &err), 0);
  assert_true(v.n[0] == 3 && v.n[1] == 2 && v.n[2] == 2 && v.spacing[2] == 3);
  assert_true(obs_volume_at(&v, 1, 0, 0) == 0.2f && obs_volume_at(&v, 2, 1, 0) == 1.0f);
  assert_true(obs_volume_at(&v, 2, 1, 1) == 1.0f);
  obs_volume_free(&v);
  s.range[0] = 51, s.range[1] = 102; /* clamped outside */
  assert_int_equal(obs_volume_read(&s, &v, &err), 0);
  assert_true(obs_volume_at(&v, 0, 0, 0) == 0.0f && obs_volume_at(&v, 2, 0, 0) == 1.0f);
  assert_true(obs_volume_at(&v, 1, 1, 0) == 1.0f);
  obs_volume_free(&v);
  const unsigned char u16[4] = {0xff, 0xff, 0x00, 0x80}; /* 65535, 32768 */
  obs_volume_source s16 = {OBS_VOLUME_FILE_RAW, NULL,      {2, 1, 1},
                           OBS_VOLUME_UINT16,   {1, 1, 1}, {0, 0}};
  s16.path = write_file(dir, "b.raw", NULL, 0, u16, sizeof u16);
  assert_int_equal(obs_volume_read(&s16, &v, &err), 0);
  assert_true(v.data[0] == 1.0f && v.data[1] == (float)(32768.0 / 65535));
  obs_volume_free(&v);
  const float f32[3] = {-2.0f, 0.0f, 6.0f};
  unsigned char le[12];
  for (int i = 0; i < 3; i++) {
    uint32_t u;
    memcpy(&u, &f32[i], 4);
    for (int b = 0; b < 4; b++) le[4 * i + b] = (unsigned char)(u >> (8 * b));
  }
  obs_volume_source sf = {OBS_VOLUME_FILE_RAW, NULL,      {1, 3, 1},
                          OBS_VOLUME_FLOAT32,  {1, 1, 1}, {0, 0}};
  sf.path = write_file(dir, "c.raw", NULL, 0, le, sizeof le);
  assert_int_equal(obs_volume_read(&sf, &v, &err), 0);
  assert_true(v.data[0] == 0.0f && v.data[1] == 0.25f && v.data[2] == 1.0f);
  obs_volume_free(&v);
  sf.dims[1] = 4;
  assert_int_equal(obs_volume_read(&sf, &v, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "12 bytes, but dims 1 x 4 x 1"));
  obs_err_clear(&err);
  sf.path = obs_test_path(dir, "missing.raw");
  assert_int_equal(obs_volume_read(&sf, &v, &err), OBS_EIO);
  obs_err_free(&err);
}

/* A .den header: version 1 and map_len in the writer's byte order, the count after them. */
static void den_header(unsigned char h[62], int big, int x, int y, int z) {
  memset(h, 0, 62);
  uint16_t f[29] = {1};
  f[25] = (uint16_t)x, f[26] = (uint16_t)y, f[27] = (uint16_t)z;
  for (int i = 0; i < 29; i++) {
    h[2 * i] = (unsigned char)(big ? f[i] >> 8 : f[i]);
    h[2 * i + 1] = (unsigned char)(big ? f[i] : f[i] >> 8);
  }
  uint32_t n = (uint32_t)(x * y * z);
  for (int b = 0; b < 4; b++) h[58 + b] = (unsigned char)(big ? n >> (24 - 8 * b) : n >> (8 * b));
}

static void test_den(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("volume-den");
  obs_err err = OBS_ERR_INIT;
  obs_volume v;
  const unsigned char data[6] = {0, 255, 51, 0, 0, 102};
  for (int big = 0; big < 2; big++) {
    unsigned char h[62];
    den_header(h, big, 3, 1, 2);
    obs_volume_source s = {OBS_VOLUME_FILE_DEN, NULL,      {0, 0, 0},
                           OBS_VOLUME_UINT8,    {0, 0, 0}, {0, 0}};
    s.path = write_file(dir, big ? "big.den" : "little.den", h, 62, data, sizeof data);
    assert_int_equal(obs_volume_read(&s, &v, &err), 0);
    assert_true(v.n[0] == 3 && v.n[1] == 1 && v.n[2] == 2 && v.spacing[0] == 1);
    assert_true(obs_volume_at(&v, 1, 0, 0) == 1.0f && obs_volume_at(&v, 2, 0, 1) == 0.4f);
    obs_volume_free(&v);
    s.path = write_file(dir, "short.den", h, 62, data, 5);
    assert_int_equal(obs_volume_read(&s, &v, &err), OBS_EINVAL);
    assert_non_null(strstr(obs_err_message(&err), "do not match the file's 5 data bytes"));
    obs_err_clear(&err);
  }
  obs_volume_source s = {OBS_VOLUME_FILE_DEN, NULL, {0, 0, 0}, OBS_VOLUME_UINT8, {0, 0, 0}, {0, 0}};
  s.path = write_file(dir, "not.den", "P6\n", 3, data, sizeof data);
  assert_int_equal(obs_volume_read(&s, &v, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "not a .den density file"));
  /* The MRI head Debian ships with VolPack (scripts/setup.sh installs it). */
  s.path = "/usr/share/doc/libvolpack1-dev/examples/brainsmall.den";
  if (obs_test_file_exists(s.path)) {
    assert_int_equal(obs_volume_read(&s, &v, &err), 0);
    size_t n = (size_t)v.n[0] * v.n[1] * v.n[2], hi = 0;
    float top = 0;
    for (size_t i = 0; i < n; i++) hi += v.data[i] > 0.1f, top = v.data[i] > top ? v.data[i] : top;
    printf("brainsmall.den: %d x %d x %d, %.1f%% above 0.1, max %.3f\n", v.n[0], v.n[1], v.n[2],
           100.0 * hi / n, top);
    /* 128 x 128 x 84 bytes: the head is about a fifth of the box, its brightest tissue 202/255. */
    assert_true(v.n[0] == 128 && v.n[1] == 128 && v.n[2] == 84);
    assert_true(hi > n / 10 && hi < n / 2 && top == 202.0f / 255);
    obs_volume_free(&v);
  }
  obs_err_free(&err);
}

/* NRRD through teem: the type's range, the file's spacings unless overridden, 3 axes only. */
static void test_nrrd(void **state) {
  (void)state;
  const char *dir = obs_test_tmpdir("volume-nrrd");
  obs_err err = OBS_ERR_INIT;
  obs_volume v;
  const char head[] =
      "NRRD0004\ntype: unsigned short\ndimension: 3\nsizes: 2 1 2\n"
      "spacings: 0.5 1 2\nendian: little\nencoding: raw\n\n";
  const unsigned char data[8] = {0, 0, 0xff, 0xff, 0x00, 0x80, 0xff, 0x3f};
  obs_volume_source s = {OBS_VOLUME_FILE_NRRD, NULL,      {0, 0, 0},
                         OBS_VOLUME_UINT8,     {0, 0, 0}, {0, 0}};
  s.path = write_file(dir, "a.nrrd", head, sizeof head - 1, data, sizeof data);
  assert_int_equal(obs_volume_read(&s, &v, &err), 0);
  assert_true(v.n[0] == 2 && v.n[1] == 1 && v.n[2] == 2);
  assert_true(v.spacing[0] == 0.5 && v.spacing[2] == 2);
  assert_true(v.data[0] == 0.0f && v.data[1] == 1.0f && v.data[2] == (float)(32768.0 / 65535));
  obs_volume_free(&v);
  s.spacing[1] = 7;
  assert_int_equal(obs_volume_read(&s, &v, &err), 0);
  assert_true(v.spacing[0] == 0.5 && v.spacing[1] == 7);
  obs_volume_free(&v);
  const char flat[] =
      "NRRD0004\ntype: float\ndimension: 2\nsizes: 2 2\nendian: little\n"
      "encoding: raw\n\n";
  const float zeros[4] = {0, 0, 0, 0};
  s.path = write_file(dir, "b.nrrd", flat, sizeof flat - 1, zeros, sizeof zeros);
  assert_int_equal(obs_volume_read(&s, &v, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "a volume has 3 axes (this NRRD has 2)"));
  obs_err_clear(&err);
  s.path = write_file(dir, "c.nrrd", "garbage", 7, NULL, 0);
  assert_int_equal(obs_volume_read(&s, &v, &err), OBS_EINVAL);
  assert_non_null(strstr(obs_err_message(&err), "cannot read as NRRD"));
  obs_err_free(&err);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_raw),
      cmocka_unit_test(test_den),
      cmocka_unit_test(test_nrrd),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
