/* The CLI's HTTP client for obscurad through libcurl (http.h). */
#include "http.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "args.h"
#include "obscura/obscura.h"

/* Prints server-supplied text with control characters replaced, so a hostile or broken server
 * cannot drive the terminal. */
void cli_put_clean(FILE *f, const char *s) {
  for (; s && *s; s++) fputc((unsigned char)*s < 0x20 || *s == 0x7f ? '?' : *s, f);
}

size_t cli_buf_write(char *data, size_t size, size_t n, void *user) {
  cli_buf *b = user;
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

void cli_response_free(cli_response *r) {
  free(r->body.p);
  memset(r, 0, sizeof *r);
}

void cli_client_close(cli_client *c) {
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
int cli_client_open(cli_client *c, const char *server) {
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
char *cli_client_url(cli_client *c, const char *ref) {
  if (!ref || ref[0] != '/' || ref[1] == '/') {
    fprintf(stderr, "obscura: the server gave an unexpected link (");
    cli_put_clean(stderr, ref ? ref : "null");
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
    cli_put_clean(stderr, ref);
    fprintf(stderr, ": %s\n", curl_url_strerror(uc));
    return NULL;
  }
  char *out = strdup(s);
  curl_free(s);
  if (!out) fprintf(stderr, "obscura: out of memory\n");
  return out;
}

const char *cli_server(const char *given) {
  if (given) return given;
  const char *env = getenv("OBSCURA_SERVER");
  return env && *env ? env : CLI_DEFAULT_SERVER;
}

char *cli_dashboard_url(cli_client *c, const char *route) {
  char ref[256];
  snprintf(ref, sizeof ref, "/#/%s", route);
  return cli_client_url(c, ref);
}

/* Resets the handle to the options every request shares and sets the URL. */
void cli_client_prepare(cli_client *c, const char *url, int post) {
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
CURLcode cli_client_json(cli_client *c, const char *method, const char *url, const char *body,
                         cli_response *r) {
  memset(r, 0, sizeof *r);
  cli_client_prepare(c, url, body != NULL);
  if (body) {
    curl_easy_setopt(c->curl, CURLOPT_POSTFIELDS, body);
    curl_easy_setopt(c->curl, CURLOPT_POSTFIELDSIZE_LARGE, (curl_off_t)strlen(body));
  }
  if (strcmp(method, body ? "POST" : "GET"))
    curl_easy_setopt(c->curl, CURLOPT_CUSTOMREQUEST, method);
  curl_easy_setopt(c->curl, CURLOPT_WRITEFUNCTION, cli_buf_write);
  curl_easy_setopt(c->curl, CURLOPT_WRITEDATA, &r->body);
  CURLcode cc = curl_easy_perform(c->curl);
  if (cc == CURLE_OK) curl_easy_getinfo(c->curl, CURLINFO_RESPONSE_CODE, &r->status);
  return cc;
}

int cli_transport_error(cli_client *c, const char *url, CURLcode cc, int overflow) {
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
int cli_http_error(const cli_client *c, const char *method, const char *url,
                   const cli_response *r) {
  json_t *j = r->body.p ? json_loads(r->body.p, 0, NULL) : NULL;
  const char *msg = json_string_value(json_object_get(j, "error"));
  fprintf(stderr, "obscura: %s %s answered %ld: ", method, url, r->status);
  if (msg) {
    cli_put_clean(stderr, msg);
  } else if (r->body.len) {
    char head[201];
    snprintf(head, sizeof head, "%s", r->body.p);
    cli_put_clean(stderr, head);
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
    cli_put_clean(stderr, json_string_value(p));
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
int cli_client_get_object(cli_client *c, const char *url, json_t **out) {
  *out = NULL;
  cli_response r;
  CURLcode cc = cli_client_json(c, "GET", url, NULL, &r);
  int rc = 0;
  if (cc) {
    rc = cli_transport_error(c, url, cc, r.body.overflow);
  } else if (r.status != 200) {
    rc = cli_http_error(c, "GET", url, &r);
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
  cli_response_free(&r);
  return rc;
}

void cli_sleep_ms(long ms) {
  struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
  while (nanosleep(&ts, &ts) && errno == EINTR) {
  }
}

int cli_poll_json(cli_client *c, const char *url, long poll_ms, double *lost_since,
                  void (*on_lost)(void *user), void *user, json_t **out) {
  *out = NULL;
  cli_response r;
  CURLcode cc = cli_client_json(c, "GET", url, NULL, &r);
  if ((cc && !r.body.overflow) || (!cc && r.status >= 500)) {
    double now = obs_now_ms();
    if (*lost_since < 0) {
      if (on_lost) on_lost(user);
      *lost_since = now;
      fprintf(stderr, "obscura: lost the server (");
      if (cc)
        fputs(c->errbuf[0] ? c->errbuf : curl_easy_strerror(cc), stderr);
      else
        fprintf(stderr, "HTTP %ld", r.status);
      fprintf(stderr, "); retrying for %d s\n", CLI_LOST_SERVER_MS / 1000);
    }
    if (now - *lost_since <= CLI_LOST_SERVER_MS) {
      cli_response_free(&r);
      cli_sleep_ms(poll_ms);
      return CLI_POLL_AGAIN;
    }
  }
  if (cc || r.status != 200) {
    if (on_lost) on_lost(user);
    int rc =
        cc ? cli_transport_error(c, url, cc, r.body.overflow) : cli_http_error(c, "GET", url, &r);
    cli_response_free(&r);
    return rc;
  }
  *lost_since = -1;
  *out = json_loads(r.body.p ? r.body.p : "", 0, NULL);
  cli_response_free(&r);
  return CLI_POLL_OK;
}
