/* obscurad's HTTP layer on libmicrohttpd (internal epoll thread pool): request bodies under the
 * size limit, bearer-token checks, security headers on every response, JSON answers, and one log
 * line plus one metrics count per request. */
#include <arpa/inet.h>
#include <ctype.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <openssl/crypto.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>

#include "obscurad.h"

static void add_security_headers(struct MHD_Response *resp) {
  MHD_add_response_header(resp, "Content-Security-Policy", "default-src 'self'; frame-ancestors 'none'");
  MHD_add_response_header(resp, "X-Content-Type-Options", "nosniff");
  MHD_add_response_header(resp, "Referrer-Policy", "no-referrer");
}

int srv_respond(srv_req *r, unsigned status, struct MHD_Response *resp) {
  if (!resp) return MHD_NO;
  add_security_headers(resp);
  if (!MHD_get_response_header(resp, "Cache-Control"))
    MHD_add_response_header(resp, "Cache-Control", "no-store");
  if (status == MHD_HTTP_UNAUTHORIZED)
    MHD_add_response_header(resp, "WWW-Authenticate", "Bearer realm=\"obscurad\"");
  enum MHD_Result ret = MHD_queue_response(r->conn, status, resp);
  MHD_destroy_response(resp);
  r->responded = 1;
  r->status = status;
  return ret;
}

struct MHD_Response *srv_json_response(json_t *body) {
  char *text = body ? json_dumps(body, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
  json_decref(body);
  if (!text) return NULL;
  struct MHD_Response *resp =
      MHD_create_response_from_buffer(strlen(text), text, MHD_RESPMEM_MUST_FREE);
  if (!resp) {
    free(text);
    return NULL;
  }
  MHD_add_response_header(resp, "Content-Type", "application/json");
  return resp;
}

/* A JSON answer, with a Location header when `location` is not NULL. Consumes `body`. */
static int respond_json(srv_req *r, unsigned status, json_t *body, const char *location) {
  struct MHD_Response *resp = srv_json_response(body);
  if (!resp) return MHD_NO;
  if (location) MHD_add_response_header(resp, "Location", location);
  return srv_respond(r, status, resp);
}

int srv_respond_json(srv_req *r, unsigned status, json_t *body) {
  return respond_json(r, status, body, NULL);
}

int srv_refuse_non_json(srv_req *r, int *ret) {
  const char *ct =
      MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
  if (!ct || !strncasecmp(ct, "application/json", 16)) return 0;
  *ret = srv_respond_error(r, MHD_HTTP_UNSUPPORTED_MEDIA_TYPE, NULL,
                           "Content-Type must be application/json (got \"%.64s\")", ct);
  return 1;
}

int srv_respond_unavailable(srv_req *r, obs_err *err) {
  srv_log("database error: %s", obs_err_message(err));
  int rc = srv_respond_error(r, MHD_HTTP_SERVICE_UNAVAILABLE, err,
                             "database unavailable, try again");
  obs_err_free(err);
  return rc;
}

int srv_respond_created(srv_req *r, json_t *body, const char *location) {
  return respond_json(r, MHD_HTTP_CREATED, body, location);
}

int srv_respond_error(srv_req *r, unsigned status, const obs_err *problems, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  json_t *list = json_array();
  const char *t = problems ? obs_err_message(problems) : "";
  while (*t) {
    const char *nl = strchr(t, '\n');
    size_t n = nl ? (size_t)(nl - t) : strlen(t);
    /* Messages quote the offending input, which need not be valid UTF-8: such bytes become '?'. */
    json_t *s = json_stringn(t, n);
    if (!s) {
      char *copy = strndup(t, n);
      for (char *q = copy; copy && *q; q++)
        if ((unsigned char)*q >= 0x80) *q = '?';
      s = copy ? json_string(copy) : NULL;
      free(copy);
    }
    json_array_append_new(list, s ? s : json_string("?"));
    t += n;
    if (*t == '\n') t++;
  }
  return srv_respond_json(r, status, json_pack("{s:s, s:o}", "error", msg, "problems", list));
}

int srv_respond_method(srv_req *r, const char *allow) {
  json_t *body = json_pack("{s:s, s:[]}", "error", "method not allowed", "problems");
  char msg[160];
  snprintf(msg, sizeof msg, "method %.16s not allowed here (allowed: %s)", r->method, allow);
  json_object_set_new(body, "error", json_string(msg));
  struct MHD_Response *resp = srv_json_response(body);
  if (!resp) return MHD_NO;
  MHD_add_response_header(resp, "Allow", allow);
  return srv_respond(r, MHD_HTTP_METHOD_NOT_ALLOWED, resp);
}

/* Bearer token check: both sides are hashed first so the comparison takes the same time whatever
 * the length or content of the guess. */
static int auth_ok(srv_app *app, struct MHD_Connection *c) {
  const char *h = MHD_lookup_connection_value(c, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION);
  if (!h || strncasecmp(h, "Bearer ", 7)) return 0;
  h += 7;
  while (*h == ' ') h++;
  size_t n = strlen(h);
  while (n && (h[n - 1] == ' ' || h[n - 1] == '\t')) n--;
  unsigned char d[32];
  srv_sha256(h, n, d);
  return CRYPTO_memcmp(d, app->token_digest, 32) == 0;
}

static int needs_auth(const srv_app *app, srv_route route) {
  return app->has_token && route != SRV_ROUTE_STATIC;
}

/* Percent-decoding as libmicrohttpd does it, except that a URL holding an encoded NUL is left
 * encoded: decoded, the C string would end at the NUL and "ao.png%00.txt" would be served as
 * "ao.png". Left as it is, the name matches no output and no file, so it gets a 404. */
static size_t unescape(void *cls, struct MHD_Connection *c, char *uri) {
  (void)cls;
  (void)c;
  if (strstr(uri, "%00")) return strlen(uri);
  return MHD_http_unescape(uri);
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url,
                                  const char *method, const char *version, const char *data,
                                  size_t *size, void **con_cls) {
  (void)version;
  srv_app *app = cls;
  srv_req *r = *con_cls;
  if (!r) {
    r = calloc(1, sizeof *r);
    if (!r) return MHD_NO;
    *con_cls = r;
    r->app = app;
    r->conn = c;
    r->method = method;
    r->path = strdup(url ? url : "/");
    r->t0 = obs_now_ms();
    if (!r->path) return MHD_NO;
    r->route = srv_api_route(r->path);
    srv_req_client(app, c, r->client, sizeof r->client);
    /* Answered before any body is read: a wrong token or an announced oversized body never
     * costs the upload. */
    if (needs_auth(app, r->route) && !auth_ok(app, c))
      return srv_respond_error(r, MHD_HTTP_UNAUTHORIZED, NULL,
                               "missing or wrong bearer token (send Authorization: Bearer "
                               "<token>)");
    const char *cl = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_CONTENT_LENGTH);
    if (cl && strtoull(cl, NULL, 10) > (unsigned long long)app->cfg.max_body)
      return srv_respond_error(r, 413, NULL,
                               "request body of %s bytes exceeds the limit max-body = %lld bytes",
                               cl, (long long)app->cfg.max_body);
    return MHD_YES;
  }
  if (r->responded) {
    *size = 0;
    return MHD_YES;
  }
  if (*size) {
    size_t n = *size;
    *size = 0;
    if (r->too_big || r->len + n > (size_t)app->cfg.max_body) {
      /* Keep reading (and dropping) so the client gets the 413 rather than a reset. */
      r->too_big = 1;
      return MHD_YES;
    }
    if (r->len + n + 1 > r->cap) {
      size_t cap = r->cap ? r->cap : 4096;
      while (cap < r->len + n + 1) cap *= 2;
      char *b = realloc(r->body, cap);
      if (!b) return MHD_NO;
      r->body = b;
      r->cap = cap;
    }
    memcpy(r->body + r->len, data, n);
    r->len += n;
    r->body[r->len] = '\0';
    return MHD_YES;
  }
  if (r->too_big)
    return srv_respond_error(r, 413, NULL,
                             "request body exceeds the limit max-body = %lld bytes",
                             (long long)app->cfg.max_body);
  int ret = srv_api_dispatch(r);
  if (!r->responded) return MHD_NO;
  return ret == MHD_YES ? MHD_YES : MHD_NO;
}

/* Control characters and quotes of a client-chosen path are escaped before they reach the log. */
static void log_safe(const char *in, char *out, size_t n) {
  size_t k = 0;
  for (const unsigned char *p = (const unsigned char *)in; *p && k + 5 < n; p++) {
    if (*p < 0x20 || *p == 0x7f || *p == '"' || *p == '\\') k += (size_t)snprintf(out + k, n - k, "\\x%02x", *p);
    else out[k++] = (char)*p;
  }
  out[k] = '\0';
}

static void on_completed(void *cls, struct MHD_Connection *c, void **con_cls,
                         enum MHD_RequestTerminationCode toe) {
  (void)c;
  srv_app *app = cls;
  srv_req *r = *con_cls;
  if (!r) return;
  *con_cls = NULL;
  srv_metrics_http(r->route, r->status);
  if (!app->cfg.quiet) {
    char path[256];
    log_safe(r->path ? r->path : "?", path, sizeof path);
    char method[24];
    log_safe(r->method ? r->method : "?", method, sizeof method);
    if (r->status)
      srv_log("%s %s %u %.2f ms%s", method, path, r->status, obs_now_ms() - r->t0,
              toe == MHD_REQUEST_TERMINATED_COMPLETED_OK ? "" : " (connection closed early)");
    else
      srv_log("%s %s - %.2f ms (no response: connection closed)", method, path,
              obs_now_ms() - r->t0);
  }
  free(r->path);
  free(r->body);
  free(r);
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap) {
  (void)cls;
  char msg[512];
  vsnprintf(msg, sizeof msg, fmt, ap);
  size_t n = strlen(msg);
  while (n && msg[n - 1] == '\n') msg[--n] = '\0';
  srv_log("http: %s", msg);
}

int srv_http_start(srv_app *app, obs_err *err) {
  struct sockaddr_storage ss;
  memset(&ss, 0, sizeof ss);
  unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_ERROR_LOG;
  if (MHD_is_feature_supported(MHD_FEATURE_EPOLL) == MHD_YES) flags |= MHD_USE_EPOLL;
  const char *host = app->cfg.listen;
  if (!strcmp(host, "localhost")) host = "127.0.0.1";
  struct sockaddr_in *v4 = (struct sockaddr_in *)&ss;
  struct sockaddr_in6 *v6 = (struct sockaddr_in6 *)&ss;
  if (inet_pton(AF_INET, host, &v4->sin_addr) == 1) {
    v4->sin_family = AF_INET;
    v4->sin_port = htons((uint16_t)app->cfg.port);
  } else if (inet_pton(AF_INET6, host, &v6->sin6_addr) == 1) {
    v6->sin6_family = AF_INET6;
    v6->sin6_port = htons((uint16_t)app->cfg.port);
    flags |= MHD_USE_IPv6;
  } else {
    return obs_err_set(err, OBS_EINVAL, "--listen: not an IPv4 or IPv6 address (got \"%s\")",
                       app->cfg.listen);
  }
  app->mhd = MHD_start_daemon(
      flags, (uint16_t)app->cfg.port, NULL, NULL, on_request, app, MHD_OPTION_EXTERNAL_LOGGER,
      on_mhd_log, NULL, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss, MHD_OPTION_THREAD_POOL_SIZE,
      (unsigned)app->cfg.http_threads, MHD_OPTION_NOTIFY_COMPLETED, on_completed, app,
      MHD_OPTION_CONNECTION_TIMEOUT, 30u, MHD_OPTION_CONNECTION_LIMIT, 1000u,
      MHD_OPTION_LISTENING_ADDRESS_REUSE, 1u, MHD_OPTION_UNESCAPE_CALLBACK, unescape, NULL,
      MHD_OPTION_END);
  if (!app->mhd)
    return obs_err_set(err, OBS_EIO, "cannot listen on %s port %d (in use, or not permitted)",
                       app->cfg.listen, app->cfg.port);
  const union MHD_DaemonInfo *info = MHD_get_daemon_info(app->mhd, MHD_DAEMON_INFO_BIND_PORT);
  app->port = info && info->port ? info->port : app->cfg.port;
  return 0;
}

void srv_http_stop(srv_app *app) {
  if (app->mhd) MHD_stop_daemon(app->mhd);
  app->mhd = NULL;
}
