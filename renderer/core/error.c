/* The obs_err message buffer: problems accumulate line by line so validation can report them all. */
#include "obscura/error.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int obs_err_set(obs_err *err, int code, const char *fmt, ...) {
  if (!err) return code;
  va_list ap;
  va_start(ap, fmt);
  int n = vsnprintf(NULL, 0, fmt, ap);
  va_end(ap);
  if (n < 0) return code;
  size_t need = err->len + (err->len ? 1 : 0) + (size_t)n + 1;
  if (need > err->cap) {
    size_t cap = err->cap ? err->cap : 256;
    while (cap < need) cap *= 2;
    char *t = realloc(err->text, cap);
    if (!t) return code; /* keep what we had: a lost message must not hide the failure code */
    err->text = t;
    err->cap = cap;
  }
  if (err->len) err->text[err->len++] = '\n';
  va_start(ap, fmt);
  vsnprintf(err->text + err->len, err->cap - err->len, fmt, ap);
  va_end(ap);
  err->len += (size_t)n;
  err->count++;
  return code;
}

const char *obs_err_message(const obs_err *err) {
  return (err && err->text) ? err->text : "";
}

void obs_err_clear(obs_err *err) {
  if (!err) return;
  err->len = 0;
  err->count = 0;
  if (err->text) err->text[0] = '\0';
}

void obs_err_replace(obs_err *err, const char *from, const char *to) {
  if (!err || !err->text || !from || !*from) return;
  size_t fl = strlen(from), tl = strlen(to), hits = 0;
  for (const char *p = strstr(err->text, from); p; p = strstr(p + fl, from)) hits++;
  if (!hits) return;
  size_t len = err->len - hits * fl + hits * tl;
  char *out = malloc(len + 1);
  if (!out) return; /* the message stays as it was: a failure to shorten it hides nothing */
  char *o = out;
  const char *s = err->text;
  for (const char *p = strstr(s, from); p; s = p + fl, p = strstr(s, from)) {
    memcpy(o, s, (size_t)(p - s));
    o += p - s;
    memcpy(o, to, tl);
    o += tl;
  }
  size_t rest = strlen(s);
  memcpy(o, s, rest + 1);
  free(err->text);
  err->text = out;
  err->len = len;
  err->cap = len + 1;
}

void obs_err_free(obs_err *err) {
  if (!err) return;
  free(err->text);
  memset(err, 0, sizeof *err);
}

const char *obs_strerror(int code) {
  switch (code) {
    case OBS_OK: return "ok";
    case OBS_EINVAL: return "invalid input";
    case OBS_ENOMEM: return "out of memory";
    case OBS_EIO: return "input/output error";
    case OBS_ECANCELED: return "cancelled";
    case OBS_EUNSUPPORTED: return "not supported";
    case OBS_ENOTFOUND: return "not found";
    case OBS_EINTERNAL: return "internal error";
    case OBS_ETRANSIENT: return "transient fault";
    case OBS_ECONFLICT: return "conflict";
    default: return "unknown error";
  }
}
