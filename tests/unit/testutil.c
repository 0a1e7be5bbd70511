/* Shared helpers for the cmocka unit tests (see testutil.h). */
#include "testutil.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "simd.h"

/* An instruction-set variant of a test (tests/CMakeLists.txt, obs_isa_variants: OBSCURA_ISA set,
 * OBS_TEST_ISA_VARIANT=1) whose cap is not below this CPU's own level would repeat the plain
 * run: it exits as skipped (ctest's SKIP_RETURN_CODE 77) before the test starts. */
__attribute__((constructor)) static void isa_variant_skip(void) {
  if (!obs_test_isa_variant() || obs_simd_isa_cap() < obs_simd_cpu_isa()) return;
  printf("skipped: OBSCURA_ISA=%s is not below this CPU's level (%s), which the plain run tests\n",
         getenv("OBSCURA_ISA") ? getenv("OBSCURA_ISA") : "", obs_simd_isa_name(obs_simd_cpu_isa()));
  exit(77);
}

static int env_is_one(const char *name) {
  const char *v = getenv(name);
  return v && !strcmp(v, "1");
}

int obs_test_sanitized(void) { return env_is_one("OBS_TEST_SANITIZED"); }

int obs_test_isa_variant(void) { return env_is_one("OBS_TEST_ISA_VARIANT"); }

void obs_test_numeric_only(void) {
  if (obs_test_sanitized()) {
    printf("skipped under the sanitizers: a numerical check, run by the release build\n");
    skip();
  }
}

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

void obs_test_assert_region(const obs_image *whole, const obs_image *part, obs_region r) {
  assert_int_equal(whole->nchannels, part->nchannels);
  assert_int_equal(whole->width, part->width);
  assert_int_equal(whole->height, part->height);
  size_t plane = (size_t)whole->width * (size_t)whole->height;
  for (int c = 0; c < whole->nchannels; c++)
    for (int y = 0; y < whole->height; y++)
      for (int x = 0; x < whole->width; x++) {
        size_t i = (size_t)c * plane + (size_t)y * (size_t)whole->width + (size_t)x;
        if (x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1)
          assert_memory_equal(&whole->data[i], &part->data[i], sizeof(float));
        else
          assert_true(part->data[i] == 0.0f);
      }
}

int obs_test_primary_channels(const obs_technique *t, const obs_image *img, const float *ch[3],
                              double *lo, double *hi) {
  const obs_output *o = obs_technique_primary(t);
  char names[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
  int n = o ? obs_output_channels(o, names) : 0;
  *lo = -INFINITY;
  *hi = INFINITY;
  if (o && (o->flags & OBS_OUTPUT_UNIT)) *lo = 0, *hi = 1;
  else if (o && o->kind == OBS_OUTPUT_RGB) *lo = 0;
  for (int k = 0; k < n; k++)
    if (!(ch[k] = obs_image_channel(img, names[k]))) return 0;
  return n;
}

const char *obs_test_fmt(const char *f, ...) {
  static char buf[16384];
  va_list ap;
  va_start(ap, f);
  vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}

int obs_test_check_sane(const char *what, const obs_technique *t, const obs_image *img) {
  size_t n = (size_t)img->width * (size_t)img->height;
  int bad = 0;
  for (int c = 0; c < img->nchannels; c++) {
    size_t nonfinite = 0;
    for (size_t i = 0; i < n; i++) nonfinite += !isfinite(img->data[(size_t)c * n + i]);
    if (nonfinite) printf("FAIL %s: %zu non-finite values in %s\n", what, nonfinite, img->names[c]);
    bad += nonfinite > 0;
  }
  const float *ch[3];
  double lo, hi;
  int nch = obs_test_primary_channels(t, img, ch, &lo, &hi);
  size_t out = 0;
  for (int k = 0; k < nch; k++)
    for (size_t i = 0; i < n; i++) out += !(ch[k][i] >= lo && ch[k][i] <= hi);
  if (!nch) printf("FAIL %s: the primary output is missing\n", what), bad++;
  if (out) printf("FAIL %s: %zu primary values outside [%g, %g]\n", what, out, lo, hi), bad++;
  return bad;
}

const char *obs_test_medium_material(const obs_technique *t) {
  return t->needs & OBS_NEED_MEDIUM
             ? ",\"material\":{\"reflectivity\":[0.5,0.5,0.5],\"medium\":\"marble\"}"
             : ",\"material\":{\"reflectivity\":[0.5,0.5,0.5]}";
}

const char *obs_test_punctual_light(const obs_technique *t) {
  return t->needs & OBS_NEED_MEDIUM
             ? ",{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],\"emission\":[3,3,3]}"
             : "";
}

void obs_test_ball(const obs_technique *t, double x, double y, double z, double r, char *buf,
                   size_t n) {
  if (t->needs & OBS_NEED_VOLUME) /* the procedural sphere's radius is 0.3 of its box's side */
    snprintf(buf, n,
             "\"shape\":{\"type\":\"volume\",\"procedural\":\"sphere\",\"dims\":[48,48,48]},"
             "\"transform\":{\"scale\":[%.17g,%.17g,%.17g],\"translate\":[%.17g,%.17g,%.17g]}",
             r / 0.3, r / 0.3, r / 0.3, x, y, z);
  else
    snprintf(buf, n,
             "\"shape\":{\"type\":\"sphere\",\"center\":[%.17g,%.17g,%.17g],\"radius\":%.17g}",
             x, y, z, r);
}
