/* A comparison's references as the comparison document names them (docs/comparisons.md,
 * "References"): what defines each one and its label, made once here; and the ranking of the
 * candidates within each group of one reference, since errors measured against different
 * references are not comparable. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "compare_internal.h"
#include "obscurad.h"

json_t *srv_compare_definition(const char *technique, const json_t *params) {
  const obs_technique *t = obs_technique_find(technique);
  json_t *d = json_object();
  /* The reference technique's own reference keys are the parameters that define its quantity
   * (rt_ao: weighting, falloff, max_distance, tau); the rest (samples, sampler, seed) only set how
   * close it comes. */
  for (const char *const *k = t ? t->reference_keys : NULL; k && *k; k++) {
    json_t *v = json_object_get(params, *k);
    if (v) json_object_set(d, *k, v);
  }
  return d;
}

char *srv_compare_label(const char *technique, const json_t *definition, const char *response) {
  char buf[1024];
  size_t n = (size_t)snprintf(buf, sizeof buf, "%s", technique ? technique : "?");
  const char *key;
  json_t *v;
  int first = 1;
  json_object_foreach((json_t *)definition, key, v) {
    char val[96];
    if (json_is_string(v)) snprintf(val, sizeof val, "%s", json_string_value(v));
    else if (json_is_number(v)) snprintf(val, sizeof val, "%.4g", json_number_value(v));
    else if (json_is_null(v)) snprintf(val, sizeof val, "none");
    else {
      char *t = json_dumps(v, JSON_ENCODE_ANY | JSON_COMPACT);
      snprintf(val, sizeof val, "%s", t ? t : "?");
      free(t);
    }
    if (n < sizeof buf)
      n += (size_t)snprintf(buf + n, sizeof buf - n, "%s%s %s", first ? ": " : ", ", key, val);
    first = 0;
  }
  if (response && strcmp(response, "identity") && n < sizeof buf)
    snprintf(buf + n, sizeof buf - n, "; mapped through %s", response);
  return strdup(buf);
}

/* ---- ranking within reference groups --------------------------------------------------------- */

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* How far the reference lets the candidates of one group be ranked (docs/comparisons.md,
 * "Ranking"), from their metrics objects: the largest reference noise, how many are at reference
 * accuracy, how many neighbours in RMSE order lie within that noise, and a warning when the
 * reference is too noisy to rank them: some candidate is at reference accuracy, or the noise is
 * at least half the spread of their RMSEs (max - min) and at least a tenth of the smallest. The
 * second bound: a reference's noise s adds s^2 to every candidate's MSE alike, moving an RMSE e
 * to sqrt(e^2 + s^2), which keeps their order; it can only matter where it moves them by a
 * visible share, and at s = e/10 that share is 0.5 %. Below it, RMSEs within the noise of each
 * other (a technique on two backends) are ties, not a reference too noisy to rank: more
 * reference samples would not tell them apart. */
static json_t *ranking_of(json_t *const *ms, size_t n) {
  size_t m = 0, at_ref = 0, ties = 0;
  double noise = NAN, *e = calloc(n + 1, sizeof *e);
  for (size_t i = 0; i < n; i++) {
    json_t *rm = json_object_get(ms[i], "rmse"), *rn = json_object_get(ms[i], "ref_noise");
    if (!json_is_number(rm)) continue;
    if (json_is_number(rn) && !(json_number_value(rn) <= noise)) noise = json_number_value(rn);
    if (json_is_true(json_object_get(ms[i], "at_reference_accuracy"))) at_ref++;
    if (e) e[m++] = json_number_value(rm);
  }
  const char *why = NULL;
  char msg[400];
  if (e && m) qsort(e, m, sizeof *e, cmp_double);
  if (e && m > 1 && noise > 0)
    for (size_t i = 1; i < m; i++) ties += e[i] - e[i - 1] <= noise;
  if (at_ref)
    why = "at reference accuracy";
  else if (e && m > 1 && noise > 0 && noise >= 0.5 * (e[m - 1] - e[0]) && noise >= 0.1 * e[0])
    why = "noise";
  if (why && at_ref)
    snprintf(msg, sizeof msg,
             "the reference is too noisy to rank the candidates: %zu of %zu are at reference "
             "accuracy (RMSE below twice its noise %.3g), so their RMSEs measure the reference's "
             "noise, not their error; render the reference with more samples",
             at_ref, m, noise);
  else if (why)
    snprintf(msg, sizeof msg,
             "the reference is too noisy to rank the candidates: its noise %.3g is at least half "
             "the spread of their RMSEs (%.3g to %.3g); render the reference with more samples",
             noise, e[0], e[m - 1]);
  json_t *r =
      json_pack("{s:o, s:I, s:I, s:b, s:o}", "ref_noise", num_or_null(noise),
                "at_reference_accuracy", (json_int_t)at_ref, "ties_within_noise", (json_int_t)ties,
                "noisy_reference", why != NULL, "warning", why ? json_string(msg) : json_null());
  free(e);
  return r;
}

/* The overall ranking facts of several groups: the largest noise, the counts summed, and each
 * group's warning under its reference's id. */
static json_t *ranking_merged(json_t *groups) {
  if (json_array_size(groups) == 1)
    return json_incref(json_object_get(json_array_get(groups, 0), "ranking"));
  double noise = NAN;
  json_int_t at_ref = 0, ties = 0;
  int noisy = 0;
  char msg[1600] = "";
  size_t n = 0;
  for (size_t g = 0; g < json_array_size(groups); g++) {
    json_t *gr = json_array_get(groups, g), *r = json_object_get(gr, "ranking");
    json_t *rn = json_object_get(r, "ref_noise");
    if (json_is_number(rn) && !(json_number_value(rn) <= noise)) noise = json_number_value(rn);
    at_ref += json_integer_value(json_object_get(r, "at_reference_accuracy"));
    ties += json_integer_value(json_object_get(r, "ties_within_noise"));
    noisy |= json_is_true(json_object_get(r, "noisy_reference"));
    const char *w = json_string_value(json_object_get(r, "warning"));
    if (w && n < sizeof msg)
      n += (size_t)snprintf(msg + n, sizeof msg - n, "%s%s: %s", n ? "; " : "",
                            json_string_value(json_object_get(gr, "reference")), w);
  }
  return json_pack("{s:o, s:I, s:I, s:b, s:o}", "ref_noise", num_or_null(noise),
                   "at_reference_accuracy", at_ref, "ties_within_noise", ties, "noisy_reference",
                   noisy, "warning", noisy ? json_string(msg) : json_null());
}

/* The Pareto set of the candidates `idx[0..k)` of one group: marks each one's `holder` (the
 * candidate object, or its "common" object) "pareto"; appends the optimal indices by ascending
 * time (then index) to `out`. */
static void pareto_of(json_t *const *holder, const obs_pareto_point *pts, const size_t *idx,
                      size_t k, json_t *out) {
  obs_pareto_point *sub = calloc(k + 1, sizeof *sub);
  unsigned char *opt = calloc(k + 1, 1);
  if (sub && opt) {
    for (size_t j = 0; j < k; j++) sub[j] = pts[idx[j]];
    obs_metrics_pareto(sub, k, opt, NULL);
  }
  for (size_t j = 0; j < k; j++) {
    int on = sub && opt && opt[j];
    json_object_set_new(holder[idx[j]], "pareto", json_boolean(on));
    if (!on) continue;
    size_t at = json_array_size(out);
    while (at > 0) {
      size_t prev = (size_t)json_integer_value(json_array_get(out, at - 1));
      if (!(pts[prev].time_ms > pts[idx[j]].time_ms)) break;
      at--;
    }
    json_array_insert_new(out, at, json_integer((json_int_t)idx[j]));
  }
  free(sub);
  free(opt);
}

json_t *srv_compare_rank(json_t *const *holder, json_t *const *metrics, const char *const *group,
                         const obs_pareto_point *pts, size_t n, json_t **pareto,
                         json_t **ranking) {
  json_t *groups = json_array();
  *pareto = json_array();
  size_t *idx = calloc(n + 1, sizeof *idx);
  json_t **ms = calloc(n + 1, sizeof *ms);
  unsigned char *done = calloc(n + 1, 1);
  for (size_t i = 0; idx && ms && done && i < n; i++) {
    if (done[i] || !group[i]) continue;
    size_t k = 0;
    for (size_t j = i; j < n; j++)
      if (!done[j] && group[j] && !strcmp(group[j], group[i])) {
        done[j] = 1;
        ms[k] = metrics[j];
        idx[k++] = j;
      }
    json_t *gp = json_array(), *members = json_array();
    pareto_of(holder, pts, idx, k, gp);
    for (size_t j = 0; j < k; j++) json_array_append_new(members, json_integer((json_int_t)idx[j]));
    /* The overall set: every group's optimal candidates, by ascending time. */
    for (size_t j = 0; j < json_array_size(gp); j++) {
      json_int_t v = json_integer_value(json_array_get(gp, j));
      size_t at = json_array_size(*pareto);
      while (at > 0 &&
             pts[json_integer_value(json_array_get(*pareto, at - 1))].time_ms > pts[v].time_ms)
        at--;
      json_array_insert_new(*pareto, at, json_integer(v));
    }
    json_array_append_new(groups, json_pack("{s:s, s:o, s:o, s:o}", "reference", group[i],
                                            "candidates", members, "pareto", gp, "ranking",
                                            ranking_of(ms, k)));
  }
  *ranking = json_array_size(groups) ? ranking_merged(groups) : ranking_of(NULL, 0);
  free(idx);
  free(ms);
  free(done);
  return groups;
}
