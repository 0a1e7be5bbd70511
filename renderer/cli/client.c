/* The obscura job-server client: submit a scene to obscurad, wait, download outputs, list jobs. */
#include "client.h"

#include <curl/curl.h>
#include <errno.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "args.h"
#include "obscura/obscura.h"

#define POLL_MS 200               /* --wait polls the job this often */
#define LOST_SERVER_MS 30000      /* --wait gives up after the server was unreachable this long */
#define MAX_JSON_BODY (64u << 20) /* larger JSON answers are refused */
#define JOBS_PAGE 100             /* jobs per request while following the `next` cursor */

void cli_client_usage(FILE *f) {
  fputs(
      "  obscura submit SCENE.json --server URL [--technique NAME] [--backend cpu|vulkan|auto]\n"
      "                 [--set /json/pointer=VALUE]... [--priority N] [--label TEXT] [--wait]\n"
      "                 [-o DIR]\n"
      "  obscura jobs --server URL [--state S] [--technique T] [--backend B] [--limit N]\n"
      "                 [--json]\n",
      f);
}

/* Prints server-supplied text with control characters replaced, so a hostile or broken server
 * cannot drive the terminal. */
static void put_clean(FILE *f, const char *s) {
  for (; s && *s; s++) fputc((unsigned char)*s < 0x20 || *s == 0x7f ? '?' : *s, f);
}

/* ---- HTTP through libcurl ---- */

typedef struct buf {
  char *p;
  size_t len, cap;
  int overflow;
} buf;

static size_t buf_write(char *data, size_t size, size_t n, void *user) {
  buf *b = user;
  size_t k = size * n;
  if (b->len + k > MAX_JSON_BODY) {
    b->overflow = 1;
    return 0;
  }
  if (b->len + k + 1 > b->cap) {
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->len + k + 1) cap *= 2;
    char *p = realloc(b->p, cap);
    if (!p) return 0;
    b->p = p;
    b->cap = cap;
  }
  memcpy(b->p + b->len, data, k);
  b->len += k;
  b->p[b->len] = '\0';
  return k;
}

typedef struct client {
  const char *server; /* --server as given, for messages */
  CURLU *base;        /* --server parsed: API paths resolve against it */
  CURL *curl;
  struct curl_slist *headers;      /* Accept, Authorization */
  struct curl_slist *post_headers; /* the same plus Content-Type */
  char errbuf[CURL_ERROR_SIZE];
  int global;    /* curl_global_init done */
  int has_token; /* an Authorization header is sent */
} client;

typedef struct response {
  long status;
  buf body;
} response;

static void response_free(response *r) {
  free(r->body.p);
  memset(r, 0, sizeof *r);
}

static void client_close(client *c) {
  if (c->curl) curl_easy_cleanup(c->curl);
  curl_slist_free_all(c->headers);
  curl_slist_free_all(c->post_headers);
  if (c->base) curl_url_cleanup(c->base);
  if (c->global) curl_global_cleanup();
  memset(c, 0, sizeof *c);
}

static int add_header(struct curl_slist **list, const char *h) {
  struct curl_slist *l = curl_slist_append(*list, h);
  if (!l) return -1;
  *list = l;
  return 0;
}

/* Parses --server and OBSCURA_TOKEN. Returns 0, or an exit status after printing why. */
static int client_open(client *c, const char *server) {
  memset(c, 0, sizeof *c);
  c->server = server;
  if (curl_global_init(CURL_GLOBAL_DEFAULT)) {
    fprintf(stderr, "obscura: libcurl failed to initialise\n");
    return EXIT_FAILURE;
  }
  c->global = 1;
  c->base = curl_url();
  if (!c->base) goto nomem;
  CURLUcode uc = curl_url_set(c->base, CURLUPART_URL, server, CURLU_GUESS_SCHEME);
  char *scheme = NULL;
  if (!uc) uc = curl_url_get(c->base, CURLUPART_SCHEME, &scheme, 0);
  if (uc || (strcmp(scheme, "http") && strcmp(scheme, "https"))) {
    fprintf(stderr, "obscura: --server must be an http:// or https:// URL (got %s)%s%s\n", server,
            uc ? ": " : "", uc ? curl_url_strerror(uc) : "");
    curl_free(scheme);
    return EXIT_BAD_INPUT;
  }
  curl_free(scheme);

  if (add_header(&c->headers, "Accept: application/json")) goto nomem;
  const char *tok = getenv("OBSCURA_TOKEN");
  if (tok) {
    while (*tok == ' ' || *tok == '\t' || *tok == '\n' || *tok == '\r') tok++;
    size_t n = strlen(tok);
    while (n &&
           (tok[n - 1] == ' ' || tok[n - 1] == '\t' || tok[n - 1] == '\n' || tok[n - 1] == '\r'))
      n--;
    for (size_t i = 0; i < n; i++) {
      if ((unsigned char)tok[i] < 0x20 || tok[i] == 0x7f) {
        fprintf(stderr, "obscura: OBSCURA_TOKEN contains a control character\n");
        return EXIT_BAD_INPUT;
      }
    }
    if (n) {
      char *h = malloc(n + 32);
      if (!h) goto nomem;
      snprintf(h, n + 32, "Authorization: Bearer %.*s", (int)n, tok);
      int bad = add_header(&c->headers, h);
      c->has_token = 1;
      free(h);
      if (bad) goto nomem;
    }
  }
  /* No "Expect: 100-continue" round trip before large bodies. */
  if (add_header(&c->headers, "Expect:")) goto nomem;
  for (struct curl_slist *l = c->headers; l; l = l->next)
    if (add_header(&c->post_headers, l->data)) goto nomem;
  if (add_header(&c->post_headers, "Content-Type: application/json")) goto nomem;
  c->curl = curl_easy_init();
  if (!c->curl) goto nomem;
  return 0;
nomem:
  fprintf(stderr, "obscura: out of memory\n");
  return EXIT_FAILURE;
}

/* The absolute URL of `ref` (an absolute path such as "/api/v1/jobs?limit=5") on the server;
 * malloc'd, NULL after printing why. Only absolute paths are accepted, so a link in a server
 * answer can never send the token to another host. */
static char *client_url(client *c, const char *ref) {
  if (!ref || ref[0] != '/' || ref[1] == '/') {
    fprintf(stderr, "obscura: the server gave an unexpected link (");
    put_clean(stderr, ref ? ref : "null");
    fprintf(stderr, ")\n");
    return NULL;
  }
  CURLU *u = curl_url_dup(c->base);
  char *s = NULL;
  CURLUcode uc = u ? curl_url_set(u, CURLUPART_URL, ref, 0) : CURLUE_OUT_OF_MEMORY;
  if (!uc) uc = curl_url_get(u, CURLUPART_URL, &s, 0);
  if (u) curl_url_cleanup(u);
  if (uc) {
    fprintf(stderr, "obscura: cannot form a URL from %s and ", c->server);
    put_clean(stderr, ref);
    fprintf(stderr, ": %s\n", curl_url_strerror(uc));
    return NULL;
  }
  char *out = strdup(s);
  curl_free(s);
  if (!out) fprintf(stderr, "obscura: out of memory\n");
  return out;
}

/* Resets the handle to the options every request shares and sets the URL. */
static void client_prepare(client *c, const char *url, int post) {
  curl_easy_reset(c->curl);
  c->errbuf[0] = '\0';
  curl_easy_setopt(c->curl, CURLOPT_URL, url);
  curl_easy_setopt(c->curl, CURLOPT_ERRORBUFFER, c->errbuf);
  curl_easy_setopt(c->curl, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c->curl, CURLOPT_CONNECTTIMEOUT, 10L);
  /* A stalled server: less than 1 byte/s for 60 s. */
  curl_easy_setopt(c->curl, CURLOPT_LOW_SPEED_LIMIT, 1L);
  curl_easy_setopt(c->curl, CURLOPT_LOW_SPEED_TIME, 60L);
  curl_easy_setopt(c->curl, CURLOPT_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(c->curl, CURLOPT_USERAGENT, "obscura/" OBSCURA_VERSION);
  curl_easy_setopt(c->curl, CURLOPT_HTTPHEADER, post ? c->post_headers : c->headers);
}

/* One request whose answer (any status) is kept in memory. CURLE_OK when an answer arrived. */
static CURLcode client_json(client *c, const char *method, const char *url, const char *body,
                            response *r) {
  memset(r, 0, sizeof *r);
  client_prepare(c, url, body != NULL);
  if (body) {
    curl_easy_setopt(c->curl, CURLOPT_POSTFIELDS, body);
    curl_easy_setopt(c->curl, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)strlen(body));
  }
  if (strcmp(method, body ? "POST" : "GET"))
    curl_easy_setopt(c->curl, CURLOPT_CUSTOMREQUEST, method);
  curl_easy_setopt(c->curl, CURLOPT_WRITEFUNCTION, buf_write);
  curl_easy_setopt(c->curl, CURLOPT_WRITEDATA, &r->body);
  CURLcode cc = curl_easy_perform(c->curl);
  if (cc == CURLE_OK) curl_easy_getinfo(c->curl, CURLINFO_RESPONSE_CODE, &r->status);
  return cc;
}

static int transport_error(client *c, const char *url, CURLcode cc, int overflow) {
  const char *why = c->errbuf[0] ? c->errbuf : curl_easy_strerror(cc);
  if (overflow)
    fprintf(stderr, "obscura: %s: the answer is larger than %u MiB\n", url, MAX_JSON_BODY >> 20);
  else if (cc == CURLE_COULDNT_CONNECT || cc == CURLE_COULDNT_RESOLVE_HOST ||
           cc == CURLE_COULDNT_RESOLVE_PROXY || cc == CURLE_OPERATION_TIMEDOUT)
    fprintf(stderr, "obscura: cannot reach the server at %s: %s\n", url, why);
  else
    fprintf(stderr, "obscura: request to %s failed: %s\n", url, why);
  return EXIT_FAILURE;
}

/* Prints a non-success answer: the server's `error` and every `problems` entry. Returns 2 for a
 * 4xx (the request was wrong: bad input, token, limits), 1 otherwise. */
static int http_error(const client *c, const char *method, const char *url, const response *r) {
  json_t *j = r->body.p ? json_loads(r->body.p, 0, NULL) : NULL;
  const char *msg = json_string_value(json_object_get(j, "error"));
  fprintf(stderr, "obscura: %s %s answered %ld: ", method, url, r->status);
  if (msg) {
    put_clean(stderr, msg);
  } else if (r->body.len) {
    char head[201];
    snprintf(head, sizeof head, "%s", r->body.p);
    put_clean(stderr, head);
  } else {
    fputs("(no message)", stderr);
  }
  fputc('\n', stderr);
  json_t *probs = json_object_get(j, "problems");
  size_t i;
  json_t *p;
  json_array_foreach(probs, i, p) {
    if (!json_is_string(p)) continue;
    fputs("  ", stderr);
    put_clean(stderr, json_string_value(p));
    fputc('\n', stderr);
  }
  json_decref(j);
  if (r->status == 401)
    fprintf(stderr, "obscura: %s\n",
            c->has_token ? "the server refused the token in OBSCURA_TOKEN"
                         : "the server wants a token: set OBSCURA_TOKEN");
  return r->status >= 400 && r->status < 500 ? EXIT_BAD_INPUT : EXIT_FAILURE;
}

/* GET `url` expecting 200 with a JSON object. Returns 0 with *out set (new reference), or an exit
 * status after printing why. */
static int client_get_object(client *c, const char *url, json_t **out) {
  *out = NULL;
  response r;
  CURLcode cc = client_json(c, "GET", url, NULL, &r);
  int rc = 0;
  if (cc) {
    rc = transport_error(c, url, cc, r.body.overflow);
  } else if (r.status != 200) {
    rc = http_error(c, "GET", url, &r);
  } else {
    json_error_t je;
    *out = json_loads(r.body.p ? r.body.p : "", 0, &je);
    if (!json_is_object(*out)) {
      fprintf(stderr, "obscura: GET %s: the answer is not a JSON object: %s\n", url, je.text);
      json_decref(*out);
      *out = NULL;
      rc = EXIT_FAILURE;
    }
  }
  response_free(&r);
  return rc;
}

static void sleep_ms(long ms) {
  struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
  while (nanosleep(&ts, &ts) && errno == EINTR) {
  }
}

/* ---- submit ---- */

typedef struct submit_opts {
  cli_scene_opts s;
  const char *server, *label, *out_dir;
  int priority; /* -1: not given (the server's default) */
  int wait;
} submit_opts;

static int parse_submit(int argc, char **argv, submit_opts *o) {
  memset(o, 0, sizeof *o);
  o->priority = -1;
  for (int i = 2; i < argc; i++) {
    int taken = cli_scene_option(&o->s, argc, argv, &i);
    if (taken < 0) return -1;
    if (taken) continue;
    const char *a = argv[i];
    if (!strcmp(a, "--server") || !strcmp(a, "--priority") || !strcmp(a, "--label") ||
        !strcmp(a, "-o")) {
      const char *val = cli_option_value(argc, argv, &i);
      if (!val) return -1;
      if (!strcmp(a, "--server")) {
        o->server = val;
      } else if (!strcmp(a, "--label")) {
        o->label = val;
      } else if (!strcmp(a, "-o")) {
        if (!*val) {
          fprintf(stderr, "obscura: -o needs a directory name\n");
          return -1;
        }
        o->out_dir = val;
        o->wait = 1;
      } else {
        char *end;
        long n = strtol(val, &end, 10);
        if (!*val || *end || n < 0 || n > 100) {
          fprintf(stderr, "obscura: --priority must be an integer from 0 to 100 (got %s)\n", val);
          return -1;
        }
        o->priority = (int)n;
      }
    } else if (!strcmp(a, "--wait")) {
      o->wait = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else if (!o->s.scene) {
      o->s.scene = a;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!o->s.scene) {
    fprintf(stderr, "obscura: missing SCENE.json\n");
    return -1;
  }
  if (!o->server) {
    fprintf(stderr, "obscura: missing --server URL\n");
    return -1;
  }
  return 0;
}

/* The request body: the validated document (overrides and --technique/--backend applied) with
 * the wrapper keys. Meshes are named as in the document; the server reads them from its own
 * --scenes-dir, so say so. */
static char *submit_body(const obs_scene *sc, const submit_opts *o) {
  json_t *objs = json_object_get(sc->doc, "objects");
  for (size_t i = 0; i < sc->nobjects; i++) {
    if (sc->objects[i].shape != OBS_SHAPE_MESH) continue;
    const char *file = json_string_value(
        json_object_get(json_object_get(json_array_get(objs, i), "shape"), "file"));
    fprintf(stderr, "obscura: note: mesh file \"%s\" is read by the server from its --scenes-dir\n",
            file ? file : "?");
  }
  json_t *doc = json_deep_copy(sc->doc);
  if (!doc) return NULL;
  if (o->priority >= 0) json_object_set_new(doc, "priority", json_integer(o->priority));
  if (o->label) {
    json_t *l = json_string(o->label);
    if (!l) {
      fprintf(stderr, "obscura: --label must be UTF-8 text\n");
      json_decref(doc);
      return NULL;
    }
    json_object_set_new(doc, "label", l);
  }
  char *text = json_dumps(doc, JSON_COMPACT);
  json_decref(doc);
  return text;
}

/* Polls the job until it is succeeded, failed or cancelled. Returns 0 with *job set to its last
 * state (new reference), or an exit status after printing why. */
static int wait_job(client *c, long long id, const char *url, json_t **job) {
  *job = NULL;
  cli_progress pr = {.tty = isatty(2), .last = -1};
  int bar = 0, last_tenth = 0;
  char state[16] = "";
  double lost_since = -1;
  for (;;) {
    response r;
    CURLcode cc = client_json(c, "GET", url, NULL, &r);
    if ((cc && !r.body.overflow) || (!cc && r.status >= 500)) {
      /* The daemon may be restarting (jobs survive that) or briefly unable to answer (503): keep
       * trying for a while. */
      double now = obs_now_ms();
      if (lost_since < 0) {
        if (bar) fputc('\n', stderr);
        bar = 0;
        pr.last = -1;
        last_tenth = 0; /* a restarted render starts again from 0 */
        lost_since = now;
        fprintf(stderr, "obscura: lost the server (");
        if (cc)
          fputs(c->errbuf[0] ? c->errbuf : curl_easy_strerror(cc), stderr);
        else
          fprintf(stderr, "HTTP %ld", r.status);
        fprintf(stderr, "); retrying for %d s\n", LOST_SERVER_MS / 1000);
      }
      if (now - lost_since <= LOST_SERVER_MS) {
        response_free(&r);
        sleep_ms(POLL_MS);
        continue;
      }
    }
    if (cc || r.status != 200) {
      if (bar) fputc('\n', stderr);
      int rc = cc ? transport_error(c, url, cc, r.body.overflow) : http_error(c, "GET", url, &r);
      response_free(&r);
      return rc;
    }
    lost_since = -1;
    json_t *j = json_loads(r.body.p ? r.body.p : "", 0, NULL);
    response_free(&r);
    const char *st = json_string_value(json_object_get(j, "state"));
    double progress = json_number_value(json_object_get(j, "progress"));
    if (!st) {
      if (bar) fputc('\n', stderr);
      fprintf(stderr, "obscura: GET %s: the answer is not a job\n", url);
      json_decref(j);
      return EXIT_FAILURE;
    }
    int done = !strcmp(st, "succeeded") || !strcmp(st, "failed") || !strcmp(st, "cancelled");
    if (strcmp(st, state)) {
      if (bar) {
        if (!strcmp(st, "succeeded")) cli_progress_draw(&pr, 1.0);
        fputc('\n', stderr);
        bar = 0;
      }
      pr.last = -1;
      last_tenth = 0;
      fprintf(stderr, "job %lld: ", id);
      put_clean(stderr, st);
      fputc('\n', stderr);
      snprintf(state, sizeof state, "%s", st);
    }
    if (done) {
      *job = j;
      return 0;
    }
    if (!strcmp(st, "running")) {
      if (pr.tty) {
        cli_progress_draw(&pr, progress);
        bar = 1;
      } else if ((int)(progress * 10.0) > last_tenth && progress < 1.0) {
        last_tenth = (int)(progress * 10.0);
        fprintf(stderr, "job %lld: running %d%%\n", id, last_tenth * 10);
      }
    }
    json_decref(j);
    sleep_ms(POLL_MS);
  }
}

/* Output file names come from the server: plain names only. */
static int safe_name(const char *s) {
  if (!s || !*s || s[0] == '.' || strlen(s) > 128) return 0;
  for (; *s; s++)
    if (!((*s >= 'a' && *s <= 'z') || (*s >= 'A' && *s <= 'Z') || (*s >= '0' && *s <= '9') ||
          *s == '.' || *s == '_' || *s == '-'))
      return 0;
  return 1;
}

typedef struct sink {
  CURL *curl;
  FILE *f;
  long status; /* 0 until the first body bytes */
  curl_off_t bytes;
  int write_failed;
  buf errbody; /* the body of a non-200 answer */
} sink;

static size_t sink_write(char *data, size_t size, size_t n, void *user) {
  sink *s = user;
  size_t k = size * n;
  if (!s->status) curl_easy_getinfo(s->curl, CURLINFO_RESPONSE_CODE, &s->status);
  if (s->status != 200) return buf_write(data, size, n, &s->errbody);
  if (fwrite(data, 1, k, s->f) != k) {
    s->write_failed = errno ? errno : EIO;
    return 0;
  }
  s->bytes += (curl_off_t)k;
  return k;
}

/* Downloads one output into DIR/name through a temporary file and rename, checking its size. */
static int download(client *c, const char *dir, const char *name, const char *ref, long long size) {
  char *url = client_url(c, ref);
  if (!url) return EXIT_FAILURE;
  char tmp[4096], final[4096];
  if (snprintf(final, sizeof final, "%s/%s", dir, name) >= (int)sizeof final ||
      snprintf(tmp, sizeof tmp, "%s/.%s.XXXXXX", dir, name) >= (int)sizeof tmp) {
    fprintf(stderr, "obscura: %s: path too long\n", dir);
    free(url);
    return EXIT_BAD_INPUT;
  }
  int fd = mkstemp(tmp);
  FILE *f = fd < 0 ? NULL : fdopen(fd, "wb");
  if (!f) {
    fprintf(stderr, "obscura: cannot create %s: %s\n", tmp, strerror(errno));
    if (fd >= 0) {
      close(fd);
      unlink(tmp);
    }
    free(url);
    return EXIT_FAILURE;
  }
  mode_t mask = umask(0);
  umask(mask);
  fchmod(fd, 0666 & ~mask);

  sink s = {.curl = c->curl, .f = f};
  client_prepare(c, url, 0);
  curl_easy_setopt(c->curl, CURLOPT_WRITEFUNCTION, sink_write);
  curl_easy_setopt(c->curl, CURLOPT_WRITEDATA, &s);
  CURLcode cc = curl_easy_perform(c->curl);
  if (cc == CURLE_OK) curl_easy_getinfo(c->curl, CURLINFO_RESPONSE_CODE, &s.status);
  int rc = 0;
  if (s.write_failed) {
    fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(s.write_failed));
    rc = EXIT_FAILURE;
  } else if (cc) {
    rc = transport_error(c, url, cc, s.errbody.overflow);
  } else if (s.status != 200) {
    response r = {.status = s.status, .body = s.errbody};
    rc = http_error(c, "GET", url, &r);
  }
  if (fflush(f) || fsync(fd)) {
    if (!rc) fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(errno));
    rc = rc ? rc : EXIT_FAILURE;
  }
  if (fclose(f) && !rc) {
    fprintf(stderr, "obscura: cannot write %s: %s\n", tmp, strerror(errno));
    rc = EXIT_FAILURE;
  }
  if (!rc && s.bytes != (curl_off_t)size) {
    fprintf(stderr, "obscura: %s: downloaded %lld bytes but the job lists %lld\n", url,
            (long long)s.bytes, size);
    rc = EXIT_FAILURE;
  }
  if (!rc && rename(tmp, final)) {
    fprintf(stderr, "obscura: cannot rename %s to %s: %s\n", tmp, final, strerror(errno));
    rc = EXIT_FAILURE;
  }
  if (rc) unlink(tmp);
  free(s.errbody.p);
  free(url);
  return rc;
}

/* Downloads every output in the job's links into `dir`. */
static int download_outputs(client *c, json_t *job, const char *dir) {
  json_t *links = json_object_get(json_object_get(job, "links"), "outputs");
  json_t *list = json_object_get(job, "outputs");
  if (!json_is_object(links) || !json_object_size(links)) {
    fprintf(stderr, "obscura: the job lists no outputs to download\n");
    return EXIT_FAILURE;
  }
  obs_err derr = OBS_ERR_INIT;
  if (obs_image_make_dirs(dir, &derr)) {
    fprintf(stderr, "obscura: %s\n", obs_err_message(&derr));
    obs_err_free(&derr);
    return EXIT_FAILURE;
  }
  const char *name;
  json_t *ref;
  json_object_foreach(links, name, ref) {
    if (!safe_name(name)) {
      fprintf(stderr, "obscura: the server listed an output with an unusable name (");
      put_clean(stderr, name);
      fprintf(stderr, ")\n");
      return EXIT_FAILURE;
    }
    json_t *size = NULL;
    size_t i;
    json_t *o;
    json_array_foreach(list, i, o) {
      if (json_is_string(json_object_get(o, "name")) &&
          !strcmp(json_string_value(json_object_get(o, "name")), name))
        size = json_object_get(o, "size");
    }
    if (!json_is_integer(size) || json_integer_value(size) < 0) {
      fprintf(stderr, "obscura: the job lists no size for output %s\n", name);
      return EXIT_FAILURE;
    }
    int rc = download(c, dir, name, json_string_value(ref), (long long)json_integer_value(size));
    if (rc) return rc;
    printf("%s/%s (%lld bytes)\n", dir, name, (long long)json_integer_value(size));
  }
  return 0;
}

static void print_finished(long long id, json_t *job) {
  json_t *be = json_object_get(job, "backend");
  const char *actual = json_string_value(json_object_get(be, "actual"));
  json_t *img = json_object_get(job, "image");
  json_t *t = json_object_get(job, "timings_ms");
  json_t *stats = json_object_get(job, "stats"), *ao = json_object_get(stats, "ao");
  /* A technique without ao: the first channel of its primary output. */
  const char *prim = json_string_value(json_object_get(stats, "primary_output"));
  const char *what = "AO";
  if (!ao && prim) {
    json_t *chs = json_object_get(json_object_get(json_object_get(stats, "outputs"), prim),
                                  "channels");
    ao = json_object_iter_value(json_object_iter(chs));
    what = prim;
  }
  printf("job %lld succeeded: ", id);
  put_clean(stdout, json_string_value(json_object_get(job, "technique")));
  putchar('/');
  put_clean(stdout, actual ? actual : "?");
  printf(" %lldx%lld, %.1f ms render (%.1f total), ", 
         (long long)json_integer_value(json_object_get(img, "width")),
         (long long)json_integer_value(json_object_get(img, "height")),
         json_number_value(json_object_get(t, "render")),
         json_number_value(json_object_get(t, "total")));
  put_clean(stdout, what);
  printf(" mean %.4f\n", json_number_value(json_object_get(ao, "mean")));
}

int cli_submit(int argc, char **argv) {
  submit_opts o;
  if (parse_submit(argc, argv, &o)) {
    fputs("usage:\n", stderr);
    cli_client_usage(stderr);
    cli_scene_opts_free(&o.s);
    return EXIT_BAD_INPUT;
  }
  client c;
  int rc = client_open(&c, o.server);
  if (rc) {
    client_close(&c);
    cli_scene_opts_free(&o.s);
    return rc;
  }
  /* Everything the renderer would refuse is refused here, before anything is sent. */
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  int lrc = cli_scene_load(&o.s, &sc, &err);
  if (lrc) {
    fprintf(stderr, "%s\n", obs_err_message(&err));
    obs_err_free(&err);
    client_close(&c);
    cli_scene_opts_free(&o.s);
    return cli_load_exit_code(lrc);
  }
  obs_err_free(&err);
  /* An unusable -o DIR is found now, not after the render. */
  if (o.out_dir && obs_image_make_dirs(o.out_dir, &err)) {
    fprintf(stderr, "obscura: %s\n", obs_err_message(&err));
    obs_err_free(&err);
    obs_scene_free(&sc);
    client_close(&c);
    cli_scene_opts_free(&o.s);
    return EXIT_BAD_INPUT;
  }
  char *body = submit_body(&sc, &o);
  obs_scene_free(&sc);
  char *url = body ? client_url(&c, "/api/v1/jobs") : NULL;
  json_t *answer = NULL, *job = NULL;
  char *self = NULL;
  long long id = 0;
  if (!url) {
    rc = body ? EXIT_FAILURE : EXIT_BAD_INPUT;
    goto done;
  }
  response r;
  CURLcode cc = client_json(&c, "POST", url, body, &r);
  if (cc) {
    rc = transport_error(&c, url, cc, r.body.overflow);
    response_free(&r);
    goto done;
  }
  if (r.status != 201) {
    rc = http_error(&c, "POST", url, &r);
    response_free(&r);
    goto done;
  }
  answer = json_loads(r.body.p ? r.body.p : "", 0, NULL);
  response_free(&r);
  json_t *jid = json_object_get(answer, "id");
  const char *ref = json_string_value(json_object_get(json_object_get(answer, "links"), "self"));
  if (!json_is_integer(jid) || !ref) {
    fprintf(stderr, "obscura: POST %s: the answer has no job id and link\n", url);
    rc = EXIT_FAILURE;
    goto done;
  }
  id = (long long)json_integer_value(jid);
  self = client_url(&c, ref);
  if (!self) {
    rc = EXIT_FAILURE;
    goto done;
  }
  printf("job %lld queued: %s\n", id, self);
  fflush(stdout);
  if (!o.wait) goto done;
  rc = wait_job(&c, id, self, &job);
  if (rc) goto done;
  const char *st = json_string_value(json_object_get(job, "state"));
  if (strcmp(st, "succeeded")) {
    const char *why = json_string_value(json_object_get(job, "error"));
    fprintf(stderr, "obscura: job %lld %s: ", id, st);
    put_clean(stderr, why ? why : "(no error message)");
    fputc('\n', stderr);
    rc = EXIT_FAILURE;
    goto done;
  }
  print_finished(id, job);
  if (o.out_dir) rc = download_outputs(&c, job, o.out_dir);
done:
  json_decref(job);
  json_decref(answer);
  free(self);
  free(url);
  free(body);
  client_close(&c);
  cli_scene_opts_free(&o.s);
  return rc;
}

/* ---- jobs ---- */

typedef struct jobs_opts {
  const char *server, *state, *technique, *backend;
  long limit;
  int json;
} jobs_opts;

static int parse_jobs(int argc, char **argv, jobs_opts *o) {
  memset(o, 0, sizeof *o);
  o->limit = 50;
  for (int i = 2; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--server") || !strcmp(a, "--state") || !strcmp(a, "--technique") ||
        !strcmp(a, "--backend") || !strcmp(a, "--limit")) {
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
      else {
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
    } else if (a[0] == '-') {
      fprintf(stderr, "obscura: unknown option %s\n", a);
      return -1;
    } else {
      fprintf(stderr, "obscura: unexpected argument %s\n", a);
      return -1;
    }
  }
  if (!o->server) {
    fprintf(stderr, "obscura: missing --server URL\n");
    return -1;
  }
  return 0;
}

/* Appends "&key=escaped(value)" to `q` (capacity `cap`). */
static int query_add(client *c, char *q, size_t cap, const char *key, const char *value) {
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

typedef struct row {
  char cell[7][64]; /* every column but the label */
  const char *label;
} row;

static void print_table(json_t *jobs) {
  static const char *const head[8] = {"ID",      "STATE",    "PROGRESS", "TECHNIQUE",
                                      "BACKEND", "PRIORITY", "CREATED",  "LABEL"};
  size_t n = json_array_size(jobs);
  row *rows = calloc(n ? n : 1, sizeof *rows);
  if (!rows) {
    fprintf(stderr, "obscura: out of memory\n");
    return;
  }
  int w[7];
  for (int k = 0; k < 7; k++) w[k] = (int)strlen(head[k]);
  for (size_t i = 0; i < n; i++) {
    json_t *j = json_array_get(jobs, i);
    json_t *be = json_object_get(j, "backend");
    row *r = &rows[i];
    snprintf(r->cell[0], 64, "%lld", (long long)json_integer_value(json_object_get(j, "id")));
    snprintf(r->cell[1], 64, "%s", str_or(json_object_get(j, "state"), "?"));
    snprintf(r->cell[2], 64, "%d%%",
             (int)(json_number_value(json_object_get(j, "progress")) * 100.0 + 1e-9));
    snprintf(r->cell[3], 64, "%s", str_or(json_object_get(j, "technique"), "?"));
    snprintf(r->cell[4], 64, "%s",
             str_or(json_object_get(be, "actual"), str_or(json_object_get(be, "requested"), "?")));
    snprintf(r->cell[5], 64, "%lld", (long long)json_integer_value(json_object_get(j, "priority")));
    snprintf(r->cell[6], 64, "%s", str_or(json_object_get(j, "created_at"), "?"));
    r->label = str_or(json_object_get(j, "label"), "");
    for (int k = 0; k < 7; k++)
      if ((int)strlen(r->cell[k]) > w[k]) w[k] = (int)strlen(r->cell[k]);
  }
  for (int k = 0; k < 7; k++) printf("%-*s  ", w[k], head[k]);
  printf("%s\n", head[7]);
  for (size_t i = 0; i < n; i++) {
    for (int k = 0; k < 7; k++) {
      put_clean(stdout, rows[i].cell[k]);
      /* No trailing blanks when the label is empty. */
      if (k < 6 || *rows[i].label) printf("%*s", w[k] - (int)strlen(rows[i].cell[k]) + 2, "");
    }
    put_clean(stdout, rows[i].label);
    putchar('\n');
  }
  free(rows);
}

int cli_jobs(int argc, char **argv) {
  jobs_opts o;
  if (parse_jobs(argc, argv, &o)) {
    fputs("usage:\n", stderr);
    cli_client_usage(stderr);
    return EXIT_BAD_INPUT;
  }
  client c;
  int rc = client_open(&c, o.server);
  json_t *all = json_array();
  json_t *next = json_null();
  long remaining = o.limit;
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
    char *url = client_url(&c, q);
    json_t *page = NULL;
    rc = url ? client_get_object(&c, url, &page) : EXIT_FAILURE;
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
    }
  }
  json_decref(next);
  json_decref(all);
  client_close(&c);
  return rc;
}
