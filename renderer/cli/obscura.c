/* The obscura command-line tool: render scenes, validate them, list techniques. */
#include <jansson.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "obscura/obscura.h"

#define EXIT_BAD_INPUT 2

static void usage(FILE *f) {
  fputs("usage:\n"
        "  obscura render SCENE.json [-o DIR] [--technique NAME] [--backend cpu|vulkan|auto]\n"
        "                 [--set /json/pointer=VALUE]... [--threads N] [--quiet]\n"
        "  obscura validate SCENE.json [--set /json/pointer=VALUE]...\n"
        "  obscura techniques\n"
        "  obscura --version\n"
        "VALUE is JSON, e.g. --set /technique/params/samples=256 --set "
        "'/technique/params/falloff=\"sqrt\"'.\n"
        "--technique replaces the document's technique; its params are dropped unless --set\n"
        "gives them. Exit codes: 0 ok, 2 bad input, 1 failure.\n",
        f);
}

typedef struct cli {
  const char *scene, *out_dir, *technique, *backend;
  obs_override ov[64];
  size_t nov;
  int threads, quiet;
} cli;

static int parse_args(int argc, char **argv, int first, cli *c) {
  memset(c, 0, sizeof *c);
  c->out_dir = "out";
  for (int i = first; i < argc; i++) {
    const char *a = argv[i];
    const char *val = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "-o") || !strcmp(a, "--technique") || !strcmp(a, "--backend") ||
        !strcmp(a, "--set") || !strcmp(a, "--threads")) {
      if (!val) {
        fprintf(stderr, "obscura: %s needs a value\n", a);
        return -1;
      }
      i++;
      if (!strcmp(a, "-o")) c->out_dir = val;
      else if (!strcmp(a, "--technique")) c->technique = val;
      else if (!strcmp(a, "--backend")) c->backend = val;
      else if (!strcmp(a, "--threads")) {
        char *end;
        long n = strtol(val, &end, 10);
        if (*end || n < 1 || n > 1024) {
          fprintf(stderr, "obscura: --threads must be an integer from 1 to 1024 (got %s)\n", val);
          return -1;
        }
        c->threads = (int)n;
      } else {
        const char *eq = strchr(val, '=');
        if (!eq || val[0] != '/' || c->nov == sizeof c->ov / sizeof c->ov[0]) {
          fprintf(stderr, "obscura: --set takes /json/pointer=VALUE (got %s)\n", val);
          return -1;
        }
        char *ptr = strndup(val, (size_t)(eq - val));
        c->ov[c->nov].pointer = ptr;
        c->ov[c->nov].value = eq + 1;
        c->nov++;
      }
    } else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) {
      c->quiet = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (!c->scene) {
      c->scene = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!c->scene) {
    fprintf(stderr, "obscura: missing SCENE.json\n");
    return -1;
  }
  return 0;
}

static void free_args(cli *c) {
  for (size_t i = 0; i < c->nov; i++) free((char *)c->ov[i].pointer);
}

/* Loads the scene with --technique/--backend folded into the document before validation, so
 * their problems are reported like any other. */
static int load(const cli *c, obs_scene *sc, obs_err *err) {
  if (!c->technique && !c->backend) return obs_scene_load_file(sc, c->scene, c->ov, c->nov, err);
  json_error_t je;
  json_t *doc = json_load_file(c->scene, JSON_REJECT_DUPLICATES, &je);
  if (!doc)
    return obs_err_set(err, access(c->scene, R_OK) ? OBS_EIO : OBS_EINVAL,
                       "%s: line %d, column %d: %s", c->scene, je.line, je.column, je.text);
  json_t *t = json_object_get(doc, "technique");
  if (!json_is_object(t)) {
    t = json_object();
    json_object_set_new(doc, "technique", t);
  }
  if (c->technique) {
    const char *old = json_string_value(json_object_get(t, "name"));
    if (!old || strcmp(old, c->technique)) json_object_del(t, "params");
    json_object_set_new(t, "name", json_string(c->technique));
  }
  if (c->backend) json_object_set_new(t, "backend", json_string(c->backend));
  char *text = json_dumps(doc, 0);
  json_decref(doc);
  char dir[PATH_MAX];
  snprintf(dir, sizeof dir, "%s", c->scene);
  char *slash = strrchr(dir, '/');
  const char *base = strrchr(c->scene, '/') ? strrchr(c->scene, '/') + 1 : c->scene;
  if (slash) *slash = '\0';
  else strcpy(dir, ".");
  int rc = obs_scene_load_string(sc, text, base, dir, c->ov, c->nov, err);
  free(text);
  return rc;
}

typedef struct progress {
  int tty;
  int last;
} progress;

static void on_progress(void *user, double f) {
  progress *p = user;
  int pct = (int)(f * 100.0);
  if (!p->tty || pct == p->last) return;
  p->last = pct;
  char bar[41];
  int n = (int)(f * 40.0);
  for (int i = 0; i < 40; i++) bar[i] = i < n ? '#' : ' ';
  bar[40] = '\0';
  fprintf(stderr, "\r[%s] %3d%%", bar, pct);
  fflush(stderr);
}

static int cmd_render(int argc, char **argv) {
  cli c;
  if (parse_args(argc, argv, 2, &c)) {
    usage(stderr);
    free_args(&c);
    return EXIT_BAD_INPUT;
  }
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  double t0 = obs_now_ms();
  int rc = load(&c, &sc, &err);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_err_free(&err);
    free_args(&c);
    return rc == OBS_EINVAL || rc == OBS_EIO ? EXIT_BAD_INPUT : EXIT_FAILURE;
  }
  double load_ms = obs_now_ms() - t0;
  progress pr = {.tty = !c.quiet && isatty(2), .last = -1};
  obs_render_opts opts = {.threads = c.threads, .progress = on_progress, .progress_user = &pr};
  obs_result res;
  rc = obs_render(&sc, &opts, &res, &err);
  if (pr.tty) fputc('\n', stderr);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_scene_free(&sc);
    obs_err_free(&err);
    free_args(&c);
    return rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE;
  }
  res.timings.load_ms = load_ms;
  res.timings.total_ms += load_ms;
  rc = obs_result_write(&res, &sc, c.out_dir, &err);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
  } else if (!c.quiet) {
    obs_stats st;
    obs_metrics_stats(&res.image, "ao", NULL, &st, NULL);
    char rays[48] = "";
    if (res.rays && res.timings.render_ms > 0)
      snprintf(rays, sizeof rays, ", %.3g Mrays/s", (double)res.rays / res.timings.render_ms / 1e3);
    printf("%s: %s/%s %dx%d, %.1f ms render (%.1f build)%s, AO mean %.4f -> %s/ao.exr\n",
           sc.name, res.technique->name, obs_backend_name(res.backend), res.image.width,
           res.image.height, res.timings.render_ms, res.timings.build_ms, rays, st.mean,
           c.out_dir);
  }
  obs_result_free(&res);
  obs_scene_free(&sc);
  obs_err_free(&err);
  free_args(&c);
  return rc == 0 ? 0 : rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

static int cmd_validate(int argc, char **argv) {
  cli c;
  if (parse_args(argc, argv, 2, &c)) {
    usage(stderr);
    free_args(&c);
    return EXIT_BAD_INPUT;
  }
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  int rc = load(&c, &sc, &err);
  if (rc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
  } else {
    printf("%s: valid (%s, %zu objects)\n", sc.name, sc.technique->name, sc.nobjects);
    obs_scene_free(&sc);
  }
  obs_err_free(&err);
  free_args(&c);
  return rc == 0 ? 0 : rc == OBS_EINVAL || rc == OBS_EIO ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

static int cmd_techniques(void) {
  json_t *reg = obs_technique_registry_json();
  char *s = json_dumps(reg, JSON_INDENT(2));
  puts(s ? s : "[]");
  free(s);
  json_decref(reg);
  return 0;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return EXIT_BAD_INPUT;
  }
  if (!strcmp(argv[1], "render")) return cmd_render(argc, argv);
  if (!strcmp(argv[1], "validate")) return cmd_validate(argc, argv);
  if (!strcmp(argv[1], "techniques")) return cmd_techniques();
  if (!strcmp(argv[1], "--version")) {
    puts("obscura " OBSCURA_VERSION);
    return 0;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    usage(stdout);
    return 0;
  }
  fprintf(stderr, "obscura: unknown command %s\n", argv[1]);
  usage(stderr);
  return EXIT_BAD_INPUT;
}
