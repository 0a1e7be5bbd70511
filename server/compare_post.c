/* POST /api/v1/comparisons: a request validated candidate by candidate through the renderer's
 * own loader, its references derived, and the comparison and its jobs stored
 * (docs/comparisons.md). */
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

#define MAX_PROBLEMS 100 /* problems reported for one request (the rest are summarised) */
#define REF_SEED 7919    /* independent of candidates' default seed 1 */
#define MAX_LABEL 256
/* Every candidate and reference is a whole scene document, kept as text until the comparison is
 * stored: the values of the scene times the documents made from it are bounded (the largest
 * bundled scene, 445 values, fits 256 candidates 17 times over). */
#define MAX_EXPANDED_VALUES 4000000

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
/* The comparison's common reference (the request's "common_reference"): one reference job every
 * candidate is also measured against, so that techniques of different definitions share a scale. */
typedef struct cmp_common {
  const obs_technique *technique;
  const json_t *params; /* borrowed from the request */
  long long samples, seed;
  obs_backend backend;
} cmp_common;

typedef struct cmp_req {
  json_t *req, *base;  /* the request; the scene document with overrides, without technique */
  const char *docname; /* bundled file name or "inline" */
  long long priority, repeats, ref_samples, ref_seed;
  obs_backend ref_want; /* reference.backend as requested; picked per reference technique */
  const char *label;
  /* The scene with its own technique, when it loads: what each candidate's params start from
   * (obs_technique_defaults_for), and the notes of the values derived from its size. */
  obs_scene scene;
  int have_scene;
  json_t *notes;
  cmp_common common;
  int has_common;
} cmp_req;

static void cmp_req_free(cmp_req *q) {
  json_decref(q->base);
  json_decref(q->req);
  json_decref(q->notes);
  if (q->have_scene) obs_scene_free(&q->scene);
  q->base = q->req = q->notes = NULL;
  q->have_scene = 0;
}

/* The candidate's params over what its technique starts from on the scene; a note per value
 * derived from the scene's size, once per comparison. */
static json_t *candidate_params(cmp_req *q, const cand *c) {
  if (!q->have_scene) return json_incref(c->params);
  json_t *notes = json_array();
  json_t *p = obs_technique_defaults_for(c->t, &q->scene, c->params, notes, NULL);
  size_t i, k;
  json_t *n, *m;
  json_array_foreach(notes, i, n) {
    int seen = 0;
    json_array_foreach(q->notes, k, m) seen |= json_equal(m, n);
    if (!seen) json_array_append(q->notes, n);
  }
  json_decref(notes);
  return p ? p : json_incref(c->params);
}

/* Loads `doc` (a scene document) as the renderer will: 0 with *sc, or the problems in `e`. */
static int load_doc(srv_app *app, json_t *doc, const char *docname, obs_scene *sc, char **text,
                    obs_err *e) {
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

/* Rewrites a problem of the common reference's document ("<doc>: /technique/params/x: ...") into
 * a pointer into the request ("request: /common_reference/params/x: ..."). */
static void common_problem(const char *docname, const char *line, obs_err *problems, int *dropped) {
  size_t dl = strlen(docname);
  const char *rest = line;
  if (!strncmp(rest, docname, dl) && !strncmp(rest + dl, ": ", 2)) rest += dl + 2;
  char out[2700];
  if (!strncmp(rest, "/technique/name", 15))
    snprintf(out, sizeof out, "request: /common_reference/technique%s", rest + 15);
  else if (!strncmp(rest, "/technique", 10))
    snprintf(out, sizeof out, "request: /common_reference%s", rest + 10);
  else
    snprintf(out, sizeof out, "request: /common_reference: %s", rest);
  add_problem(problems, dropped, out);
}

/* Registers the reference job `rd` defines (its technique with its params, the reference's
 * quality and seed; `common`: the comparison's common reference, else the reference of candidate
 * `entry`), shared with any reference of the same definition. Returns its index with *key (its
 * params as canonical JSON, malloc'ed), or -1 with the problems reported. */
static int add_reference(srv_app *app, cmp_req *q, expansion *x, const obs_reference_def *rd,
                         int entry, const cmp_common *common, char **key, obs_err *problems,
                         int *dropped) {
  *key = NULL;
  const char *ref_name = rd->technique->name;
  obs_err e = OBS_ERR_INIT;
  obs_backend want = common ? common->backend : q->ref_want, ref_be;
  /* The reference technique may run on fewer backends than rt_ao (path_trace: cpu only). */
  if (srv_pick_backend(rd->technique, want, app->vulkan_lane, &ref_be, &e)) {
    char line[1200];
    if (common)
      snprintf(line, sizeof line, "request: /common_reference/backend: %s", obs_err_message(&e));
    else
      snprintf(line, sizeof line, "request: /reference/backend: the reference of /candidates/%d "
               "(%s): %s", entry, ref_name, obs_err_message(&e));
    add_problem(problems, dropped, line);
    obs_err_free(&e);
    return -1;
  }
  json_t *params = json_deep_copy(rd->params);
  json_object_set_new(params, rd->technique->reference_quality,
                      json_integer(common ? common->samples : q->ref_samples));
  json_object_set_new(params, "seed", json_integer(common ? common->seed : q->ref_seed));
  json_t *rdoc = json_deep_copy(q->base);
  json_object_set_new(rdoc, "technique", technique_obj(ref_name, ref_be, params));
  json_decref(params);
  obs_scene rs;
  memset(&rs, 0, sizeof rs);
  char *rtext = NULL;
  if (!load_doc(app, rdoc, q->docname, &rs, &rtext, &e)) srv_submit_check_limits(app, &rs, 1, &e);
  json_decref(rdoc);
  int found = -1;
  const char *t = e.text;
  for (const char *p = t; e.count && p && *p;) {
    const char *nl = strchr(p, '\n');
    size_t len = nl ? (size_t)(nl - p) : strlen(p);
    char line[2600];
    if (common) {
      snprintf(line, sizeof line, "%.*s", (int)len, p);
      common_problem(q->docname, line, problems, dropped);
    } else {
      /* The reference inherits its definition from the candidate: say which candidate. */
      snprintf(line, sizeof line, "request: /reference: the reference of /candidates/%d (%s): %.*s",
               entry, ref_name, (int)len, p);
      add_problem(problems, dropped, line);
    }
    p = nl ? nl + 1 : p + len;
  }
  char *k = e.count ? NULL
                    : json_dumps(rs.params, JSON_COMPACT | JSON_SORT_KEYS | JSON_REAL_PRECISION(17));
  for (int i = 0; k && i < x->nrefs; i++)
    if (!strcmp(x->refs[i].key, k) && !strcmp(x->refs[i].technique, ref_name)) found = i;
  if (k && found < 0) {
    ref_job *nr = realloc(x->refs, (size_t)(x->nrefs + 1) * sizeof *nr);
    if (nr) {
      x->refs = nr;
      ref_job *r = &x->refs[x->nrefs];
      r->technique = ref_name;
      r->doc = rtext;
      rtext = NULL;
      r->key = strdup(k);
      r->width = rs.width;
      r->height = rs.height;
      r->spp = rs.spp;
      r->work = obs_scene_work(&rs);
      r->backend = ref_be;
      if (r->key) found = x->nrefs++;
    }
  }
  if (!e.count && found < 0) obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
  if (found >= 0) *key = k;
  else free(k);
  free(rtext);
  obs_scene_free(&rs);
  obs_err_free(&e);
  return found;
}

/* The candidate's further measurements: against the common reference when that measures the
 * quantity the candidate estimates (it is the candidate's own reference technique or one its
 * technique declares for another output), and each other output against its declared reference
 * (obs_reference_alt; skipped where the alternative's needs_false parameter is true, as the two
 * are then not the same quantity) or against its own reference job's (obs_output_pair). */
static void add_measures(srv_app *app, cmp_req *q, cand *c, obs_scene *sc, expansion *x,
                         obs_reference_facts *facts, obs_err *problems, int *dropped) {
  if (x->common >= 0) {
    const char *ct = x->refs[x->common].technique;
    int same = !strcmp(ct, x->refs[c->ref].technique);
    for (const obs_reference_alt *a = c->t->reference_alts; a && a->technique; a++)
      same |= !strcmp(a->technique->name, ct);
    if (same) {
      c->common_ref = x->common;
      c->common_key = strdup(x->refs[x->common].key);
    }
  }
  for (const obs_reference_alt *a = c->t->reference_alts; a && a->technique && c->nalt < 4; a++) {
    if (c->against && !strcmp(c->against, a->technique->name)) continue; /* the primary row */
    if (a->needs_false && json_is_true(json_object_get(sc->params, a->needs_false))) continue;
    obs_reference_def rd;
    obs_err e = OBS_ERR_INIT;
    if (obs_technique_reference_against(sc->technique, sc, sc->params, a->technique->name, facts,
                                        &rd, &e)) {
      obs_err_free(&e);
      continue;
    }
    char *key = NULL;
    int r = add_reference(app, q, x, &rd, c->entry, NULL, &key, problems, dropped);
    obs_reference_def_free(&rd);
    if (r < 0) continue;
    c->alt_ref[c->nalt] = r;
    c->alt_output[c->nalt] = NULL;
    c->alt_key[c->nalt++] = key;
  }
  /* Outputs compared with the own reference job's (the bent normals), where it has them. */
  const obs_technique *rt = obs_technique_find(x->refs[c->ref].technique);
  for (const obs_output_pair *q = c->t->compared_outputs; q && q->output && c->nalt < 8; q++) {
    if (!rt || !obs_technique_output(rt, q->reference_output)) continue;
    c->alt_ref[c->nalt] = c->ref;
    c->alt_output[c->nalt] = q->output;
    c->alt_key[c->nalt++] = strdup(x->refs[c->ref].key);
  }
}

/* Validates one candidate like a job (scene rules, parameters, backend, limits), derives its
 * reference and registers it (shared when another candidate has the same definition). */
static void validate_candidate(srv_app *app, cmp_req *q, cand *c, expansion *x,
                               obs_reference_facts *facts, obs_err *problems, int *dropped) {
  json_t *doc = json_deep_copy(q->base);
  json_t *params = candidate_params(q, c);
  json_object_set_new(doc, "technique", technique_obj(c->t->name, c->backend, params));
  json_decref(params);
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
  srv_submit_check_limits(app, &sc, 1, &e);
  if (e.count) {
    remap_problems(&e, q->docname, c, "", problems, dropped);
    goto out;
  }
  /* The reference: the technique the candidate's hook names, with the candidate's definition,
   * the reference's quality (samples) and seed. */
  obs_reference_def rd;
  if (obs_technique_reference_against(sc.technique, &sc, sc.params, c->against, facts, &rd, &e)) {
    char line[1200];
    snprintf(line, sizeof line, "request: /candidates/%d%s: cannot define its reference: %s",
             c->entry, c->against ? "/against" : "", obs_err_message(&e));
    add_problem(problems, dropped, line);
    goto out;
  }
  c->response = rd.response;
  char *key = NULL;
  c->ref = add_reference(app, q, x, &rd, c->entry, NULL, &key, problems, dropped);
  obs_reference_def_free(&rd);
  if (c->ref < 0) goto out;
  c->ref_key = key;
  add_measures(app, q, c, &sc, x, facts, problems, dropped);
  c->doc = text;
  text = NULL;
  c->params_full = json_dumps(sc.params, JSON_COMPACT | JSON_REAL_PRECISION(17));
  c->width = sc.width;
  c->height = sc.height;
  c->spp = sc.spp;
  c->work = obs_scene_work(&sc);
  if (!c->params_full) obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
out:
  free(text);
  obs_scene_free(&sc);
  obs_err_free(&e);
  json_decref(doc);
}

/* A comparison's jobs (candidates and references) within --max-comparison-jobs: each is a queued
 * row with its own copy of the scene, and a request of a few kilobytes can ask for hundreds. */
static int too_many_jobs(srv_app *app, obs_jpath *p, int ncandidates, int njobs) {
  if (njobs <= app->cfg.max_comparison_jobs) return 0;
  size_t m = obs_jpath_push_key(p, "candidates");
  obs_jpath_fail(p,
                 "%d candidates and their references make %s%d jobs; this server takes at most "
                 "max-comparison-jobs = %d per comparison (use fewer candidates)",
                 ncandidates, njobs == ncandidates + 1 ? "at least " : "", njobs,
                 app->cfg.max_comparison_jobs);
  obs_jpath_pop(p, m);
  return 1;
}

/* A reference's samples, seed and backend (p at the object holding them); the backend is checked
 * against the reference technique once it is known. */
static void reference_opts(obs_jpath *p, const json_t *o, long long *samples, long long *seed,
                           obs_backend *backend) {
  obs_json_get_int(p, o, "samples", 0, 1, 65536, samples);
  obs_json_get_int(p, o, "seed", 0, 0, 4294967295LL, seed);
  const char *b = NULL;
  const char *rbe[] = {obs_backend_name(OBS_BACKEND_CPU), obs_backend_name(OBS_BACKEND_VULKAN),
                       obs_backend_name(OBS_BACKEND_AUTO), NULL};
  if (!obs_json_get_string(p, o, "backend", 0, rbe, &b) && b) obs_backend_parse(b, backend);
}

/* The request's "common_reference" (optional): a technique that can serve as a reference, its
 * params (checked with the scene like a job's, once the scene is read) and the reference options;
 * samples, seed and backend default to the request's reference's. */
static void read_common(obs_jpath *p, const json_t *req, cmp_req *q) {
  int absent = 0;
  json_t *cr = obs_json_get_object(p, req, "common_reference", 0, &absent);
  if (!cr) return;
  size_t m = obs_jpath_push_key(p, "common_reference");
  static const char *const keys[] = {"technique", "params", "samples", "backend", "seed", NULL};
  obs_json_check_keys(p, cr, keys);
  cmp_common *c = &q->common;
  c->samples = q->ref_samples;
  c->seed = q->ref_seed;
  c->backend = q->ref_want;
  reference_opts(p, cr, &c->samples, &c->seed, &c->backend);
  const char *tn = NULL;
  if (!obs_json_get_string(p, cr, "technique", 1, NULL, &tn)) {
    c->technique = obs_technique_find(tn);
    size_t k = obs_jpath_push_key(p, "technique");
    char list[512] = "";
    for (size_t i = 0; i < obs_technique_count(); i++) {
      const obs_technique *t = obs_technique_at(i);
      size_t l = strlen(list);
      if (t->reference_quality) snprintf(list + l, sizeof list - l, "%s\"%s\"", l ? ", " : "", t->name);
    }
    if (!c->technique || !c->technique->reference_quality) {
      obs_jpath_fail(p, "must be a technique that can serve as a reference: %s (got %s)", list,
                     obs_json_brief(json_object_get(cr, "technique")));
      c->technique = NULL;
    }
    obs_jpath_pop(p, k);
  }
  c->params = obs_json_get_object(p, cr, "params", 0, &absent);
  /* The reference's quality and seed are the options beside params, as for "reference". */
  const char *own[2] = {c->technique ? c->technique->reference_quality : NULL, "seed"};
  for (int i = 0; i < 2 && c->params; i++) {
    if (!own[i] || !json_object_get(c->params, own[i])) continue;
    size_t k = obs_jpath_push_key(p, "params");
    size_t k2 = obs_jpath_push_key(p, own[i]);
    obs_jpath_fail(p, "is set by /common_reference/%s, not in params", i ? "seed" : "samples");
    obs_jpath_pop(p, k2);
    obs_jpath_pop(p, k);
  }
  q->has_common = c->technique && (c->params || absent);
  obs_jpath_pop(p, m);
}

/* Parses and validates the request; fills `x` with every candidate and reference. Returns 0 or
 * the HTTP status (problems listed). */
static unsigned parse_request(srv_app *app, const char *body, size_t len, cmp_req *q, expansion *x,
                              const char **message, obs_err *problems) {
  memset(q, 0, sizeof *q);
  *message = "request is not a valid comparison";
  if (!body || !len) {
    *message = "request body is empty (send {\"scene_file\": ..., \"candidates\": [...]})";
    return 400;
  }
  unsigned status = srv_submit_read_body(body, len,
                                         "a comparison like {\"scene_file\": ..., "
                                         "\"candidates\": [...]}",
                                         &q->req, message, problems);
  if (status) return status;
  obs_jpath p;
  obs_jpath_init(&p, "request", problems);
  json_t *req = q->req;
  static const char *const keys[] = {"scene_file", "scene",      "set",
                                     "label",      "priority",   "repeats",
                                     "reference",  "candidates", "common_reference",
                                     "budget_ms",
                                     NULL};
  obs_json_check_keys(&p, req, keys);
  /* The budget the comparison's answer is read at (stored with the request). */
  double budget_ms = 0;
  obs_json_get_number(&p, req, "budget_ms", 0, 0, 1e9, 1, 0, &budget_ms);
  q->priority = 50;
  q->repeats = SRV_COMPARE_REPEATS;
  q->ref_samples = SRV_COMPARE_REF_SAMPLES;
  q->ref_seed = REF_SEED;
  q->ref_want = OBS_BACKEND_CPU;
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
    obs_json_check_keys(&p, ref, rkeys);
    reference_opts(&p, ref, &q->ref_samples, &q->ref_seed, &q->ref_want);
    obs_jpath_pop(&p, m);
  }
  read_common(&p, req, q);
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
    /* Each candidate brings its technique; the scene's own gives the params they start from. */
    json_t *copy = json_deep_copy(q->base);
    obs_err ignored = OBS_ERR_INIT;
    q->have_scene = copy && !obs_scene_load_json(&q->scene, copy, q->docname, app->scenes_real,
                                                 NULL, 0, &ignored);
    obs_err_free(&ignored);
    json_decref(copy);
    q->notes = json_array();
    json_object_del(q->base, "technique");
  }
  json_t *cands = obs_json_get_array(&p, req, "candidates", 1, &absent);
  if (cands && json_array_size(cands) == 0) {
    size_t m = obs_jpath_push_key(&p, "candidates");
    obs_jpath_fail(&p, "must list at least one candidate");
    obs_jpath_pop(&p, m);
  }
  if (cands) srv_compare_expand(app, &p, cands, x);
  if (problems->count) return 422;
  /* Before validating hundreds of combinations: every candidate is a job, and at least one
   * reference is another. */
  if (too_many_jobs(app, &p, x->n, x->n + 1)) return 422;
  /* Each candidate's document (and its reference's) is the scene plus its parameters. */
  double copies = 2.0 * x->n * (double)obs_json_count_values(q->base, OBS_JSON_MAX_DEPTH);
  for (int i = 0; i < x->n && copies <= MAX_EXPANDED_VALUES; i++)
    copies += 2.0 * (double)obs_json_count_values(x->c[i].params, OBS_JSON_MAX_DEPTH);
  if (copies > MAX_EXPANDED_VALUES) {
    size_t m = obs_jpath_push_key(&p, "candidates");
    obs_jpath_fail(&p,
                   "%d candidates (and their references) over a scene of %zu JSON values "
                   "make %.0f values; at most %d per comparison (use fewer candidates or a "
                   "smaller scene)",
                   x->n, obs_json_count_values(q->base, OBS_JSON_MAX_DEPTH), copies,
                   MAX_EXPANDED_VALUES);
    obs_jpath_pop(&p, m);
    return 422;
  }
  /* Every combination validated like a job, all problems collected. */
  obs_reference_facts facts;
  memset(&facts, 0, sizeof facts);
  int dropped = 0;
  x->common = -1;
  if (q->has_common) {
    obs_reference_def rd = {.technique = q->common.technique,
                            .params = q->common.params ? json_deep_copy(q->common.params)
                                                       : json_object(),
                            .response = OBS_RESPONSE_IDENTITY};
    char *key = NULL;
    x->common = add_reference(app, q, x, &rd, -1, &q->common, &key, problems, &dropped);
    free(key);
    obs_reference_def_free(&rd);
    if (problems->count) return 422;
  }
  for (int i = 0; i < x->n; i++)
    validate_candidate(app, q, &x->c[i], x, &facts, problems, &dropped);
  if (dropped) obs_err_set(problems, OBS_EINVAL, "request: ... and %d more problems", dropped);
  if (problems->count) return 422;
  if (too_many_jobs(app, &p, x->n, x->n + x->nrefs)) return 422;
  return 0;
}

/* The rows to insert: a job per reference, a job and a candidate row per candidate (borrowing
 * from q and x). */
static void new_rows(const cmp_req *q, const expansion *x, srv_new_job *refs,
                     srv_new_candidate *cs) {
  for (int i = 0; i < x->nrefs; i++) {
    ref_job *rj = &x->refs[i];
    refs[i] =
        (srv_new_job){.priority = (int)q->priority,
                      .label = q->label,
                      .scene = q->docname,
                      .doc = rj->doc,
                      .technique = rj->technique,
                      .backend_requested = obs_backend_name(rj->backend),
                      .lane = rj->backend == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU,
                      .width = rj->width,
                      .height = rj->height,
                      .spp = rj->spp,
                      /* A reference is rendered once: its time is not ranked. */
                      .repeats = 1,
                      .warmup = 0,
                      .work = rj->work,
                      .backend_reason = "reference of a comparison"};
  }
  for (int i = 0; i < x->n; i++) {
    cand *c = &x->c[i];
    cs[i].job =
        (srv_new_job){.priority = (int)q->priority,
                      .label = q->label,
                      .scene = q->docname,
                      .doc = c->doc,
                      .technique = c->t->name,
                      .backend_requested = obs_backend_name(c->backend),
                      .lane = c->backend == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU,
                      .width = c->width,
                      .height = c->height,
                      .spp = c->spp,
                      .repeats = (int)q->repeats,
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
}

/* The further measurements' rows (borrowing from x); ms has room for every one. */
static int new_measures(const expansion *x, srv_new_measure *ms) {
  int n = 0;
  for (int i = 0; i < x->n; i++) {
    const cand *c = &x->c[i];
    if (c->common_ref >= 0)
      ms[n++] = (srv_new_measure){i, c->common_ref, "common", c->common_key, "identity", NULL};
    for (int k = 0; k < c->nalt; k++)
      ms[n++] = (srv_new_measure){i, c->alt_ref[k], "output", c->alt_key[k], "identity",
                                  c->alt_output[k]};
  }
  return n;
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
    srv_compare_expansion_free(&x);
    cmp_req_free(&q);
    return rc;
  }
  srv_new_job *refs = calloc((size_t)x.nrefs + 1, sizeof *refs);
  srv_new_candidate *cs = calloc((size_t)x.n + 1, sizeof *cs);
  srv_new_measure *ms = calloc((size_t)x.n * 9 + 1, sizeof *ms);
  char *request = json_dumps(q.req, JSON_COMPACT | JSON_REAL_PRECISION(17));
  char *notes_text = json_array_size(q.notes) ? json_dumps(q.notes, JSON_COMPACT) : NULL;
  int64_t id = 0;
  unsigned admit = 0;
  int retry = 0;
  int rc = !refs || !cs || !ms || !request ? obs_err_set(&problems, OBS_ENOMEM, "out of memory")
                                           : 0;
  int nms = rc ? 0 : new_measures(&x, ms);
  int width = x.n ? x.c[0].width : 0, height = x.n ? x.c[0].height : 0;
  if (!rc) new_rows(&q, &x, refs, cs);
  if (!rc) {
    srv_new_comparison nc = {.label = q.label,
                             .notes = notes_text,
                             .scene = q.docname,
                             .request = request,
                             .width = width,
                             .height = height,
                             .repeats = (int)q.repeats,
                             .references = refs,
                             .nreferences = x.nrefs,
                             .candidates = cs,
                             .ncandidates = x.n,
                             .measures = ms,
                             .nmeasures = nms};
    admit = srv_admit_comparison(r->app, r->client, &nc, &id, &retry, &problems);
    rc = admit ? OBS_EIO : 0;
  }
  int nrefs = x.nrefs, ncand = x.n;
  free(refs);
  free(cs);
  free(ms);
  free(request);
  free(notes_text);
  srv_compare_expansion_free(&x);
  json_t *notes = json_incref(q.notes);
  cmp_req_free(&q);
  if (admit == 429) {
    json_decref(notes);
    rc = srv_respond_too_busy(r, retry, &problems);
    obs_err_free(&problems);
    return rc;
  }
  if (rc) {
    json_decref(notes);
    return srv_respond_unavailable(r, &problems);
  }
  srv_log("comparison %lld: submitted (%d candidates, %d references)", (long long)id, ncand, nrefs);
  srv_sched_notify(r->app);
  char self[64], csv[72];
  snprintf(self, sizeof self, API "/comparisons/%lld", (long long)id);
  snprintf(csv, sizeof csv, "%s.csv", self);
  /* Values derived from the scene's size, so the client can say so. */
  return srv_respond_created(
      r,
      json_pack("{s:I, s:s, s:i, s:i, s:{s:s, s:s}, s:o}", "id", (json_int_t)id, "state", "running",
                "candidates", ncand, "references", nrefs, "links", "self", self, "csv", csv,
                "notes", notes ? notes : json_array()),
      self);
}
