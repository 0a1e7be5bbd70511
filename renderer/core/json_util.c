/* Strict JSON reading for scene documents: every problem is reported with its JSON pointer. */
#include "json_util.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

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

const char *obs_json_brief(const json_t *v) {
  static _Thread_local char buf[72];
  if (!v) return "nothing";
  char *s = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(10));
  if (!s) return "?";
  size_t n = strlen(s);
  if (n > 60) {
    memcpy(buf, s, 57);
    memcpy(buf + 57, "...", 4);
  } else {
    memcpy(buf, s, n + 1);
  }
  free(s);
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

/* One parameter value against its schema entry. */
static int param_check(obs_jpath *p, const json_t *sch, const json_t *v) {
  json_t *type = json_object_get(sch, "type");
  json_t *en = json_object_get(sch, "enum");
  if (type) {
    int ok = 0;
    size_t n = json_is_array(type) ? json_array_size(type) : 1;
    char names[128] = "";
    for (size_t i = 0; i < n; i++) {
      const char *t = json_string_value(json_is_array(type) ? json_array_get(type, i) : type);
      long long dummy;
      if (!t) continue;
      if ((!strcmp(t, "number") && obs_json_is_number(v)) ||
          (!strcmp(t, "integer") && obs_json_as_int(v, &dummy)) ||
          (!strcmp(t, "string") && json_is_string(v)) ||
          (!strcmp(t, "boolean") && json_is_boolean(v)) || (!strcmp(t, "null") && json_is_null(v)))
        ok = 1;
      size_t l = strlen(names);
      snprintf(names + l, sizeof names - l, "%s%s", l ? " or " : "",
               !strcmp(t, "integer") ? "an integer"
               : !strcmp(t, "number") ? "a number"
               : !strcmp(t, "null")   ? "null"
                                      : t);
    }
    if (!ok) return obs_jpath_fail(p, "must be %s (got %s)", names, obs_json_brief(v));
  }
  if (en) {
    size_t i;
    json_t *c;
    char list[256] = "";
    json_array_foreach(en, i, c) {
      if (json_equal((json_t *)c, (json_t *)v)) return 0;
      size_t l = strlen(list);
      char *s = json_dumps(c, JSON_ENCODE_ANY);
      snprintf(list + l, sizeof list - l, "%s%s", l ? ", " : "", s ? s : "?");
      free(s);
    }
    return obs_jpath_fail(p, "must be one of %s (got %s)", list, obs_json_brief(v));
  }
  if (obs_json_is_number(v)) {
    double d = obs_json_number(v);
    json_t *b;
    if ((b = json_object_get(sch, "minimum")) && !(d >= json_number_value(b)))
      return obs_jpath_fail(p, "must be >= %.10g (got %s)", json_number_value(b),
                            obs_json_brief(v));
    if ((b = json_object_get(sch, "exclusiveMinimum")) && !(d > json_number_value(b)))
      return obs_jpath_fail(p, "must be > %.10g (got %s)", json_number_value(b), obs_json_brief(v));
    if ((b = json_object_get(sch, "maximum")) && !(d <= json_number_value(b)))
      return obs_jpath_fail(p, "must be <= %.10g (got %s)", json_number_value(b),
                            obs_json_brief(v));
    if ((b = json_object_get(sch, "exclusiveMaximum")) && !(d < json_number_value(b)))
      return obs_jpath_fail(p, "must be < %.10g (got %s)", json_number_value(b), obs_json_brief(v));
  }
  return 0;
}

json_t *obs_json_params_resolve(obs_jpath *p, const json_t *schema, const json_t *value) {
  json_t *props = json_object_get(schema, "properties");
  int bad = 0;
  if (value && !json_is_object(value)) {
    obs_jpath_fail(p, "must be an object (got %s)", obs_json_brief(value));
    return NULL;
  }
  json_t *out = json_object();
  if (value) {
    const char *key;
    json_t *v;
    json_object_foreach((json_t *)value, key, v) {
      size_t m = obs_jpath_push_key(p, key);
      json_t *sch = json_object_get(props, key);
      if (!sch) {
        obs_jpath_fail(p, "unknown parameter");
        bad++;
      } else if (param_check(p, sch, v)) {
        bad++;
      } else {
        /* An integral real (64.0) passed as an integer: store a true integer so readers that
         * ask for one get it, not 0. */
        long long iv;
        json_t *type = json_object_get(sch, "type");
        int want_int = json_is_string(type) && !strcmp(json_string_value(type), "integer");
        if (want_int && json_is_real(v) && obs_json_as_int(v, &iv))
          json_object_set_new(out, key, json_integer((json_int_t)iv));
        else
          json_object_set(out, key, v);
      }
      obs_jpath_pop(p, m);
    }
  }
  const char *key;
  json_t *sch;
  json_object_foreach(props, key, sch) {
    json_t *def = json_object_get(sch, "default");
    if (!json_object_get(out, key) && def) json_object_set(out, key, def);
  }
  if (bad) {
    json_decref(out);
    return NULL;
  }
  return out;
}
