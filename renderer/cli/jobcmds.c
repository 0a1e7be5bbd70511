/* `obscura job ID`, `obscura cancel ID`, `obscura fetch ID -o DIR` and `obscura comparisons`:
 * one job shown, cancelled or downloaded, and the comparisons listed, through obscurad's API. */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "client.h"
#include "http.h"

typedef struct one_opts {
  const char *server, *id, *out_dir;
  long limit;
  int json;
} one_opts;

/* Options of the four commands: `flags` says which they take ('i' an ID, 'j' --json, 'o' -o DIR,
 * 'l' --limit); --server always. */
static int parse_one(int argc, char **argv, const char *flags, one_opts *o) {
  memset(o, 0, sizeof *o);
  o->limit = 50;
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--server") || (strchr(flags, 'o') && !strcmp(a, "-o")) ||
        (strchr(flags, 'l') && !strcmp(a, "--limit"))) {
      const char *val = cli_option_value(argc, argv, &i);
      if (!val) return -1;
      if (!strcmp(a, "--server")) {
        o->server = val;
      } else if (!strcmp(a, "-o")) {
        if (!*val) {
          fprintf(stderr, "obscura: -o needs a directory name\n");
          return -1;
        }
        o->out_dir = val;
      } else {
        char *end;
        long n = strtol(val, &end, 10);
        if (!*val || *end || n < 1 || n > 500) {
          fprintf(stderr, "obscura: --limit must be an integer from 1 to 500 (got %s)\n", val);
          return -1;
        }
        o->limit = n;
      }
    } else if (strchr(flags, 'j') && !strcmp(a, "--json")) {
      o->json = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (strchr(flags, 'i') && !o->id) {
      /* Only digits reach a URL. */
      if (strspn(a, "0123456789") != strlen(a) || a[0] == '0' || strlen(a) > 18) {
        fprintf(stderr, "obscura: a job id is a positive integer (got %s)\n", a);
        return -1;
      }
      o->id = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (strchr(flags, 'i') && !o->id) {
    fprintf(stderr, "obscura: missing the job ID (obscura jobs lists them)\n");
    return -1;
  }
  if (strchr(flags, 'o') && !o->out_dir) {
    fprintf(stderr, "obscura: missing -o DIR, where the outputs go\n");
    return -1;
  }
  o->server = cli_server(o->server);
  return 0;
}

/* GET `path` (an API path) as a JSON object. Returns 0 with *out, or an exit status. */
static int get_path(cli_client *c, const char *path, json_t **out) {
  char *url = cli_client_url(c, path);
  int rc = url ? cli_client_get_object(c, url, out) : EXIT_FAILURE;
  free(url);
  return rc;
}

static const char *str_or(json_t *v, const char *dflt) {
  const char *s = json_string_value(v);
  return s ? s : dflt;
}

static void print_json(json_t *j) {
  char *s = json_dumps(j, JSON_INDENT(2));
  if (s) puts(s);
  free(s);
}

/* One "  key   value" line of server text, control characters removed. */
static void fact(const char *key, const char *value) {
  printf("  %-10s ", key);
  cli_put_clean(stdout, value ? value : "-");
  putchar('\n');
}

/* The mean of the job's primary output, as its summary gives it: AO, else the first channel of
 * the primary output, else the luminance of an RGB one. */
static void print_mean(json_t *stats) {
  json_t *ao = json_object_get(stats, "ao");
  const char *prim = json_string_value(json_object_get(stats, "primary_output"));
  if (json_is_number(json_object_get(ao, "mean"))) {
    printf("  %-10s %.4f\n", "AO mean", json_number_value(json_object_get(ao, "mean")));
    return;
  }
  json_t *out = json_object_get(json_object_get(stats, "outputs"), prim ? prim : "");
  json_t *lum = json_object_get(out, "luminance_mean");
  json_t *ch = json_object_iter_value(json_object_iter(json_object_get(out, "channels")));
  if (json_is_number(lum)) {
    printf("  %-10s %.4f (%s luminance)\n", "mean", json_number_value(lum), prim);
  } else if (json_is_number(json_object_get(ch, "mean"))) {
    printf("  %-10s %.4f (", "mean", json_number_value(json_object_get(ch, "mean")));
    cli_put_clean(stdout, prim);
    puts(")");
  }
}

static void print_job(cli_client *c, json_t *j) {
  char line[256];
  json_t *be = json_object_get(j, "backend"), *img = json_object_get(j, "image");
  json_t *t = json_object_get(j, "timings_ms");
  const char *scene = json_string_value(json_object_get(j, "scene_name"));
  printf("job %lld: ", (long long)json_integer_value(json_object_get(j, "id")));
  cli_put_clean(stdout, json_string_value(json_object_get(j, "state")));
  printf(" %d%%\n", (int)(json_number_value(json_object_get(j, "progress")) * 100.0 + 1e-9));
  snprintf(line, sizeof line, "%s on %s (requested %s)",
           str_or(json_object_get(j, "technique"), "?"),
           str_or(json_object_get(be, "actual"), "-"),
           str_or(json_object_get(be, "requested"), "?"));
  fact("technique", line);
  fact("scene", scene ? scene : json_string_value(json_object_get(j, "scene")));
  long long spp = (long long)json_integer_value(json_object_get(img, "spp"));
  /* image.spp is where in each pixel the technique runs, not its own samples (paths, rays). */
  snprintf(line, sizeof line, "%lldx%lld, %lld pixel sample%s (image.spp)",
           (long long)json_integer_value(json_object_get(img, "width")),
           (long long)json_integer_value(json_object_get(img, "height")), spp, spp == 1 ? "" : "s");
  fact("image", line);
  fact("label", json_string_value(json_object_get(j, "label")));
  fact("created", json_string_value(json_object_get(j, "created_at")));
  fact("finished", json_string_value(json_object_get(j, "finished_at")));
  if (json_is_number(json_object_get(t, "total"))) {
    printf("  %-10s %.1f ms render, %.1f ms total\n", "time",
           json_number_value(json_object_get(t, "render")),
           json_number_value(json_object_get(t, "total")));
  }
  print_mean(json_object_get(j, "stats"));
  size_t i;
  json_t *v;
  json_array_foreach(json_object_get(j, "warnings"), i, v) fact("warning", json_string_value(v));
  if (json_is_string(json_object_get(j, "error")))
    fact("error", json_string_value(json_object_get(j, "error")));
  json_array_foreach(json_object_get(j, "outputs"), i, v) {
    snprintf(line, sizeof line, "%s (%lld bytes)",
             str_or(json_object_get(v, "name"), "?"),
             (long long)json_integer_value(json_object_get(v, "size")));
    fact(i ? "" : "outputs", line);
  }
  char route[64];
  snprintf(route, sizeof route, "jobs/%lld", (long long)json_integer_value(json_object_get(j, "id")));
  char *page = cli_dashboard_url(c, route);
  if (page) fact("page", page);
  free(page);
}

int cli_job(int argc, char **argv) {
  one_opts o;
  if (parse_one(argc, argv, "ij", &o)) {
    cli_hint("job");
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  char path[64];
  snprintf(path, sizeof path, "/api/v1/jobs/%s", o.id);
  json_t *j = NULL;
  if (!rc) rc = get_path(&c, path, &j);
  if (!rc && o.json) print_json(j);
  else if (!rc) print_job(&c, j);
  json_decref(j);
  cli_client_close(&c);
  return rc;
}

int cli_cancel(int argc, char **argv) {
  one_opts o;
  if (parse_one(argc, argv, "i", &o)) {
    cli_hint("cancel");
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  char path[64];
  snprintf(path, sizeof path, "/api/v1/jobs/%s/cancel", o.id);
  char *url = rc ? NULL : cli_client_url(&c, path);
  if (!rc && !url) rc = EXIT_FAILURE;
  if (!rc) {
    cli_response r;
    CURLcode cc = cli_client_json(&c, "POST", url, "{}", &r);
    if (cc) {
      rc = cli_transport_error(&c, url, cc, r.body.overflow);
    } else if (r.status != 202) {
      rc = cli_http_error(&c, "POST", url, &r);
    } else {
      /* A queued job is cancelled at once; a running one stops between tiles. */
      json_t *j = json_loads(r.body.p ? r.body.p : "", 0, NULL);
      const char *st = json_string_value(json_object_get(j, "state"));
      printf("job %s: %s\n", o.id,
             st && !strcmp(st, "cancelled") ? "cancelled"
                                            : "cancel requested (the render stops between tiles)");
      json_decref(j);
    }
    cli_response_free(&r);
  }
  free(url);
  cli_client_close(&c);
  return rc;
}

int cli_fetch(int argc, char **argv) {
  one_opts o;
  if (parse_one(argc, argv, "io", &o)) {
    cli_hint("fetch");
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  char path[64];
  snprintf(path, sizeof path, "/api/v1/jobs/%s", o.id);
  json_t *j = NULL;
  if (!rc) rc = get_path(&c, path, &j);
  const char *st = rc ? NULL : json_string_value(json_object_get(j, "state"));
  if (!rc && (!st || strcmp(st, "succeeded"))) {
    fprintf(stderr, "obscura: job %s is %s: only a succeeded job has outputs\n", o.id,
            st ? st : "in an unknown state");
    rc = EXIT_BAD_INPUT;
  }
  if (!rc) rc = cli_download_outputs(&c, j, o.out_dir);
  json_decref(j);
  cli_client_close(&c);
  return rc;
}

int cli_comparisons(int argc, char **argv) {
  one_opts o;
  if (parse_one(argc, argv, "jl", &o)) {
    cli_hint("comparisons");
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  char path[64];
  snprintf(path, sizeof path, "/api/v1/comparisons?limit=%ld", o.limit);
  json_t *page = NULL;
  if (!rc) rc = get_path(&c, path, &page);
  json_t *list = json_object_get(page, "comparisons");
  if (!rc && !json_is_array(list)) {
    fprintf(stderr, "obscura: the comparison list has no \"comparisons\" array\n");
    rc = EXIT_FAILURE;
  }
  if (!rc && o.json) {
    print_json(page);
  } else if (!rc) {
    printf("%-6s  %-9s  %-6s  %-24s  %-20s  %s\n", "ID", "STATE", "DONE", "CREATED", "SCENE",
           "LABEL");
    size_t i;
    json_t *x;
    json_array_foreach(list, i, x) {
      char done[32];
      snprintf(done, sizeof done, "%lld/%lld",
               (long long)json_integer_value(json_object_get(x, "done")),
               (long long)json_integer_value(json_object_get(x, "candidates")));
      printf("%-6lld  ", (long long)json_integer_value(json_object_get(x, "id")));
      const char *cells[] = {json_string_value(json_object_get(x, "state")), done,
                             json_string_value(json_object_get(x, "created_at")),
                             json_string_value(json_object_get(x, "scene"))};
      const int widths[] = {9, 6, 24, 20};
      for (int k = 0; k < 4; k++) {
        const char *s = cells[k] ? cells[k] : "?";
        cli_put_clean(stdout, s);
        printf("%*s", widths[k] - (int)strlen(s) + 2 > 0 ? widths[k] - (int)strlen(s) + 2 : 1, "");
      }
      cli_put_clean(stdout, str_or(json_object_get(x, "label"), ""));
      putchar('\n');
    }
  }
  json_decref(page);
  cli_client_close(&c);
  return rc;
}
