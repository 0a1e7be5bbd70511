/* Shared helpers for the cmocka unit tests (see testutil.h). */
#include "testutil.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static void mkdir_p(const char *path) {
  char buf[1024];
  snprintf(buf, sizeof buf, "%s", path);
  for (char *p = buf + 1; *p; p++) {
    if (*p == '/') {
      *p = '\0';
      mkdir(buf, 0755);
      *p = '/';
    }
  }
  mkdir(buf, 0755);
}

const char *obs_test_tmpdir(const char *tag) {
  static char buf[1024];
  const char *base = getenv("OBS_TMP");
  if (!base || !*base) base = "/tmp/obscura-tests";
  snprintf(buf, sizeof buf, "%s/%s-%ld", base, tag, (long)getpid());
  mkdir_p(buf);
  return buf;
}

const char *obs_test_src(const char *rel) {
  static char buf[1024];
  snprintf(buf, sizeof buf, "%s/%s", OBS_SOURCE_DIR, rel);
  return buf;
}

const char *obs_test_path(const char *dir, const char *name) {
  static char buf[4200];
  snprintf(buf, sizeof buf, "%s/%s", dir, name);
  return buf;
}

int obs_test_file_exists(const char *path) {
  struct stat st;
  return stat(path, &st) == 0;
}

uint32_t obs_test_rand(uint32_t *s) {
  uint32_t x = *s;
  x ^= x << 13;
  x ^= x >> 17;
  x ^= x << 5;
  return *s = x;
}

void obs_test_load(const char *json, const char *name, obs_scene *sc) {
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(sc, json, name, NULL, NULL, 0, &err);
  if (rc) fprintf(stderr, "load failed: %s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_err_free(&err);
}

void obs_test_render(const char *json, int threads, obs_result *res) {
  obs_scene sc;
  obs_test_load(json, "test.json", &sc);
  obs_err err = OBS_ERR_INIT;
  obs_render_opts opts = {.threads = threads};
  int rc = obs_render(&sc, &opts, res, &err);
  if (rc) fprintf(stderr, "render failed: %s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

void obs_test_assert_finite(const obs_image *img) {
  size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->nchannels;
  for (size_t i = 0; i < n; i++) {
    if (!isfinite(img->data[i])) {
      fprintf(stderr, "non-finite value at %zu (channel %s)\n", i,
              img->names[i / ((size_t)img->width * (size_t)img->height)]);
      fail();
    }
  }
}
