/* Internal helpers for strict JSON reading: JSON-pointer paths, typed getters that report problems
 * with the pointer and the offending value. */
#ifndef OBS_JSON_UTIL_H
#define OBS_JSON_UTIL_H

#include <jansson.h>
#include <stddef.h>
#include "obscura/error.h"

/* A JSON pointer under construction. Push/pop keep it in step with the walk of the document. */
typedef struct obs_jpath {
  char buf[1024];
  size_t len;
  const char *doc; /* document name prefixed to every message */
  obs_err *err;
} obs_jpath;

void obs_jpath_init(obs_jpath *p, const char *doc, obs_err *err);
size_t obs_jpath_push_key(obs_jpath *p, const char *key);
size_t obs_jpath_push_index(obs_jpath *p, size_t i);
void obs_jpath_pop(obs_jpath *p, size_t mark);
/* Adds "<doc>: <pointer>: <message>" to the error list. Returns OBS_EINVAL. */
int obs_jpath_fail(obs_jpath *p, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* Short JSON rendering of a value for "(got ...)" (static buffer, truncated). */
const char *obs_json_brief(const json_t *v);

/* Reports every key of `obj` not in the NULL-terminated `allowed` list. Returns number found. */
int obs_json_check_keys(obs_jpath *p, const json_t *obj, const char *const *allowed);
/* Whether v is a JSON number (integer or real). */
int obs_json_is_number(const json_t *v);
double obs_json_number(const json_t *v);
/* Integers may be written as integral reals (64.0), matching JSON Schema's definition. */
int obs_json_as_int(const json_t *v, long long *out);

/* Typed field getters: each returns 0 and fills *out, or reports a problem under the field's
 * pointer and returns OBS_EINVAL. A missing optional field returns 1 and leaves *out untouched. */
int obs_json_get_number(obs_jpath *p, const json_t *obj, const char *key, int required,
                        double lo, double hi, int lo_exclusive, int hi_exclusive, double *out);
int obs_json_get_int(obs_jpath *p, const json_t *obj, const char *key, int required, long long lo,
                     long long hi, long long *out);
int obs_json_get_vec3(obs_jpath *p, const json_t *obj, const char *key, int required, double lo,
                      double hi, double out[3]);
/* String field that must be one of `choices` (NULL-terminated) when choices is non-NULL. */
int obs_json_get_string(obs_jpath *p, const json_t *obj, const char *key, int required,
                        const char *const *choices, const char **out);
/* Object/array fields: return the borrowed value, or NULL after reporting (or when optional+absent:
 * then *absent is set to 1). */
json_t *obs_json_get_object(obs_jpath *p, const json_t *obj, const char *key, int required,
                            int *absent);
json_t *obs_json_get_array(obs_jpath *p, const json_t *obj, const char *key, int required,
                           int *absent);

/* ---- limits on untrusted JSON ----------------------------------------------------------------
 * jansson parses with its own depth limit (2048) but dumps, copies, compares and frees documents
 * recursively without one, and a parsed value costs ~20x its text in memory. Untrusted text is
 * therefore pre-scanned, without allocating, before jansson builds anything. */

/* Deepest nesting the pre-scan can follow (fixed stack of open containers). */
#define OBS_JSON_SCAN_DEPTH_CAP 256

typedef struct obs_json_limits {
  int max_depth;     /* nested arrays/objects allowed (1..OBS_JSON_SCAN_DEPTH_CAP) */
  size_t max_values; /* JSON values (containers and scalars; object keys not counted); 0: any */
  size_t max_string; /* bytes of one string as written, escapes included; 0: any */
} obs_json_limits;

/* Checks `len` bytes of JSON text against `lim` without allocating. Syntax is not checked beyond
 * what the walk needs (the parser does that); strings, escapes included, are skipped exactly. On a
 * broken limit adds "<doc>: <pointer-like location>: <which limit>" to `err` and returns
 * OBS_EINVAL; otherwise 0. `values`, when not NULL, receives the count seen. */
int obs_json_prescan(const char *text, size_t len, const obs_json_limits *lim, const char *doc,
                     obs_err *err, size_t *values);
/* The same, also refusing numbers the parser cannot hold, with their pointer: an integer literal
 * (no '.', 'e', 'E') outside json_int_t's 64 bits and a real whose magnitude rounds to infinity
 * ("<doc>: /objects/1/shape/center/2: number too large for a double ..."). obs_json_prescan leaves
 * those to the parser, which names only a line and column. */
int obs_json_prescan_strict(const char *text, size_t len, const obs_json_limits *lim,
                            const char *doc, obs_err *err, size_t *values);
/* The same, also refusing numbers the parser would store as another value: a nonzero number
 * too small for any double (below 4.9e-324 in magnitude: 1e-99999 would be read as 0), an
 * integer literal a double cannot hold exactly (9007199254740993 would be read as
 * 9007199254740992), and a fraction a double rounds to a whole number (0.99999999999999999 would
 * be read as 1, which an integer field accepts). For documents whose numbers mean what they say:
 * requests, scene files, --set values. */
int obs_json_prescan_exact(const char *text, size_t len, const obs_json_limits *lim,
                           const char *doc, obs_err *err, size_t *values);
/* What happens to the number token t[0..n) when it is parsed: OBS_JSON_NUMBER_OK, or beyond what
 * the parser stores (_INT_RANGE: an integer, no '.', 'e' or 'E', outside json_int_t's 64 bits;
 * _REAL_RANGE: a real whose magnitude rounds to infinity), or, with `exact`, stored as another
 * value (_UNDERFLOW, _INEXACT, _ROUNDS_WHOLE, as obs_json_prescan_exact says). *read_as (may be
 * NULL) gets the double it becomes when that was computed. Tokens that are not numbers give OK
 * (the parser refuses those). */
enum {
  OBS_JSON_NUMBER_OK,
  OBS_JSON_NUMBER_INT_RANGE,
  OBS_JSON_NUMBER_REAL_RANGE,
  OBS_JSON_NUMBER_UNDERFLOW,
  OBS_JSON_NUMBER_INEXACT,
  OBS_JSON_NUMBER_ROUNDS_WHOLE
};
int obs_json_number_fault(const char *t, size_t n, int exact, double *read_as);
/* What a fault of obs_json_number_fault is, for a message. */
const char *obs_json_number_fault_text(int fault);
/* Whether a parsed value nests deeper than `max_depth` arrays/objects: reports the first place
 * under the pointer `p` and returns OBS_EINVAL, else 0. Recursion stops at max_depth + 1. */
int obs_json_check_depth(obs_jpath *p, const json_t *v, int max_depth);
/* Values in `v` (itself included), not descending below `max_depth` levels. */
size_t obs_json_count_values(const json_t *v, int max_depth);
/* Puts `val` (stolen, also on failure) at `pointer` (RFC 6901) in `doc`, creating missing object
 * members on the way. The pointer is checked whole (token count, escapes) before anything changes,
 * so a failure leaves `doc` as it was. */
int obs_json_pointer_put(json_t *doc, const char *pointer, json_t *val, obs_err *err);
/* `s` shortened for a message: at most `n` - 1 bytes, the cut marked with "..." (`buf` holds it
 * when shortened; otherwise `s` itself is returned). */
const char *obs_json_clip(const char *s, char *buf, size_t n);
/* Reads a whole file into a NUL-terminated buffer (owned by the caller) of at most `max` bytes;
 * refuses files with NUL bytes (not JSON text). Returns 0, OBS_EIO, OBS_EINVAL or OBS_ENOMEM with
 * a message naming `path`. */
int obs_json_read_file(const char *path, size_t max, char **out, size_t *len, obs_err *err);

#endif
