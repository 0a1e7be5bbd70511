/* The CLI's HTTP client for obscurad (libcurl), shared by `obscura submit` (submit.c) and
 * `obscura jobs` (client.c): one handle per command, JSON answers kept in memory, and the
 * messages of transport and HTTP errors. */
#ifndef OBSCURA_CLI_HTTP_H
#define OBSCURA_CLI_HTTP_H

#include <curl/curl.h>
#include <jansson.h>
#include <stdio.h>

#define MAX_JSON_BODY (64u << 20) /* larger JSON answers are refused */
/* The server when neither --server nor $OBSCURA_SERVER names one: where scripts/run (and
 * obscurad's default --port) listens. */
#define CLI_DEFAULT_SERVER "http://127.0.0.1:8080"

typedef struct cli_buf {
  char *p;
  size_t len, cap;
  int overflow;
} cli_buf;

typedef struct cli_client {
  const char *server; /* --server as given, for messages */
  CURLU *base;        /* --server parsed: API paths resolve against it */
  CURL *curl;
  struct curl_slist *headers;      /* Accept, Authorization */
  struct curl_slist *post_headers; /* the same plus Content-Type */
  char errbuf[CURL_ERROR_SIZE];
  int global;    /* curl_global_init done */
  int has_token; /* an Authorization header is sent */
} cli_client;

typedef struct cli_response {
  long status;
  cli_buf body;
} cli_response;

/* Prints server-supplied text with control characters replaced, so a hostile or broken server
 * cannot drive the terminal. */
void cli_put_clean(FILE *f, const char *s);
/* A libcurl write callback appending to the cli_buf `user` (at most MAX_JSON_BODY bytes). */
size_t cli_buf_write(char *data, size_t size, size_t n, void *user);
void cli_response_free(cli_response *r);
/* The server to talk to: --server when given, else a non-empty $OBSCURA_SERVER, else
 * CLI_DEFAULT_SERVER. */
const char *cli_server(const char *given);
/* The dashboard page of `route` ("jobs/12", "comparisons/3") on the server; malloc'd, NULL after
 * printing why. */
char *cli_dashboard_url(cli_client *c, const char *route);
/* Parses --server and OBSCURA_TOKEN. Returns 0, or an exit status after printing why. */
int cli_client_open(cli_client *c, const char *server);
void cli_client_close(cli_client *c);
/* The absolute URL of `ref` (an absolute path such as "/api/v1/jobs?limit=5") on the server;
 * malloc'd, NULL after printing why. */
char *cli_client_url(cli_client *c, const char *ref);
/* Resets the handle to the options every request shares and sets the URL. */
void cli_client_prepare(cli_client *c, const char *url, int post);
/* One request whose answer (any status) is kept in memory. CURLE_OK when an answer arrived. */
CURLcode cli_client_json(cli_client *c, const char *method, const char *url, const char *body,
                         cli_response *r);
/* Prints why no answer came (or it was too large). Returns the exit status 1. */
int cli_transport_error(cli_client *c, const char *url, CURLcode cc, int overflow);
/* Prints a non-success answer: the server's `error` and every `problems` entry. Returns 2 for a
 * 4xx, 1 otherwise. */
int cli_http_error(const cli_client *c, const char *method, const char *url, const cli_response *r);
/* GET `url` expecting 200 with a JSON object. Returns 0 with *out set (new reference), or an exit
 * status after printing why. */
int cli_client_get_object(cli_client *c, const char *url, json_t **out);
void cli_sleep_ms(long ms);
/* Downloads every output the job document `job` links into `dir` (created when missing), each
 * through a temporary file and checked against its listed size, printing "DIR/NAME (N bytes)"
 * per file. Returns 0, or an exit status after printing why (submit.c). */
int cli_download_outputs(cli_client *c, json_t *job, const char *dir);

/* A followed resource given up on after the server was unreachable this long. */
#define CLI_LOST_SERVER_MS 30000
enum { CLI_POLL_OK = 0, CLI_POLL_AGAIN = -1 };
/* One GET of a resource being followed (a job, a comparison). CLI_POLL_OK: *out is the answer's
 * body (new reference) and *lost_since is reset. CLI_POLL_AGAIN: the daemon is restarting or
 * briefly overloaded (jobs and comparisons survive that): on the first such answer `on_lost`
 * (may be NULL) runs with `user` and the cause is printed; the call has slept `poll_ms`, and the
 * caller asks again. Otherwise an exit status, after printing why (also once the server was
 * lost for CLI_LOST_SERVER_MS). *lost_since starts at -1. */
int cli_poll_json(cli_client *c, const char *url, long poll_ms, double *lost_since,
                  void (*on_lost)(void *user), void *user, json_t **out);

#endif
