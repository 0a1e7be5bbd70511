/* Output bits pinned (a Vulkan test: it renders on lavapipe too, with the driver set-up the
 * Vulkan tests get): every bundled scene rendered small by every registered technique x backend,
 * each EXR channel hashed and compared with tests/data/output_hashes.txt, so a refactor of the
 * framework cannot change a technique's output without this test saying which channel moved.
 *
 * A pin's key says on which paths its bits hold:
 *  - "cpu", "vulkan": on every instruction-set level and CPU. Every technique's own arithmetic
 *    keeps the scalar code's bits at every level (simd.h), so these are most channels;
 *  - "cpu/avx2/intel" (backend, level, CPU vendor): only there. Embree's kernels differ in the
 *    last bits between its levels and, through approximate reciprocals (rcpps, rcp14), between
 *    vendors, so a channel of a technique that needs a BVH, or traces with Embree on its own
 *    (obs_technique.embree_backends), may move with either; such a case is always pinned per
 *    level, since another vendor's levels may disagree where the pinning machine's agree.
 * A channel with an exact pin must match it: a pinned line that exists and differs fails. A
 * channel pinned only for other levels or vendors (a machine the pins have never seen) is instead
 * compared within its technique's declared tolerance (obs_range.tol) with the committed reference
 * render tests/data/hash_refs/<case>.exr, and the test says so; without a reference it fails.
 *
 * OBSCURA_WRITE_HASHES=<dir> (tests/data) re-pins instead of comparing: it renders every case at
 * each level this CPU has, writes one line where the levels agree and one line per level where
 * they do not, keeps other vendors' lines for channels whose bits this machine did not move, and
 * writes the references (rendered at sse2) of the cases with per-level lines.
 * Techniques that need materials render only the scenes whose objects all have one, and every
 * technique only the scenes whose load it accepts. */
#include <dirent.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "simd.h"
#include "testutil.h"
#include "vktest.h"

static const char *const scenes[] = {"cornell_box",      "sphere_on_plane", "teapot",
                                     "displaced_sphere", "volume_torus",    "volume_torus_mesh",
                                     "sss_marble",  "ibl_sky"};

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

/* One render: a scene, a technique on a backend, a parameter set. */
typedef struct hcase {
  const char *scene;
  const obs_technique *t;
  obs_backend be;
  const char *tag, *params; /* params NULL: the scene's own */
} hcase;

/* One line of the pin file. */
typedef struct pin {
  char scene[48], tech[32], key[48], tag[24], channel[OBS_CHANNEL_NAME_MAX];
  uint64_t hash;
} pin;

typedef struct pin_list {
  pin *v;
  size_t n, cap;
} pin_list;

static void pins_add(pin_list *p, const pin *x) {
  if (p->n == p->cap) {
    p->cap = p->cap ? 2 * p->cap : 256;
    p->v = realloc(p->v, p->cap * sizeof *p->v);
    assert_non_null(p->v);
  }
  p->v[p->n++] = *x;
}

/* Reads the pin file (comment and blank lines skipped); a missing file is an empty list. */
static void pins_load(const char *path, pin_list *p) {
  FILE *f = fopen(path, "r");
  char line[512];
  while (f && fgets(line, sizeof line, f)) {
    pin x;
    if (line[0] == '#' || line[0] == '\n') continue;
    int got = sscanf(line, "%47s %31s %47s %23s %31s %" SCNx64, x.scene, x.tech, x.key, x.tag,
                     x.channel, &x.hash);
    if (got != 6) fprintf(stderr, "%s: unreadable line: %s", path, line);
    assert_int_equal(got, 6);
    pins_add(p, &x);
  }
  if (f) fclose(f);
}

/* Whether pin x is of case c's channel `channel` (on c's backend, under any key). */
static int same_case(const pin *x, const hcase *c, const char *channel) {
  const char *be = obs_backend_name(c->be);
  size_t n = strlen(be);
  return !strcmp(x->scene, c->scene) && !strcmp(x->tech, c->t->name) && !strcmp(x->tag, c->tag) &&
         !strcmp(x->channel, channel) && !strncmp(x->key, be, n) &&
         (x->key[n] == '\0' || x->key[n] == '/');
}

/* The key of pins that hold on every path: the backend's name. */
static const char *plain_key(const hcase *c) { return obs_backend_name(c->be); }

/* The CPU's vendor; OBS_TEST_VENDOR stands in another (a machine the pins have never seen). */
static const char *cpu_vendor(void) {
  const char *v = getenv("OBS_TEST_VENDOR");
  if (v && *v) return v;
#if OBS_SIMD_AVX2
  __builtin_cpu_init();
  if (__builtin_cpu_is("intel")) return "intel";
  if (__builtin_cpu_is("amd")) return "amd";
#endif
  return "other";
}

/* Whether the case's bits may depend on the level and vendor (it traces with Embree). */
static int per_level(const hcase *c) {
  return (c->t->needs & OBS_NEED_BVH) || (c->t->embree_backends & (1u << c->be));
}

/* The key of pins for level `isa` on this CPU's vendor: "cpu/avx2/intel". */
static void level_key(const hcase *c, int isa, char *buf, size_t n) {
  snprintf(buf, n, "%s/%s/%s", obs_backend_name(c->be), obs_simd_isa_name(isa), cpu_vendor());
}

/* Whether key `k` is a per-level key of `vendor` (NULL: of any vendor but this CPU's). */
static int key_of_vendor(const char *k, const char *vendor) {
  const char *v = strrchr(k, '/');
  if (!v || v == strchr(k, '/')) return 0;
  return vendor ? !strcmp(v + 1, vendor) : strcmp(v + 1, cpu_vendor()) != 0;
}

/* Counts the pins of (case, channel) under key `key`; *match gets whether one holds `hash`. */
static int pins_under(const pin_list *p, const hcase *c, const char *channel, const char *key,
                      uint64_t hash, int *match) {
  int n = 0;
  *match = 0;
  for (size_t i = 0; i < p->n; i++)
    if (same_case(&p->v[i], c, channel) && !strcmp(p->v[i].key, key)) {
      n++;
      *match |= p->v[i].hash == hash;
    }
  return n;
}

static uint64_t fnv1a(const float *v, size_t n) {
  uint64_t h = 1469598103934665603ull;
  const unsigned char *b = (const unsigned char *)v;
  for (size_t i = 0; i < n * sizeof *v; i++) h = (h ^ b[i]) * 1099511628211ull;
  return h;
}

static uint64_t channel_hash(const obs_image *img, int c) {
  size_t plane = (size_t)img->width * (size_t)img->height;
  return fnv1a(img->data + (size_t)c * plane, plane);
}

static void render_case(const hcase *c, obs_result *res) {
  char path[512], name[64], bname[32];
  snprintf(path, sizeof path, "scenes/%s.json", c->scene);
  snprintf(name, sizeof name, "\"%s\"", c->t->name);
  snprintf(bname, sizeof bname, "\"%s\"", obs_backend_name(c->be));
  obs_override ov[5] = {{"/image/width", "64"}, {"/image/height", "48"}, {"/technique/name", name},
                        {"/technique/backend", bname}, {"/technique/params", c->params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src(path), ov, c->params ? 5 : 4, &err);
  if (rc) fprintf(stderr, "%s: %s\n", path, obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_render_opts opts = {.threads = 2};
  rc = obs_render(&sc, &opts, res, &err);
  if (rc) fprintf(stderr, "%s %s: %s\n", path, c->t->name, obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

/* Whether technique t renders bundled scene `scene`: only a scene whose load it accepts with its
 * own default params (the loader refuses unmet needs: materials for path_trace, a volume for a
 * volume technique, a medium for sss_single, a map or no map, lights of a kind it takes), and of
 * those, a surface technique the scenes with surfaces and a media technique the scenes with
 * media, which no other technique renders (they are made for scattering inside media). */
static int renders(const obs_technique *t, const char *scene) {
  char path[512], name[64];
  snprintf(path, sizeof path, "scenes/%s.json", scene);
  snprintf(name, sizeof name, "\"%s\"", t->name);
  obs_override ov[2] = {{"/technique/name", name}, {"/technique/params", "{}"}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int loads = obs_scene_load_file(&sc, obs_test_src(path), ov, 2, &err) == 0;
  obs_err_free(&err);
  if (!loads) return 0;
  int surfaces = 0, media = 0;
  for (size_t i = 0; i < sc.nobjects; i++) {
    media |= sc.objects[i].has_medium;
    surfaces |= sc.objects[i].shape.type != OBS_SHAPE_VOLUME;
  }
  obs_scene_free(&sc);
  if (media) return (t->needs & OBS_NEED_MEDIUM) != 0;
  return (t->needs & OBS_NEED_VOLUME) || surfaces;
}

/* Every case, in the pin file's order; *skipped_vk counts Vulkan cases without a device. */
static size_t list_cases(hcase *out, size_t max, int *skipped_vk) {
  size_t n = 0;
  for (size_t s = 0; s < sizeof scenes / sizeof scenes[0]; s++)
    for (size_t i = 0; i < obs_technique_count(); i++) {
      const obs_technique *t = obs_technique_at(i);
      for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
        if (!t->run[b] || !renders(t, scenes[s])) continue;
        if (!obs_technique_has_backend(t, (obs_backend)b)) {
          (*skipped_vk)++;
          continue;
        }
        /* Each scene names rt_ao: its own params apply to rt_ao, the others start from {}. */
        assert_true(n < max);
        out[n++] = (hcase){scenes[s], t, (obs_backend)b, "scene",
                           strcmp(t->name, "rt_ao") ? "{}" : NULL};
        for (size_t e = 0; e < sizeof extras / sizeof extras[0]; e++)
          if (!strcmp(extras[e].technique, t->name) && !strcmp(scenes[s], "cornell_box")) {
            assert_true(n < max);
            out[n++] = (hcase){scenes[s], t, (obs_backend)b, extras[e].tag, extras[e].json};
          }
      }
    }
  return n;
}

static const char *ref_path(const char *dir, const hcase *c) {
  static char buf[768];
  snprintf(buf, sizeof buf, "%s/hash_refs/%s.%s.%s.%s.exr", dir, c->scene, c->t->name,
           obs_backend_name(c->be), c->tag);
  return buf;
}

/* The output of `t` that channel `ch` belongs to ("normal" for "normal.X"); NULL: none. */
static const obs_output *channel_output(const obs_technique *t, const char *ch) {
  size_t len = strcspn(ch, ".");
  for (const obs_output *o = t->outputs; o->name; o++)
    if (strlen(o->name) == len && !strncmp(o->name, ch, len)) return o;
  return NULL;
}

/* Channel `ch` of a render (`got`, whose alpha marks the covered pixels) against the same
 * channel of the reference, within the case's declared tolerance: values (AO, radiance,
 * stderr, coverage) by mean and share of pixels over ao_pixel, directions by the share over
 * `normal`, depth by the share over depth_rel. Writes what it measured into `note`; returns
 * 1 when within. */
static int within_tolerance(const hcase *c, const obs_image *got, const char *ch,
                            const float *ref, char *note, size_t len) {
  const obs_tolerance *tol = &c->t->range[c->be].tol;
  const float *a = obs_image_channel(got, ch), *alpha = obs_image_channel(got, "alpha");
  const obs_output *o = channel_output(c->t, ch);
  int vec = o && o->kind == OBS_OUTPUT_VECTOR, depth = o && o->kind == OBS_OUTPUT_DEPTH;
  double limit = vec ? tol->normal : depth ? tol->depth_rel : tol->ao_pixel;
  size_t n = (size_t)got->width * (size_t)got->height, cov = 0, over = 0;
  double sum = 0, worst = 0;
  if (c->t->range[c->be].size_max <= 0) {
    snprintf(note, len, "no declared tolerance for %s on %s", c->t->name, plain_key(c));
    return 0;
  }
  for (size_t i = 0; i < n; i++) {
    if (alpha && !(alpha[i] > 0) && strcmp(ch, "alpha")) continue;
    double d = fabs((double)a[i] - (double)ref[i]);
    if (depth) d = ref[i] != 0 ? d / fabs((double)ref[i]) : d;
    if (!(d == d)) d = INFINITY; /* a NaN on one side only */
    cov++;
    sum += d;
    worst = fmax(worst, d);
    over += d > limit;
  }
  double mean = cov ? sum / (double)cov : 0;
  int ok = (double)over <= tol->share * (double)cov && (vec || depth || mean <= tol->ao_mean);
  snprintf(note, len, "mean |d| %.3g%s, %zu of %zu pixels over %g (max %.3g; allowed %g %%)",
           mean, vec || depth ? "" : obs_test_fmt(" (allowed %g)", tol->ao_mean), over, cov,
           limit, worst, 100 * tol->share);
  return ok;
}

/* Compares one rendered case with the pins; returns the number of failing channels. `ref`
 * holds the case's reference once read (obs_image, zeroed when not). */
static int compare_case(const hcase *c, const obs_result *res, const pin_list *pins,
                        const char *data_dir) {
  char key[64];
  int isa = obs_simd_isa(), bad = 0, have_ref = 0;
  obs_image ref = {0};
  level_key(c, isa, key, sizeof key);
  for (int ch = 0; ch < res->image.nchannels; ch++) {
    const char *name = res->image.names[ch];
    uint64_t h = channel_hash(&res->image, ch);
    int match;
    char line[256];
    snprintf(line, sizeof line, "%s %s %s %s %s %016" PRIx64, c->scene, c->t->name,
             per_level(c) ? key : plain_key(c), c->tag, name, h);
    if (pins_under(pins, c, name, plain_key(c), h, &match) ||
        (per_level(c) && pins_under(pins, c, name, key, h, &match))) {
      if (!match) {
        fprintf(stderr, "differs from its pin: %s\n", line), bad++;
        for (size_t i = 0; i < pins->n; i++)
          if (same_case(&pins->v[i], c, name))
            fprintf(stderr, "          pinned: %s %016" PRIx64 "\n", pins->v[i].key,
                    pins->v[i].hash);
      }
      continue;
    }
    if (!per_level(c)) {
      fprintf(stderr, "no pin: %s\n", line), bad++;
      continue;
    }
    if (!have_ref) {
      obs_err err = OBS_ERR_INIT;
      have_ref = access(ref_path(data_dir, c), R_OK) == 0 &&
                 obs_image_read_exr(&ref, ref_path(data_dir, c), &err) == 0;
      obs_err_free(&err);
      have_ref = have_ref ? 1 : -1;
    }
    const float *r = have_ref > 0 ? obs_image_channel(&ref, name) : NULL;
    char note[256];
    if (!r || ref.width != res->image.width || ref.height != res->image.height) {
      fprintf(stderr, "no pin for %s and no reference channel in %s\n", line,
              ref_path(data_dir, c)),
          bad++;
    } else if (!within_tolerance(c, &res->image, name, r, note, sizeof note)) {
      fprintf(stderr, "no pin for %s; OUTSIDE the declared tolerance of the reference: %s\n",
              line, note),
          bad++;
    } else {
      printf("no pin for %s; within the declared tolerance of the reference %s: %s\n", line,
             ref_path(data_dir, c) + strlen(data_dir) + 1, note);
    }
  }
  if (have_ref > 0) obs_image_free(&ref);
  return bad;
}

/* Pins of this process's keys that no rendered case produced (a case or channel removed). */
static int unrendered(const pin_list *pins, const hcase *cases, size_t ncases,
                      const obs_result *res) {
  int bad = 0;
  char key[64];
  for (size_t i = 0; i < pins->n; i++) {
    const pin *x = &pins->v[i];
    int mine = 0, found = 0;
    for (size_t k = 0; k < ncases && !found; k++) {
      const hcase *c = &cases[k];
      level_key(c, obs_simd_isa(), key, sizeof key);
      if (strcmp(x->key, plain_key(c)) && (!per_level(c) || strcmp(x->key, key))) continue;
      mine = 1;
      found = same_case(x, c, x->channel) && obs_image_channel(&res[k].image, x->channel);
    }
    if (mine && !found) {
      fprintf(stderr, "not rendered: %s %s %s %s %s\n", x->scene, x->tech, x->key, x->tag,
              x->channel);
      bad++;
    }
  }
  return bad;
}

static void set_level(int isa) {
  setenv("OBSCURA_ISA", isa == OBS_ISA_SSE2 ? "sse2" : isa == OBS_ISA_AVX2 ? "avx2" : "native", 1);
}

#define MAX_CASES 128

/* Re-pins one case from its renders at levels 0..top (res[isa]); returns whether any of its
 * channels has per-level pins afterwards. `changed` gets whether this machine moved any bits. */
static int repin_case(const hcase *c, obs_result *res, int top, const pin_list *old,
                      pin_list *out, int *changed) {
  int keyed = 0;
  *changed = 0;
  for (int ch = 0; ch < res[top].image.nchannels; ch++) {
    const char *name = res[top].image.names[ch];
    pin x = {.hash = channel_hash(&res[top].image, ch)};
    snprintf(x.scene, sizeof x.scene, "%s", c->scene);
    snprintf(x.tech, sizeof x.tech, "%s", c->t->name);
    snprintf(x.tag, sizeof x.tag, "%s", c->tag);
    snprintf(x.channel, sizeof x.channel, "%s", name);
    int lo = per_level(c) ? OBS_ISA_SSE2 : top, same = 1, unchanged = 1, own = 0, match;
    for (int l = lo; l <= top; l++) {
      char key[64];
      uint64_t h = channel_hash(&res[l].image, ch);
      same &= h == x.hash;
      level_key(c, l, key, sizeof key);
      int n = pins_under(old, c, name, plain_key(c), h, &match);
      int accepted = n && match;
      if (per_level(c)) {
        own += pins_under(old, c, name, key, h, &match);
        accepted |= match;
      }
      unchanged &= accepted;
    }
    int mark = 0;
    for (size_t i = 0; i < old->n; i++)
      mark |= same_case(&old->v[i], c, name) && !strcmp(old->v[i].key, plain_key(c));
    if (unchanged) { /* keep the lines as they are, other vendors' with them */
      for (size_t i = 0; i < old->n; i++)
        if (same_case(&old->v[i], c, name)) {
          pins_add(out, &old->v[i]);
          keyed |= strcmp(old->v[i].key, plain_key(c)) != 0;
        }
      continue;
    }
    *changed = 1;
    /* A case that traces with Embree is pinned per level even where this machine's levels
     * agree: another vendor's may not, and would fail a plain pin it never had a say in. */
    if (same && !per_level(c)) {
      snprintf(x.key, sizeof x.key, "%s", plain_key(c));
      pins_add(out, &x);
    } else {
      for (int l = lo; l <= top; l++) {
        level_key(c, l, x.key, sizeof x.key);
        x.hash = channel_hash(&res[l].image, ch);
        pins_add(out, &x);
      }
      keyed = 1;
    }
    /* Other vendors' lines survive only where this vendor had none: bits that moved here moved
     * there too (their machines compare with the reference until re-pinned there). */
    for (size_t i = 0; !own && !mark && i < old->n; i++)
      if (same_case(&old->v[i], c, name) && key_of_vendor(old->v[i].key, NULL)) {
        pins_add(out, &old->v[i]);
        keyed = 1;
      }
  }
  return keyed;
}

/* Writes the reference of a case: its per-level channels (those with a key other than the
 * plain one in `pins`) from `res`, rendered at sse2. */
static void write_ref(const char *dir, const hcase *c, const obs_result *res,
                      const pin_list *pins) {
  const char *names[OBS_IMAGE_MAX_CHANNELS];
  int n = 0;
  for (int ch = 0; ch < res->image.nchannels; ch++)
    for (size_t i = 0; i < pins->n; i++)
      if (same_case(&pins->v[i], c, res->image.names[ch]) &&
          strcmp(pins->v[i].key, plain_key(c))) {
        names[n++] = res->image.names[ch];
        break;
      }
  obs_image img;
  obs_err err = OBS_ERR_INIT;
  assert_int_equal(obs_image_init(&img, res->image.width, res->image.height, n, names, &err), 0);
  size_t plane = (size_t)img.width * (size_t)img.height;
  for (int k = 0; k < n; k++)
    memcpy(img.data + (size_t)k * plane, obs_image_channel(&res->image, names[k]),
           plane * sizeof(float));
  obs_exr_opts o = obs_exr_opts_default();
  o.compression = OBS_EXR_ZIP;
  o.zip_level = 9;
  int rc = obs_image_write_exr_opts(&img, ref_path(dir, c), &o, &err);
  if (rc) fprintf(stderr, "%s\n", obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_image_free(&img);
  obs_err_free(&err);
}

/* Removes references of cases that no longer have per-level pins. */
static void prune_refs(const char *dir, const hcase *cases, size_t n, const int *keep) {
  char d[640];
  snprintf(d, sizeof d, "%s/hash_refs", dir);
  DIR *dp = opendir(d);
  for (struct dirent *e; dp && (e = readdir(dp)) != NULL;) {
    if (!strstr(e->d_name, ".exr")) continue;
    int used = 0;
    for (size_t k = 0; k < n && !used; k++)
      used = keep[k] && !strcmp(strrchr(ref_path(dir, &cases[k]), '/') + 1, e->d_name);
    if (!used) {
      char p[1024];
      snprintf(p, sizeof p, "%s/%s", d, e->d_name);
      remove(p);
    }
  }
  if (dp) closedir(dp);
}

static void write_pins(const char *dir, const hcase *cases, size_t ncases) {
  char path[640];
  snprintf(path, sizeof path, "%s/output_hashes.txt", dir);
  pin_list old = {0}, out = {0};
  pins_load(path, &old);
  snprintf(path, sizeof path, "%s/hash_refs", dir);
  mkdir(path, 0777);
  int top = obs_simd_cpu_isa(), keep[MAX_CASES] = {0};
  for (size_t k = 0; k < ncases; k++) {
    const hcase *c = &cases[k];
    obs_result res[OBS_ISA_AVX512 + 1];
    int lo = per_level(c) ? OBS_ISA_SSE2 : top, changed;
    for (int l = lo; l <= top; l++) {
      set_level(l);
      render_case(c, &res[l]);
    }
    unsetenv("OBSCURA_ISA");
    size_t first = out.n;
    keep[k] = repin_case(c, res, top, &old, &out, &changed);
    pin_list mine = {out.v + first, out.n - first, 0};
    if (keep[k] && (changed || access(ref_path(dir, c), R_OK) != 0))
      write_ref(dir, c, &res[lo], &mine);
    for (int l = lo; l <= top; l++) obs_result_free(&res[l]);
  }
  prune_refs(dir, cases, ncases, keep);
  snprintf(path, sizeof path, "%s/output_hashes.txt", dir);
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs("# Output hashes: <scene> <technique> <key> <params> <channel> <fnv1a-64 of its floats>."
        "\n# Key \"cpu\"/\"vulkan\": the bits on every level and CPU; \"cpu/<level>/<vendor>\":"
        "\n# there only (the case's reference is tests/data/hash_refs/). Written by"
        "\n# OBSCURA_WRITE_HASHES=tests/data build/tests/test_output_hashes"
        " (tests/vulkan/test_output_hashes.c).\n", f);
  for (size_t i = 0; i < out.n; i++)
    fprintf(f, "%s %s %s %s %s %016" PRIx64 "\n", out.v[i].scene, out.v[i].tech, out.v[i].key,
            out.v[i].tag, out.v[i].channel, out.v[i].hash);
  fclose(f);
  free(old.v);
  free(out.v);
}

static void test_output_hashes(void **state) {
  (void)state;
  static hcase cases[MAX_CASES];
  int skipped_vk = 0;
  size_t n = list_cases(cases, MAX_CASES, &skipped_vk);
  const char *dump = getenv("OBSCURA_WRITE_HASHES");
  if (dump && *dump) {
    assert_int_equal(skipped_vk, 0);
    write_pins(dump, cases, n);
    return;
  }
  assert_int_equal(skipped_vk, 0);
  char data_dir[512];
  snprintf(data_dir, sizeof data_dir, "%s", obs_test_src("tests/data"));
  pin_list pins = {0};
  pins_load(obs_test_fmt("%s/output_hashes.txt", data_dir), &pins);
  assert_true(pins.n > 0);
  printf("level %s, CPU vendor %s\n", obs_simd_isa_name(obs_simd_isa()), cpu_vendor());
  /* A stand-in vendor (OBS_TEST_VENDOR, tests/CMakeLists.txt) changes only what the per-level
   * cases are held to: every other case meets the same pins at the same level as in the plain run,
   * and so does the check for unrendered pins, so those are left to it. */
  const char *stand_in = getenv("OBS_TEST_VENDOR");
  int per_level_only = stand_in && *stand_in;
  if (per_level_only) {
    size_t m = 0;
    for (size_t k = 0; k < n; k++)
      if (per_level(&cases[k])) cases[m++] = cases[k];
    printf("%zu per-level cases of %zu (the plain run checks the others)\n", m, n);
    n = m;
  }
  obs_result *res = calloc(n, sizeof *res);
  int bad = 0;
  for (size_t k = 0; k < n; k++) {
    render_case(&cases[k], &res[k]);
    bad += compare_case(&cases[k], &res[k], &pins, data_dir);
  }
  if (!per_level_only) bad += unrendered(&pins, cases, n, res);
  for (size_t k = 0; k < n; k++) obs_result_free(&res[k]);
  free(res);
  free(pins.v);
  assert_int_equal(bad, 0);
}

int main(void) {
  /* The Vulkan tests' fixture: the device renders share is closed at the end, so nothing of the
   * loader or the driver is left for LeakSanitizer. */
  const struct CMUnitTest tests[] = {
      cmocka_unit_test_teardown(test_output_hashes, vktest_quiet_teardown)};
  return cmocka_run_group_tests(tests, vktest_group_setup, vktest_group_teardown);
}
