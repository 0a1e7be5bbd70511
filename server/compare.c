/* Speed/accuracy comparisons (docs/comparisons.md): expanding a request into candidate and
 * reference jobs, the comparison API (JSON and CSV), the metrics step that runs when a candidate
 * and its reference have both succeeded, and the time-budget choice of POST /api/v1/jobs. */
#include <jansson.h>
#include <math.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "json_util.h"
#include "obscurad.h"

#define API "/api/v1"
#define MAX_CANDIDATES 256
#define MAX_LIST 64          /* values in one list of a grid */
#define MAX_PROBLEMS 100     /* problems reported for one request (the rest are summarised) */
#define DEFAULT_REPEATS 3
#define REF_SAMPLES 1024
#define REF_SEED 7919        /* independent of candidates' default seed 1 */
#define MAX_LABEL 256
/* Every candidate and reference is a whole scene document, kept as text until the comparison is
 * stored: the values of the scene times the documents made from it are bounded (the largest
 * bundled scene, 445 values, fits 256 candidates 17 times over). */
#define MAX_EXPANDED_VALUES 4000000

/* ---- small helpers --------------------------------------------------------------------------- */

/* JSON cannot carry NaN or infinities: such a number is shown as null. */
static json_t *num_or_null(double v) { return isfinite(v) ? json_real(v) : json_null(); }


/* The comparison's state from its counts (docs/comparisons.md): running while a job is queued or
 * running, or while finished candidates still wait for their metrics; failed when a candidate can
 * no longer get metrics; succeeded when all have them. */
static const char *state_of(const json_t *row) {
  json_int_t active = json_integer_value(json_object_get(row, "active"));
  json_int_t broken = json_integer_value(json_object_get(row, "broken"));
  json_int_t measured = json_integer_value(json_object_get(row, "measured"));
  json_int_t total = json_integer_value(json_object_get(row, "candidates"));
  if (active) return "running";
  if (broken) return "failed";
  return measured == total ? "succeeded" : "running";
}


/* ---- POST /api/v1/comparisons: expansion and validation -------------------------------------- */

/* One expanded candidate. */
typedef struct cand {
  int entry;              /* index into the request's candidates */
  const obs_technique *t;
  obs_backend backend;
  int backend_pos;        /* index in the entry's backend list, -1 when a single string */
  json_t *params;         /* this combination's parameter values (owned) */
  json_t *pos;            /* key -> index in that parameter's list (owned; only listed keys) */
  /* Filled once validated: */
  char *doc, *params_full, *ref_key;
  int width, height, spp;
  double work;
  obs_response response;
  int ref;                /* index into the references */
} cand;

typedef struct ref_job {
  char *doc, *key; /* key: the reference's rt_ao params, canonical JSON */
  int width, height, spp;
  double work;
  obs_backend backend;
} ref_job;

typedef struct expansion {
  cand *c;
  int n, cap;
  ref_job *refs;
  int nrefs;
} expansion;

static void expansion_free(expansion *x) {
  for (int i = 0; i < x->n; i++) {
    json_decref(x->c[i].params);
    json_decref(x->c[i].pos);
    free(x->c[i].doc);
    free(x->c[i].params_full);
    free(x->c[i].ref_key);
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
  json_t *schema = json_loads(t->params_schema, 0, NULL);
  json_t *type = json_object_get(json_object_get(json_object_get(schema, "properties"), key),
                                 "type");
  int arr = json_is_string(type) && !strcmp(json_string_value(type), "array");
  for (size_t i = 0; json_is_array(type) && i < json_array_size(type); i++) {
    const char *ti = json_string_value(json_array_get(type, i));
    if (ti && !strcmp(ti, "array")) arr = 1;
  }
  json_decref(schema);
  return arr;
}

/* Adds one problem unless the same text is already listed (a bad value shows up in every
 * combination it takes part in) or the list is full. */
static void add_problem(obs_err *problems, int *dropped, const char *line) {
  const char *t = problems->text;
  size_t n = strlen(line);
  for (const char *p = t; p && *p;) {
    const char *e = strchr(p, '\n');
    size_t len = e ? (size_t)(e - p) : strlen(p);
    if (len == n && !strncmp(p, line, n)) return;
    p = e ? e + 1 : p + len;
  }
  if (problems->count >= MAX_PROBLEMS) {
    (*dropped)++;
    return;
  }
  obs_err_set(problems, OBS_EINVAL, "%s", line);
}

/* Rewrites the renderer's problems about a candidate's scene document ("<doc>: /technique/...")
 * into pointers into the request (/candidates/<entry>/params/<key>[/<list index>]...); problems
 * about the scene itself keep their document pointer. */
static void remap_problems(const obs_err *from, const char *docname, const cand *c,
                           const char *what, obs_err *problems, int *dropped) {
  const char *t = from->text;
  size_t dl = strlen(docname);
  for (const char *p = t; p && *p;) {
    const char *e = strchr(p, '\n');
    size_t len = e ? (size_t)(e - p) : strlen(p);
    char line[2048], out[2600];
    snprintf(line, sizeof line, "%.*s", (int)len, p);
    p = e ? e + 1 : p + len;
    const char *rest = line;
    if (!strncmp(rest, docname, dl) && !strncmp(rest + dl, ": ", 2)) rest += dl + 2;
    char base[96];
    snprintf(base, sizeof base, "request: /candidates/%d", c->entry);
    if (!strncmp(rest, "/technique/params/", 18)) {
      const char *key = rest + 18;
      size_t kl = strcspn(key, "/:");
      char k[128];
      snprintf(k, sizeof k, "%.*s", (int)(kl < sizeof k ? kl : sizeof k - 1), key);
      json_t *pos = json_object_get(c->pos, k);
      char idx[32] = "";
      if (pos) snprintf(idx, sizeof idx, "/%lld", (long long)json_integer_value(pos));
      snprintf(out, sizeof out, "%s%s/params/%s%s%s", base, what, k, idx, key + kl);
    } else if (!strncmp(rest, "/technique/params", 17)) {
      snprintf(out, sizeof out, "%s%s/params%s", base, what, rest + 17);
    } else if (!strncmp(rest, "/technique/backend", 18)) {
      char idx[32] = "";
      if (c->backend_pos >= 0) snprintf(idx, sizeof idx, "/%d", c->backend_pos);
      snprintf(out, sizeof out, "%s%s/backend%s%s", base, what, idx, rest + 18);
    } else if (!strncmp(rest, "/technique", 10)) {
      snprintf(out, sizeof out, "%s%s/technique%s", base, what, rest + 10);
    } else {
      snprintf(out, sizeof out, "%s", line);
    }
    add_problem(problems, dropped, out);
  }
}

/* The parts of a request shared by every candidate. */
typedef struct cmp_req {
  json_t *req, *base;  /* the request; the scene document with overrides, without technique */
  const char *docname; /* bundled file name or "inline" */
  long long priority, repeats, ref_samples, ref_seed;
  obs_backend ref_backend;
  const char *label;
} cmp_req;

/* Reads the candidate entries into the expansion (structure only: values are checked later by
 * the renderer's own validation, once per combination). */
static void expand_entries(srv_app *app, obs_jpath *p, const json_t *cands, expansion *x) {
  double total = 0;
  size_t ne = json_array_size(cands);
  size_t top = obs_jpath_push_key(p, "candidates");
  for (size_t i = 0; i < ne; i++) {
    json_t *e = json_array_get(cands, i);
    size_t m = obs_jpath_push_index(p, i);
    if (!json_is_object(e)) {
      obs_jpath_fail(p, "must be an object like {\"technique\": \"hbao\", \"backend\": [\"cpu\"], "
                        "\"params\": {\"directions\": [4, 8]}} (got %s)", obs_json_brief(e));
      obs_jpath_pop(p, m);
      continue;
    }
    static const char *const keys[] = {"technique", "backend", "params", NULL};
    obs_json_check_keys(p, e, keys);
    const char *tn = NULL;
    const obs_technique *t = NULL;
    if (!obs_json_get_string(p, e, "technique", 1, NULL, &tn) && !(t = obs_technique_find(tn))) {
      size_t k = obs_jpath_push_key(p, "technique");
      obs_jpath_fail(p, "not a technique (got %s; GET /api/v1/techniques lists them)",
                     obs_json_brief(json_object_get(e, "technique")));
      obs_jpath_pop(p, k);
    }
    /* Backends: a string or a non-empty list; absent = every backend the technique has here. */
    obs_backend bes[8];
    int nb = 0, listed = 0, bad = 0;
    json_t *bv = json_object_get(e, "backend");
    size_t k = obs_jpath_push_key(p, "backend");
    if (!bv) {
      for (int b = OBS_BACKEND_CPU; t && b < OBS_BACKEND_COUNT; b++)
        if (t->run[b] && (b != OBS_BACKEND_VULKAN || app->vulkan_lane)) bes[nb++] = (obs_backend)b;
    } else if (json_is_string(bv) || json_is_array(bv)) {
      listed = json_is_array(bv);
      size_t n = listed ? json_array_size(bv) : 1;
      if (listed && (n == 0 || n > 2)) {
        obs_jpath_fail(p, "must list 1 or 2 backends (got %zu)", n);
        bad = 1;
      }
      for (size_t j = 0; !bad && j < n; j++) {
        json_t *v = listed ? json_array_get(bv, j) : bv;
        size_t q = listed ? obs_jpath_push_index(p, j) : p->len;
        const char *s = json_string_value(v);
        if (!s || (strcmp(s, "cpu") && strcmp(s, "vulkan"))) {
          obs_jpath_fail(p, "must be \"cpu\" or \"vulkan\" (got %s)", obs_json_brief(v));
          bad = 1;
        } else {
          obs_backend b = strcmp(s, "cpu") ? OBS_BACKEND_VULKAN : OBS_BACKEND_CPU;
          for (int q2 = 0; q2 < nb; q2++)
            if (bes[q2] == b) {
              obs_jpath_fail(p, "is listed twice (got %s)", obs_json_brief(v));
              bad = 1;
            }
          bes[nb++] = b;
        }
        if (listed) obs_jpath_pop(p, q);
      }
    } else {
      obs_jpath_fail(p, "must be \"cpu\", \"vulkan\" or a list of them (got %s)",
                     obs_json_brief(bv));
      bad = 1;
    }
    obs_jpath_pop(p, k);
    int absent = 0;
    json_t *params = obs_json_get_object(p, e, "params", 0, &absent);
    /* The grid: every list-valued parameter (unless the parameter is itself an array). */
    const char *keyv[64];
    size_t lens[64];
    int nk = 0;
    double combos = nb;
    const char *key;
    json_t *v;
    k = obs_jpath_push_key(p, "params");
    json_object_foreach(params, key, v) {
      if (!json_is_array(v) || (t && param_is_array(t, key))) continue;
      size_t q = obs_jpath_push_key(p, key);
      if (json_array_size(v) == 0) {
        obs_jpath_fail(p, "an empty list gives no candidates: give at least one value");
        bad = 1;
      } else if (json_array_size(v) > MAX_LIST) {
        obs_jpath_fail(p, "must list at most %d values (got %zu)", MAX_LIST, json_array_size(v));
        bad = 1;
      } else if (nk < 64) {
        keyv[nk] = key;
        lens[nk++] = json_array_size(v);
        combos *= (double)json_array_size(v);
      }
      obs_jpath_pop(p, q);
    }
    obs_jpath_pop(p, k);
    obs_jpath_pop(p, m);
    total += combos;
    if (!t || bad || !nb || (params == NULL && !absent) || p->err->count) continue;
    if (total > MAX_CANDIDATES) continue; /* reported once below */
    /* The Cartesian product, backends outermost, then the parameters in request order. */
    for (int bi = 0; bi < nb; bi++) {
      size_t idx[64] = {0};
      for (;;) {
        if (x->n == x->cap) {
          x->cap = x->cap ? 2 * x->cap : 16;
          cand *nc = realloc(x->c, (size_t)x->cap * sizeof *nc);
          if (!nc) {
            /* Never accept a truncated grid. */
            obs_jpath_fail(p, "out of memory expanding the grid");
            return;
          }
          x->c = nc;
        }
        cand *c = &x->c[x->n++];
        memset(c, 0, sizeof *c);
        c->entry = (int)i;
        c->t = t;
        c->backend = bes[bi];
        c->backend_pos = listed ? bi : -1;
        /* Shallow: only top-level keys are replaced below, so candidates share the rest of
         * the entry's parameters instead of each holding a copy of them. */
        c->params = params ? json_copy(params) : json_object();
        c->pos = json_object();
        for (int q = 0; q < nk; q++) {
          json_object_set(c->params, keyv[q], json_array_get(json_object_get(params, keyv[q]),
                                                              idx[q]));
          json_object_set_new(c->pos, keyv[q], json_integer((json_int_t)idx[q]));
        }
        int q = nk - 1;
        while (q >= 0 && ++idx[q] == lens[q]) idx[q--] = 0;
        if (q < 0) break;
      }
    }
  }
  if (total > MAX_CANDIDATES)
    obs_jpath_fail(p, "expands to %.0f candidates; at most %d per comparison", total,
                   MAX_CANDIDATES);
  obs_jpath_pop(p, top);
}

/* Loads `doc` (a scene document) as the renderer will: 0 with *sc, or the problems in `e`. */
static int load_doc(srv_app *app, json_t *doc, const char *docname, obs_scene *sc,
                    char **text, obs_err *e) {
  *text = NULL;
  int rc = obs_scene_load_json(sc, doc, docname, app->scenes_real, NULL, 0, e);
  if (rc) return rc;
  /* Stored as the renderer will read it back (obs_scene_load_string at render time). */
  *text = json_dumps(sc->doc, JSON_COMPACT | JSON_REAL_PRECISION(17));
  return *text ? 0 : obs_err_set(e, OBS_ENOMEM, "out of memory");
}

static json_t *technique_obj(const char *name, obs_backend b, const json_t *params) {
  return json_pack("{s:s, s:s, s:O}", "name", name, "backend", obs_backend_name(b), "params",
                   params);
}

/* Validates one candidate like a job (scene rules, parameters, backend, limits), derives its
 * reference and registers it (shared when another candidate has the same definition). */
static void validate_candidate(srv_app *app, const cmp_req *q, cand *c, expansion *x,
                               obs_reference_facts *facts, obs_err *problems, int *dropped) {
  json_t *doc = json_deep_copy(q->base);
  json_object_set_new(doc, "technique", technique_obj(c->t->name, c->backend, c->params));
  obs_scene sc;
  memset(&sc, 0, sizeof sc);
  obs_err e = OBS_ERR_INIT;
  char *text = NULL;
  if (load_doc(app, doc, q->docname, &sc, &text, &e)) {
    remap_problems(&e, q->docname, c, "", problems, dropped);
    goto out;
  }
  obs_backend be;
  if (srv_pick_backend(sc.technique, c->backend, app->vulkan_lane, &be, &e)) {
    char line[1200];
    snprintf(line, sizeof line, "%s: /technique/backend: %s", q->docname, obs_err_message(&e));
    obs_err_clear(&e);
    obs_err_set(&e, OBS_EINVAL, "%s", line);
    remap_problems(&e, q->docname, c, "", problems, dropped);
    goto out;
  }
  srv_submit_check_limits(app, &sc, &e);
  if (e.count) {
    remap_problems(&e, q->docname, c, "", problems, dropped);
    goto out;
  }
  /* The reference: rt_ao with the candidate's AO definition, the reference's samples and seed. */
  json_t *refp = NULL;
  if (obs_technique_reference(sc.technique, &sc, sc.params, facts, &refp, &c->response, &e)) {
    char line[1200];
    snprintf(line, sizeof line, "request: /candidates/%d: cannot define its reference: %s",
             c->entry, obs_err_message(&e));
    add_problem(problems, dropped, line);
    goto out;
  }
  json_object_set_new(refp, "samples", json_integer(q->ref_samples));
  json_object_set_new(refp, "seed", json_integer(q->ref_seed));
  json_t *rdoc = json_deep_copy(q->base);
  json_object_set_new(rdoc, "technique", technique_obj("rt_ao", q->ref_backend, refp));
  json_decref(refp);
  obs_scene rs;
  memset(&rs, 0, sizeof rs);
  char *rtext = NULL;
  obs_err re = OBS_ERR_INIT;
  if (!load_doc(app, rdoc, q->docname, &rs, &rtext, &re)) srv_submit_check_limits(app, &rs, &re);
  json_decref(rdoc);
  if (re.count) {
    /* The reference inherits its definition from the candidate: say which candidate. */
    const char *t = re.text;
    for (const char *p = t; p && *p;) {
      const char *nl = strchr(p, '\n');
      size_t len = nl ? (size_t)(nl - p) : strlen(p);
      char line[2600];
      snprintf(line, sizeof line, "request: /reference: the reference of /candidates/%d "
               "(rt_ao): %.*s", c->entry, (int)len, p);
      add_problem(problems, dropped, line);
      p = nl ? nl + 1 : p + len;
    }
    free(rtext);
    obs_scene_free(&rs);
    obs_err_free(&re);
    goto out;
  }
  obs_err_free(&re);
  char *key = json_dumps(rs.params, JSON_COMPACT | JSON_SORT_KEYS | JSON_REAL_PRECISION(17));
  int found = -1;
  for (int i = 0; key && i < x->nrefs; i++)
    if (!strcmp(x->refs[i].key, key)) found = i;
  if (key && found < 0) {
    ref_job *nr = realloc(x->refs, (size_t)(x->nrefs + 1) * sizeof *nr);
    if (nr) {
      x->refs = nr;
      ref_job *r = &x->refs[x->nrefs];
      r->doc = rtext;
      rtext = NULL;
      r->key = key;
      key = NULL;
      r->width = rs.width;
      r->height = rs.height;
      r->spp = rs.spp;
      r->work = (double)rs.width * rs.height * rs.spp * srv_submit_samples(rs.params);
      r->backend = q->ref_backend;
      found = x->nrefs++;
    }
  }
  c->ref = found;
  c->ref_key = found >= 0 ? strdup(x->refs[found].key) : NULL;
  free(key);
  free(rtext);
  obs_scene_free(&rs);
  c->doc = text;
  text = NULL;
  c->params_full = json_dumps(sc.params, JSON_COMPACT | JSON_REAL_PRECISION(17));
  c->width = sc.width;
  c->height = sc.height;
  c->spp = sc.spp;
  c->work = (double)sc.width * sc.height * sc.spp * srv_submit_samples(sc.params);
  if (found < 0 || !c->params_full || !c->ref_key)
    obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
out:
  free(text);
  obs_scene_free(&sc);
  obs_err_free(&e);
  json_decref(doc);
}

/* Parses and validates the request; fills `x` with every candidate and reference. Returns 0 or
 * the HTTP status (problems listed). */
static unsigned parse_request(srv_app *app, const char *body, size_t len, cmp_req *q,
                              expansion *x, const char **message, obs_err *problems) {
  memset(q, 0, sizeof *q);
  *message = "request is not a valid comparison";
  if (!body || !len) {
    *message = "request body is empty (send {\"scene_file\": ..., \"candidates\": [...]})";
    return 400;
  }
  unsigned status = srv_submit_read_body(body, len, "a comparison like {\"scene_file\": ..., "
                                         "\"candidates\": [...]}", &q->req, message, problems);
  if (status) return status;
  obs_jpath p;
  obs_jpath_init(&p, "request", problems);
  json_t *req = q->req;
  static const char *const keys[] = {"scene_file", "scene", "set", "label", "priority",
                                     "repeats", "reference", "candidates", NULL};
  obs_json_check_keys(&p, req, keys);
  q->priority = 50;
  q->repeats = DEFAULT_REPEATS;
  q->ref_samples = REF_SAMPLES;
  q->ref_seed = REF_SEED;
  q->ref_backend = OBS_BACKEND_CPU;
  obs_json_get_int(&p, req, "priority", 0, 0, 100, &q->priority);
  obs_json_get_int(&p, req, "repeats", 0, 1, SRV_MAX_REPEATS, &q->repeats);
  if (obs_json_get_string(&p, req, "label", 0, NULL, &q->label) == 0 && q->label &&
      strlen(q->label) > MAX_LABEL) {
    size_t m = obs_jpath_push_key(&p, "label");
    obs_jpath_fail(&p, "must be at most %d bytes (got %zu)", MAX_LABEL, strlen(q->label));
    obs_jpath_pop(&p, m);
  }
  int absent = 0;
  json_t *ref = obs_json_get_object(&p, req, "reference", 0, &absent);
  if (ref) {
    size_t m = obs_jpath_push_key(&p, "reference");
    static const char *const rkeys[] = {"samples", "backend", "seed", NULL};
    static const char *const rbe[] = {"cpu", "vulkan", "auto", NULL};
    obs_json_check_keys(&p, ref, rkeys);
    obs_json_get_int(&p, ref, "samples", 0, 1, 65536, &q->ref_samples);
    obs_json_get_int(&p, ref, "seed", 0, 0, 4294967295LL, &q->ref_seed);
    const char *b = NULL;
    if (!obs_json_get_string(&p, ref, "backend", 0, rbe, &b) && b) {
      obs_backend want = !strcmp(b, "cpu") ? OBS_BACKEND_CPU
                         : !strcmp(b, "vulkan") ? OBS_BACKEND_VULKAN : OBS_BACKEND_AUTO;
      obs_err e = OBS_ERR_INIT;
      if (srv_pick_backend(obs_technique_find("rt_ao"), want, app->vulkan_lane, &q->ref_backend,
                           &e)) {
        size_t k = obs_jpath_push_key(&p, "backend");
        obs_jpath_fail(&p, "%s", obs_err_message(&e));
        obs_jpath_pop(&p, k);
      }
      obs_err_free(&e);
    }
    obs_jpath_pop(&p, m);
  }
  json_t *sets = srv_submit_get_sets(&p, req);
  json_t *file = json_object_get(req, "scene_file"), *inl = json_object_get(req, "scene");
  q->docname = "inline";
  if (file && inl) {
    size_t m = obs_jpath_push_key(&p, "scene");
    obs_jpath_fail(&p, "give either scene_file or scene, not both");
    obs_jpath_pop(&p, m);
  } else if (file) {
    q->base = srv_submit_load_bundled(app, &p, file);
    if (json_is_string(file)) q->docname = json_string_value(file);
  } else if (inl) {
    if (!json_is_object(inl)) {
      size_t m = obs_jpath_push_key(&p, "scene");
      obs_jpath_fail(&p, "must be a scene document (an object) (got %s)", obs_json_brief(inl));
      obs_jpath_pop(&p, m);
    } else {
      q->base = json_deep_copy(inl);
    }
  } else {
    obs_jpath_fail(&p, "needs scene_file (a bundled scene) or scene (an inline document)");
  }
  if (q->base && !json_is_object(q->base)) {
    obs_err_set(problems, OBS_EINVAL, "%s: must be a scene document (an object)", q->docname);
  } else if (q->base) {
    if (sets) srv_submit_apply_sets(&p, sets, q->base);
    /* The scene's own technique is ignored: each candidate brings one. */
    json_object_del(q->base, "technique");
  }
  json_t *cands = obs_json_get_array(&p, req, "candidates", 1, &absent);
  if (cands && json_array_size(cands) == 0) {
    size_t m = obs_jpath_push_key(&p, "candidates");
    obs_jpath_fail(&p, "must list at least one candidate");
    obs_jpath_pop(&p, m);
  }
  if (cands) expand_entries(app, &p, cands, x);
  if (problems->count) return 422;
  /* Each candidate's document (and its reference's) is the scene plus its parameters. */
  double copies = 2.0 * x->n * (double)obs_json_count_values(q->base, OBS_JSON_MAX_DEPTH);
  for (int i = 0; i < x->n && copies <= MAX_EXPANDED_VALUES; i++)
    copies += 2.0 * (double)obs_json_count_values(x->c[i].params, OBS_JSON_MAX_DEPTH);
  if (copies > MAX_EXPANDED_VALUES) {
    size_t m = obs_jpath_push_key(&p, "candidates");
    obs_jpath_fail(&p, "%d candidates (and their references) over a scene of %zu JSON values "
                   "make %.0f values; at most %d per comparison (use fewer candidates or a "
                   "smaller scene)", x->n, obs_json_count_values(q->base, OBS_JSON_MAX_DEPTH),
                   copies, MAX_EXPANDED_VALUES);
    obs_jpath_pop(&p, m);
    return 422;
  }
  /* Every combination validated like a job, all problems collected. */
  obs_reference_facts facts;
  memset(&facts, 0, sizeof facts);
  int dropped = 0;
  for (int i = 0; i < x->n; i++) validate_candidate(app, q, &x->c[i], x, &facts, problems, &dropped);
  if (dropped) obs_err_set(problems, OBS_EINVAL, "request: ... and %d more problems", dropped);
  if (problems->count) return 422;
  return 0;
}

int srv_compare_post(srv_req *r) {
  int refused;
  if (srv_refuse_non_json(r, &refused)) return refused;
  if (srv_refuse_when_faulted(r, &refused)) return refused;
  cmp_req q;
  expansion x;
  memset(&x, 0, sizeof x);
  obs_err problems = OBS_ERR_INIT;
  const char *message = NULL;
  unsigned status = parse_request(r->app, r->body, r->len, &q, &x, &message, &problems);
  if (status) {
    int rc = srv_respond_error(r, status, &problems, "%s", message);
    obs_err_free(&problems);
    expansion_free(&x);
    json_decref(q.base);
    json_decref(q.req);
    return rc;
  }
  srv_new_job *refs = calloc((size_t)x.nrefs + 1, sizeof *refs);
  srv_new_candidate *cs = calloc((size_t)x.n + 1, sizeof *cs);
  char *request = json_dumps(q.req, JSON_COMPACT | JSON_REAL_PRECISION(17));
  int64_t id = 0;
  unsigned admit = 0;
  int retry = 0;
  int rc = !refs || !cs || !request ? obs_err_set(&problems, OBS_ENOMEM, "out of memory") : 0;
  int width = x.n ? x.c[0].width : 0, height = x.n ? x.c[0].height : 0;
  for (int i = 0; !rc && i < x.nrefs; i++) {
    ref_job *rj = &x.refs[i];
    refs[i] = (srv_new_job){.priority = (int)q.priority,
                            .label = q.label,
                            .scene = q.docname,
                            .doc = rj->doc,
                            .technique = "rt_ao",
                            .backend_requested = obs_backend_name(rj->backend),
                            .lane = rj->backend == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN
                                                                      : SRV_LANE_CPU,
                            .width = rj->width,
                            .height = rj->height,
                            .spp = rj->spp,
                            /* A reference is rendered once: its time is not ranked. */
                            .repeats = 1,
                            .warmup = 0,
                            .work = rj->work,
                            .backend_reason = "reference of a comparison"};
  }
  for (int i = 0; !rc && i < x.n; i++) {
    cand *c = &x.c[i];
    cs[i].job = (srv_new_job){.priority = (int)q.priority,
                              .label = q.label,
                              .scene = q.docname,
                              .doc = c->doc,
                              .technique = c->t->name,
                              .backend_requested = obs_backend_name(c->backend),
                              .lane = c->backend == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN
                                                                       : SRV_LANE_CPU,
                              .width = c->width,
                              .height = c->height,
                              .spp = c->spp,
                              .repeats = (int)q.repeats,
                              .warmup = 1,
                              .work = c->work,
                              .backend_reason = "requested by a comparison"};
    cs[i].reference = c->ref;
    cs[i].technique = c->t->name;
    cs[i].backend = obs_backend_name(c->backend);
    cs[i].params = c->params_full;
    cs[i].reference_params = c->ref_key;
    cs[i].response = obs_response_name(c->response);
  }
  if (!rc) {
    srv_new_comparison nc = {.label = q.label,
                             .scene = q.docname,
                             .request = request,
                             .width = width,
                             .height = height,
                             .repeats = (int)q.repeats,
                             .references = refs,
                             .nreferences = x.nrefs,
                             .candidates = cs,
                             .ncandidates = x.n};
    admit = srv_admit_comparison(r->app, r->client, &nc, &id, &retry, &problems);
    rc = admit ? OBS_EIO : 0;
  }
  int nrefs = x.nrefs, ncand = x.n;
  free(refs);
  free(cs);
  free(request);
  expansion_free(&x);
  json_decref(q.base);
  json_decref(q.req);
  if (admit == 429) {
    rc = srv_respond_too_busy(r, retry, &problems);
    obs_err_free(&problems);
    return rc;
  }
  if (rc) return srv_respond_unavailable(r, &problems);
  srv_log("comparison %lld: submitted (%d candidates, %d references)", (long long)id, ncand,
          nrefs);
  srv_sched_notify(r->app);
  char self[64], csv[72];
  snprintf(self, sizeof self, API "/comparisons/%lld", (long long)id);
  snprintf(csv, sizeof csv, "%s.csv", self);
  return srv_respond_created(
      r, json_pack("{s:I, s:s, s:i, s:i, s:{s:s, s:s}}", "id", (json_int_t)id, "state", "running",
                   "candidates", ncand, "references", nrefs, "links", "self", self, "csv", csv),
      self);
}

/* ---- GET /api/v1/comparisons/{id}[.csv] ------------------------------------------------------ */

static const char *const stages[4] = {"build", "render", "post", "total"};

/* {"median": {...} | null, "runs": [...]} from the runs rows of one job. */
static json_t *timings_of(const json_t *runs, json_int_t job, json_t **machine) {
  json_t *list = json_array();
  double v[4][SRV_MAX_REPEATS];
  size_t n = 0;
  if (machine) *machine = NULL;
  for (size_t i = 0; i < json_array_size(runs); i++) {
    json_t *row = json_array_get(runs, i);
    if (json_integer_value(json_object_get(row, "job")) != job) continue;
    json_t *o = json_object();
    for (int k = 0; k < 4; k++) {
      char col[16];
      snprintf(col, sizeof col, "%s_ms", stages[k]);
      double d = json_number_value(json_object_get(row, col));
      json_object_set_new(o, stages[k], num_or_null(d));
      if (n < SRV_MAX_REPEATS) v[k][n] = d;
    }
    json_array_append_new(list, o);
    if (n < SRV_MAX_REPEATS) n++;
    if (machine && !*machine && json_is_string(json_object_get(row, "cpu_model")))
      *machine = json_pack("{s:O, s:O, s:O}", "cpu_model", json_object_get(row, "cpu_model"),
                           "cores", json_object_get(row, "cores"), "vulkan_device",
                           json_object_get(row, "vulkan_device"));
  }
  json_t *med = json_null();
  if (n) {
    json_decref(med);
    med = json_object();
    for (int k = 0; k < 4; k++) json_object_set_new(med, stages[k], num_or_null(srv_median(v[k], n)));
  }
  if (machine && !*machine) *machine = json_null();
  return json_pack("{s:o, s:o}", "median", med, "runs", list);
}

static int has_output(const json_t *outs, json_int_t job, const char *name) {
  for (size_t i = 0; i < json_array_size(outs); i++) {
    json_t *row = json_array_get(outs, i);
    if (json_integer_value(json_object_get(row, "job")) == job &&
        !strcmp(json_string_value(json_object_get(row, "name")), name))
      return 1;
  }
  return 0;
}

static void output_link(json_t *links, const json_t *outs, json_int_t job, const char *name,
                        const char *as) {
  if (!has_output(outs, job, name)) return;
  char url[128];
  snprintf(url, sizeof url, API "/jobs/%lld/outputs/%s", (long long)job, name);
  json_object_set_new(links, as, json_string(url));
}

/* The PNG of the primary output of `technique` ("ao.png" for today's AO techniques). */
static const char *primary_png(const char *technique) {
  const obs_output *o = obs_technique_primary(obs_technique_find(technique));
  return o && o->png ? o->png : "ao.png";
}

/* The comparison document of docs/comparisons.md. 0, OBS_ENOTFOUND, or a database error. */
static int comparison_json(srv_app *app, int64_t id, json_t **out, obs_err *err) {
  *out = NULL;
  srv_arg arg = {SRV_ARG_INT, id, 0, NULL};
  json_t *head = NULL, *cands = NULL, *runs = NULL, *outs = NULL;
  int rc = srv_db_query(app->db, SRV_Q_COMPARISON, &arg, 1, &head, err);
  if (!rc && json_array_size(head) == 0) rc = OBS_ENOTFOUND;
  if (!rc) rc = srv_db_query(app->db, SRV_Q_CANDIDATES, &arg, 1, &cands, err);
  if (!rc) rc = srv_db_query(app->db, SRV_Q_COMPARISON_RUNS, &arg, 1, &runs, err);
  if (!rc) rc = srv_db_query(app->db, SRV_Q_COMPARISON_OUTPUTS, &arg, 1, &outs, err);
  if (rc) {
    json_decref(head);
    json_decref(cands);
    json_decref(runs);
    json_decref(outs);
    return rc;
  }
  json_t *h = json_array_get(head, 0);
  json_t *o = json_object();
  json_object_set_new(o, "id", json_integer(id));
  json_object_set(o, "label", json_object_get(h, "label"));
  json_object_set(o, "scene", json_object_get(h, "scene"));
  json_object_set_new(o, "state", json_string(state_of(h)));
  json_object_set_new(o, "created_at",
                      srv_json_time(json_integer_value(json_object_get(h, "created_ms"))));
  json_object_set(o, "repeats", json_object_get(h, "repeats"));
  json_object_set_new(o, "image", json_pack("{s:O, s:O}", "width", json_object_get(h, "width"),
                                            "height", json_object_get(h, "height")));
  json_t *refs = json_array(), *list = json_array();
  size_t n = json_array_size(cands);
  obs_pareto_point *pts = calloc(n + 1, sizeof *pts);
  unsigned char *opt = calloc(n + 1, 1);
  for (size_t i = 0; i < n; i++) {
    json_t *row = json_array_get(cands, i);
    json_int_t job = json_integer_value(json_object_get(row, "job"));
    json_int_t rjob = json_integer_value(json_object_get(row, "reference_job"));
    /* References: each once, in the order candidates name them. */
    int seen = 0;
    for (size_t k = 0; k < json_array_size(refs); k++)
      if (json_integer_value(json_object_get(json_array_get(refs, k), "job_id")) == rjob) seen = 1;
    if (!seen) {
      json_t *ro = json_object();
      json_object_set_new(ro, "job_id", json_integer(rjob));
      const char *rst = json_string_value(json_object_get(row, "ref_state"));
      json_object_set(ro, "state", json_object_get(row, "ref_state"));
      double prog = json_number_value(json_object_get(row, "ref_progress"));
      if (rst && !strcmp(rst, "running")) srv_sched_progress(app, rjob, &prog);
      json_object_set_new(ro, "progress", json_real(prog));
      json_t *rp = json_loads(json_string_value(json_object_get(row, "reference_params")), 0,
                              NULL);
      json_object_set_new(ro, "params", rp ? rp : json_null());
      json_t *sum = json_loads(json_string_value(json_object_get(row, "ref_summary"))
                                   ? json_string_value(json_object_get(row, "ref_summary"))
                                   : "null",
                               JSON_DECODE_ANY, NULL);
      json_t *se = json_object_get(sum, "ao_stderr_mean");
      json_object_set_new(ro, "ao_stderr_mean",
                          json_is_number(se) ? num_or_null(json_number_value(se)) : json_null());
      json_decref(sum);
      json_object_set_new(ro, "timings_ms", timings_of(runs, rjob, NULL));
      json_t *links = json_object();
      char url[96];
      snprintf(url, sizeof url, API "/jobs/%lld", (long long)rjob);
      json_object_set_new(links, "job", json_string(url));
      output_link(links, outs, rjob, "ao.png", "ao.png");
      output_link(links, outs, rjob,
                  primary_png(json_string_value(json_object_get(row, "technique"))), "image");
      json_object_set_new(ro, "links", links);
      json_array_append_new(refs, ro);
    }
    json_t *co = json_object();
    json_object_set(co, "index", json_object_get(row, "idx"));
    json_object_set_new(co, "job_id", json_integer(job));
    json_object_set_new(co, "reference_job_id", json_integer(rjob));
    json_object_set(co, "technique", json_object_get(row, "technique"));
    json_object_set(co, "backend", json_object_get(row, "backend"));
    json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
    json_object_set_new(co, "params", params ? params : json_object());
    json_object_set(co, "response", json_object_get(row, "response"));
    const char *st = json_string_value(json_object_get(row, "state"));
    json_object_set(co, "state", json_object_get(row, "state"));
    double prog = json_number_value(json_object_get(row, "progress"));
    if (st && !strcmp(st, "running")) srv_sched_progress(app, job, &prog);
    json_object_set_new(co, "progress", json_real(prog));
    json_t *machine = NULL;
    json_t *tm = timings_of(runs, job, &machine);
    json_object_set_new(co, "timings_ms", tm);
    const char *mt = json_string_value(json_object_get(row, "metrics"));
    json_t *metrics = mt ? json_loads(mt, 0, NULL) : NULL;
    json_object_set_new(co, "metrics", metrics ? metrics : json_null());
    json_object_set(co, "error", json_object_get(row, "metrics_error"));
    json_object_set_new(co, "machine", machine);
    json_t *links = json_object();
    char url[96];
    snprintf(url, sizeof url, API "/jobs/%lld", (long long)job);
    json_object_set_new(links, "job", json_string(url));
    /* "image" is the primary output's PNG of any technique; "ao.png" stays for AO ones. */
    const char *png = primary_png(json_string_value(json_object_get(row, "technique")));
    output_link(links, outs, job, "ao.png", "ao.png");
    output_link(links, outs, job, png, "image");
    output_link(links, outs, job, "error.png", "error.png");
    output_link(links, outs, job, "error.exr", "error.exr");
    output_link(links, outs, rjob, png, "reference.png");
    json_object_set_new(co, "links", links);
    /* Ranking: median total time against RMSE; anything missing takes no part (NaN). */
    json_t *med = json_object_get(tm, "median");
    json_t *total = json_object_get(med, "total"), *rmse = json_object_get(metrics, "rmse");
    if (pts) {
      pts[i].time_ms = metrics && json_is_number(total) ? json_number_value(total) : NAN;
      pts[i].error = json_is_number(rmse) ? json_number_value(rmse) : NAN;
      pts[i].at_reference_accuracy =
          json_is_true(json_object_get(metrics, "at_reference_accuracy"));
    }
    json_array_append_new(list, co);
  }
  if (pts && opt) obs_metrics_pareto(pts, n, opt, NULL);
  /* The Pareto indices by ascending time (then index): the frontier from fast to accurate. */
  json_t *pareto = json_array();
  for (size_t i = 0; i < n; i++) {
    int on = opt && opt[i];
    json_object_set_new(json_array_get(list, i), "pareto", json_boolean(on));
    if (!on) continue;
    size_t at = json_array_size(pareto);
    while (at > 0) {
      size_t prev = (size_t)json_integer_value(json_array_get(pareto, at - 1));
      if (!(pts[prev].time_ms > pts[i].time_ms)) break;
      at--;
    }
    json_array_insert_new(pareto, at, json_integer((json_int_t)i));
  }
  free(pts);
  free(opt);
  json_object_set_new(o, "references", refs);
  json_object_set_new(o, "candidates", list);
  json_object_set_new(o, "pareto", pareto);
  char self[64], csv[72];
  snprintf(self, sizeof self, API "/comparisons/%lld", (long long)id);
  snprintf(csv, sizeof csv, "%s.csv", self);
  json_object_set_new(o, "links", json_pack("{s:s, s:s}", "self", self, "csv", csv));
  json_decref(head);
  json_decref(cands);
  json_decref(runs);
  json_decref(outs);
  *out = o;
  return 0;
}

/* ---- CSV ------------------------------------------------------------------------------------- */

typedef struct sbuf {
  char *p;
  size_t len, cap;
  int oom;
} sbuf;

static void sb_put(sbuf *b, const char *s, size_t n) {
  if (b->oom) return;
  if (b->len + n + 1 > b->cap) {
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->len + n + 1) cap *= 2;
    char *np = realloc(b->p, cap);
    if (!np) {
      b->oom = 1;
      return;
    }
    b->p = np;
    b->cap = cap;
  }
  memcpy(b->p + b->len, s, n);
  b->len += n;
  b->p[b->len] = '\0';
}

/* One field, quoted per RFC 4180 when it holds a comma, quote or line break. */
static void csv_field(sbuf *b, const char *s, int first) {
  if (!first) sb_put(b, ",", 1);
  if (!s) return;
  if (!strpbrk(s, ",\"\r\n")) {
    sb_put(b, s, strlen(s));
    return;
  }
  sb_put(b, "\"", 1);
  for (const char *c = s; *c; c++) {
    if (*c == '"') sb_put(b, "\"", 1);
    sb_put(b, c, 1);
  }
  sb_put(b, "\"", 1);
}

/* A JSON value as a CSV field: numbers exactly as the JSON answer writes them (12 significant
 * digits, srv_respond_json), so both parse to the same double; strings raw, booleans true/false,
 * null empty. */
static void csv_value(sbuf *b, const json_t *v) {
  char buf[64];
  if (json_is_integer(v)) {
    snprintf(buf, sizeof buf, "%lld", (long long)json_integer_value(v));
    csv_field(b, buf, 0);
  } else if (json_is_real(v)) {
    char *t = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT | JSON_REAL_PRECISION(12));
    csv_field(b, t ? t : "", 0);
    free(t);
  } else if (json_is_string(v)) {
    csv_field(b, json_string_value(v), 0);
  } else if (json_is_boolean(v)) {
    csv_field(b, json_is_true(v) ? "true" : "false", 0);
  } else {
    csv_field(b, NULL, 0);
  }
}

static char *comparison_csv(const json_t *o, size_t *len) {
  sbuf b = {0};
  static const char header[] =
      "index,job_id,technique,backend,params,state,total_ms,build_ms,render_ms,post_ms,runs,rmse,"
      "bias,max_abs,psnr,ssim,ref_noise,at_reference_accuracy,pareto,cpu_model,cores,"
      "vulkan_device\r\n";
  sb_put(&b, header, sizeof header - 1);
  json_t *cands = json_object_get(o, "candidates");
  for (size_t i = 0; i < json_array_size(cands); i++) {
    json_t *c = json_array_get(cands, i);
    char buf[32];
    snprintf(buf, sizeof buf, "%lld", (long long)json_integer_value(json_object_get(c, "index")));
    csv_field(&b, buf, 1);
    csv_value(&b, json_object_get(c, "job_id"));
    csv_value(&b, json_object_get(c, "technique"));
    csv_value(&b, json_object_get(c, "backend"));
    sbuf pb = {0};
    const char *key;
    json_t *v;
    int first = 1;
    json_object_foreach(json_object_get(c, "params"), key, v) {
      if (!first) sb_put(&pb, ";", 1);
      first = 0;
      sb_put(&pb, key, strlen(key));
      sb_put(&pb, "=", 1);
      char *t = json_is_string(v) ? strdup(json_string_value(v))
                                  : json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT |
                                                      JSON_REAL_PRECISION(12));
      if (t) sb_put(&pb, t, strlen(t));
      free(t);
    }
    csv_field(&b, pb.p ? pb.p : "", 0);
    free(pb.p);
    csv_value(&b, json_object_get(c, "state"));
    json_t *tm = json_object_get(c, "timings_ms"), *med = json_object_get(tm, "median");
    static const char *const order[4] = {"total", "build", "render", "post"};
    for (int k = 0; k < 4; k++) csv_value(&b, json_object_get(med, order[k]));
    snprintf(buf, sizeof buf, "%zu", json_array_size(json_object_get(tm, "runs")));
    csv_field(&b, buf, 0);
    json_t *m = json_object_get(c, "metrics");
    static const char *const mk[7] = {"rmse", "bias", "max_abs", "psnr", "ssim", "ref_noise",
                                      "at_reference_accuracy"};
    for (int k = 0; k < 7; k++) csv_value(&b, json_object_get(m, mk[k]));
    csv_value(&b, json_object_get(c, "pareto"));
    json_t *mach = json_object_get(c, "machine");
    csv_value(&b, json_object_get(mach, "cpu_model"));
    csv_value(&b, json_object_get(mach, "cores"));
    csv_value(&b, json_object_get(mach, "vulkan_device"));
    sb_put(&b, "\r\n", 2);
  }
  if (b.oom) {
    free(b.p);
    return NULL;
  }
  *len = b.len;
  return b.p;
}

int srv_compare_get(srv_req *r, int64_t id, int csv) {
  json_t *o = NULL;
  obs_err err = OBS_ERR_INIT;
  int rc = comparison_json(r->app, id, &o, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no comparison %lld", (long long)id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  if (!csv) return srv_respond_json(r, MHD_HTTP_OK, o);
  size_t len = 0;
  char *text = comparison_csv(o, &len);
  json_decref(o);
  if (!text) return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "out of memory");
  struct MHD_Response *resp = MHD_create_response_from_buffer(len, text, MHD_RESPMEM_MUST_FREE);
  char disp[96];
  snprintf(disp, sizeof disp, "inline; filename=\"comparison-%lld.csv\"", (long long)id);
  MHD_add_response_header(resp, "Content-Type", "text/csv; charset=utf-8; header=present");
  MHD_add_response_header(resp, "Content-Disposition", disp);
  return srv_respond(r, MHD_HTTP_OK, resp);
}

/* ---- GET /api/v1/comparisons ----------------------------------------------------------------- */

typedef struct list_query {
  int64_t after;
  int limit;
  int seen[2];
  obs_err *problems;
} list_query;

static enum MHD_Result on_list_arg(void *cls, enum MHD_ValueKind kind, const char *key,
                                   const char *value) {
  (void)kind;
  list_query *q = cls;
  int k = !strcmp(key, "limit") ? 0 : !strcmp(key, "after") ? 1 : -1;
  char shown[80];
  srv_printable(value, shown, sizeof shown);
  if (k < 0) {
    char ks[40];
    srv_printable(key, ks, sizeof ks);
    obs_err_set(q->problems, OBS_EINVAL, "query: /%s: unknown parameter (known: limit, after)", ks);
    return MHD_YES;
  }
  if (q->seen[k]++) {
    obs_err_set(q->problems, OBS_EINVAL, "query: /%s: given more than once", key);
    return MHD_YES;
  }
  int64_t n;
  if (!value) value = "";
  if (srv_parse_id(value, strlen(value), &n) || (k == 0 && n > 500))
    obs_err_set(q->problems, OBS_EINVAL,
                k ? "query: /after: must be a comparison id from a previous page's \"next\" "
                    "(got \"%s\")"
                  : "query: /limit: must be an integer from 1 to 500 (got \"%s\")",
                shown);
  else if (k == 0) q->limit = (int)n;
  else q->after = n;
  return MHD_YES;
}

int srv_compare_list(srv_req *r) {
  obs_err problems = OBS_ERR_INIT;
  list_query q = {0, 50, {0, 0}, &problems};
  MHD_get_connection_values(r->conn, MHD_GET_ARGUMENT_KIND, on_list_arg, &q);
  if (problems.count) {
    int rc = srv_respond_error(r, MHD_HTTP_BAD_REQUEST, &problems, "bad query parameters");
    obs_err_free(&problems);
    return rc;
  }
  json_t *rows = NULL;
  srv_arg args[2] = {{SRV_ARG_INT, q.after, 0, NULL}, {SRV_ARG_INT, q.limit + 1, 0, NULL}};
  if (srv_db_query(r->app->db, SRV_Q_COMPARISONS, args, 2, &rows, &problems))
    return srv_respond_unavailable(r, &problems);
  json_t *list = json_array();
  size_t n = json_array_size(rows), shown = n > (size_t)q.limit ? (size_t)q.limit : n;
  for (size_t i = 0; i < shown; i++) {
    json_t *row = json_array_get(rows, i);
    json_int_t total = json_integer_value(json_object_get(row, "candidates"));
    json_int_t done = json_integer_value(json_object_get(row, "measured")) +
                      json_integer_value(json_object_get(row, "broken"));
    json_array_append_new(
        list, json_pack("{s:O, s:O, s:O, s:s, s:o, s:I, s:I}", "id", json_object_get(row, "id"),
                        "label", json_object_get(row, "label"), "scene",
                        json_object_get(row, "scene"), "state", state_of(row), "created_at",
                        srv_json_time(json_integer_value(json_object_get(row, "created_ms"))),
                        "candidates", total, "done", done));
  }
  json_t *next = json_null();
  if (n > shown && shown) {
    char buf[24];
    snprintf(buf, sizeof buf, "%lld",
             (long long)json_integer_value(json_object_get(json_array_get(rows, shown - 1), "id")));
    json_decref(next);
    next = json_string(buf);
  }
  json_decref(rows);
  return srv_respond_json(r, MHD_HTTP_OK, json_pack("{s:o, s:o}", "comparisons", list, "next",
                                                    next));
}

/* ---- the metrics step ------------------------------------------------------------------------ */

/* One at a time: the candidate's and the reference's workers may both find the pair ready, and
 * the error images of one candidate must be written once. */
static pthread_mutex_t metrics_mu = PTHREAD_MUTEX_INITIALIZER;

/* Computes and stores one candidate's metrics and error images. Returns 0, or <0 with the reason
 * in `why` when the inputs cannot give metrics (stored as metrics_error). Database trouble is only
 * logged: the next start retries. */
static void metrics_one(srv_app *app, const json_t *row) {
  json_int_t cmp = json_integer_value(json_object_get(row, "comparison"));
  int idx = (int)json_integer_value(json_object_get(row, "idx"));
  json_int_t job = json_integer_value(json_object_get(row, "job"));
  json_int_t rjob = json_integer_value(json_object_get(row, "reference_job"));
  obs_response resp = OBS_RESPONSE_IDENTITY;
  obs_err e = OBS_ERR_INIT;
  obs_image eimg;
  memset(&eimg, 0, sizeof eimg);
  char dir[4200], rdir[4200];
  srv_results_path(app, job, dir, sizeof dir);
  srv_results_path(app, rjob, rdir, sizeof rdir);
  srv_output outs[16], err_outs[2];
  int nouts = 0, nerr = 0;
  obs_compare m;
  int rc = obs_response_parse(json_string_value(json_object_get(row, "response")), &resp)
               ? obs_err_set(&e, OBS_EINVAL, "unknown response mapping")
               : 0;
  json_t *extra = json_object();
  if (!rc) rc = srv_compare_primary(dir, rdir, resp, &m, extra, &eimg, &e);
  /* Written into the candidate's published directory under staging names and renamed, so a crash
   * leaves either no error image or a whole one (recorded below, or again after a restart). */
  if (!rc) rc = obs_metrics_write_error_files(&eimg, dir, &e);
  if (!rc) rc = srv_outputs_describe(dir, outs, 16, &nouts, &e);
  for (int i = 0; !rc && i < nouts; i++)
    if (!strncmp(outs[i].name, "error.", 6) && nerr < (int)(sizeof err_outs / sizeof *err_outs))
      err_outs[nerr++] = outs[i];
  char *metrics = NULL;
  if (!rc) {
    json_t *mj = json_object();
    json_object_set_new(mj, "rmse", num_or_null(m.rmse));
    json_object_set_new(mj, "bias", num_or_null(m.bias));
    json_object_set_new(mj, "max_abs", num_or_null(m.max_abs));
    json_object_set_new(mj, "psnr", num_or_null(m.psnr));
    json_object_set_new(mj, "ssim", num_or_null(m.ssim));
    json_object_set_new(mj, "ref_noise", num_or_null(m.ref_noise));
    json_object_set_new(mj, "at_reference_accuracy", json_boolean(m.at_reference_accuracy));
    json_object_set_new(mj, "pixels", json_integer(m.pixels));
    json_object_update(mj, extra);
    metrics = json_dumps(mj, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(mj);
  }
  obs_err dberr = OBS_ERR_INIT;
  /* I/O trouble and memory shortage may pass (a full disk is freed): leave the candidate pending,
   * so the next trigger or the next start retries, instead of failing the comparison for good. */
  if (rc == OBS_EIO || rc == OBS_ENOMEM)
    srv_log("comparison %lld candidate %d: metrics postponed: %s", (long long)cmp, idx,
            obs_err_message(&e));
  else if (srv_db_set_metrics(app->db, cmp, idx, job, metrics, rc ? obs_err_message(&e) : NULL,
                              err_outs, nerr, &dberr))
    srv_log("comparison %lld candidate %d: cannot store metrics: %s", (long long)cmp, idx,
            obs_err_message(&dberr));
  else if (rc)
    srv_log("comparison %lld candidate %d: no metrics: %s", (long long)cmp, idx,
            obs_err_message(&e));
  else
    srv_log("comparison %lld candidate %d: rmse %.4g, ssim %.4g (job %lld vs reference %lld)",
            (long long)cmp, idx, m.rmse, m.ssim, (long long)job, (long long)rjob);
  free(metrics);
  json_decref(extra);
  obs_err_free(&dberr);
  obs_err_free(&e);
  obs_image_free(&eimg);
}

void srv_compare_metrics(srv_app *app, int64_t job) {
  pthread_mutex_lock(&metrics_mu);
  json_t *rows = NULL;
  obs_err err = OBS_ERR_INIT;
  srv_arg arg = {SRV_ARG_INT, job, 0, NULL};
  if (srv_db_query(app->db, SRV_Q_METRICS_PENDING, &arg, 1, &rows, &err))
    srv_log("comparison metrics: %s", obs_err_message(&err));
  for (size_t i = 0; i < json_array_size(rows); i++) metrics_one(app, json_array_get(rows, i));
  json_decref(rows);
  obs_err_free(&err);
  pthread_mutex_unlock(&metrics_mu);
}

/* Whether a stored candidate can inform a time budget here: a known technique, a backend this
 * daemon runs, and a finite RMSE (filled in). */
static int budget_row(const srv_app *app, const json_t *row, double *rmse, int *at_ref) {
  const char *be = json_string_value(json_object_get(row, "backend"));
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(row, "technique")));
  if (!t || !be || (!strcmp(be, "vulkan") && !app->vulkan_lane)) return 0;
  json_t *m = json_loads(json_string_value(json_object_get(row, "metrics")), 0, NULL);
  json_t *rm = json_object_get(m, "rmse");
  *rmse = json_is_number(rm) ? json_number_value(rm) : NAN;
  *at_ref = json_is_true(json_object_get(m, "at_reference_accuracy"));
  json_decref(m);
  return !isnan(*rmse);
}

/* ---- time budgets ---------------------------------------------------------------------------- */

int srv_compare_budget_choice(srv_app *app, const char *scene, double pixels, double budget_ms,
                              json_t **choice, obs_err *problems) {
  *choice = NULL;
  json_t *rows = NULL;
  obs_err err = OBS_ERR_INIT;
  if (srv_db_query(app->db, SRV_Q_BUDGET, NULL, 0, &rows, &err)) {
    int rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: cannot read the stored "
                         "measurements: %s", obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  /* Measurements of this scene at a similar size, else of any scene at a similar size. */
  size_t n = json_array_size(rows);
  int same_scene = 0;
  for (size_t i = 0; i < n; i++) {
    json_t *row = json_array_get(rows, i);
    double px = json_number_value(json_object_get(row, "pixels"));
    const char *sc = json_string_value(json_object_get(row, "scene"));
    double rmse;
    int at_ref;
    if (px >= pixels / 2 && px <= pixels * 2 && sc && !strcmp(sc, scene) &&
        budget_row(app, row, &rmse, &at_ref))
      same_scene = 1;
  }
  int best = -1, measured = 0;
  double best_ms = 0, best_rmse = 0, fastest_ms = INFINITY;
  int best_at_ref = 0;
  for (size_t i = 0; i < n; i++) {
    json_t *row = json_array_get(rows, i);
    double px = json_number_value(json_object_get(row, "pixels"));
    const char *sc = json_string_value(json_object_get(row, "scene"));
    if (!(px >= pixels / 2 && px <= pixels * 2)) continue;
    if (same_scene && (!sc || strcmp(sc, scene))) continue;
    double rmse;
    int at_ref;
    if (!budget_row(app, row, &rmse, &at_ref)) continue;
    json_t *runs = NULL;
    srv_arg arg = {SRV_ARG_INT, json_integer_value(json_object_get(row, "job")), 0, NULL};
    double v[SRV_MAX_REPEATS];
    size_t nv = 0;
    if (!srv_db_query(app->db, SRV_Q_JOB_RUNS, &arg, 1, &runs, &err))
      for (size_t k = 0; k < json_array_size(runs) && nv < SRV_MAX_REPEATS; k++)
        v[nv++] = json_number_value(json_object_get(json_array_get(runs, k), "total_ms"));
    obs_err_clear(&err);
    json_decref(runs);
    double ms = srv_median(v, nv);
    if (isnan(ms)) continue;
    measured++;
    if (ms < fastest_ms) fastest_ms = ms;
    if (ms > budget_ms) continue;
    /* Within the reference's noise, configurations are equally accurate: the fastest wins. */
    int better = best < 0 || (at_ref && !best_at_ref) ||
                 (at_ref && best_at_ref && ms < best_ms) ||
                 (!at_ref && !best_at_ref && (rmse < best_rmse || (rmse == best_rmse && ms < best_ms)));
    if (better) {
      best = (int)i;
      best_ms = ms;
      best_rmse = rmse;
      best_at_ref = at_ref;
    }
  }
  obs_err_free(&err);
  int rc = 0;
  if (!measured) {
    rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: nothing has been measured "
                     "yet for %s or any scene of a similar size (%.0f pixel samples, within 2x): "
                     "run a comparison first (POST /api/v1/comparisons)", scene, pixels);
  } else if (best < 0) {
    rc = obs_err_set(problems, OBS_EINVAL, "request: /time_budget_ms: none of the %d measured "
                     "configurations%s fits %g ms: the fastest takes %.4g ms (median)", measured,
                     same_scene ? " of this scene" : " of similar scenes", budget_ms, fastest_ms);
  } else {
    json_t *row = json_array_get(rows, (size_t)best);
    json_t *params = json_loads(json_string_value(json_object_get(row, "params")), 0, NULL);
    char reason[600];
    snprintf(reason, sizeof reason,
             "%s among %d measured configuration(s) %s that fit %g ms: %s on %s takes %.4g ms "
             "(median) with RMSE %.4g (comparison %lld, candidate %lld)",
             best_at_ref ? "the fastest at reference accuracy" : "the lowest RMSE", measured,
             same_scene ? "of this scene" : "of scenes of a similar size", budget_ms,
             json_string_value(json_object_get(row, "technique")),
             json_string_value(json_object_get(row, "backend")), best_ms, best_rmse,
             (long long)json_integer_value(json_object_get(row, "comparison")),
             (long long)json_integer_value(json_object_get(row, "idx")));
    *choice = json_pack("{s:O, s:O, s:o, s:f, s:f, s:O, s:s}", "technique",
                        json_object_get(row, "technique"), "backend",
                        json_object_get(row, "backend"), "params",
                        params ? params : json_object(), "expected_ms", best_ms, "expected_rmse",
                        best_rmse, "comparison_id", json_object_get(row, "comparison"), "reason",
                        reason);
    if (!*choice) rc = obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  }
  json_decref(rows);
  return rc;
}
