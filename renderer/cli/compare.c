/* `obscura compare`: a comparison request read from a JSON file sent to obscurad, then followed to
 * its end and summed up: per candidate the median time and the error against the reference, and
 * the Pareto set. */
#include <errno.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "args.h"
#include "client.h"
#include "http.h"
#include "obscura/obscura.h"

#define POLL_MS 500 /* the comparison is polled this often */

typedef struct compare_opts {
  const char *file, *server;
  int no_wait, json;
} compare_opts;

static int parse_compare(int argc, char **argv, compare_opts *o) {
  memset(o, 0, sizeof *o);
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--server")) {
      if (!(o->server = cli_option_value(argc, argv, &i))) return -1;
    } else if (!strcmp(a, "--no-wait")) {
      o->no_wait = 1;
    } else if (!strcmp(a, "--json")) {
      o->json = 1;
    } else if (a[0] == '-' && a[1]) {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (!o->file) {
      o->file = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!o->file) {
    fprintf(stderr, "obscura: missing the comparison request FILE\n");
    return -1;
  }
  o->server = cli_server(o->server);
  return 0;
}

/* The request document: a JSON object from the file, or from standard input for "-". */
static json_t *read_request(const char *file) {
  FILE *f = strcmp(file, "-") ? fopen(file, "rb") : stdin;
  if (!f) {
    fprintf(stderr, "obscura: %s: cannot open comparison request: %s\n", file, strerror(errno));
    return NULL;
  }
  json_error_t je;
  json_t *doc = json_loadf(f, JSON_REJECT_DUPLICATES, &je);
  if (f != stdin) fclose(f);
  if (!doc) {
    fprintf(stderr, "obscura: %s: line %d, column %d: %s\n", file, je.line, je.column, je.text);
    return NULL;
  }
  if (!json_is_object(doc)) {
    fprintf(stderr, "obscura: %s: the comparison request must be a JSON object\n", file);
    json_decref(doc);
    return NULL;
  }
  return doc;
}

/* POSTs the request. Returns 0 with the comparison's id and self link (malloc'd), or an exit
 * status after printing why. */
static int post_request(cli_client *c, json_t *req, long long *id, char **self) {
  char *body = json_dumps(req, JSON_COMPACT);
  char *url = body ? cli_client_url(c, "/api/v1/comparisons") : NULL;
  int rc = 0;
  if (!url) {
    free(body);
    return EXIT_FAILURE;
  }
  cli_response r;
  CURLcode cc = cli_client_json(c, "POST", url, body, &r);
  if (cc) {
    rc = cli_transport_error(c, url, cc, r.body.overflow);
  } else if (r.status != 201) {
    rc = cli_http_error(c, "POST", url, &r);
  } else {
    json_t *a = json_loads(r.body.p ? r.body.p : "", 0, NULL);
    json_t *jid = json_object_get(a, "id");
    const char *ref = json_string_value(json_object_get(json_object_get(a, "links"), "self"));
    if (!json_is_integer(jid) || !ref) {
      fprintf(stderr, "obscura: POST %s: the answer has no comparison id and link\n", url);
      rc = EXIT_FAILURE;
    } else {
      *id = (long long)json_integer_value(jid);
      *self = cli_client_url(c, ref);
      if (!*self) rc = EXIT_FAILURE;
      fprintf(stderr, "comparison %lld: %lld candidate(s), %lld reference(s)\n", *id,
              (long long)json_integer_value(json_object_get(a, "candidates")),
              (long long)json_integer_value(json_object_get(a, "references")));
      size_t k;
      json_t *note;
      json_array_foreach(json_object_get(a, "notes"), k, note) {
        fputs("obscura: note: ", stderr);
        cli_put_clean(stderr, json_string_value(note));
        fputc('\n', stderr);
      }
    }
    json_decref(a);
  }
  cli_response_free(&r);
  free(url);
  free(body);
  return rc;
}

/* Candidates with metrics or that can no longer get them. */
static size_t candidates_done(json_t *cmp) {
  size_t i, n = 0;
  json_t *cand;
  json_array_foreach(json_object_get(cmp, "candidates"), i, cand) {
    const char *st = json_string_value(json_object_get(cand, "state"));
    if (!json_is_null(json_object_get(cand, "metrics")) ||
        !json_is_null(json_object_get(cand, "error")) ||
        (st && (!strcmp(st, "failed") || !strcmp(st, "cancelled"))))
      n++;
  }
  return n;
}

/* Polls the comparison until it is no longer running. Returns 0 with *out (new reference), or an
 * exit status after printing why. */
static int follow(cli_client *c, long long id, const char *url, json_t **out) {
  *out = NULL;
  size_t last_done = (size_t)-1;
  double lost_since = -1;
  for (;;) {
    json_t *cmp;
    int rc = cli_poll_json(c, url, POLL_MS, &lost_since, NULL, NULL, &cmp);
    if (rc == CLI_POLL_AGAIN) continue;
    if (rc) return rc;
    const char *st = json_string_value(json_object_get(cmp, "state"));
    if (!st || !json_is_array(json_object_get(cmp, "candidates"))) {
      fprintf(stderr, "obscura: GET %s: the answer is not a comparison\n", url);
      json_decref(cmp);
      return EXIT_FAILURE;
    }
    size_t done = candidates_done(cmp);
    if (done != last_done) {
      fprintf(stderr, "comparison %lld: %zu/%zu candidate(s) done\n", id, done,
              json_array_size(json_object_get(cmp, "candidates")));
      last_done = done;
    }
    if (strcmp(st, "running")) {
      *out = cmp;
      return 0;
    }
    json_decref(cmp);
    cli_sleep_ms(POLL_MS);
  }
}

/* The parameters in which `cand` differs from another candidate of its technique, as
 * "name=value ..." (the defaults they share are noise). */
static void varying_params(json_t *cands, json_t *cand, char *out, size_t n) {
  out[0] = '\0';
  size_t len = 0;
  const char *key, *tech = json_string_value(json_object_get(cand, "technique"));
  json_t *v;
  json_object_foreach(json_object_get(cand, "params"), key, v) {
    int varies = 0;
    size_t i;
    json_t *other;
    json_array_foreach(cands, i, other) {
      const char *ot = json_string_value(json_object_get(other, "technique"));
      if (!tech || !ot || strcmp(tech, ot)) continue;
      json_t *ov = json_object_get(json_object_get(other, "params"), key);
      if (!ov || !json_equal(ov, v)) varies = 1;
    }
    if (!varies) continue;
    char *val = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(6));
    int k = snprintf(out + len, n - len, "%s%s=%s", len ? " " : "", key, val ? val : "?");
    free(val);
    if (k < 0 || (size_t)k >= n - len) break;
    len += (size_t)k;
  }
}

static void put_number(json_t *v, const char *fmt, int width) {
  char s[32] = "-";
  if (json_is_number(v)) snprintf(s, sizeof s, fmt, json_number_value(v));
  printf("%*s", width, s);
}

/* Why a candidate has no metrics: its error, else its job's or its reference's end. */
static void print_why(json_t *cmp, json_t *cand) {
  if (!json_is_null(json_object_get(cand, "metrics"))) return;
  const char *err = json_string_value(json_object_get(cand, "error"));
  const char *st = json_string_value(json_object_get(cand, "state"));
  if (err) {
    fputs("  error: ", stdout);
    cli_put_clean(stdout, err);
    return;
  }
  if (st && (!strcmp(st, "failed") || !strcmp(st, "cancelled"))) {
    printf("  error: job %lld ", (long long)json_integer_value(json_object_get(cand, "job_id")));
    cli_put_clean(stdout, st);
    return;
  }
  json_int_t ref = json_integer_value(json_object_get(cand, "reference_job_id"));
  size_t i;
  json_t *r;
  json_array_foreach(json_object_get(cmp, "references"), i, r) {
    const char *rs = json_string_value(json_object_get(r, "state"));
    if (json_integer_value(json_object_get(r, "job_id")) != ref || !rs) continue;
    if (!strcmp(rs, "failed") || !strcmp(rs, "cancelled")) {
      printf("  error: reference job %lld ", (long long)ref);
      cli_put_clean(stdout, rs);
    }
  }
}

/* The metric columns: the metric table's top-level figures some candidate has, in its order
 * (the reference's noise, information rather than a quality, left out). Returns how many. */
static int metric_columns(json_t *cands, const obs_metric **cols) {
  const obs_metric *t = obs_metric_table();
  int n = 0;
  for (int k = 0; k < OBS_METRIC_COUNT; k++) {
    if (t[k].json_group || t[k].direction == OBS_METRIC_NONE) continue;
    size_t i;
    json_t *cand;
    json_array_foreach(cands, i, cand) {
      if (obs_metric_json_get(json_object_get(cand, "metrics"), &t[k])) {
        cols[n++] = &t[k];
        break;
      }
    }
  }
  return n;
}

/* The table of candidates, then the Pareto set. */
static void print_summary(long long id, json_t *cmp) {
  json_t *cands = json_object_get(cmp, "candidates");
  const obs_metric *cols[OBS_METRIC_COUNT];
  int ncols = metric_columns(cands, cols);
  printf("%3s  %-10s  %-7s  %10s", "#", "TECHNIQUE", "BACKEND", "TIME_MS");
  for (int k = 0; k < ncols; k++) {
    char head[24];
    snprintf(head, sizeof head, "%s", cols[k]->name);
    for (char *p = head; *p; p++) *p = (char)(*p >= 'a' && *p <= 'z' ? *p - 32 : *p);
    printf("  %10s", head);
  }
  printf("  %s\n", "PARAMS");
  size_t i;
  json_t *cand;
  json_array_foreach(cands, i, cand) {
    json_t *m = json_object_get(cand, "metrics");
    json_t *median = json_object_get(json_object_get(cand, "timings_ms"), "median");
    char params[256];
    varying_params(cands, cand, params, sizeof params);
    printf("%3lld%s ", (long long)json_integer_value(json_object_get(cand, "index")),
           json_is_true(json_object_get(cand, "pareto")) ? "*" : " ");
    printf(" %-10s  %-7s  ", json_string_value(json_object_get(cand, "technique")),
           json_string_value(json_object_get(cand, "backend")));
    put_number(json_object_get(median, "total"), "%.2f", 10);
    for (int k = 0; k < ncols; k++) {
      char fmt[8];
      snprintf(fmt, sizeof fmt, "%%.%dg", cols[k]->digits);
      fputs("  ", stdout);
      put_number(obs_metric_json_get(m, cols[k]), fmt, 10);
    }
    if (params[0]) fputs("  ", stdout);
    cli_put_clean(stdout, params);
    print_why(cmp, cand);
    putchar('\n');
  }
  printf("pareto (* above, fastest first):");
  json_t *p;
  json_array_foreach(json_object_get(cmp, "pareto"), i, p)
      printf(" %lld", (long long)json_integer_value(p));
  printf("\ncomparison %lld ", id);
  cli_put_clean(stdout, json_string_value(json_object_get(cmp, "state")));
  putchar('\n');
}

int cli_compare(int argc, char **argv) {
  compare_opts o;
  if (parse_compare(argc, argv, &o)) {
    cli_hint("compare");
    return EXIT_BAD_INPUT;
  }
  json_t *req = read_request(o.file);
  if (!req) return EXIT_BAD_INPUT;
  cli_client c;
  int rc = cli_client_open(&c, o.server);
  long long id = 0;
  char *self = NULL, *page = NULL;
  json_t *cmp = NULL;
  if (!rc) rc = post_request(&c, req, &id, &self);
  json_decref(req);
  if (rc) goto done;
  char route[64];
  snprintf(route, sizeof route, "comparisons/%lld", id);
  page = cli_dashboard_url(&c, route);
  if (!page) {
    rc = EXIT_FAILURE;
    goto done;
  }
  /* With --json, stdout carries the document alone. */
  fprintf(o.json ? stderr : stdout, "comparison %lld queued: %s\n", id, page);
  fflush(stdout);
  if (o.no_wait) goto done;
  rc = follow(&c, id, self, &cmp);
  if (rc) goto done;
  if (o.json) {
    char *s = json_dumps(cmp, JSON_INDENT(2));
    if (s) puts(s);
    free(s);
  } else {
    print_summary(id, cmp);
  }
  /* A reference too noisy to rank the candidates makes the table's order meaningless: said
   * after it, where it is read, also with --json (on stderr). */
  const char *warning =
      json_string_value(json_object_get(json_object_get(cmp, "ranking"), "warning"));
  if (warning) {
    fputs("obscura: warning: ", stderr);
    cli_put_clean(stderr, warning);
    fputc('\n', stderr);
  }
  rc = strcmp(json_string_value(json_object_get(cmp, "state")), "succeeded") ? EXIT_FAILURE : 0;
done:
  json_decref(cmp);
  free(page);
  free(self);
  cli_client_close(&c);
  return rc;
}
