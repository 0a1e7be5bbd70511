/* Internal helpers for strict JSON reading: JSON-pointer paths, typed getters that report problems
 * with the pointer and the offending value, and a validator for technique parameter schemas. */
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

/* Validates `value` (a params object, may be NULL) against a parameter schema (the subset used by
 * the registry: type, enum, minimum, maximum, exclusiveMinimum, exclusiveMaximum, default,
 * additionalProperties false) and returns a new object with defaults filled in, or NULL after
 * reporting problems. */
json_t *obs_json_params_resolve(obs_jpath *p, const json_t *schema, const json_t *value);

#endif
