/* obscurad's answers: every response goes out through srv_respond with the security headers, and
 * the JSON bodies, errors ({"error", "problems"}), refusals (non-JSON bodies, 503 while faulted or
 * busy, 429 over a queue limit) and 405s are built here, below every handler and the HTTP layer
 * that routes to them. */
#include <microhttpd.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "obscurad.h"

static void add_security_headers(struct MHD_Response *resp) {
  MHD_add_response_header(resp, "Content-Security-Policy",
                          "default-src 'self'; frame-ancestors 'none'");
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

/* Whether a Content-Type value names the media type application/json: compared without case,
 * parameters (`; charset=utf-8`) allowed, nothing else (application/jsonp, application/json-seq
 * and +json suffixes are other types). */
static int is_json_type(const char *ct) {
  while (*ct == ' ' || *ct == '\t') ct++;
  size_t n = strcspn(ct, "; \t");
  if (n != 16 || strncasecmp(ct, "application/json", 16)) return 0;
  ct += n;
  while (*ct == ' ' || *ct == '\t') ct++;
  return *ct == '\0' || *ct == ';';
}

/* The 415 for a body that is not declared JSON; 0 when it is, or when there is no body. */
int srv_refuse_content_type(srv_req *r, int has_body) {
  const char *ct =
      MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
  if (!has_body || (ct && is_json_type(ct))) return 0;
  if (!ct)
    return srv_respond_error(r, MHD_HTTP_UNSUPPORTED_MEDIA_TYPE, NULL,
                             "a request body needs Content-Type: application/json (none given)");
  char shown[80];
  srv_printable(ct, shown, sizeof shown);
  return srv_respond_error(r, MHD_HTTP_UNSUPPORTED_MEDIA_TYPE, NULL,
                           "Content-Type must be application/json (got \"%s\")", shown);
}

int srv_refuse_non_json(srv_req *r, int *ret) {
  *ret = srv_refuse_content_type(r, r->len > 0);
  return r->responded;
}

int srv_respond_unavailable(srv_req *r, obs_err *err) {
  srv_log("database error: %s", obs_err_message(err));
  int rc =
      srv_respond_error(r, MHD_HTTP_SERVICE_UNAVAILABLE, err, "database unavailable, try again");
  obs_err_free(err);
  return rc;
}

int srv_respond_created(srv_req *r, json_t *body, const char *location) {
  return respond_json(r, MHD_HTTP_CREATED, body, location);
}

/* {"error": msg, "problems": [one string per line of `problems`]}. */
static json_t *error_json(const obs_err *problems, const char *msg) {
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
  return json_pack("{s:s, s:o}", "error", msg, "problems", list);
}

int srv_respond_error(srv_req *r, unsigned status, const obs_err *problems, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  return srv_respond_json(r, status, error_json(problems, msg));
}

/* 503 with Retry-After: the request was fine, the server has no room for it right now. */
int srv_respond_busy(srv_req *r, const char *fmt, ...) {
  char msg[512];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  struct MHD_Response *resp = srv_json_response(error_json(NULL, msg));
  if (!resp) return MHD_NO;
  MHD_add_response_header(resp, "Retry-After", "1");
  return srv_respond(r, MHD_HTTP_SERVICE_UNAVAILABLE, resp);
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

/* 429 with Retry-After and the problems: the queue is over a cap. */
int srv_respond_too_busy(srv_req *r, int retry_after, const obs_err *problems) {
  json_t *list = json_array();
  const char *t = obs_err_message(problems);
  while (*t) {
    size_t n = strcspn(t, "\n");
    json_array_append_new(list, json_stringn(t, n));
    t += n;
    if (*t) t++;
  }
  char msg[96];
  snprintf(msg, sizeof msg, "the queue is over a limit of this server: try again in %d s",
           retry_after);
  struct MHD_Response *resp =
      srv_json_response(json_pack("{s:s, s:o}", "error", msg, "problems", list));
  if (!resp) return MHD_NO;
  char ra[16];
  snprintf(ra, sizeof ra, "%d", retry_after);
  MHD_add_response_header(resp, "Retry-After", ra);
  return srv_respond(r, 429, resp);
}

int srv_refuse_when_faulted(srv_req *r, int *ret) {
  char fault[1400];
  /* Before any parsing: while the database file is lost or corrupt nothing accepted would
   * survive a restart. */
  if (!srv_fault_refusing(fault, sizeof fault)) return 0;
  *ret = srv_respond_error(r, MHD_HTTP_SERVICE_UNAVAILABLE, NULL,
                           "not accepting work: %s (see GET /api/v1/health)", fault);
  return 1;
}
