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
  const char *ref_name = rd.technique->name;
  /* The reference technique may run on fewer backends than rt_ao (path_trace: cpu only). */
  obs_backend ref_be;
  if (srv_pick_backend(rd.technique, q->ref_want, app->vulkan_lane, &ref_be, &e)) {
    char line[1200];
    snprintf(line, sizeof line,
             "request: /reference/backend: the reference of /candidates/%d "
             "(%s): %s",
             c->entry, ref_name, obs_err_message(&e));
    add_problem(problems, dropped, line);
    obs_reference_def_free(&rd);
    goto out;
  }
  json_object_set_new(rd.params, rd.technique->reference_quality, json_integer(q->ref_samples));
  json_object_set_new(rd.params, "seed", json_integer(q->ref_seed));
  json_t *rdoc = json_deep_copy(q->base);
  json_object_set_new(rdoc, "technique", technique_obj(ref_name, ref_be, rd.params));
  obs_reference_def_free(&rd);
  obs_scene rs;
  memset(&rs, 0, sizeof rs);
  char *rtext = NULL;
  obs_err re = OBS_ERR_INIT;
  if (!load_doc(app, rdoc, q->docname, &rs, &rtext, &re)) srv_submit_check_limits(app, &rs, 1, &re);
  json_decref(rdoc);
  if (re.count) {
    /* The reference inherits its definition from the candidate: say which candidate. */
    const char *t = re.text;
    for (const char *p = t; p && *p;) {
      const char *nl = strchr(p, '\n');
      size_t len = nl ? (size_t)(nl - p) : strlen(p);
      char line[2600];
      snprintf(line, sizeof line,
               "request: /reference: the reference of /candidates/%d "
               "(%s): %.*s",
               c->entry, ref_name, (int)len, p);
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
    if (!strcmp(x->refs[i].key, key) && !strcmp(x->refs[i].technique, ref_name)) found = i;
  if (key && found < 0) {
    ref_job *nr = realloc(x->refs, (size_t)(x->nrefs + 1) * sizeof *nr);
    if (nr) {
      x->refs = nr;
      ref_job *r = &x->refs[x->nrefs];
      r->technique = ref_name;
      r->doc = rtext;
      rtext = NULL;
      r->key = key;
      key = NULL;
      r->width = rs.width;
      r->height = rs.height;
      r->spp = rs.spp;
      r->work = obs_scene_work(&rs);
      r->backend = ref_be;
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
  c->work = obs_scene_work(&sc);
  if (found < 0 || !c->params_full || !c->ref_key)
    obs_err_set(problems, OBS_ENOMEM, "request: out of memory");
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
  static const char *const keys[] = {"scene_file", "scene",     "set",        "label", "priority",
                                     "repeats",    "reference", "candidates", "budget_ms",
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
    obs_json_get_int(&p, ref, "samples", 0, 1, 65536, &q->ref_samples);
    obs_json_get_int(&p, ref, "seed", 0, 0, 4294967295LL, &q->ref_seed);
    const char *b = NULL;
    const char *rbe[] = {obs_backend_name(OBS_BACKEND_CPU), obs_backend_name(OBS_BACKEND_VULKAN),
                         obs_backend_name(OBS_BACKEND_AUTO), NULL};
    /* Checked against each reference technique once the candidates name them. */
    if (!obs_json_get_string(&p, ref, "backend", 0, rbe, &b) && b)
      obs_backend_parse(b, &q->ref_want);
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
  char *request = json_dumps(q.req, JSON_COMPACT | JSON_REAL_PRECISION(17));
  char *notes_text = json_array_size(q.notes) ? json_dumps(q.notes, JSON_COMPACT) : NULL;
  int64_t id = 0;
  unsigned admit = 0;
  int retry = 0;
  int rc = !refs || !cs || !request ? obs_err_set(&problems, OBS_ENOMEM, "out of memory") : 0;
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
                             .ncandidates = x.n};
    admit = srv_admit_comparison(r->app, r->client, &nc, &id, &retry, &problems);
    rc = admit ? OBS_EIO : 0;
  }
  int nrefs = x.nrefs, ncand = x.n;
  free(refs);
  free(cs);
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
