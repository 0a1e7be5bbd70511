/* Texts generated from the technique registry, of which the repository keeps copies that tests
 * compare: the technique part of schema/scene.schema.json, the parameter tables of
 * docs/techniques/<name>.md and the registry block of schema/openapi.yaml
 * (scripts/gen-registry.sh writes them). */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/technique.h"
#include "params.h"
#include "strbuf.h"

/* The shortest text that reads back as the same double (1e+30, 0.01, 1.5707963267948966). */
static void shortest(double v, char *buf, size_t n) {
  for (int prec = 1; prec <= 17; prec++) {
    snprintf(buf, n, "%.*g", prec, v);
    if (strtod(buf, NULL) == v) return;
  }
}

/* ---- JSON with short numbers, one line per member except where a value fits on one ------- */

static int is_leaf(const json_t *v) {
  if (json_is_array(v)) {
    for (size_t i = 0; i < json_array_size(v); i++)
      if (json_is_object(json_array_get(v, i)) || json_is_array(json_array_get(v, i))) return 0;
    return 1;
  }
  if (!json_is_object(v)) return 1;
  const char *k;
  json_t *x;
  json_object_foreach((json_t *)v, k, x) {
    if (json_is_object(x)) return 0;
    if (json_is_array(x) && !is_leaf(x)) return 0;
  }
  return 1;
}

static void put_inline(obs_strbuf *b, const json_t *v) {
  char num[40];
  if (json_is_object(v)) {
    const char *k;
    json_t *x;
    int first = 1;
    obs_strbuf_put(b, "{");
    json_object_foreach((json_t *)v, k, x) {
      json_t *key = json_string(k);
      char *ks = json_dumps(key, JSON_ENCODE_ANY);
      obs_strbuf_put(b, "%s%s: ", first ? "" : ", ", ks ? ks : "\"?\"");
      free(ks);
      json_decref(key);
      put_inline(b, x);
      first = 0;
    }
    obs_strbuf_put(b, "}");
  } else if (json_is_array(v)) {
    obs_strbuf_put(b, "[");
    for (size_t i = 0; i < json_array_size(v); i++) {
      obs_strbuf_put(b, "%s", i ? ", " : "");
      put_inline(b, json_array_get(v, i));
    }
    obs_strbuf_put(b, "]");
  } else if (json_is_real(v)) {
    shortest(json_real_value(v), num, sizeof num);
    obs_strbuf_put(b, "%s", num);
  } else {
    char *s = json_dumps(v, JSON_ENCODE_ANY);
    obs_strbuf_put(b, "%s", s ? s : "null");
    free(s);
  }
}

/* Writes v at `indent`; members of an object or array that fit within 100 columns, and every
 * leaf (an object of scalars, such as one parameter), stay on one line. */
static void put_json(obs_strbuf *b, const json_t *v, int indent, int column) {
  obs_strbuf probe = {0};
  put_inline(&probe, v);
  int fits = !probe.failed && (size_t)column + probe.len <= 100;
  free(probe.s);
  if (fits || is_leaf(v) || !(json_is_object(v) || json_is_array(v))) {
    put_inline(b, v);
    return;
  }
  int obj = json_is_object(v);
  obs_strbuf_put(b, "%s\n", obj ? "{" : "[");
  size_t n = obj ? json_object_size(v) : json_array_size(v), i = 0;
  if (obj) {
    const char *k;
    json_t *x;
    json_object_foreach((json_t *)v, k, x) {
      json_t *key = json_string(k);
      char *ks = json_dumps(key, JSON_ENCODE_ANY);
      obs_strbuf_put(b, "%*s%s: ", indent + 2, "", ks ? ks : "\"?\"");
      put_json(b, x, indent + 2, indent + 4 + (int)(ks ? strlen(ks) : 3));
      obs_strbuf_put(b, "%s\n", ++i < n ? "," : "");
      free(ks);
      json_decref(key);
    }
  } else {
    for (; i < n;) {
      obs_strbuf_put(b, "%*s", indent + 2, "");
      put_json(b, json_array_get(v, i), indent + 2, indent + 2);
      obs_strbuf_put(b, "%s\n", ++i < n ? "," : "");
    }
  }
  obs_strbuf_put(b, "%*s%s", indent, "", obj ? "}" : "]");
}

/* ---- schema/scene.schema.json ------------------------------------------------------------- */

static json_t *technique_def(void) {
  json_t *names = json_array(), *backends = json_array(), *all = json_array();
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const char *name = obs_technique_at(i)->name;
    char ref[160];
    snprintf(ref, sizeof ref, "#/$defs/%s_params", name);
    json_array_append_new(names, json_string(name));
    json_array_append_new(
        all, json_pack("{s{s{s{ss}}s[s]}s{s{s{ss}}}}", "if", "properties", "name", "const", name,
                       "required", "name", "then", "properties", "params", "$ref", ref));
  }
  for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++)
    json_array_append_new(backends, json_string(obs_backend_name((obs_backend)b)));
  json_array_append_new(backends, json_string(obs_backend_name(OBS_BACKEND_AUTO)));
  return json_pack(
      "{sssssbs[s]s{s{ssso}s{sssoss}s{ssss}}so}", "description",
      "Which technique renders the scene, on which backend, with which parameters. This member "
      "and the <name>_params members after it are generated from the technique registry "
      "(scripts/gen-registry.sh); the test cli.registry_schema compares them.",
      "type", "object", "additionalProperties", 0, "required", "name", "properties", "name",
      "description", "A technique from the registry (`obscura techniques`).", "enum", names,
      "backend", "description", "Backend; auto picks the best available one.", "enum", backends,
      "default", "auto", "params", "description",
      "Technique parameters; see the technique's $defs entry.", "type", "object", "allOf", all);
}

static json_t *params_def(const obs_technique *t) {
  json_t *s = obs_technique_params_schema(t);
  char desc[600];
  snprintf(desc, sizeof desc, "Parameters of %s: %s.%s", t->name, t->description,
           t->rules && t->rules->param ? " Cross-field rules in allOf." : "");
  json_t *o = json_pack("{ss}", "description", desc);
  json_object_update(o, s);
  json_decref(s);
  if (t->rules && t->rules->param) {
    /* when param is value, needs is required and a number (not null) */
    json_t *all = json_array();
    for (const obs_param_rule *r = t->rules; r->param; r++)
      json_array_append_new(
          all, json_pack("{s:{s:{s:{s:s}}, s:[s]}, s:{s:[s], s:{s:{s:s}}}}", "if", "properties",
                         r->param, "const", r->value, "required", r->param, "then", "required",
                         r->needs, "properties", r->needs, "type", "number"));
    json_object_set_new(o, "allOf", all);
  }
  return o;
}

char *obs_registry_scene_schema(void) {
  obs_strbuf b = {0};
  json_t *tech = technique_def();
  obs_strbuf_put(&b, "    \"technique\": ");
  put_json(&b, tech, 4, 17);
  json_decref(tech);
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    json_t *d = params_def(t);
    obs_strbuf_put(&b, ",\n    \"%s_params\": ", t->name);
    put_json(&b, d, 4, 15 + (int)strlen(t->name));
    json_decref(d);
  }
  obs_strbuf_put(&b, "\n");
  return obs_strbuf_finish(&b);
}

/* ---- docs/techniques/<name>.md --------------------------------------------------------------- */

static void put_cell(obs_strbuf *b, const char *s) {
  for (; *s; s++) obs_strbuf_put(b, *s == '|' ? "\\|" : "%c", *s);
}

static void put_range(obs_strbuf *b, const obs_param *p) {
  char lo[40], hi[40];
  if (p->type == OBS_PARAM_BOOL || p->type == OBS_PARAM_ENUM) return;
  if (p->type == OBS_PARAM_NAMES) {
    obs_strbuf_put(b, "names of the scene's objects");
    return;
  }
  if (p->values) {
    obs_strbuf_put(b, "one of ");
    for (int i = 0; i < p->nvalues; i++) obs_strbuf_put(b, "%s%d", i ? ", " : "", p->values[i]);
    return;
  }
  shortest(p->min, lo, sizeof lo);
  shortest(p->max, hi, sizeof hi);
  obs_strbuf_put(b, "%s%s, %s%s", p->flags & OBS_PARAM_MIN_EXCLUSIVE ? "(" : "[", lo, hi,
                 p->flags & OBS_PARAM_MAX_EXCLUSIVE ? ")" : "]");
}

char *obs_registry_params_markdown(const char *technique) {
  const obs_technique *t = obs_technique_find(technique);
  if (!t) return NULL;
  static const char *const types[] = {[OBS_PARAM_BOOL] = "boolean",
                                      [OBS_PARAM_INT] = "integer (int32)",
                                      [OBS_PARAM_UINT] = "integer (uint32)",
                                      [OBS_PARAM_FLOAT] = "number (float32)",
                                      [OBS_PARAM_DOUBLE] = "number (float64)",
                                      [OBS_PARAM_ENUM] = "string",
                                      [OBS_PARAM_RGB] = "[R, G, B] (float64)",
                                      [OBS_PARAM_NAMES] = "array of strings or null"};
  obs_strbuf b = {0};
  obs_strbuf_put(&b, "| name | type | default | range | description |\n|---|---|---|---|---|\n");
  for (size_t i = 0; i < t->params_size; i++) {
    const obs_param *p = &t->params[i];
    obs_strbuf_put(&b, "| `%s` | ", p->name);
    if (p->type == OBS_PARAM_ENUM) {
      for (int c = 0; p->choices[c]; c++)
        obs_strbuf_put(&b, "%s`%s`", c ? " \\| " : "", p->choices[c]);
    } else {
      obs_strbuf_put(&b, "%s%s", types[p->type], p->flags & OBS_PARAM_NULLABLE ? " or null" : "");
    }
    json_t *def = obs_param_default_json(p);
    obs_strbuf d = {0};
    if (json_is_string(def))
      obs_strbuf_put(&d, "`%s`", json_string_value(def));
    else
      put_inline(&d, def);
    json_decref(def);
    obs_strbuf_put(&b, " | %s | ", d.s ? d.s : "");
    free(d.s);
    put_range(&b, p);
    obs_strbuf_put(&b, " | ");
    put_cell(&b, p->description);
    obs_strbuf_put(&b, " |\n");
  }
  obs_strbuf_put(
      &b, "\nWork per pixel sample in the server's limits (the descriptor's cost hook): %s.\n",
      t->cost_rule ? t->cost_rule : "1");
  return obs_strbuf_finish(&b);
}

/* ---- schema/openapi.yaml ----------------------------------------------------------------------
 */

char *obs_registry_openapi(void) {
  obs_strbuf b = {0};
  obs_strbuf_put(&b,
                 "    TechniqueName:\n      description: A technique of the registry (GET "
                 "/api/v1/techniques).\n      type: string\n      enum: [");
  for (size_t i = 0; i < obs_technique_count(); i++)
    obs_strbuf_put(&b, "%s%s", i ? ", " : "", obs_technique_at(i)->name);
  obs_strbuf_put(&b, "]\n");
  /* Every file a registered technique's job may record (the route's name parameter). */
  char files[64][OBS_OUTPUT_FILE_MAX];
  size_t nf = obs_output_file_names(files, 64);
  obs_strbuf_put(&b,
                 "    OutputFileName:\n      description: A file the registered techniques write "
                 "(their declared outputs'\n        EXR, PNGs and per-patch files, and "
                 "summary.json).\n      type: string\n      enum: [");
  for (size_t i = 0; i < nf; i++) obs_strbuf_put(&b, "%s%s", i ? ", " : "", files[i]);
  obs_strbuf_put(&b, "]\n");
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    json_t *s = obs_technique_params_schema(t);
    obs_strbuf_put(&b, "    %s_params: ", t->name);
    put_json(&b, s, 6, 12 + (int)strlen(t->name));
    obs_strbuf_put(&b, "\n");
    json_decref(s);
  }
  return obs_strbuf_finish(&b);
}
