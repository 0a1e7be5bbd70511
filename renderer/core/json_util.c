/* Strict JSON reading for scene documents: every problem is reported with its JSON pointer; JSON
 * pointers; and the bounds (depth, value count, string length) untrusted JSON is held to before
 * jansson builds it. */
#include "json_util.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/scene.h"

void obs_jpath_init(obs_jpath *p, const char *doc, obs_err *err) {
  p->buf[0] = '\0';
  p->len = 0;
  p->doc = doc ? doc : "document";
  p->err = err;
}

static void jpath_append(obs_jpath *p, const char *s, int escape) {
  for (; *s && p->len + 3 < sizeof p->buf; s++) {
    if (escape && (*s == '~' || *s == '/')) {
      p->buf[p->len++] = '~';
      p->buf[p->len++] = *s == '~' ? '0' : '1';
    } else {
      p->buf[p->len++] = *s;
    }
  }
  p->buf[p->len] = '\0';
}

size_t obs_jpath_push_key(obs_jpath *p, const char *key) {
  size_t mark = p->len;
  jpath_append(p, "/", 0);
  jpath_append(p, key, 1);
  return mark;
}

size_t obs_jpath_push_index(obs_jpath *p, size_t i) {
  char tmp[32];
  snprintf(tmp, sizeof tmp, "/%zu", i);
  size_t mark = p->len;
  jpath_append(p, tmp, 0);
  return mark;
}

void obs_jpath_pop(obs_jpath *p, size_t mark) {
  p->len = mark;
  p->buf[mark] = '\0';
}

int obs_jpath_fail(obs_jpath *p, const char *fmt, ...) {
  char msg[768];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  return obs_err_set(p->err, OBS_EINVAL, "%s: %s: %s", p->doc, p->len ? p->buf : "/", msg);
}

/* Collects the start of a dump and stops it there: a brief of a huge value costs no more than a
 * brief of a small one. */
typedef struct brief_buf {
  char *buf;
  size_t len, cap;
  int cut;
} brief_buf;

static int brief_put(const char *s, size_t n, void *user) {
  brief_buf *b = user;
  size_t room = b->cap - b->len;
  if (n > room) {
    memcpy(b->buf + b->len, s, room);
    b->len += room;
    b->cut = 1;
    return -1;
  }
  memcpy(b->buf + b->len, s, n);
  b->len += n;
  return 0;
}

const char *obs_json_brief(const json_t *v) {
  static _Thread_local char buf[72];
  if (!v) return "nothing";
  char head[61];
  brief_buf b = {head, 0, sizeof head - 1, 0};
  if (json_dump_callback(v, brief_put, &b, JSON_ENCODE_ANY | JSON_COMPACT |
                                               JSON_REAL_PRECISION(10)) && !b.cut)
    return "?";
  if (b.cut) {
    size_t keep = 57;
    while (keep && ((unsigned char)head[keep] & 0xC0) == 0x80) keep--;
    memcpy(buf, head, keep);
    memcpy(buf + keep, "...", 4);
  } else {
    memcpy(buf, head, b.len);
    buf[b.len] = '\0';
  }
  return buf;
}

int obs_json_check_keys(obs_jpath *p, const json_t *obj, const char *const *allowed) {
  int bad = 0;
  const char *key;
  json_t *val;
  json_object_foreach((json_t *)obj, key, val) {
    int ok = 0;
    for (const char *const *a = allowed; *a; a++) {
      if (strcmp(*a, key) == 0) {
        ok = 1;
        break;
      }
    }
    if (!ok) {
      size_t m = obs_jpath_push_key(p, key);
      obs_jpath_fail(p, "unknown field");
      obs_jpath_pop(p, m);
      bad++;
    }
  }
  return bad;
}

int obs_json_is_number(const json_t *v) { return v && (json_is_integer(v) || json_is_real(v)); }

double obs_json_number(const json_t *v) { return json_number_value(v); }

int obs_json_as_int(const json_t *v, long long *out) {
  if (json_is_integer(v)) {
    *out = (long long)json_integer_value(v);
    return 1;
  }
  if (json_is_real(v)) {
    double d = json_real_value(v);
    if (isfinite(d) && d == floor(d) && fabs(d) < 9.0e15) {
      *out = (long long)d;
      return 1;
    }
  }
  return 0;
}

/* Range check shared by numbers and integers; reports the rule that failed. */
static int check_range(obs_jpath *p, const json_t *v, double d, double lo, double hi, int lo_ex,
                       int hi_ex) {
  if (lo_ex ? !(d > lo) : !(d >= lo)) {
    return obs_jpath_fail(p, "must be %s %.10g (got %s)", lo_ex ? ">" : ">=", lo,
                          obs_json_brief(v));
  }
  if (hi_ex ? !(d < hi) : !(d <= hi)) {
    return obs_jpath_fail(p, "must be %s %.10g (got %s)", hi_ex ? "<" : "<=", hi,
                          obs_json_brief(v));
  }
  return 0;
}

static json_t *field(obs_jpath *p, const json_t *obj, const char *key, int required, size_t *mark,
                     int *rc) {
  json_t *v = json_object_get(obj, key);
  *mark = obs_jpath_push_key(p, key);
  if (!v) {
    *rc = required ? obs_jpath_fail(p, "is required") : 1;
    obs_jpath_pop(p, *mark);
  }
  return v;
}

int obs_json_get_number(obs_jpath *p, const json_t *obj, const char *key, int required,
                        double lo, double hi, int lo_exclusive, int hi_exclusive, double *out) {
  size_t m;
  int rc = 0;
  json_t *v = field(p, obj, key, required, &m, &rc);
  if (!v) return rc;
  if (!obs_json_is_number(v)) {
    rc = obs_jpath_fail(p, "must be a number (got %s)", obs_json_brief(v));
  } else {
    double d = obs_json_number(v);
    rc = check_range(p, v, d, lo, hi, lo_exclusive, hi_exclusive);
    if (!rc) *out = d;
  }
  obs_jpath_pop(p, m);
  return rc;
}

int obs_json_get_int(obs_jpath *p, const json_t *obj, const char *key, int required, long long lo,
                     long long hi, long long *out) {
  size_t m;
  int rc = 0;
  json_t *v = field(p, obj, key, required, &m, &rc);
  if (!v) return rc;
  long long i;
  if (!obs_json_as_int(v, &i)) {
    rc = obs_jpath_fail(p, "must be an integer (got %s)", obs_json_brief(v));
  } else if (i < lo || i > hi) {
    rc = obs_jpath_fail(p, "must be %s %lld (got %s)", i < lo ? ">=" : "<=", i < lo ? lo : hi,
                        obs_json_brief(v));
  } else {
    *out = i;
  }
  obs_jpath_pop(p, m);
  return rc;
}

int obs_json_get_vec3(obs_jpath *p, const json_t *obj, const char *key, int required, double lo,
                      double hi, double out[3]) {
  size_t m;
  int rc = 0;
  json_t *v = field(p, obj, key, required, &m, &rc);
  if (!v) return rc;
  if (!json_is_array(v) || json_array_size(v) != 3) {
    rc = obs_jpath_fail(p, "must be an array of 3 numbers (got %s)", obs_json_brief(v));
  } else {
    for (size_t i = 0; i < 3; i++) {
      json_t *c = json_array_get(v, i);
      size_t mi = obs_jpath_push_index(p, i);
      if (!obs_json_is_number(c)) {
        rc = obs_jpath_fail(p, "must be a number (got %s)", obs_json_brief(c));
      } else if (check_range(p, c, obs_json_number(c), lo, hi, 0, 0)) {
        rc = OBS_EINVAL;
      } else {
        out[i] = obs_json_number(c);
      }
      obs_jpath_pop(p, mi);
    }
  }
  obs_jpath_pop(p, m);
  return rc;
}

int obs_json_get_string(obs_jpath *p, const json_t *obj, const char *key, int required,
                        const char *const *choices, const char **out) {
  size_t m;
  int rc = 0;
  json_t *v = field(p, obj, key, required, &m, &rc);
  if (!v) return rc;
  if (!json_is_string(v)) {
    rc = obs_jpath_fail(p, "must be a string (got %s)", obs_json_brief(v));
  } else if (choices) {
    const char *s = json_string_value(v);
    int ok = 0;
    char list[256] = "";
    for (const char *const *c = choices; *c; c++) {
      if (strcmp(*c, s) == 0) ok = 1;
      size_t l = strlen(list);
      snprintf(list + l, sizeof list - l, "%s\"%s\"", l ? ", " : "", *c);
    }
    if (!ok) rc = obs_jpath_fail(p, "must be one of %s (got %s)", list, obs_json_brief(v));
    else *out = s;
  } else {
    *out = json_string_value(v);
  }
  obs_jpath_pop(p, m);
  return rc;
}

static json_t *get_container(obs_jpath *p, const json_t *obj, const char *key, int required,
                             int *absent, int want_object) {
  size_t m;
  int rc = 0;
  if (absent) *absent = 0;
  json_t *v = field(p, obj, key, required, &m, &rc);
  if (!v) {
    if (rc == 1 && absent) *absent = 1;
    return NULL;
  }
  if (want_object ? !json_is_object(v) : !json_is_array(v)) {
    obs_jpath_fail(p, "must be %s (got %s)", want_object ? "an object" : "an array",
                   obs_json_brief(v));
    v = NULL;
  }
  obs_jpath_pop(p, m);
  return v;
}

json_t *obs_json_get_object(obs_jpath *p, const json_t *obj, const char *key, int required,
                            int *absent) {
  return get_container(p, obj, key, required, absent, 1);
}

json_t *obs_json_get_array(obs_jpath *p, const json_t *obj, const char *key, int required,
                           int *absent) {
  return get_container(p, obj, key, required, absent, 0);
}

/* ---- limits on untrusted JSON ---------------------------------------------------------------- */

/* One open array or object of the pre-scan: enough to name where a limit broke. */
typedef struct scan_level {
  unsigned char object;   /* 1: object, 0: array */
  unsigned char want_key; /* object: the next string is a member name */
  size_t index;           /* array: position of the current element */
  size_t key, key_len;    /* object: the current member name, as written in the text */
} scan_level;

/* Writes the location of the value being scanned ("/objects/3/shape") into `out`, shortened with
 * "..." when long; member names appear as written (escapes kept), '~' and '/' escaped. */
static void scan_location(const char *text, const scan_level *lv, int depth, char *out,
                          size_t n) {
  size_t k = 0;
  int cut = 0;
  for (int d = 0; d < depth && !cut; d++) {
    char tok[32];
    const char *s = tok;
    size_t sl;
    if (lv[d].object) {
      s = text + lv[d].key;
      sl = lv[d].key_len;
    } else {
      snprintf(tok, sizeof tok, "%zu", lv[d].index);
      sl = strlen(tok);
    }
    if (k + 1 >= n - 4) cut = 1;
    else out[k++] = '/';
    for (size_t i = 0; i < sl && !cut; i++) {
      int esc = s[i] == '~' || s[i] == '/';
      if (k + (esc ? 2 : 1) >= n - 4) {
        cut = 1;
      } else if (esc) {
        out[k++] = '~';
        out[k++] = s[i] == '~' ? '0' : '1';
      } else {
        out[k++] = (unsigned char)s[i] < 0x20 ? '?' : s[i];
      }
    }
  }
  if (cut) {
    memcpy(out + k, "...", 3);
    k += 3;
  }
  if (k == 0) out[k++] = '/';
  out[k] = '\0';
}

/* Counts one value at the current position; fails once the count passes the limit. */
static int scan_value(const char *text, const scan_level *lv, int depth, size_t *values,
                      const obs_json_limits *lim, const char *doc, obs_err *err) {
  if (++*values <= lim->max_values || !lim->max_values) return 0;
  char where[200];
  scan_location(text, lv, depth, where, sizeof where);
  return obs_err_set(err, OBS_EINVAL, "%s: %s: more than %zu JSON values; at most %zu are "
                     "accepted in one document", doc, where, lim->max_values, lim->max_values);
}

static int prescan(const char *text, size_t len, const obs_json_limits *lim, int numbers,
                   const char *doc, obs_err *err, size_t *values_out) {
  scan_level lv[OBS_JSON_SCAN_DEPTH_CAP];
  int max_depth = lim->max_depth < 1 ? 1
                  : lim->max_depth > OBS_JSON_SCAN_DEPTH_CAP ? OBS_JSON_SCAN_DEPTH_CAP
                                                              : lim->max_depth;
  int depth = 0, rc = 0;
  size_t values = 0, i = 0;
  char where[200];
  double as = 0;
  if (!doc) doc = "document";
  while (i < len && !rc) {
    unsigned char c = (unsigned char)text[i];
    scan_level *top = depth ? &lv[depth - 1] : NULL;
    if (c == '"') {
      size_t start = ++i;
      while (i < len && text[i] != '"') i += text[i] == '\\' && i + 1 < len ? 2 : 1;
      size_t end = i < len ? i : len;
      i = end + 1;
      if (top && top->object && top->want_key) {
        top->key = start;
        top->key_len = end - start;
        top->want_key = 0;
        if (lim->max_string && end - start > lim->max_string) {
          scan_location(text, lv, depth, where, sizeof where);
          rc = obs_err_set(err, OBS_EINVAL, "%s: %s: member name of %zu bytes; at most %zu are "
                           "accepted", doc, where, end - start, lim->max_string);
        }
        continue;
      }
      rc = scan_value(text, lv, depth, &values, lim, doc, err);
      if (!rc && lim->max_string && end - start > lim->max_string) {
        scan_location(text, lv, depth, where, sizeof where);
        rc = obs_err_set(err, OBS_EINVAL, "%s: %s: string of %zu bytes; at most %zu are accepted",
                         doc, where, end - start, lim->max_string);
      }
      continue;
    }
    switch (c) {
      case '{':
      case '[':
        rc = scan_value(text, lv, depth, &values, lim, doc, err);
        if (rc) break;
        if (depth == max_depth) {
          scan_location(text, lv, depth, where, sizeof where);
          rc = obs_err_set(err, OBS_EINVAL, "%s: %s: nested deeper than %d arrays/objects (the "
                           "depth limit)", doc, where, max_depth);
          break;
        }
        lv[depth] = (scan_level){.object = c == '{', .want_key = c == '{'};
        depth++;
        break;
      case '}':
      case ']':
        if (depth) depth--;
        break;
      case ',':
        if (top && top->object) top->want_key = 1;
        else if (top) top->index++;
        break;
      case ':':
        if (top && top->object) top->want_key = 0;
        break;
      case ' ':
      case '\t':
      case '\n':
      case '\r':
        break;
      default:
        /* A number or literal (or junk the parser will refuse): one value, however long. */
        rc = scan_value(text, lv, depth, &values, lim, doc, err);
        size_t start = i;
        while (i + 1 < len && (isalnum((unsigned char)text[i + 1]) || text[i + 1] == '.' ||
                               text[i + 1] == '+' || text[i + 1] == '-'))
          i++;
        int fault = rc || !numbers ? 0
                    : obs_json_number_fault(text + start, i + 1 - start, numbers > 1, &as);
        if (fault) {
          scan_location(text, lv, depth, where, sizeof where);
          size_t tl = i + 1 - start;
          char became[64] = "";
          if (fault >= OBS_JSON_NUMBER_UNDERFLOW)
            snprintf(became, sizeof became, "; it would be read as %.17g", as);
          rc = obs_err_set(err, OBS_EINVAL, "%s: %s: %s (got %.*s%s%s)", doc, where,
                           obs_json_number_fault_text(fault), (int)(tl > 40 ? 40 : tl),
                           text + start, tl > 40 ? "..." : "", became);
        }
        break;
    }
    i++;
  }
  if (values_out) *values_out = values;
  return rc;
}

int obs_json_prescan(const char *text, size_t len, const obs_json_limits *lim, const char *doc,
                     obs_err *err, size_t *values) {
  return prescan(text, len, lim, 0, doc, err, values);
}

int obs_json_prescan_strict(const char *text, size_t len, const obs_json_limits *lim,
                            const char *doc, obs_err *err, size_t *values) {
  return prescan(text, len, lim, 1, doc, err, values);
}

int obs_json_prescan_exact(const char *text, size_t len, const obs_json_limits *lim,
                           const char *doc, obs_err *err, size_t *values) {
  return prescan(text, len, lim, 2, doc, err, values);
}

static int depth_walk(obs_jpath *p, const json_t *v, int level, int max_depth) {
  if (!json_is_object(v) && !json_is_array(v)) return 0;
  if (level >= max_depth)
    return obs_jpath_fail(p, "nested deeper than %d arrays/objects (the depth limit)", max_depth);
  int rc = 0;
  if (json_is_object(v)) {
    const char *key;
    json_t *c;
    json_object_foreach((json_t *)v, key, c) {
      size_t m = obs_jpath_push_key(p, key);
      rc = depth_walk(p, c, level + 1, max_depth);
      obs_jpath_pop(p, m);
      if (rc) break;
    }
  } else {
    size_t idx;
    json_t *c;
    json_array_foreach(v, idx, c) {
      size_t m = obs_jpath_push_index(p, idx);
      rc = depth_walk(p, c, level + 1, max_depth);
      obs_jpath_pop(p, m);
      if (rc) break;
    }
  }
  return rc;
}

int obs_json_check_depth(obs_jpath *p, const json_t *v, int max_depth) {
  return depth_walk(p, v, 0, max_depth);
}

size_t obs_json_count_values(const json_t *v, int max_depth) {
  if (!v) return 0;
  size_t n = 1;
  if (max_depth <= 0) return n;
  const char *key;
  json_t *c;
  size_t idx;
  if (json_is_object(v)) {
    json_object_foreach((json_t *)v, key, c) n += obs_json_count_values(c, max_depth - 1);
  } else if (json_is_array(v)) {
    json_array_foreach(v, idx, c) n += obs_json_count_values(c, max_depth - 1);
  }
  return n;
}

const char *obs_json_clip(const char *s, char *buf, size_t n) {
  size_t l = strlen(s);
  if (l < n) return s;
  size_t keep = n > 4 ? n - 4 : 0;
  /* Never cut a UTF-8 sequence in two. */
  while (keep && ((unsigned char)s[keep] & 0xC0) == 0x80) keep--;
  memcpy(buf, s, keep);
  memcpy(buf + keep, "...", 4);
  return buf;
}

int obs_json_read_file(const char *path, size_t max, char **out, size_t *len_out, obs_err *err) {
  *out = NULL;
  *len_out = 0;
  FILE *f = fopen(path, "rb");
  if (!f) return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(errno));
  size_t cap = 1 << 16, len = 0;
  char *buf = malloc(cap + 1);
  while (buf) {
    size_t n = fread(buf + len, 1, cap - len, f);
    len += n;
    if (len < cap) break;
    if (cap >= max) {
      free(buf);
      fclose(f);
      return obs_err_set(err, OBS_EINVAL, "%s: larger than %zu MiB", path, max >> 20);
    }
    cap = cap * 2 > max ? max : cap * 2;
    char *nb = realloc(buf, cap + 1);
    if (!nb) free(buf);
    buf = nb;
  }
  int ioerr = ferror(f);
  fclose(f);
  if (!buf) return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  if (ioerr) {
    free(buf);
    return obs_err_set(err, OBS_EIO, "%s: read error", path);
  }
  buf[len] = '\0';
  if (memchr(buf, '\0', len)) {
    free(buf);
    return obs_err_set(err, OBS_EINVAL, "%s: invalid JSON: contains a NUL byte", path);
  }
  *out = buf;
  *len_out = len;
  return 0;
}

/* ---- JSON pointers (RFC 6901) ---------------------------------------------------------------- */

static int unescape_token(const char *s, size_t n, char *out, size_t cap) {
  size_t j = 0;
  for (size_t i = 0; i < n; i++) {
    if (j + 1 >= cap) return -1;
    if (s[i] == '~') {
      if (i + 1 >= n || (s[i + 1] != '0' && s[i + 1] != '1')) return -1;
      out[j++] = s[i + 1] == '0' ? '~' : '/';
      i++;
    } else {
      out[j++] = s[i];
    }
  }
  out[j] = '\0';
  return 0;
}

static int parse_index(const char *tok, size_t *out) {
  if (!*tok) return -1;
  size_t v = 0;
  for (const char *c = tok; *c; c++) {
    if (*c < '0' || *c > '9' || v > 100000000) return -1;
    v = v * 10 + (size_t)(*c - '0');
  }
  if (tok[0] == '0' && tok[1]) return -1;
  *out = v;
  return 0;
}

#define TOKEN_MAX 512

/* The whole pointer is checked before the walk: shape, token count, escapes, token length. */
static int pointer_check(const char *pointer, obs_err *err) {
  char clip[160];
  if (!pointer || pointer[0] != '/')
    return obs_err_set(err, OBS_EINVAL, "pointer must start with '/' (got \"%s\")",
                       obs_json_clip(pointer ? pointer : "", clip, sizeof clip));
  size_t tokens = 0;
  for (const char *c = pointer; *c; c++) tokens += *c == '/';
  if (tokens > OBS_POINTER_MAX_TOKENS)
    return obs_err_set(err, OBS_EINVAL, "pointer \"%s\" (%zu bytes) has %zu reference tokens; at "
                       "most %d are accepted (scene documents nest fewer than 10 levels)",
                       obs_json_clip(pointer, clip, sizeof clip), strlen(pointer), tokens,
                       OBS_POINTER_MAX_TOKENS);
  char tok[TOKEN_MAX];
  for (const char *s = pointer + 1;;) {
    const char *e = strchr(s, '/');
    size_t n = e ? (size_t)(e - s) : strlen(s);
    if (unescape_token(s, n, tok, sizeof tok))
      return obs_err_set(err, OBS_EINVAL, "malformed pointer token (a '~' not followed by 0 or "
                         "1, or longer than %d bytes) in \"%s\"", TOKEN_MAX - 1,
                         obs_json_clip(pointer, clip, sizeof clip));
    if (!e) break;
    s = e + 1;
  }
  /* Member names must be UTF-8 (jansson refuses others). */
  json_t *probe = json_string(pointer);
  if (!probe) return obs_err_set(err, OBS_EINVAL, "pointer is not valid UTF-8");
  json_decref(probe);
  return 0;
}

int obs_json_pointer_put(json_t *doc, const char *pointer, json_t *val, obs_err *err) {
  int rc = pointer_check(pointer, err);
  if (rc) {
    json_decref(val);
    return rc;
  }
  char clip[160];
  json_t *cur = doc;
  const char *s = pointer + 1;
  char tok[TOKEN_MAX];
  /* Nothing fails after the first member is created (everything below it is new objects), so a
   * refused pointer leaves the document unchanged. */
  for (;;) {
    const char *e = strchr(s, '/');
    size_t n = e ? (size_t)(e - s) : strlen(s);
    unescape_token(s, n, tok, sizeof tok);
    int last = e == NULL;
    if (json_is_object(cur)) {
      /* The _new setters take the reference even when they fail. */
      if (last)
        return json_object_set_new(cur, tok, val) ? obs_err_set(err, OBS_ENOMEM, "out of memory")
                                                  : 0;
      json_t *next = json_object_get(cur, tok);
      if (!next) {
        if (json_object_set_new(cur, tok, json_object())) break;
        next = json_object_get(cur, tok);
      }
      cur = next;
    } else if (json_is_array(cur)) {
      size_t idx;
      if (parse_index(tok, &idx) || idx >= json_array_size(cur)) {
        json_decref(val);
        return obs_err_set(err, OBS_EINVAL, "array index \"%s\" out of range in \"%s\"", tok,
                           obs_json_clip(pointer, clip, sizeof clip));
      }
      if (last)
        return json_array_set_new(cur, idx, val) ? obs_err_set(err, OBS_ENOMEM, "out of memory")
                                                 : 0;
      cur = json_array_get(cur, idx);
    } else {
      json_decref(val);
      return obs_err_set(err, OBS_EINVAL,
                         "\"%s\" goes through a value that is not an object or array",
                         obs_json_clip(pointer, clip, sizeof clip));
    }
    s = e + 1;
  }
  json_decref(val);
  return obs_err_set(err, OBS_ENOMEM, "out of memory");
}

int obs_json_pointer_set(json_t *doc, const char *pointer, const char *value, obs_err *err) {
  int rc = pointer_check(pointer, err);
  if (rc) return rc;
  /* The value is untrusted text too: bounded before it is parsed. */
  static const obs_json_limits lim = {OBS_JSON_MAX_DEPTH, 0, 0};
  if (!value) value = "";
  if (obs_json_prescan_exact(value, strlen(value), &lim, "value", err, NULL)) return OBS_EINVAL;
  json_error_t je;
  json_t *val = json_loads(value, JSON_DECODE_ANY | JSON_REJECT_DUPLICATES, &je);
  if (!val) return obs_err_set(err, OBS_EINVAL, "value is not valid JSON: %s", je.text);
  return obs_json_pointer_put(doc, pointer, val, err);
}
