/* Technique parameters from their descriptor's table (obs_param): validation of a document's
 * params with JSON-pointer messages, defaults, binding into the technique's C struct, and each
 * entry's JSON Schema and faults (the table's schema, cost and self-check as a whole:
 * renderer/registry/descriptor.c). */
#include "params.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* An integral value small enough to be exact in a double becomes a JSON integer, anything else a
 * real: a default written 1 stays 1 in documents and the schema, 0.01 stays a real. */
static json_t *number_json(double v) {
  if (v == floor(v) && fabs(v) < 9007199254740992.0) return json_integer((json_int_t)v);
  return json_real(v);
}

static int is_number_type(obs_param_type t) {
  return t == OBS_PARAM_INT || t == OBS_PARAM_UINT || t == OBS_PARAM_FLOAT || t == OBS_PARAM_DOUBLE;
}

static int is_int_type(obs_param_type t) { return t == OBS_PARAM_INT || t == OBS_PARAM_UINT; }

/* Types with a numeric range: the numbers and the components of an RGB. */
static int has_range(obs_param_type t) { return is_number_type(t) || t == OBS_PARAM_RGB; }

json_t *obs_param_default_json(const obs_param *d) {
  switch (d->type) {
    case OBS_PARAM_BOOL:
      return json_boolean(d->def != 0);
    case OBS_PARAM_NAMES:
      return json_null();
    case OBS_PARAM_ENUM: {
      long n = 0;
      while (d->choices && d->choices[n]) n++;
      long i = (long)d->def;
      return i >= 0 && i < n ? json_string(d->choices[i]) : json_null();
    }
    default:
      if ((d->flags & OBS_PARAM_NULLABLE) && (d->flags & OBS_PARAM_DEFAULT_NULL))
        return json_null();
      if (d->type == OBS_PARAM_RGB)
        return json_pack("[ooo]", number_json(d->def), number_json(d->def), number_json(d->def));
      return is_int_type(d->type) ? json_integer((json_int_t)d->def) : number_json(d->def);
  }
}

/* "must be one of ..." for the choices of an enum or the values of an integer. */
static int fail_one_of(obs_jpath *p, const obs_param *d, const json_t *v) {
  char list[256] = "";
  size_t l = 0;
  for (int i = 0; d->type == OBS_PARAM_ENUM ? d->choices[i] != NULL : i < d->nvalues; i++) {
    if (d->type == OBS_PARAM_ENUM)
      snprintf(list + l, sizeof list - l, "%s\"%s\"", l ? ", " : "", d->choices[i]);
    else
      snprintf(list + l, sizeof list - l, "%s%d", l ? ", " : "", d->values[i]);
    l = strlen(list);
  }
  return obs_jpath_fail(p, "must be one of %s (got %s)", list, obs_json_brief(v));
}

/* The range check of one number `v` (a value, or a component of an RGB). */
static int check_range(obs_jpath *p, const obs_param *d, const json_t *v) {
  double x = obs_json_number(v);
  int lo_ex = (d->flags & OBS_PARAM_MIN_EXCLUSIVE) != 0,
      hi_ex = (d->flags & OBS_PARAM_MAX_EXCLUSIVE) != 0;
  if (!isinf(d->min) && (lo_ex ? !(x > d->min) : !(x >= d->min)))
    return obs_jpath_fail(p, "must be %s %.10g (got %s)", lo_ex ? ">" : ">=", d->min,
                          obs_json_brief(v));
  if (!isinf(d->max) && (hi_ex ? !(x < d->max) : !(x <= d->max)))
    return obs_jpath_fail(p, "must be %s %.10g (got %s)", hi_ex ? "<" : "<=", d->max,
                          obs_json_brief(v));
  return 0;
}

/* An RGB: three numbers, each in the range (a bad component named by its index). */
static int check_rgb(obs_jpath *p, const obs_param *d, const json_t *v) {
  int nullable = (d->flags & OBS_PARAM_NULLABLE) != 0;
  if (nullable && json_is_null(v)) return 0;
  int ok = json_is_array(v) && json_array_size(v) == 3;
  for (size_t i = 0; ok && i < 3; i++) ok = obs_json_is_number(json_array_get(v, i));
  if (!ok)
    return obs_jpath_fail(p, "must be an array of 3 numbers [R, G, B]%s (got %s)",
                          nullable ? " or null" : "", obs_json_brief(v));
  int bad = 0;
  for (size_t i = 0; i < 3; i++) {
    size_t m = obs_jpath_push_index(p, i);
    bad |= check_range(p, d, json_array_get(v, i)) != 0;
    obs_jpath_pop(p, m);
  }
  return bad ? OBS_EINVAL : 0;
}

/* A list of names: null, or an array of distinct non-empty strings that fit obs_param_names (a
 * bad item named by its index). Whether each names an object is the scene's check. */
static int check_names(obs_jpath *p, const json_t *v) {
  if (json_is_null(v)) return 0;
  if (!json_is_array(v))
    return obs_jpath_fail(p, "must be an array of object names or null (got %s)",
                          obs_json_brief(v));
  int bad = 0;
  size_t bytes = 0;
  for (size_t i = 0; i < json_array_size(v); i++) {
    const json_t *e = json_array_get(v, i);
    size_t m = obs_jpath_push_index(p, i);
    if (!json_is_string(e) || !json_string_length(e)) {
      bad |= obs_jpath_fail(p, "must be a non-empty string (got %s)", obs_json_brief(e)) != 0;
    } else {
      bytes += json_string_length(e) + 1;
      for (size_t j = 0; j < i; j++)
        if (json_equal((json_t *)e, json_array_get(v, j))) {
          bad |= obs_jpath_fail(p, "repeats item %zu (got %s)", j, obs_json_brief(e)) != 0;
          break;
        }
    }
    obs_jpath_pop(p, m);
  }
  if (!bad && bytes > OBS_PARAM_NAMES_BYTES)
    return obs_jpath_fail(p, "the names must take at most %d bytes with a terminator each (got %zu)",
                          OBS_PARAM_NAMES_BYTES, bytes);
  return bad ? OBS_EINVAL : 0;
}

int obs_param_names_has(const obs_param_names *n, const char *name) {
  if (n->count < 0) return 1;
  const char *at = n->text;
  for (int i = 0; i < n->count; i++, at += strlen(at) + 1)
    if (!strcmp(at, name)) return 1;
  return 0;
}

int obs_param_check(obs_jpath *p, const obs_param *d, const json_t *v) {
  int nullable = (d->flags & OBS_PARAM_NULLABLE) != 0;
  long long iv = 0;
  switch (d->type) {
    case OBS_PARAM_RGB:
      return check_rgb(p, d, v);
    case OBS_PARAM_NAMES:
      return check_names(p, v);
    case OBS_PARAM_BOOL:
      if (!json_is_boolean(v))
        return obs_jpath_fail(p, "must be boolean (got %s)", obs_json_brief(v));
      return 0;
    case OBS_PARAM_ENUM:
      for (int i = 0; json_is_string(v) && d->choices[i]; i++)
        if (!strcmp(d->choices[i], json_string_value(v))) return 0;
      return fail_one_of(p, d, v);
    case OBS_PARAM_INT:
    case OBS_PARAM_UINT:
      if (nullable && json_is_null(v)) return 0;
      if (!obs_json_as_int(v, &iv))
        return obs_jpath_fail(p, "must be an integer%s (got %s)", nullable ? " or null" : "",
                              obs_json_brief(v));
      if (d->values) {
        for (int i = 0; i < d->nvalues; i++)
          if (iv == d->values[i]) return 0;
        return fail_one_of(p, d, v);
      }
      break;
    default:
      if (nullable && json_is_null(v)) return 0;
      if (!obs_json_is_number(v))
        return obs_jpath_fail(p, "must be a number%s (got %s)", nullable ? " or null" : "",
                              obs_json_brief(v));
      break;
  }
  return check_range(p, d, v);
}

static const obs_param *find_param(const obs_technique *t, const char *name) {
  for (size_t i = 0; i < t->params_size; i++)
    if (!strcmp(t->params[i].name, name)) return &t->params[i];
  return NULL;
}

/* Edit distance (insert, delete, substitute, swap of neighbours) between two short names; names
 * longer than the table are treated as far away. */
static size_t name_distance(const char *a, const char *b) {
  enum { N = 64 };
  size_t la = strlen(a), lb = strlen(b);
  if (la >= N || lb >= N) return (size_t)-1;
  size_t d[N][N];
  for (size_t i = 0; i <= la; i++) d[i][0] = i;
  for (size_t j = 0; j <= lb; j++) d[0][j] = j;
  for (size_t i = 1; i <= la; i++)
    for (size_t j = 1; j <= lb; j++) {
      size_t best = d[i - 1][j - 1] + (a[i - 1] != b[j - 1]);
      if (d[i - 1][j] + 1 < best) best = d[i - 1][j] + 1;
      if (d[i][j - 1] + 1 < best) best = d[i][j - 1] + 1;
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] &&
          d[i - 2][j - 2] + 1 < best)
        best = d[i - 2][j - 2] + 1;
      d[i][j] = best;
    }
  return d[la][lb];
}

const char *obs_params_nearest(const obs_technique *t, const char *name) {
  const char *best = NULL;
  size_t best_d = (size_t)-1, len = strlen(name);
  /* A third of the name may be wrong (at least one letter, at most three). */
  size_t limit = len / 3 < 1 ? 1 : len / 3 > 3 ? 3 : len / 3;
  for (size_t i = 0; i < t->params_size; i++) {
    size_t dist = name_distance(name, t->params[i].name);
    if (dist <= limit && dist < best_d) {
      best_d = dist;
      best = t->params[i].name;
    }
  }
  return best;
}

/* "unknown parameter", with the nearest declared name when one is close. */
static int fail_unknown(obs_jpath *p, const obs_technique *t, const char *key) {
  const char *near = obs_params_nearest(t, key);
  if (near) return obs_jpath_fail(p, "unknown parameter (did you mean \"%s\"?)", near);
  return obs_jpath_fail(p, "unknown parameter");
}

json_t *obs_params_resolve(obs_jpath *p, const obs_technique *t, const json_t *value) {
  if (value && !json_is_object(value)) {
    obs_jpath_fail(p, "must be an object (got %s)", obs_json_brief(value));
    return NULL;
  }
  json_t *out = json_object();
  if (!out) {
    obs_err_set(p->err, OBS_ENOMEM, "%s: out of memory", p->doc);
    return NULL;
  }
  int bad = 0;
  const char *key;
  json_t *v;
  json_object_foreach((json_t *)value, key, v) {
    size_t m = obs_jpath_push_key(p, key);
    const obs_param *d = find_param(t, key);
    long long iv;
    if (!d) {
      fail_unknown(p, t, key);
      bad++;
    } else if (obs_param_check(p, d, v)) {
      bad++;
    } else if (is_int_type(d->type) && json_is_real(v) && obs_json_as_int(v, &iv)) {
      /* An integral real (64.0) given for an integer is stored as one. */
      json_object_set_new(out, key, json_integer((json_int_t)iv));
    } else {
      json_object_set(out, key, v);
    }
    obs_jpath_pop(p, m);
  }
  for (size_t i = 0; i < t->params_size; i++)
    if (!json_object_get(out, t->params[i].name))
      json_object_set_new(out, t->params[i].name, obs_param_default_json(&t->params[i]));
  if (bad) {
    json_decref(out);
    return NULL;
  }
  return out;
}

void obs_params_check_rules(const obs_technique *t, const json_t *params, const char *doc,
                            obs_err *err) {
  for (const obs_param_rule *r = t->rules; r && r->param; r++) {
    const char *v = json_string_value(json_object_get(params, r->param));
    if (v && !strcmp(v, r->value) && json_is_null(json_object_get(params, r->needs)))
      obs_err_set(err, OBS_EINVAL,
                  "%s: /technique/params/%s: %s \"%s\" needs a finite %s (got null)", doc, r->needs,
                  r->param, r->value, r->needs);
  }
}

/* Stores one checked value (NULL: the default) at its offset. */
static void store(const obs_param *d, const json_t *v, unsigned char *dst) {
  unsigned char *at = dst + d->offset;
  long long iv = 0;
  double x = d->def;
  int is_null = v ? json_is_null(v) : (d->flags & OBS_PARAM_DEFAULT_NULL) != 0;
  if (v && obs_json_is_number(v)) x = obs_json_number(v);
  if (v && is_int_type(d->type) && obs_json_as_int(v, &iv)) x = (double)iv;
  if (is_null && (d->flags & OBS_PARAM_NULLABLE)) x = d->null_value;
  switch (d->type) {
    case OBS_PARAM_BOOL: {
      int b = v ? json_is_true(v) : d->def != 0;
      memcpy(at, &b, sizeof b);
      break;
    }
    case OBS_PARAM_ENUM: {
      int idx = (int)d->def;
      for (int i = 0; v && d->choices[i]; i++)
        if (!strcmp(d->choices[i], json_string_value(v))) idx = i;
      memcpy(at, &idx, sizeof idx);
      break;
    }
    case OBS_PARAM_INT: {
      int32_t i = (int32_t)x;
      memcpy(at, &i, sizeof i);
      break;
    }
    case OBS_PARAM_UINT: {
      uint32_t u = (uint32_t)x;
      memcpy(at, &u, sizeof u);
      break;
    }
    case OBS_PARAM_FLOAT: {
      float f = (float)x;
      /* Rounding to float can carry a value onto an exclusive maximum (pi/2 rounds up): step back
       * one ulp so the bound the technique relies on still holds. A positive value below float's
       * range becomes 0, which the techniques document. */
      if ((d->flags & OBS_PARAM_MAX_EXCLUSIVE) && !is_null && (double)f >= d->max)
        f = nextafterf(f, -INFINITY);
      memcpy(at, &f, sizeof f);
      break;
    }
    case OBS_PARAM_DOUBLE:
      memcpy(at, &x, sizeof x);
      break;
    case OBS_PARAM_RGB: {
      double c[3] = {x, x, x};
      for (size_t i = 0; v && json_is_array(v) && i < 3; i++)
        c[i] = obs_json_number(json_array_get(v, i));
      memcpy(at, c, sizeof c);
      break;
    }
    case OBS_PARAM_NAMES: {
      obs_param_names n = {.count = -1};
      if (v && json_is_array(v)) {
        size_t used = 0;
        n.count = (int)json_array_size(v);
        for (int i = 0; i < n.count; i++) {
          const char *s = json_string_value(json_array_get(v, (size_t)i));
          memcpy(n.text + used, s, strlen(s) + 1);
          used += strlen(s) + 1;
        }
      }
      memcpy(at, &n, sizeof n);
      break;
    }
  }
}

int obs_params_bind(const obs_technique *t, const json_t *params, void *dst, obs_err *err) {
  if (!t || !dst) return obs_err_set(err, OBS_EINVAL, "params: no technique or destination");
  char doc[96];
  snprintf(doc, sizeof doc, "%s params", t->name);
  obs_jpath p;
  obs_jpath_init(&p, doc, err);
  if (params && !json_is_object(params))
    return obs_jpath_fail(&p, "must be an object (got %s)", obs_json_brief(params));
  int bad = 0;
  const char *key;
  json_t *v;
  json_object_foreach((json_t *)params, key, v) {
    size_t m = obs_jpath_push_key(&p, key);
    const obs_param *d = find_param(t, key);
    if (!d)
      bad |= fail_unknown(&p, t, key) != 0;
    else
      bad |= obs_param_check(&p, d, v) != 0;
    obs_jpath_pop(&p, m);
  }
  if (bad) return OBS_EINVAL;
  memset(dst, 0, t->bound_size);
  for (size_t i = 0; i < t->params_size; i++)
    store(&t->params[i], json_object_get(params, t->params[i].name), dst);
  return 0;
}

int obs_params_bind_new(const obs_technique *t, const json_t *params, void **out, obs_err *err) {
  *out = NULL;
  void *b = calloc(1, t && t->bound_size ? t->bound_size : 1);
  if (!b) return obs_err_set(err, OBS_ENOMEM, "params: out of memory");
  int rc = obs_params_bind(t, params, b, err);
  if (rc) {
    free(b);
    return rc;
  }
  *out = b;
  return 0;
}

json_t *obs_param_schema(const obs_param *d) {
  json_t *o = json_object();
  static const char *const type_names[] = {[OBS_PARAM_BOOL] = "boolean",
                                           [OBS_PARAM_INT] = "integer",
                                           [OBS_PARAM_UINT] = "integer",
                                           [OBS_PARAM_FLOAT] = "number",
                                           [OBS_PARAM_DOUBLE] = "number",
                                           [OBS_PARAM_RGB] = "array"};
  if (d->type == OBS_PARAM_NAMES) {
    json_object_set_new(o, "type", json_pack("[ss]", "array", "null"));
    json_object_set_new(o, "items", json_pack("{sssi}", "type", "string", "minLength", 1));
    json_object_set_new(o, "uniqueItems", json_true());
  } else if (d->type == OBS_PARAM_ENUM) {
    json_t *e = json_array();
    for (int i = 0; d->choices[i]; i++) json_array_append_new(e, json_string(d->choices[i]));
    json_object_set_new(o, "enum", e);
  } else if (d->flags & OBS_PARAM_NULLABLE) {
    json_object_set_new(o, "type", json_pack("[ss]", type_names[d->type], "null"));
  } else {
    json_object_set_new(o, "type", json_string(type_names[d->type]));
  }
  if (is_int_type(d->type) && d->values) {
    json_t *e = json_array();
    for (int i = 0; i < d->nvalues; i++) json_array_append_new(e, json_integer(d->values[i]));
    json_object_set_new(o, "enum", e);
  } else if (has_range(d->type)) {
    /* An RGB's range bounds its components: it goes on the items. */
    json_t *r = o;
    if (d->type == OBS_PARAM_RGB) {
      r = json_pack("{ss}", "type", "number");
      json_object_set_new(o, "items", r);
      json_object_set_new(o, "minItems", json_integer(3));
      json_object_set_new(o, "maxItems", json_integer(3));
    }
    if (!isinf(d->min))
      json_object_set_new(r, d->flags & OBS_PARAM_MIN_EXCLUSIVE ? "exclusiveMinimum" : "minimum",
                          number_json(d->min));
    if (!isinf(d->max))
      json_object_set_new(r, d->flags & OBS_PARAM_MAX_EXCLUSIVE ? "exclusiveMaximum" : "maximum",
                          number_json(d->max));
  }
  json_object_set_new(o, "default", obs_param_default_json(d));
  json_object_set_new(o, "description", json_string(d->description ? d->description : ""));
  return o;
}

static size_t type_size(obs_param_type t) {
  switch (t) {
    case OBS_PARAM_RGB:
      return 3 * sizeof(double);
    case OBS_PARAM_NAMES:
      return sizeof(obs_param_names);
    case OBS_PARAM_DOUBLE:
      return sizeof(double);
    case OBS_PARAM_FLOAT:
      return sizeof(float);
    case OBS_PARAM_INT:
      return sizeof(int32_t);
    case OBS_PARAM_UINT:
      return sizeof(uint32_t);
    default:
      return sizeof(int);
  }
}

int obs_param_entry_fault(const obs_param *d, size_t bound_size, char *why, size_t n) {
  int nullable = (d->flags & OBS_PARAM_NULLABLE) != 0;
  if ((unsigned)d->type > OBS_PARAM_NAMES) return snprintf(why, n, "unknown type %d", d->type);
  size_t sz = type_size(d->type), align = d->type == OBS_PARAM_RGB     ? sizeof(double)
                                          : d->type == OBS_PARAM_NAMES ? sizeof(int)
                                                                       : sz;
  if (!d->description || !*d->description) return snprintf(why, n, "has no description");
  if (d->offset + sz > bound_size || d->offset % align)
    return snprintf(why, n, "offset %zu does not hold a %zu-byte member inside %zu bytes",
                    d->offset, sz, bound_size);
  if ((nullable || (d->flags & OBS_PARAM_DEFAULT_NULL)) && !has_range(d->type))
    return snprintf(why, n, "only numbers and RGBs can be null");
  if ((d->flags & OBS_PARAM_DEFAULT_NULL) && !nullable)
    return snprintf(why, n, "a null default needs OBS_PARAM_NULLABLE");
  if (d->type == OBS_PARAM_ENUM && (!d->choices || !d->choices[0]))
    return snprintf(why, n, "an enum needs choices");
  if (d->values && (!is_int_type(d->type) || d->nvalues < 1))
    return snprintf(why, n, "a list of values needs an integer type and at least one value");
  if (has_range(d->type) && !d->values) {
    double lo = is_int_type(d->type) ? (d->type == OBS_PARAM_UINT ? 0 : INT32_MIN) : -INFINITY;
    double hi = d->type == OBS_PARAM_UINT  ? UINT32_MAX
                : d->type == OBS_PARAM_INT ? INT32_MAX
                                           : INFINITY;
    if (d->type == OBS_PARAM_FLOAT) lo = -FLT_MAX, hi = FLT_MAX;
    if (!(d->min >= lo && d->max <= hi && d->min <= d->max))
      return snprintf(why, n, "range [%g, %g] is empty or beyond what its type stores", d->min,
                      d->max);
    if (is_int_type(d->type) && (d->min != floor(d->min) || d->max != floor(d->max)))
      return snprintf(why, n, "integer bounds must be integers");
  }
  return 0;
}
