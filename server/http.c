/* obscurad's HTTP layer on libmicrohttpd (internal epoll thread pool): strict message framing,
 * same-origin and JSON-only mutating requests, bearer-token and session-cookie checks, request
 * bodies under the size and in-flight limits, security headers on every response, JSON answers,
 * and one log line plus one metrics count per request. Connection-level limits live in guard.c. */
#include <arpa/inet.h>
#include <ctype.h>
#include <errno.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <openssl/crypto.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#include "obscurad.h"

/* What http.c keeps about a request beyond what the handlers see. `r` comes first: handlers get
 * &h->r and on_completed turns it back. */
typedef struct http_req {
  srv_req r;
  int64_t reserved; /* bytes of the in-flight budget held for the body buffer */
  int overloaded;   /* a chunked body outgrew the in-flight budget: dropped, answered 503 */
  void *guard_ctx;  /* the connection as the guard knows it */
} http_req;

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

/* A request without a valid bearer token: the session cookie stands in for it on reads alone. A
 * request that changes something needs the token itself, so a cookie a browser attaches on its
 * own can never act (SameSite=Strict and the origin checks aside); a read the browser marks as
 * cross-site gets no help from the cookie either. Answers 401 unless the cookie is accepted. */
static int check_session(srv_req *r) {
  int s = srv_session_check(r->app, r->conn);
  const char *site = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Sec-Fetch-Site");
  int cross = site && !strcasecmp(site, "cross-site");
  int safe = !strcmp(r->method, "GET") || !strcmp(r->method, "HEAD");
  if (s == SRV_SESSION_OK && safe && !cross && r->route != SRV_ROUTE_SESSION) return MHD_YES;
  const char *why = s == SRV_SESSION_NONE      ? ""
                    : s == SRV_SESSION_EXPIRED ? "; the session cookie has expired (POST "
                                                 "/api/v1/session with the token again)"
                    : s == SRV_SESSION_INVALID ? "; the session cookie is not valid (signed "
                                                 "before a restart, or altered)"
                    : cross ? "; the session cookie is not accepted on cross-site requests"
                            : "; the session cookie stands in for the token on GET and HEAD "
                              "only";
  return srv_respond_error(r, MHD_HTTP_UNAUTHORIZED, NULL,
                           "missing or wrong bearer token (send Authorization: Bearer "
                           "<token>)%s",
                           why);
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

/* ---- checks of a request's headers, before any body is read ---------------------------------- */

typedef struct header_counts {
  int host, content_length, transfer_encoding;
} header_counts;

static enum MHD_Result count_header(void *cls, enum MHD_ValueKind kind, const char *key,
                                    const char *value) {
  (void)kind;
  (void)value;
  header_counts *n = cls;
  if (!strcasecmp(key, MHD_HTTP_HEADER_HOST)) n->host++;
  else if (!strcasecmp(key, MHD_HTTP_HEADER_CONTENT_LENGTH)) n->content_length++;
  else if (!strcasecmp(key, MHD_HTTP_HEADER_TRANSFER_ENCODING)) n->transfer_encoding++;
  return MHD_YES;
}

/* Framing that a proxy in front could read differently from libmicrohttpd (the root of request
 * smuggling) and requests HTTP/1.1 forbids. libmicrohttpd itself takes the first of repeated
 * headers, reads a body of unknown coding until the connection closes, and does not require
 * Host. Sets *has_body. Like every check below, it answers when the request fails it; the caller
 * then returns what it returned. */
static int check_framing(srv_req *r, const char *version, int *has_body) {
  header_counts n = {0, 0, 0};
  MHD_get_connection_values(r->conn, MHD_HEADER_KIND, count_header, &n);
  *has_body = 0;
  if (n.content_length > 1)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "Content-Length given %d times (send it once)", n.content_length);
  if (n.transfer_encoding > 1)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "Transfer-Encoding given %d times (send it once)",
                             n.transfer_encoding);
  if (n.transfer_encoding && n.content_length)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "both Content-Length and Transfer-Encoding given (send one)");
  if (n.transfer_encoding) {
    const char *te =
        MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_TRANSFER_ENCODING);
    if (!te || strcasecmp(te, "chunked")) {
      char shown[80];
      srv_printable(te, shown, sizeof shown);
      return srv_respond_error(r, MHD_HTTP_NOT_IMPLEMENTED, NULL,
                               "Transfer-Encoding \"%s\" is not supported (only chunked)", shown);
    }
    *has_body = 1;
  }
  if (n.content_length) {
    const char *cl =
        MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    *has_body = cl && strtoull(cl, NULL, 10) > 0;
  }
  if (n.host > 1)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL, "Host given %d times (send it once)",
                             n.host);
  int v11 = version && !strncmp(version, "HTTP/1.", 7) && strcmp(version, MHD_HTTP_VERSION_1_0);
  if (!n.host && v11)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "an %s request needs a Host header", MHD_HTTP_VERSION_1_1);
  return MHD_YES;
}

/* The host of "host[:port]" or "[v6][:port]", brackets dropped; -1 when malformed or too long. */
static int host_part(const char *hostport, char *out, size_t n) {
  const char *end;
  if (*hostport == '[') {
    hostport++;
    end = strchr(hostport, ']');
    if (!end || (end[1] && end[1] != ':')) return -1;
  } else {
    end = strchr(hostport, ':');
    if (!end) end = hostport + strlen(hostport);
  }
  size_t len = (size_t)(end - hostport);
  if (!len || len >= n) return -1;
  memcpy(out, hostport, len);
  out[len] = '\0';
  return 0;
}

/* Whether the IP literal `ip` (family af) is the configured listen address or the address this
 * connection arrived at (which covers --listen 0.0.0.0 or ::). */
static int is_own_address(srv_req *r, int af, const unsigned char *ip) {
  unsigned char b[16];
  size_t len = af == AF_INET ? 4 : 16;
  if (inet_pton(af, r->app->cfg.listen, b) == 1 && !memcmp(b, ip, len)) return 1;
  const union MHD_ConnectionInfo *ci =
      MHD_get_connection_info(r->conn, MHD_CONNECTION_INFO_CONNECTION_FD);
  struct sockaddr_storage ss;
  socklen_t sl = sizeof ss;
  if (!ci || getsockname(ci->connect_fd, (struct sockaddr *)&ss, &sl)) return 0;
  if (ss.ss_family == AF_INET && af == AF_INET)
    return !memcmp(&((struct sockaddr_in *)&ss)->sin_addr, ip, 4);
  if (ss.ss_family != AF_INET6) return 0;
  const unsigned char *a = ((struct sockaddr_in6 *)&ss)->sin6_addr.s6_addr;
  if (af == AF_INET6) return !memcmp(a, ip, 16);
  static const unsigned char mapped[12] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xff, 0xff};
  return !memcmp(a, mapped, 12) && !memcmp(a + 12, ip, 4);
}

/* A Host a page of this daemon's own origin can carry: a loopback name or address, or this
 * daemon's own address. A page on a foreign name that was made to resolve here (DNS rebinding)
 * carries that name. */
static int host_trusted(srv_req *r, const char *hostport) {
  char h[256];
  if (host_part(hostport, h, sizeof h)) return 0;
  if (!strcasecmp(h, "localhost") || !strcasecmp(h, "localhost.")) return 1;
  unsigned char ip[16];
  if (inet_pton(AF_INET, h, ip) == 1) return ip[0] == 127 || is_own_address(r, AF_INET, ip);
  if (inet_pton(AF_INET6, h, ip) == 1)
    return IN6_IS_ADDR_LOOPBACK((struct in6_addr *)ip) || is_own_address(r, AF_INET6, ip);
  return 0;
}

/* "host:port" and "host" name the same origin when the port is HTTP's default. */
static int same_hostport(const char *a, const char *b) {
  size_t na = strlen(a), nb = strlen(b);
  if (na > 3 && !strcmp(a + na - 3, ":80")) na -= 3;
  if (nb > 3 && !strcmp(b + nb - 3, ":80")) nb -= 3;
  return na == nb && !strncasecmp(a, b, na);
}

static int is_safe_method(const char *m) {
  return !strcmp(m, "GET") || !strcmp(m, "HEAD") || !strcmp(m, "OPTIONS");
}

/* A request that changes something must come from this daemon's own pages or from a client that
 * is not a browser (no Origin, no Sec-Fetch-Site): a page elsewhere can make a browser send a
 * POST (a "simple" request needs no CORS preflight) but cannot forge these two headers. */
static int check_origin(srv_req *r) {
  if (is_safe_method(r->method)) return MHD_YES;
  const char *site = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Sec-Fetch-Site");
  char shown[120], host_shown[120];
  if (site && strcasecmp(site, "same-origin") && strcasecmp(site, "none")) {
    srv_printable(site, shown, sizeof shown);
    return srv_respond_error(r, MHD_HTTP_FORBIDDEN, NULL,
                             "cross-site request refused: Sec-Fetch-Site is \"%s\" (requests "
                             "that change anything must be same-origin)",
                             shown);
  }
  const char *origin = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Origin");
  if (!origin) return MHD_YES;
  const char *host = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_HOST);
  srv_printable(origin, shown, sizeof shown);
  srv_printable(host ? host : "", host_shown, sizeof host_shown);
  if (!strcmp(origin, "null"))
    return srv_respond_error(r, MHD_HTTP_FORBIDDEN, NULL,
                             "cross-origin request refused: Origin is \"null\" (a sandboxed "
                             "page, a file or a redirect), not this server's origin");
  if (!host || strncasecmp(origin, "http://", 7) || !same_hostport(origin + 7, host))
    return srv_respond_error(r, MHD_HTTP_FORBIDDEN, NULL,
                             "cross-origin request refused: Origin \"%s\" is not this server's "
                             "origin \"http://%s\"",
                             shown, host_shown);
  if (!host_trusted(r, host))
    return srv_respond_error(r, MHD_HTTP_FORBIDDEN, NULL,
                             "request refused: Host \"%s\" is neither a loopback name or address "
                             "nor this server's address (a foreign name resolving here is how "
                             "DNS rebinding reaches a local server)",
                             host_shown);
  return MHD_YES;
}

/* The body's share of the in-flight budget, taken before any byte is read: an announced length
 * whole (its buffer is allocated once), a chunked body as it grows (append_body). */
static int take_body_budget(http_req *h) {
  srv_req *r = &h->r;
  srv_app *app = r->app;
  const char *cl =
      MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
  unsigned long long n = cl ? strtoull(cl, NULL, 10) : 0;
  if (n > (unsigned long long)app->cfg.max_body)
    return srv_respond_error(r, 413, NULL,
                             "request body of %llu bytes exceeds the limit max-body = %lld bytes",
                             n, (long long)app->cfg.max_body);
  if (!n) return MHD_YES;
  if (srv_guard_reserve(app->guard, (int64_t)n + 1)) {
    srv_refused("max-inflight-bytes");
    return srv_respond_busy(r,
                        "request bodies in flight would exceed max-inflight-bytes = %lld bytes "
                        "with this one of %llu bytes: try again shortly",
                        (long long)app->cfg.max_inflight, n);
  }
  h->reserved = (int64_t)n + 1;
  r->body = malloc((size_t)n + 1);
  if (!r->body) return srv_respond_busy(r, "out of memory for a body of %llu bytes", n);
  r->cap = (size_t)n + 1;
  return MHD_YES;
}

/* Drops what a refused body holds, so its budget serves others while the rest is read. */
static void drop_body(http_req *h) {
  free(h->r.body);
  h->r.body = NULL;
  h->r.len = h->r.cap = 0;
  srv_guard_release(h->r.app->guard, h->reserved);
  h->reserved = 0;
}

static enum MHD_Result append_body(http_req *h, const char *data, size_t n) {
  srv_req *r = &h->r;
  srv_app *app = r->app;
  /* A refused body is read and dropped so the client gets the answer rather than a reset. */
  if (r->too_big || h->overloaded) return MHD_YES;
  if (r->len + n > (size_t)app->cfg.max_body) {
    r->too_big = 1;
    drop_body(h);
    return MHD_YES;
  }
  if (r->len + n + 1 > r->cap) {
    size_t cap = r->cap ? r->cap : 4096;
    while (cap < r->len + n + 1) cap *= 2;
    if (cap > (size_t)app->cfg.max_body + 1) cap = (size_t)app->cfg.max_body + 1;
    if (srv_guard_reserve(app->guard, (int64_t)cap - h->reserved)) {
      h->overloaded = 1;
      drop_body(h);
      return MHD_YES;
    }
    h->reserved = (int64_t)cap;
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

/* Everything that can be decided from the request line and headers, cheapest and most
 * fundamental first: framing, room, origin, token, media type, size. */
static int header_checks(http_req *h, const char *version) {
  srv_req *r = &h->r;
  srv_app *app = r->app;
  const union MHD_ConnectionInfo *ci =
      MHD_get_connection_info(r->conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
  h->guard_ctx = ci ? ci->socket_context : NULL;
  int has_body = 0;
  int ret = check_framing(r, version, &has_body);
  int busy = srv_guard_headers_done(app->guard, h->guard_ctx, has_body && !r->responded);
  if (r->responded) return ret;
  /* The reserve of connections is for the health check: a monitor must see a busy server as up. */
  if (busy && r->route != SRV_ROUTE_HEALTH) {
    srv_refused("max-connections");
    return srv_respond_busy(r,
                        "every connection up to max-connections = %d is busy: try again shortly",
                        app->cfg.max_connections);
  }
  ret = check_origin(r);
  if (r->responded) return ret;
  /* Answered before any body is read: a wrong token or an announced oversized body never
   * costs the upload. */
  if (needs_auth(app, r->route) && !auth_ok(app, r->conn)) {
    ret = check_session(r);
    if (r->responded) return ret;
  }
  ret = srv_refuse_content_type(r, has_body);
  if (r->responded) return ret;
  return take_body_budget(h);
}

/* A request answered from its headers no longer counts as uploading: its body is discarded, and
 * the guard must not pick the connection as the oldest upload and cut the answer off. */
static int first_call(http_req *h, const char *version) {
  int ret = header_checks(h, version);
  if (h->r.responded) srv_guard_body_done(h->r.app->guard, h->guard_ctx);
  return ret;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *c, const char *url,
                                  const char *method, const char *version, const char *data,
                                  size_t *size, void **con_cls) {
  srv_app *app = cls;
  http_req *h = *con_cls;
  if (!h) {
    h = calloc(1, sizeof *h);
    if (!h) return MHD_NO;
    *con_cls = h;
    srv_req *r = &h->r;
    r->app = app;
    r->conn = c;
    r->method = method;
    r->path = strdup(url ? url : "/");
    r->t0 = obs_now_ms();
    if (!r->path) return MHD_NO;
    r->route = srv_api_route(r->path);
    srv_req_client(app, c, r->client, sizeof r->client);
    return first_call(h, version) == MHD_YES ? MHD_YES : MHD_NO;
  }
  srv_req *r = &h->r;
  if (r->responded) {
    *size = 0;
    return MHD_YES;
  }
  if (*size) {
    size_t n = *size;
    *size = 0;
    srv_guard_body_progress(app->guard, h->guard_ctx, n);
    return append_body(h, data, n);
  }
  srv_guard_body_done(app->guard, h->guard_ctx);
  if (h->overloaded) {
    srv_refused("max-inflight-bytes");
    return srv_respond_busy(r, "request bodies in flight exceed max-inflight-bytes = %lld bytes: "
                        "try again shortly",
                        (long long)app->cfg.max_inflight);
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
  srv_app *app = cls;
  const union MHD_ConnectionInfo *ci =
      MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
  srv_guard_request_done(app->guard, ci ? ci->socket_context : NULL);
  http_req *h = *con_cls;
  if (!h) return;
  *con_cls = NULL;
  srv_guard_release(app->guard, h->reserved);
  srv_req *r = &h->r;
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
  free(h);
}

/* Connections as the guard sees them: it must hear of each close before libmicrohttpd closes
 * the descriptor, which it does (daemon.c reports MHD_CONNECTION_NOTIFY_CLOSED first). */
static void on_connection(void *cls, struct MHD_Connection *c, void **socket_context,
                          enum MHD_ConnectionNotificationCode toe) {
  srv_app *app = cls;
  if (toe == MHD_CONNECTION_NOTIFY_STARTED) {
    const union MHD_ConnectionInfo *fd =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD);
    const union MHD_ConnectionInfo *addr =
        MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
    *socket_context =
        fd ? srv_guard_started(app->guard, fd->connect_fd, addr ? addr->client_addr : NULL)
           : NULL;
  } else if (toe == MHD_CONNECTION_NOTIFY_CLOSED) {
    srv_guard_closed(app->guard, *socket_context);
    *socket_context = NULL;
  }
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap) {
  (void)cls;
  char msg[512];
  vsnprintf(msg, sizeof msg, fmt, ap);
  size_t n = strlen(msg);
  while (n && msg[n - 1] == '\n') msg[--n] = '\0';
  srv_log("http: %s", msg);
}

/* The listening socket, bound before anything else of the daemon starts: a port another process
 * listens on is refused here, with its reason, before the database is opened (whose recovery
 * would requeue another daemon's running jobs). SO_REUSEADDR lets a restart bind while the last
 * run's connections linger in TIME_WAIT; SO_REUSEPORT is never set, since with it a second daemon
 * would bind the same port and the kernel would share the connections between the two. */
int srv_http_bind(srv_app *app, obs_err *err) {
  struct sockaddr_storage ss;
  memset(&ss, 0, sizeof ss);
  const char *host = app->cfg.listen;
  if (!strcmp(host, "localhost")) host = "127.0.0.1";
  struct sockaddr_in *v4 = (struct sockaddr_in *)&ss;
  struct sockaddr_in6 *v6 = (struct sockaddr_in6 *)&ss;
  socklen_t len;
  if (inet_pton(AF_INET, host, &v4->sin_addr) == 1) {
    v4->sin_family = AF_INET;
    v4->sin_port = htons((uint16_t)app->cfg.port);
    len = sizeof *v4;
  } else if (inet_pton(AF_INET6, host, &v6->sin6_addr) == 1) {
    v6->sin6_family = AF_INET6;
    v6->sin6_port = htons((uint16_t)app->cfg.port);
    len = sizeof *v6;
  } else {
    return obs_err_set(err, OBS_EINVAL, "--listen: not an IPv4 or IPv6 address (got \"%s\")",
                       app->cfg.listen);
  }
  int fd = socket(ss.ss_family, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return obs_err_set(err, OBS_EIO, "cannot create a socket: %s", strerror(errno));
  int one = 1;
  setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (ss.ss_family == AF_INET6) setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof one);
  if (bind(fd, (struct sockaddr *)&ss, len) || listen(fd, SOMAXCONN)) {
    int e = errno;
    close(fd);
    return obs_err_set(err, OBS_EIO, "cannot listen on %s port %d: %s%s", app->cfg.listen,
                       app->cfg.port, strerror(e),
                       e == EADDRINUSE ? " (another obscurad or another program listens there: "
                                         "stop it or choose another --port)"
                       : e == EACCES   ? " (ports below 1024 need privileges)"
                       : e == EADDRNOTAVAIL ? " (no interface of this machine has that address)"
                                            : "");
  }
  struct sockaddr_storage got;
  socklen_t gl = sizeof got;
  app->port = app->cfg.port;
  if (!getsockname(fd, (struct sockaddr *)&got, &gl))
    app->port = ntohs(got.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&got)->sin6_port
                                                : ((struct sockaddr_in *)&got)->sin_port);
  app->listen_fd = fd;
  app->listening = 1;
  return 0;
}

int srv_http_start(srv_app *app, obs_err *err) {
  unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_ERROR_LOG;
  if (MHD_is_feature_supported(MHD_FEATURE_EPOLL) == MHD_YES) flags |= MHD_USE_EPOLL;
  if (!app->listening && srv_http_bind(app, err)) return OBS_EIO;
  if (strchr(app->cfg.listen, ':')) flags |= MHD_USE_IPv6;
  if (srv_guard_create(&app->cfg, &app->guard, err)) return OBS_EIO;
  app->mhd = MHD_start_daemon(
      flags, 0, NULL, NULL, on_request, app, MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, NULL,
      MHD_OPTION_LISTEN_SOCKET, (MHD_socket)app->listen_fd, MHD_OPTION_THREAD_POOL_SIZE,
      (unsigned)app->cfg.http_threads, MHD_OPTION_NOTIFY_COMPLETED, on_completed, app,
      MHD_OPTION_NOTIFY_CONNECTION, on_connection, app, MHD_OPTION_CONNECTION_TIMEOUT, 30u,
      MHD_OPTION_CONNECTION_LIMIT, (unsigned)app->cfg.max_connections,
      MHD_OPTION_UNESCAPE_CALLBACK, unescape, NULL, MHD_OPTION_END);
  if (!app->mhd) {
    srv_guard_free(app->guard);
    app->guard = NULL;
    return obs_err_set(err, OBS_EIO, "cannot start the HTTP server on %s port %d",
                       app->cfg.listen, app->port);
  }
  /* libmicrohttpd owns the socket now and closes it when it stops. */
  app->listening = 0;
  return 0;
}

void srv_http_stop(srv_app *app) {
  if (app->mhd) MHD_stop_daemon(app->mhd);
  app->mhd = NULL;
  if (app->listening) close(app->listen_fd);
  app->listening = 0;
  srv_guard_free(app->guard);
  app->guard = NULL;
}
