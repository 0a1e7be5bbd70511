/* Helpers shared by the obscura subcommands: scene options, scene loading, progress bar. */
#include "args.h"

#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

const char *cli_option_value(int argc, char **argv, int *i) {
  if (*i + 1 >= argc) {
    fprintf(stderr, "obscura: %s needs a value\n", argv[*i]);
    return NULL;
  }
  return argv[++*i];
}

/* A --set VALUE is JSON when it parses as JSON: a number (8, 0.5, -1e3), true, false, null, a
 * quoted string, an array or an object. A bare word that does not (sqrt, cosine) is a string,
 * so enum values need no shell-proof quotes; a value that starts like a number or a JSON
 * container and does not parse is a mistake, not a string. Returns the JSON text to apply
 * (malloc'd), or NULL after printing why. */
static char *set_value(const char *arg, const char *eq) {
  const char *value = eq + 1;
  json_error_t je;
  json_t *v = json_loads(value, JSON_DECODE_ANY, &je);
  if (v) {
    json_decref(v);
    char *copy = strdup(value);
    if (!copy) fprintf(stderr, "obscura: out of memory\n");
    return copy;
  }
  int bare = *value && !strchr("{[\"-+.0123456789 \t\n", *value);
  json_t *s = bare ? json_string(value) : NULL;
  char *quoted = s ? json_dumps(s, JSON_ENCODE_ANY) : NULL;
  json_decref(s);
  if (!quoted)
    fprintf(stderr, "obscura: --set %s: the value is not JSON: %s\n", arg, je.text);
  return quoted;
}

int cli_scene_option(cli_scene_opts *o, int argc, char **argv, int *i) {
  const char *a = argv[*i];
  if (strcmp(a, "--technique") && strcmp(a, "--backend") && strcmp(a, "--set") &&
      strcmp(a, "--base-dir"))
    return 0;
  const char *val = cli_option_value(argc, argv, i);
  if (!val) return -1;
  if (!strcmp(a, "--technique")) {
    o->technique = val;
  } else if (!strcmp(a, "--base-dir")) {
    struct stat st;
    if (stat(val, &st) || !S_ISDIR(st.st_mode)) {
      fprintf(stderr, "obscura: --base-dir %s: not a directory\n", val);
      return -1;
    }
    o->base_dir = val;
  } else if (!strcmp(a, "--backend")) {
    o->backend = val;
  } else {
    const char *eq = strchr(val, '=');
    if (!eq || val[0] != '/' || o->nov == CLI_MAX_OVERRIDES) {
      fprintf(stderr, "obscura: --set takes /json/pointer=VALUE (got %s)\n", val);
      return -1;
    }
    char *value = set_value(val, eq);
    if (!value) return -1;
    char *ptr = strndup(val, (size_t)(eq - val));
    if (!ptr) {
      free(value);
      fprintf(stderr, "obscura: out of memory\n");
      return -1;
    }
    o->ov[o->nov].pointer = ptr;
    o->ov[o->nov].value = value;
    o->nov++;
  }
  return 1;
}

void cli_scene_opts_free(cli_scene_opts *o) {
  for (size_t i = 0; i < o->nov; i++) {
    free((char *)o->ov[i].pointer);
    free((char *)o->ov[i].value);
  }
  o->nov = 0;
}

/* Sets the params of `doc`'s technique object to those --technique's technique starts from on the
 * scene (obs_technique_defaults_for: lengths fitted to the scene's size), saying on stderr which
 * were derived; a parameter --set gives is left to it. An unknown technique is left to the
 * loader's message. The scene is loaded as it is, overrides aside (they may name the new
 * technique's parameters). */
static int switch_technique(const cli_scene_opts *o, json_t *doc, const char *base,
                            const char *dir, obs_err *err) {
  json_t *t = json_object_get(doc, "technique");
  const obs_technique *to = obs_technique_find(o->technique);
  json_object_del(t, "params");
  json_object_del(t, "backend"); /* the scene's backend was chosen for its own technique */
  if (!to) return 0;
  static const char prefix[] = "/technique/params/";
  json_t *given = json_object();
  for (size_t i = 0; i < o->nov; i++)
    if (!strncmp(o->ov[i].pointer, prefix, sizeof prefix - 1))
      json_object_set_new(given, o->ov[i].pointer + sizeof prefix - 1, json_null());
  obs_scene old;
  char *text = json_dumps(doc, 0);
  int rc = text ? obs_scene_load_string(&old, text, base, dir, NULL, 0, err)
                : obs_err_set(err, OBS_ENOMEM, "out of memory");
  free(text);
  if (rc) {
    json_decref(given);
    return rc;
  }
  json_t *notes = json_array();
  json_t *params = obs_technique_defaults_for(to, &old, given, notes, err);
  obs_scene_free(&old);
  json_decref(given);
  if (!params) {
    json_decref(notes);
    return OBS_ENOMEM;
  }
  /* What --set gives is set by the loader; a placeholder must not stand in for it. */
  for (size_t i = 0; i < o->nov; i++)
    if (!strncmp(o->ov[i].pointer, prefix, sizeof prefix - 1))
      json_object_del(params, o->ov[i].pointer + sizeof prefix - 1);
  size_t k;
  json_t *note;
  json_array_foreach(notes, k, note) fprintf(stderr, "obscura: note: %s\n", json_string_value(note));
  json_decref(notes);
  json_object_set_new(t, "params", params);
  return 0;
}

int cli_scene_load(const cli_scene_opts *o, obs_scene *sc, obs_err *err) {
  /* Why the file cannot be read (missing, permission, ...), before any parsing. */
  FILE *f = fopen(o->scene, "rb");
  if (!f) {
    memset(sc, 0, sizeof *sc);
    return obs_err_set(err, OBS_EIO, "%s: cannot open scene file: %s", o->scene, strerror(errno));
  }
  fclose(f);
  if (!o->technique && !o->backend && !o->base_dir)
    return obs_scene_load_file(sc, o->scene, o->ov, o->nov, err);
  memset(sc, 0, sizeof *sc);
  json_error_t je;
  json_t *doc = json_load_file(o->scene, JSON_REJECT_DUPLICATES, &je);
  if (!doc)
    return obs_err_set(err, access(o->scene, R_OK) ? OBS_EIO : OBS_EINVAL,
                       "%s: line %d, column %d: %s", o->scene, je.line, je.column, je.text);
  json_t *t = json_object_get(doc, "technique");
  if (!json_is_object(t)) {
    t = json_object();
    json_object_set_new(doc, "technique", t);
  }
  char dir[PATH_MAX];
  snprintf(dir, sizeof dir, "%s", o->scene);
  char *slash = strrchr(dir, '/');
  const char *base = strrchr(o->scene, '/') ? strrchr(o->scene, '/') + 1 : o->scene;
  if (o->base_dir)
    snprintf(dir, sizeof dir, "%s", o->base_dir);
  else if (slash)
    *slash = '\0';
  else
    strcpy(dir, ".");
  if (o->technique) {
    const char *old = json_string_value(json_object_get(t, "name"));
    if (!old || strcmp(old, o->technique)) {
      int rc = switch_technique(o, doc, base, dir, err);
      if (rc) {
        json_decref(doc);
        return rc;
      }
    }
    json_object_set_new(t, "name", json_string(o->technique));
  }
  if (o->backend) json_object_set_new(t, "backend", json_string(o->backend));
  char *text = json_dumps(doc, 0);
  json_decref(doc);
  int rc = obs_scene_load_string(sc, text, base, dir, o->ov, o->nov, err);
  free(text);
  return rc;
}

int cli_load_exit_code(int rc) {
  return rc == OBS_EINVAL || rc == OBS_EIO ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

int cli_progress_file(cli_progress *p, const char *path) {
  p->fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (p->fd < 0) {
    fprintf(stderr, "obscura: --progress-file %s: %s\n", path, strerror(errno));
    return -1;
  }
  p->last_file = -1;
  cli_progress_draw(p, 0);
  return 0;
}

/* The fraction in --progress-file, whole: a reader sees the old text or the new one (same
 * length, one pwrite at offset 0). */
static void progress_write(cli_progress *p, double f) {
  int k = (int)(f * 1e4);
  if (p->fd <= 0 || k == p->last_file) return;
  p->last_file = k;
  char text[16];
  int n = snprintf(text, sizeof text, "%d.%04d\n", k / 10000, k % 10000);
  if (pwrite(p->fd, text, (size_t)n, 0) != n) {
    close(p->fd); /* a full disk: the render matters more than its progress */
    p->fd = -1;
  }
}

void cli_progress_draw(void *user, double f) {
  cli_progress *p = user;
  progress_write(p, f);
  int pct = (int)(f * 100.0);
  if (!p->tty || pct == p->last) return;
  p->last = pct;
  char bar[41];
  int n = (int)(f * 40.0);
  for (int i = 0; i < 40; i++) bar[i] = i < n ? '#' : ' ';
  bar[40] = '\0';
  FILE *out = p->f ? p->f : stderr;
  fprintf(out, "\r[%s] %3d%%", bar, pct);
  fflush(out);
}
