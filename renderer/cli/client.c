/* `obscura jobs`: a filtered list of jobs as a table or JSON. `obscura submit` is in submit.c,
 * `obscura compare` in compare.c, the HTTP client in http.c. */
#include "client.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "http.h"
#include "obscura/obscura.h"

#define JOBS_PAGE 100 /* jobs per request while following the `next` cursor */

typedef struct jobs_opts {
  const char *server, *state, *technique, *backend;
  const char *after; /* the job id to list below (a previous listing's "next"), NULL = newest */
  long limit;
  int json;
  int all; /* every page, whatever --limit says */
} jobs_opts;

static int parse_jobs(int argc, char **argv, jobs_opts *o) {
  memset(o, 0, sizeof *o);
  o->limit = 50;
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--server") || !strcmp(a, "--state") || !strcmp(a, "--technique") ||
        !strcmp(a, "--backend") || !strcmp(a, "--limit") || !strcmp(a, "--after")) {
      const char *val = cli_option_value(argc, argv, &i);
      if (!val) return -1;
      if (!strcmp(a, "--server"))
        o->server = val;
      else if (!strcmp(a, "--state"))
        o->state = val;
      else if (!strcmp(a, "--technique"))
        o->technique = val;
      else if (!strcmp(a, "--backend"))
        o->backend = val;
      else if (!strcmp(a, "--after")) {
        char *end;
        long long id = strtoll(val, &end, 10);
        if (!*val || *end || id < 1 || val[0] == '0' || val[0] == '+') {
          fprintf(stderr, "obscura: --after must be a job id (a listing's \"next\"; got %s)\n", val);
          return -1;
        }
        o->after = val;
      } else {
        char *end;
        long n = strtol(val, &end, 10);
        if (!*val || *end || n < 1 || n > 1000000) {
          fprintf(stderr, "obscura: --limit must be an integer from 1 to 1000000 (got %s)\n", val);
          return -1;
        }
        o->limit = n;
      }
    } else if (!strcmp(a, "--json")) {
      o->json = 1;
    } else if (!strcmp(a, "--all")) {
      o->all = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  o->server = cli_server(o->server);
  return 0;
}

/* Appends "&key=escaped(value)" to `q` (capacity `cap`). */
static int query_add(cli_client *c, char *q, size_t cap, const char *key, const char *value) {
  if (!value) return 0;
  char *e = curl_easy_escape(c->curl, value, 0);
  if (!e) return -1;
  size_t len = strlen(q);
  int n = snprintf(q + len, cap - len, "&%s=%s", key, e);
  curl_free(e);
  return n < 0 || (size_t)n >= cap - len ? -1 : 0;
}

static const char *str_or(json_t *v, const char *dflt) {
  const char *s = json_string_value(v);
  return s ? s : dflt;
}

#define NCOL 9 /* table columns before the label */

typedef struct row {
  char cell[NCOL][64]; /* every column but the label */
  const char *label;
} row;

/* A duration for people: milliseconds below a second, else seconds. */
static void fmt_ms(char *out, size_t n, json_t *ms) {
  if (!json_is_number(ms)) {
    snprintf(out, n, "-");
    return;
  }
  double v = json_number_value(ms);
  if (v < 1000.0)
    snprintf(out, n, "%.1f ms", v);
  else
    snprintf(out, n, "%.2f s", v / 1000.0);
}

static void fill_row(row *r, json_t *j) {
  json_t *be = json_object_get(j, "backend");
  snprintf(r->cell[0], 64, "%lld", (long long)json_integer_value(json_object_get(j, "id")));
  snprintf(r->cell[1], 64, "%s", str_or(json_object_get(j, "state"), "?"));
  snprintf(r->cell[2], 64, "%d%%",
           (int)(json_number_value(json_object_get(j, "progress")) * 100.0 + 1e-9));
  snprintf(r->cell[3], 64, "%s", str_or(json_object_get(j, "technique"), "?"));
  snprintf(r->cell[4], 64, "%s",
           str_or(json_object_get(be, "actual"), str_or(json_object_get(be, "requested"), "?")));
  /* An inline scene's name (its file's, sent by submit) says more than "inline". */
  snprintf(r->cell[5], 64, "%s",
           str_or(json_object_get(j, "scene_name"), str_or(json_object_get(j, "scene"), "?")));
  fmt_ms(r->cell[6], 64, json_object_get(json_object_get(j, "timings_ms"), "total"));
  snprintf(r->cell[7], 64, "%lld", (long long)json_integer_value(json_object_get(j, "priority")));
  snprintf(r->cell[8], 64, "%s", str_or(json_object_get(j, "created_at"), "?"));
  r->label = str_or(json_object_get(j, "label"), "");
}

static void print_table(json_t *jobs) {
  static const char *const head[NCOL + 1] = {"ID",    "STATE", "PROGRESS", "TECHNIQUE", "BACKEND",
                                             "SCENE", "TIME",  "PRIORITY", "CREATED",   "LABEL"};
  size_t n = json_array_size(jobs);
  row *rows = calloc(n ? n : 1, sizeof *rows);
  if (!rows) {
    fprintf(stderr, "obscura: out of memory\n");
    return;
  }
  int w[NCOL];
  for (int k = 0; k < NCOL; k++) w[k] = (int)strlen(head[k]);
  for (size_t i = 0; i < n; i++) {
    fill_row(&rows[i], json_array_get(jobs, i));
    for (int k = 0; k < NCOL; k++)
      if ((int)strlen(rows[i].cell[k]) > w[k]) w[k] = (int)strlen(rows[i].cell[k]);
  }
  for (int k = 0; k < NCOL; k++) printf("%-*s  ", w[k], head[k]);
  printf("%s\n", head[NCOL]);
  for (size_t i = 0; i < n; i++) {
    for (int k = 0; k < NCOL; k++) {
      cli_put_clean(stdout, rows[i].cell[k]);
      /* No trailing blanks when the label is empty. */
      if (k < NCOL - 1 || *rows[i].label)
        printf("%*s", w[k] - (int)strlen(rows[i].cell[k]) + 2, "");
    }
    cli_put_clean(stdout, rows[i].label);
    putchar('\n');
  }
  free(rows);
}

int cli_jobs(int argc, char **argv) {
  jobs_opts o;
  if (parse_jobs(argc, argv, &o)) {
    cli_hint("jobs");
    return EXIT_BAD_INPUT;
  }
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  json_t *all = json_array();
  /* Keyset pages: each starts below the last id of the one before (the server's "next"). */
  json_t *next = o.after ? json_string(o.after) : json_null();
  long remaining = o.all ? LONG_MAX : o.limit;
  while (!rc && remaining > 0) {
    char q[2048];
    snprintf(q, sizeof q, "/api/v1/jobs?limit=%ld", remaining < JOBS_PAGE ? remaining : JOBS_PAGE);
    if (query_add(&c, q, sizeof q, "state", o.state) ||
        query_add(&c, q, sizeof q, "technique", o.technique) ||
        query_add(&c, q, sizeof q, "backend", o.backend) ||
        (json_is_string(next) && query_add(&c, q, sizeof q, "after", json_string_value(next)))) {
      fprintf(stderr, "obscura: query too long\n");
      rc = EXIT_BAD_INPUT;
      break;
    }
    char *url = cli_client_url(&c, q);
    json_t *page = NULL;
    rc = url ? cli_client_get_object(&c, url, &page) : EXIT_FAILURE;
    free(url);
    if (rc) break;
    json_t *jobs = json_object_get(page, "jobs");
    if (!json_is_array(jobs)) {
      fprintf(stderr, "obscura: the job list has no \"jobs\" array\n");
      json_decref(page);
      rc = EXIT_FAILURE;
      break;
    }
    size_t n = json_array_size(jobs);
    json_array_extend(all, jobs);
    remaining -= (long)n;
    json_decref(next);
    next = json_incref(json_object_get(page, "next"));
    if (!next) next = json_null();
    json_decref(page);
    if (!json_is_string(next) || n == 0) break;
  }
  if (!rc) {
    if (o.json) {
      json_t *out = json_pack("{sOsO}", "jobs", all, "next", next);
      char *s = out ? json_dumps(out, JSON_INDENT(2)) : NULL;
      if (s) puts(s);
      free(s);
      json_decref(out);
    } else {
      print_table(all);
      /* Where the next page starts, so a long history can be read page by page. */
      if (json_is_string(next))
        fprintf(stderr, "obscura: older jobs follow: obscura jobs --after %s\n",
                json_string_value(next));
    }
  }
  json_decref(next);
  json_decref(all);
  cli_client_close(&c);
  return rc;
}
