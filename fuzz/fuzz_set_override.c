/* libFuzzer target: the CLI's `--set /json/pointer=VALUE` path. The first input byte picks one of
 * the bundled scenes without meshes; the rest is read as lines, each split at its first '=' into
 * a pointer and a value exactly as `obscura render --set` splits its argument (which refuses a
 * value that is not JSON), and the scene
 * is loaded with those overrides (obs_scene_load_string, which applies them with
 * obs_json_pointer_set). The load must succeed with a complete scene or fail with problems naming
 * the scene; each override is also applied alone to a fresh copy of the document, which must
 * either take it or say why. */
#include <dirent.h>
#include <jansson.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "obscura/obscura.h"

#define MAX_SCENES 16

static struct {
  char *name, *text;
} scenes[MAX_SCENES];
static size_t nscenes;
static char dir[4096];

static char *read_all(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = NULL;
  size_t len = 0, cap = 0, n;
  char chunk[65536];
  while ((n = fread(chunk, 1, sizeof chunk, f)) > 0) {
    if (len + n + 1 > cap) {
      cap = (len + n + 1) * 2;
      char *nb = realloc(buf, cap);
      if (!nb) break;
      buf = nb;
    }
    memcpy(buf + len, chunk, n);
    len += n;
  }
  fclose(f);
  if (buf) buf[len] = '\0';
  return buf;
}

static int by_name(const void *a, const void *b) {
  return strcmp(((const char *const *)a)[0], ((const char *const *)b)[0]);
}

/* The bundled scenes, sorted by name so that a reproducer picks the same scene everywhere. */
int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  const char *env = getenv("OBS_FUZZ_SCENES");
  snprintf(dir, sizeof dir, "%s", env && *env ? env : OBS_SOURCE_DIR "/scenes");
  DIR *d = opendir(dir);
  if (!d) {
    fprintf(stderr, "fuzz_set_override: cannot open the scenes directory %s\n", dir);
    exit(1);
  }
  struct dirent *e;
  while ((e = readdir(d)) && nscenes < MAX_SCENES) {
    size_t n = strlen(e->d_name);
    if (n < 6 || strcmp(e->d_name + n - 5, ".json") || e->d_name[0] == '.') continue;
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
    char *text = read_all(path);
    if (!text) continue;
    /* A mesh scene imports its mesh on every load (seconds per input under ASan): mesh import has
     * a target of its own, and the override path is the same for every scene. */
    if (strstr(text, "\"mesh\"")) {
      free(text);
      continue;
    }
    scenes[nscenes].name = strdup(e->d_name);
    scenes[nscenes].text = text;
    nscenes++;
  }
  closedir(d);
  if (!nscenes) {
    fprintf(stderr, "fuzz_set_override: no scenes in %s\n", dir);
    exit(1);
  }
  qsort(scenes, nscenes, sizeof scenes[0], by_name);
  return 0;
}

static void fail(const char *what, const char *detail) {
  fprintf(stderr, "fuzz_set_override: %s: %s\n", what, detail);
  abort();
}

/* Applies one override alone to a fresh parse of the scene: success, or a message. */
static void apply_alone(const char *scene, const obs_override *ov) {
  json_t *doc = json_loads(scene, JSON_REJECT_DUPLICATES, NULL);
  if (!doc) fail("a bundled scene does not parse", scene);
  obs_err err = OBS_ERR_INIT;
  int rc = obs_json_pointer_set(doc, ov->pointer, ov->value, &err);
  if (rc > 0 || (rc < 0 && err.count < 1)) fail("obs_json_pointer_set failed silently", ov->pointer);
  obs_err_free(&err);
  json_decref(doc);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  if (size < 1) return 0;
  size_t si = data[0] % nscenes;
  char *text = malloc(size);
  if (!text) return 0;
  memcpy(text, data + 1, size - 1);
  text[size - 1] = '\0';

  /* Lines the CLI accepts go through its own parser (cli_scene_option); other lines with an '='
   * are split the same way by hand, since the library must also cope with pointers the CLI would
   * refuse (the daemon passes request keys). Pointers and values are owned. */
  cli_scene_opts o;
  memset(&o, 0, sizeof o);
  char *line = text;
  while (line && o.nov < CLI_MAX_OVERRIDES) {
    char *next = strchr(line, '\n');
    if (next) *next++ = '\0';
    char *eq = strchr(line, '=');
    json_t *value = eq ? json_loads(eq + 1, JSON_DECODE_ANY, NULL) : NULL;
    int is_json = value != NULL;
    json_decref(value);
    if (eq && line[0] == '/') {
      /* The CLI takes a pointer with a JSON value or a bare word (a string, args.c), and refuses
       * a value that is neither before any scene is read; the library then judges the pair. */
      char *argv[] = {"obscura", "--set", line, NULL};
      int bare = !is_json && eq[1] && !strchr("{[\"-+.0123456789 \t\n", eq[1]);
      size_t before = o.nov;
      int i = 1, rc = cli_scene_option(&o, 3, argv, &i);
      if (is_json && rc != 1) fail("the CLI refused a valid --set", line);
      if (!is_json && !bare && rc != -1) fail("the CLI took a --set whose value is not JSON", line);
      if (bare && rc == 1) {
        json_t *w = json_loads(o.ov[before].value, JSON_DECODE_ANY, NULL);
        if (!json_is_string(w) || strcmp(json_string_value(w), eq + 1))
          fail("a bare --set word did not become that string", line);
        json_decref(w);
      }
    } else if (eq) {
      char *ptr = strndup(line, (size_t)(eq - line));
      char *val = strdup(eq + 1);
      if (ptr && val) {
        o.ov[o.nov].pointer = ptr;
        o.ov[o.nov].value = val;
        o.nov++;
      } else {
        free(ptr);
        free(val);
      }
    }
    line = next;
  }
  const obs_override *ov = o.ov;
  size_t nov = o.nov;
  for (size_t i = 0; i < nov; i++) apply_alone(scenes[si].text, &ov[i]);

  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_string(&sc, scenes[si].text, scenes[si].name, dir, ov, nov, &err);
  if (rc == 0) {
    if (!sc.technique || !sc.doc || !sc.params || sc.width < 1 || sc.height < 1)
      fail("accepted an incomplete scene", scenes[si].name);
    obs_scene_free(&sc);
  } else if (rc > 0 || err.count < 1 ||
             strncmp(obs_err_message(&err), scenes[si].name, strlen(scenes[si].name))) {
    fail("a failure without a problem naming the scene", obs_err_message(&err));
  }
  obs_err_free(&err);
  cli_scene_opts_free(&o);
  free(text);
  return 0;
}
