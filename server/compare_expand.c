/* POST /api/v1/comparisons, first step: a request's candidate entries expanded into one
 * candidate per combination of listed parameter values and backends (docs/comparisons.md). */
#include <jansson.h>
#include <math.h>
#include <microhttpd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "compare_internal.h"
#include "json_util.h"
#include "obscurad.h"

#define MAX_CANDIDATES 256
#define MAX_LIST 64 /* values in one list of a grid */

void srv_compare_expansion_free(expansion *x) {
  for (int i = 0; i < x->n; i++) {
    json_decref(x->c[i].params);
    json_decref(x->c[i].pos);
    free(x->c[i].doc);
    free(x->c[i].params_full);
    free(x->c[i].ref_key);
    free(x->c[i].common_key);
    for (int k = 0; k < x->c[i].nalt; k++) free(x->c[i].alt_key[k]);
  }
  for (int i = 0; i < x->nrefs; i++) {
    free(x->refs[i].doc);
    free(x->refs[i].key);
  }
  free(x->c);
  free(x->refs);
  memset(x, 0, sizeof *x);
}

/* Whether parameter `key` of technique `t` is itself an array (never expanded). */
static int param_is_array(const obs_technique *t, const char *key) {
  json_t *schema = obs_technique_params_schema(t);
  json_t *type =
      json_object_get(json_object_get(json_object_get(schema, "properties"), key), "type");
  int arr = json_is_string(type) && !strcmp(json_string_value(type), "array");
  for (size_t i = 0; json_is_array(type) && i < json_array_size(type); i++) {
    const char *ti = json_string_value(json_array_get(type, i));
    if (ti && !strcmp(ti, "array")) arr = 1;
  }
  json_decref(schema);
  return arr;
}

/* An entry's backends (p at its "backend"): a string or a list of 1-2; absent = every backend the
 * technique has here. Fills bes/nb and *listed; returns 1 when a problem was reported. */
static int entry_backends(const srv_app *app, obs_jpath *p, const obs_technique *t,
                          const json_t *bv, obs_backend bes[8], int *nb, int *listed) {
  int bad = 0;
  *nb = 0;
  *listed = 0;
  if (!bv) {
    for (int b = OBS_BACKEND_CPU; t && b < OBS_BACKEND_COUNT; b++)
      if (t->run[b] && (b != OBS_BACKEND_VULKAN || app->vulkan_lane)) bes[(*nb)++] = (obs_backend)b;
    return 0;
  }
  if (!json_is_string(bv) && !json_is_array(bv)) {
    obs_jpath_fail(p, "must be \"cpu\", \"vulkan\" or a list of them (got %s)", obs_json_brief(bv));
    return 1;
  }
  *listed = json_is_array(bv);
  size_t n = *listed ? json_array_size(bv) : 1;
  if (*listed && (n == 0 || n > 2)) {
    obs_jpath_fail(p, "must list 1 or 2 backends (got %zu)", n);
    return 1;
  }
  for (size_t j = 0; !bad && j < n; j++) {
    json_t *v = *listed ? json_array_get(bv, j) : (json_t *)bv;
    size_t q = *listed ? obs_jpath_push_index(p, j) : p->len;
    obs_backend b = OBS_BACKEND_AUTO;
    if (obs_backend_parse(json_string_value(v), &b) || b == OBS_BACKEND_AUTO) {
      obs_jpath_fail(p, "must be \"cpu\" or \"vulkan\" (got %s)", obs_json_brief(v));
      bad = 1;
    } else {
      for (int q2 = 0; q2 < *nb; q2++)
        if (bes[q2] == b) {
          obs_jpath_fail(p, "is listed twice (got %s)", obs_json_brief(v));
          bad = 1;
        }
      bes[(*nb)++] = b;
    }
    if (*listed) obs_jpath_pop(p, q);
  }
  return bad;
}

/* The list-valued parameters of an entry: their names and list lengths. */
typedef struct grid {
  const char *keyv[64];
  size_t lens[64];
  int nk;
} grid;

/* The grid of an entry's parameters (p at its "params"): every list-valued parameter, unless the
 * parameter is itself an array. Fills g and multiplies *combos; returns 1 when a problem was
 * reported. */
static int entry_grid(obs_jpath *p, const obs_technique *t, const json_t *params, grid *g,
                      double *combos) {
  int bad = 0;
  const char *key;
  json_t *v;
  g->nk = 0;
  json_object_foreach((json_t *)params, key, v) {
    if (!json_is_array(v) || (t && param_is_array(t, key))) continue;
    size_t q = obs_jpath_push_key(p, key);
    if (json_array_size(v) == 0) {
      obs_jpath_fail(p, "an empty list gives no candidates: give at least one value");
      bad = 1;
    } else if (json_array_size(v) > MAX_LIST) {
      obs_jpath_fail(p, "must list at most %d values (got %zu)", MAX_LIST, json_array_size(v));
      bad = 1;
    } else if (g->nk < 64) {
      g->keyv[g->nk] = key;
      g->lens[g->nk++] = json_array_size(v);
      *combos *= (double)json_array_size(v);
    }
    obs_jpath_pop(p, q);
  }
  return bad;
}

/* Appends entry `i`'s Cartesian product to x: backends outermost, then the parameters in request
 * order, the last varying fastest. Returns -1 (reported) when out of memory. */
static int entry_product(obs_jpath *p, expansion *x, int i, const obs_technique *t,
                         const char *against, const obs_backend *bes, int nb, int listed,
                         const json_t *params, const grid *g) {
  for (int bi = 0; bi < nb; bi++) {
    size_t idx[64] = {0};
    for (;;) {
      if (x->n == x->cap) {
        x->cap = x->cap ? 2 * x->cap : 16;
        cand *nc = realloc(x->c, (size_t)x->cap * sizeof *nc);
        if (!nc) {
          /* Never accept a truncated grid. */
          obs_jpath_fail(p, "out of memory expanding the grid");
          return -1;
        }
        x->c = nc;
      }
      cand *c = &x->c[x->n++];
      memset(c, 0, sizeof *c);
      c->common_ref = -1;
      c->entry = i;
      c->t = t;
      c->against = against;
      c->backend = bes[bi];
      c->backend_pos = listed ? bi : -1;
      /* Shallow: only top-level keys are replaced below, so candidates share the rest of the
       * entry's parameters instead of each holding a copy of them. */
      c->params = params ? json_copy((json_t *)params) : json_object();
      c->pos = json_object();
      for (int q = 0; q < g->nk; q++) {
        json_object_set(c->params, g->keyv[q],
                        json_array_get(json_object_get(params, g->keyv[q]), idx[q]));
        json_object_set_new(c->pos, g->keyv[q], json_integer((json_int_t)idx[q]));
      }
      int q = g->nk - 1;
      while (q >= 0 && ++idx[q] == g->lens[q]) idx[q--] = 0;
      if (q < 0) break;
    }
  }
  return 0;
}

void srv_compare_expand(srv_app *app, obs_jpath *p, const json_t *cands, expansion *x) {
  double total = 0;
  size_t ne = json_array_size(cands);
  size_t top = obs_jpath_push_key(p, "candidates");
  for (size_t i = 0; i < ne; i++) {
    json_t *e = json_array_get(cands, i);
    size_t m = obs_jpath_push_index(p, i);
    if (!json_is_object(e)) {
      obs_jpath_fail(p,
                     "must be an object like {\"technique\": \"hbao\", \"backend\": [\"cpu\"], "
                     "\"params\": {\"directions\": [4, 8]}} (got %s)",
                     obs_json_brief(e));
      obs_jpath_pop(p, m);
      continue;
    }
    static const char *const keys[] = {"technique", "backend", "params", "against", NULL};
    obs_json_check_keys(p, e, keys);
    /* Another reference than the technique's own (obs_reference_alt), checked per candidate. */
    const char *against = NULL;
    json_t *av = json_object_get(e, "against");
    if (av && !json_is_null(av)) obs_json_get_string(p, e, "against", 0, NULL, &against);
    const char *tn = NULL;
    const obs_technique *t = NULL;
    if (!obs_json_get_string(p, e, "technique", 1, NULL, &tn) && !(t = obs_technique_find(tn))) {
      size_t k = obs_jpath_push_key(p, "technique");
      obs_jpath_fail(p, "not a technique (got %s; GET /api/v1/techniques lists them)",
                     obs_json_brief(json_object_get(e, "technique")));
      obs_jpath_pop(p, k);
    }
    obs_backend bes[8];
    int nb = 0, listed = 0;
    size_t k = obs_jpath_push_key(p, "backend");
    int bad = entry_backends(app, p, t, json_object_get(e, "backend"), bes, &nb, &listed);
    obs_jpath_pop(p, k);
    int absent = 0;
    json_t *params = obs_json_get_object(p, e, "params", 0, &absent);
    grid g;
    double combos = nb;
    k = obs_jpath_push_key(p, "params");
    bad |= entry_grid(p, t, params, &g, &combos);
    obs_jpath_pop(p, k);
    obs_jpath_pop(p, m);
    total += combos;
    if (!t || bad || !nb || (params == NULL && !absent) || p->err->count) continue;
    if (total > MAX_CANDIDATES) continue; /* reported once below */
    if (entry_product(p, x, (int)i, t, against, bes, nb, listed, params, &g)) return;
  }
  if (total > MAX_CANDIDATES)
    obs_jpath_fail(p, "expands to %.0f candidates; at most %d per comparison", total,
                   MAX_CANDIDATES);
  obs_jpath_pop(p, top);
}
