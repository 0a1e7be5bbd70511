/* Dashboard sessions: POST /api/v1/session, authenticated with the bearer token, answers an
 * HttpOnly, SameSite=Strict cookie that stands in for the token on GET and HEAD requests, so that
 * the dashboard's <img> elements and download links (which cannot send an Authorization header)
 * work when the daemon has --token-file. The cookie is stateless: its expiry time and an
 * HMAC-SHA256 of it under a key drawn at each start, so a restart ends every session. */
#include <jansson.h>
#include <microhttpd.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "obscurad.h"

#define COOKIE_NAME "obscura_session"

int srv_session_init(srv_app *app) {
  return RAND_bytes(app->session_key, (int)sizeof app->session_key) == 1 ? 0 : OBS_EIO;
}

/* The signature of an expiry time, as 64 lowercase hex digits. The "obscura-session." prefix
 * keeps the key from signing anything else by accident. */
static void sign(const srv_app *app, long long expires, char hex[65]) {
  char msg[64];
  int n = snprintf(msg, sizeof msg, "obscura-session.%lld", expires);
  unsigned char mac[EVP_MAX_MD_SIZE];
  unsigned len = 0;
  HMAC(EVP_sha256(), app->session_key, (int)sizeof app->session_key, (const unsigned char *)msg,
       (size_t)n, mac, &len);
  for (unsigned i = 0; i < 32; i++) snprintf(hex + 2 * i, 3, "%02x", mac[i]);
  hex[64] = '\0';
}

int srv_session_check(srv_app *app, struct MHD_Connection *c) {
  const char *v = MHD_lookup_connection_value(c, MHD_COOKIE_KIND, COOKIE_NAME);
  if (!v) return SRV_SESSION_NONE;
  /* "<expiry, unix seconds>.<64 hex digits>": anything else is not one of ours. */
  const char *dot = strchr(v, '.');
  if (!dot || dot == v || dot - v > 18 || strlen(dot + 1) != 64) return SRV_SESSION_INVALID;
  long long expires = 0;
  for (const char *p = v; p < dot; p++) {
    if (*p < '0' || *p > '9') return SRV_SESSION_INVALID;
    expires = expires * 10 + (*p - '0');
  }
  char want[65];
  sign(app, expires, want);
  /* Constant time: a forged cookie learns nothing from how long the refusal took. */
  if (CRYPTO_memcmp(want, dot + 1, 64)) return SRV_SESSION_INVALID;
  return expires > (long long)time(NULL) ? SRV_SESSION_OK : SRV_SESSION_EXPIRED;
}

static int answer(srv_req *r, json_t *body, const char *cookie) {
  struct MHD_Response *resp = srv_json_response(body);
  if (!resp) return MHD_NO;
  if (cookie) MHD_add_response_header(resp, MHD_HTTP_HEADER_SET_COOKIE, cookie);
  return srv_respond(r, MHD_HTTP_OK, resp);
}

/* POST: a new cookie (the bearer token was checked like on every /api route); DELETE: the cookie
 * is cleared. Without --token-file there is nothing to stand in for: no cookie. */
int srv_session_serve(srv_req *r) {
  srv_app *app = r->app;
  int post = !strcmp(r->method, "POST");
  if (!post && strcmp(r->method, "DELETE")) return srv_respond_method(r, "POST, DELETE");
  if (!app->has_token) return answer(r, json_pack("{s:b}", "token_required", 0), NULL);
  if (!post)
    return answer(r, json_pack("{s:b}", "token_required", 1),
                  COOKIE_NAME "=; Path=/; Max-Age=0; HttpOnly; SameSite=Strict");
  long long ttl = app->cfg.session_seconds;
  time_t expires = time(NULL) + (time_t)ttl;
  char hex[65], cookie[256], iso[32];
  sign(app, (long long)expires, hex);
  snprintf(cookie, sizeof cookie,
           COOKIE_NAME "=%lld.%s; Path=/; Max-Age=%lld; HttpOnly; SameSite=Strict",
           (long long)expires, hex, ttl);
  struct tm tm;
  gmtime_r(&expires, &tm);
  strftime(iso, sizeof iso, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return answer(r,
                json_pack("{s:b, s:s, s:I}", "token_required", 1, "expires", iso, "expires_in",
                          (json_int_t)ttl),
                cookie);
}
