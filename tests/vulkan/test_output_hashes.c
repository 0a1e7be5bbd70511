/* Output bits pinned (a Vulkan test: it renders on lavapipe too, with the driver set-up the
 * Vulkan tests get): every bundled scene rendered small by every registered technique x backend,
 * each EXR channel hashed and compared with tests/data/output_hashes.txt, so a refactor of the
 * framework cannot change a technique's output without this test saying which channel moved.
 * OBSCURA_WRITE_HASHES=<file> writes the current hashes there instead of comparing.
 * Embree's hits differ in the last bits between its instruction sets, so the lines of techniques
 * that need a BVH (rt_ao, path_trace) are keyed by the level this process runs ("cpu/avx2";
 * regenerate under each OBSCURA_ISA); the screen-space techniques give the same bits on every
 * path and have one line per channel. A key may have more than one line: Embree's approximate
 * reciprocals (rcpps) differ between CPU vendors at one level, so a channel can land on other bits
 * on an AMD and an Intel avx2 machine, and any of a key's lines passes. Techniques that need materials render only the scenes whose
 * objects all have one (the Cornell box). */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "simd.h"
#include "testutil.h"
#include "vktest.h"

static const char *const scenes[] = {"cornell_box", "sphere_on_plane", "teapot",
                                     "displaced_sphere", "volume_torus"};

/* Parameter sets beyond the defaults: the scene's own params for its own technique, and these. */
typedef struct extra_params {
  const char *technique, *tag, *json;
} extra_params;
static const extra_params extras[] = {
    {"hbao", "r60", "{\"radius\":60}"},
    {"hbao", "half_res", "{\"radius\":60,\"half_res\":true,\"directions\":6,\"steps\":5}"},
    {"ssao", "hemi", "{\"samples\":24,\"normal_oriented\":true}"},
    {"rt_ao", "exp_uniform", "{\"samples\":8,\"falloff\":\"exp\",\"tau\":2,"
                             "\"weighting\":\"uniform\",\"max_distance\":3,\"sampler\":\"halton\"}"},
};

static uint64_t fnv1a(const float *v, size_t n) {
  uint64_t h = 1469598103934665603ull;
  const unsigned char *b = (const unsigned char *)v;
  for (size_t i = 0; i < n * sizeof *v; i++) h = (h ^ b[i]) * 1099511628211ull;
  return h;
}

/* Renders one case and appends "<case> <channel> <hash>" lines to `out`. */
static void render_case(const char *scene, const obs_technique *t, obs_backend be, const char *tag,
                        const char *params, char **out, size_t *len) {
  char path[512];
  snprintf(path, sizeof path, "scenes/%s.json", scene);
  obs_override ov[5] = {{"/image/width", "64"}, {"/image/height", "48"},
                        {"/technique/name", NULL}, {"/technique/backend", NULL},
                        {"/technique/params", params}};
  char name[64], bname[32];
  snprintf(name, sizeof name, "\"%s\"", t->name);
  snprintf(bname, sizeof bname, "\"%s\"", obs_backend_name(be));
  ov[2].value = name;
  ov[3].value = bname;
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src(path), ov, params ? 5 : 4, &err);
  if (rc) fprintf(stderr, "%s: %s\n", path, obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_render_opts opts = {.threads = 2};
  obs_result res;
  rc = obs_render(&sc, &opts, &res, &err);
  if (rc) fprintf(stderr, "%s %s: %s\n", path, t->name, obs_err_message(&err));
  assert_int_equal(rc, 0);
  size_t plane = (size_t)res.image.width * (size_t)res.image.height;
  for (int c = 0; c < res.image.nchannels; c++) {
    char line[256], key[32];
    snprintf(key, sizeof key, "%s%s%s", obs_backend_name(be), t->needs & OBS_NEED_BVH ? "/" : "",
             t->needs & OBS_NEED_BVH ? obs_simd_isa_name(obs_simd_isa()) : "");
    int n = snprintf(line, sizeof line, "%s %s %s %s %s %016" PRIx64 "\n", scene, t->name, key,
                     tag, res.image.names[c],
                     fnv1a(res.image.data + (size_t)c * plane, plane));
    *out = realloc(*out, *len + (size_t)n + 1);
    memcpy(*out + *len, line, (size_t)n + 1);
    *len += (size_t)n;
  }
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Whether technique t renders bundled scene `scene`: volume techniques the scenes with volumes,
 * the others the scenes with surfaces, and techniques that need materials (path_trace) only
 * scenes whose objects all have one. */
static int renders(const obs_technique *t, const char *scene) {
  char path[512];
  snprintf(path, sizeof path, "scenes/%s.json", scene);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_scene_load_file(&sc, obs_test_src(path), NULL, 0, &err), 0);
  int all = 1, volumes = 0, surfaces = 0;
  for (size_t i = 0; i < sc.nobjects; i++) {
    all &= sc.objects[i].has_material;
    volumes |= sc.objects[i].shape.type == OBS_SHAPE_VOLUME;
    surfaces |= sc.objects[i].shape.type != OBS_SHAPE_VOLUME;
  }
  obs_scene_free(&sc);
  obs_err_free(&err);
  if (t->needs & OBS_NEED_VOLUME) return volumes;
  return surfaces && (all || !(t->needs & OBS_NEED_MATERIALS));
}

static char *read_text(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *s = malloc((size_t)n + 1);
  size_t got = fread(s, 1, (size_t)n, f);
  s[got] = '\0';
  fclose(f);
  return s;
}

/* The line of `text` whose first five fields (the case and channel) are those of `line`, or
 * NULL; `len` gets its length. */
static const char *find_line(const char *text, const char *line, size_t *len) {
  size_t key = 0;
  for (int f = 0; f < 5; f++) key += strcspn(line + key, " ") + 1;
  for (const char *l = text; *l;) {
    size_t n = strcspn(l, "\n");
    if (n >= key && !strncmp(l, line, key)) {
      *len = n;
      return l;
    }
    l += n + (l[n] == '\n');
  }
  return NULL;
}

/* Whether `want` holds exactly `line` (n bytes) under any of the lines that share its key. */
static int matches(const char *want, const char *line, size_t n) {
  size_t m;
  for (const char *w = want; (w = find_line(w, line, &m)) != NULL; w += m + (w[m] == '\n'))
    if (m == n && !strncmp(w, line, n)) return 1;
  return 0;
}

/* Whether line `l` of the hash file belongs to another instruction set than this process runs. */
static int other_isa(const char *l, size_t n) {
  const char *slash = memchr(l, '/', n);
  if (!slash) return 0;
  const char *isa = obs_simd_isa_name(obs_simd_isa());
  return strncmp(slash + 1, isa, strlen(isa)) || slash[1 + strlen(isa)] != ' ';
}

/* Counts the channels whose hash differs or that one side lacks, naming each. */
static int compare(const char *want, const char *got) {
  int bad = 0;
  for (const char *l = got; *l;) {
    size_t n = strcspn(l, "\n"), m;
    const char *w = find_line(want, l, &m);
    if (!w || !matches(want, l, n)) {
      fprintf(stderr, "expected: %.*s\n     got: %.*s\n", w ? (int)m : 4, w ? w : "none",
              (int)n, l);
      bad++;
    }
    l += n + (l[n] == '\n');
  }
  for (const char *l = want; *l;) {
    size_t n = strcspn(l, "\n"), m;
    if (!other_isa(l, n) && !find_line(got, l, &m)) {
      fprintf(stderr, "not rendered: %.*s\n", (int)n, l);
      bad++;
    }
    l += n + (l[n] == '\n');
  }
  return bad;
}

static void test_output_hashes(void **state) {
  (void)state;
  char *got = NULL;
  size_t len = 0;
  int skipped_vk = 0;
  for (size_t s = 0; s < sizeof scenes / sizeof scenes[0]; s++)
    for (size_t i = 0; i < obs_technique_count(); i++) {
      const obs_technique *t = obs_technique_at(i);
      for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
        if (!t->run[b] || !renders(t, scenes[s])) continue;
        if (!obs_technique_has_backend(t, (obs_backend)b)) {
          skipped_vk++;
          continue;
        }
        /* Each scene names rt_ao: its own params apply to rt_ao, the others start from {}. */
        render_case(scenes[s], t, (obs_backend)b, "scene",
                    strcmp(t->name, "rt_ao") ? "{}" : NULL, &got, &len);
        for (size_t e = 0; e < sizeof extras / sizeof extras[0]; e++)
          if (!strcmp(extras[e].technique, t->name) && !strcmp(scenes[s], "cornell_box"))
            render_case(scenes[s], t, (obs_backend)b, extras[e].tag, extras[e].json, &got, &len);
      }
    }
  const char *dump = getenv("OBSCURA_WRITE_HASHES");
  if (dump && *dump) {
    FILE *f = fopen(dump, "w");
    assert_non_null(f);
    fputs(got, f);
    fclose(f);
  } else {
    assert_int_equal(skipped_vk, 0);
    char *want = read_text(obs_test_src("tests/data/output_hashes.txt"));
    assert_non_null(want);
    assert_int_equal(compare(want, got), 0);
    free(want);
  }
  free(got);
}

int main(void) {
  /* The Vulkan tests' fixture: the device renders share is closed at the end, so nothing of the
   * loader or the driver is left for LeakSanitizer. */
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_output_hashes, vktest_quiet_teardown)};
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
