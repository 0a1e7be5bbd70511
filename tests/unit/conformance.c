/* The conformance suite over the registry (see conformance.h). Everything it knows about a
 * technique comes from the registry: its backends, its needs, its parameter schema (ranges, enums,
 * defaults) and its outputs, so it runs unchanged over any technique that registers. */
#include "conformance.h"
#include "extent.h"
#include "extremes.h"
#include "testutil.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A ball on a ground quad under a quad light, every object with a material, a constant sky: enough
 * for any technique's needs; every length scaled by `s`. */
static char *scene_doc_sized(const obs_technique *t, obs_backend be, const char *params,
                             int materials, int lights, double s, int w, int h) {
  const char *mat = materials ? ",\"material\":{\"reflectivity\":[0.5,0.5,0.5]}" : "";
  /* Techniques that scatter inside media see a marble ball (obs_test_medium_material). */
  const char *ball_mat = materials ? obs_test_medium_material(t) : "";
  char light[512] = "";
  if (lights)
    snprintf(light, sizeof light,
             "\"lights\":[{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,"
             "%.17g],[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]],\"emission\":[4,4,4]}%s],"
             "\"environment\":{\"color\":[0.2,0.2,0.2]},",
             -s, 4 * s, -s, s, 4 * s, -s, s, 4 * s, s, -s, 4 * s, s, obs_test_punctual_light(t));
  char ball[512];
  obs_test_ball(t, 0, s, 0, 0.5 * s, ball, sizeof ball);
  char *doc = malloc(4096);
  snprintf(doc, 4096,
           "{\"camera\":{\"type\":\"perspective\",\"position\":[0,%.17g,%.17g],"
           "\"look_at\":[0,%.17g,0],\"up\":[0,1,0],\"fov_y\":45},"
           "\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,0,%.17g],"
           "[%.17g,0,%.17g],[%.17g,0,%.17g],[%.17g,0,%.17g]]}%s},{%s%s}],"
           "%s\"technique\":{\"name\":\"%s\",\"backend\":\"%s\",\"params\":%s}}",
           3 * s, -4 * s, 0.3 * s, w, h, -5 * s, -5 * s, -5 * s, 5 * s, 5 * s, 5 * s, 5 * s, -5 * s,
           mat, ball, ball_mat, light, t->name, obs_backend_name(be), params ? params : "{}");
  return doc;
}

static char *scene_doc_scaled(const obs_technique *t, obs_backend be, const char *params,
                              int materials, int lights, double s) {
  return scene_doc_sized(t, be, params, materials, lights, s, 24, 16);
}

static char *scene_doc(const obs_technique *t, obs_backend be, const char *params, int materials,
                       int lights) {
  return scene_doc_scaled(t, be, params, materials, lights, 1.0);
}

/* Loads and renders `doc` with `threads` threads; returns the first failing rc (err says why). */
static int render(const char *doc, int threads, obs_result *res, obs_err *err) {
  obs_scene sc;
  memset(res, 0, sizeof *res);
  int rc = obs_scene_load_string(&sc, doc, "conformance.json", NULL, NULL, 0, err);
  if (rc) return rc;
  obs_render_opts o = {.threads = threads};
  rc = obs_render(&sc, &o, res, err);
  obs_scene_free(&sc);
  return rc;
}

typedef int (*pair_fn)(const obs_technique *t, obs_backend be);

static int each_pair(obs_backend be, int *ran, pair_fn fn) {
  int bad = 0, n = 0;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    if (!obs_technique_has_backend(t, be)) continue;
    n++;
    int b = fn(t, be);
    printf("%s/%s: %s\n", t->name, obs_backend_name(be), b ? "FAILED" : "conforms");
    bad += b;
  }
  if (ran) *ran = n;
  return bad;
}

/* The timings' accounting (not their values): summary.json's stages, the render's with the
 * caller's load and write, are each >= 0 (a negative "prepare" or "other" means stages overlap)
 * and sum to its total, up to the rounding of the sums. */
static int stages_account(const char *what, obs_result *res, const obs_scene *sc) {
  res->timings.load_ms = 0.25;
  res->timings.write_ms = 0.5;
  res->timings.total_ms += 0.75;
  json_t *sum = obs_result_summary_json(res, sc);
  json_t *tm = json_object_get(sum, "timings_ms"), *st = json_object_get(tm, "stages"), *v;
  double total = json_number_value(json_object_get(tm, "total")), acc = 0;
  const char *name;
  int bad = 0;
  char list[512] = "";
  size_t len = 0;
  json_object_foreach(st, name, v) {
    double ms = json_number_value(v);
    acc += ms;
    if (len < sizeof list)
      len += (size_t)snprintf(list + len, sizeof list - len, " %s=%.4g", name, ms);
    if (!(ms >= -1e-9 * (1 + total))) printf("FAIL %s: stage %s is %.6g ms\n", what, name, ms), bad++;
  }
  if (!(fabs(acc - total) <= 1e-9 * (1 + total)) || !json_object_get(st, "other"))
    printf("FAIL %s: stages sum to %.9g ms, total %.9g ms:%s\n", what, acc, total, list), bad++;
  else
    printf("     %s: stages%s\n", what, list);
  json_decref(sum);
  return bad;
}

/* Renders `params` and checks the result is sane; `what` labels the failure lines. With `key`
 * (the one parameter set), a refusal by validation that points at another parameter is a
 * cross-field rule (the check hook) and passes: that value needs a partner to be valid. So does
 * one that points at the key itself and names the backend: a value another backend runs. */
static int render_sane(const obs_technique *t, obs_backend be, const char *params, const char *key,
                       const char *what) {
  /* Parameter ends can be the costliest settings (65536 rays or paths per pixel): a small image. */
  char *doc =
      key ? scene_doc_sized(t, be, params, 1, 1, 1.0, 12, 8) : scene_doc(t, be, params, 1, 1);
  obs_result res;
  obs_err err = OBS_ERR_INIT;
  obs_scene sc;
  int bad = 0, rc = obs_scene_load_string(&sc, doc, "conformance.json", NULL, NULL, 0, &err);
  memset(&res, 0, sizeof res);
  if (rc) {
    char own[160];
    snprintf(own, sizeof own, "/technique/params/%s:", key ? key : "");
    const char *m = obs_err_message(&err);
    if (key && strstr(m, own) && strstr(m, "backend"))
      printf("     %s: refused on this backend: %s\n", what, m);
    else if (!key || strstr(m, own) || !strstr(m, "/technique/params/"))
      printf("FAIL %s: refused: %s\n", what, m), bad++;
    else
      printf("     %s: refused by a cross-field rule: %s\n", what, m);
    rc = 0;
    goto done;
  }
  obs_render_opts o = {.threads = 2};
  double t0 = obs_now_ms();
  rc = obs_render(&sc, &o, &res, &err);
  double secs = (obs_now_ms() - t0) / 1e3;
  if (rc)
    printf("FAIL %s: %s\n", what, obs_err_message(&err)), bad++;
  else
    bad += obs_test_check_sane(what, t, &res.image) + stages_account(what, &res, &sc);
  obs_scene_free(&sc);
  /* The costly settings are named, so a slow suite shows where its time goes. */
  if (secs >= 1.0) printf("     %s: rendered in %.1f s\n", what, secs);
done:
  obs_result_free(&res);
  obs_err_free(&err);
  free(doc);
  return bad;
}

static int defaults_pair(const obs_technique *t, obs_backend be) {
  char what[128];
  snprintf(what, sizeof what, "%s/%s defaults", t->name, obs_backend_name(be));
  return render_sane(t, be, "{}", NULL, what);
}

int obs_conformance_defaults(obs_backend be, int *ran) { return each_pair(be, ran, defaults_pair); }

/* The registry's parameter schema of `t` (new reference). */
static json_t *params_schema(const obs_technique *t) {
  json_t *reg = obs_technique_registry_json(), *out = NULL;
  for (size_t i = 0; i < json_array_size(reg); i++) {
    json_t *e = json_array_get(reg, i);
    if (!strcmp(json_string_value(json_object_get(e, "name")), t->name))
      out = json_incref(json_object_get(json_object_get(e, "params_schema"), "properties"));
  }
  json_decref(reg);
  return out;
}

/* The values at the ends of one property's declared range: an inclusive end itself, an exclusive
 * one approached from inside (a zero lower bound by 1e-30: the smallest length a document may
 * ask for is what the technique must survive). Returns how many were written (0..2). */
static int numeric_ends(const json_t *prop, double ends[2]) {
  int n = 0;
  json_t *lo = json_object_get(prop, "minimum"), *xlo = json_object_get(prop, "exclusiveMinimum");
  json_t *hi = json_object_get(prop, "maximum"), *xhi = json_object_get(prop, "exclusiveMaximum");
  if (json_is_number(lo))
    ends[n++] = json_number_value(lo);
  else if (json_is_number(xlo)) {
    double v = json_number_value(xlo);
    ends[n++] = v == 0 ? 1e-30 : v + fabs(v) * 1e-6;
  }
  if (json_is_number(hi))
    ends[n++] = json_number_value(hi);
  else if (json_is_number(xhi))
    ends[n++] = json_number_value(xhi) * (1 - 1e-7);
  return n;
}

/* Companions of a parameter at one of its ends: the technique's other cost drivers held small
 * ("key":value pairs, each left out when it is the parameter under test), so an end that
 * multiplies the work (4096 directions) is not multiplied again by another's default (64 x 64
 * lines per direction). Still a valid setting at that end, and the end's own handling is what
 * the check is about. */
static const char *const *end_companions(const char *name) {
  static const char *const omap[] = {"directions", "16", "bundle_resolution", "16", NULL};
  static const char *const ibl[] = {"shadow_maps", "4", "map_size", "64", NULL};
  static const char *const none[] = {NULL};
  return !strcmp(name, "obscurance_map") ? omap : !strcmp(name, "ibl_shadows") ? ibl : none;
}

/* Ends whose cost is one fixed stage at its largest (a 512^3 proximity volume voxelised and
 * flooded, or its finest level at 512, or its flood run ten times as far; 4096 peeled directions
 * or 512^2 bundles; 65536 volume samples; 65536 paths per pixel, a loop count that sizes no
 * buffer; ibl_shadows' 1024^2 shadow maps: 1 to 60 s each under ASan). They are the same loops
 * as at the default, at a larger count; the release build renders them at the machine's own
 * instruction-set level, and the sanitizer builds and the lower levels' variants (whose paths the
 * default and every other end walk) leave these out, saying so. */
static int release_only_end(const char *technique, const char *key, const char *value) {
  static const char *const ends[][3] = {{"proximity_ao", "volume_res", "512"},
                                        {"proximity_ao", "min_res", "512"},
                                        {"proximity_ao", "propagation_fraction", "10"},
                                        {"obscurance_map", "directions", "4096"},
                                        {"obscurance_map", "bundle_resolution", "512"},
                                        {"volume_ao", "samples", "65536"},
                                        {"isosurface_mesh", "grid", "256"},
                                        {"path_trace", "samples", "65536"},
                                        {"ibl_shadows", "map_size", "1024"}};
  for (size_t i = 0; i < sizeof ends / sizeof ends[0]; i++)
    if (!strcmp(ends[i][0], technique) && !strcmp(ends[i][1], key) && !strcmp(ends[i][2], value))
      return 1;
  return 0;
}

static int param_ends_pair(const obs_technique *t, obs_backend be) {
  json_t *props = params_schema(t);
  const char *key;
  json_t *prop;
  int bad = 0;
  json_object_foreach(props, key, prop) {
    char vals[8][64];
    int nv = 0;
    json_t *type = json_object_get(prop, "type"), *en = json_object_get(prop, "enum");
    const char *ty =
        json_is_string(type) ? json_string_value(type) : json_string_value(json_array_get(type, 0));
    if (json_is_array(en)) {
      for (size_t i = 0; i < json_array_size(en) && nv < 8; i++) {
        char *s = json_dumps(json_array_get(en, i), JSON_ENCODE_ANY);
        snprintf(vals[nv++], sizeof vals[0], "%s", s);
        free(s);
      }
    } else if (ty && !strcmp(ty, "boolean")) {
      snprintf(vals[nv++], sizeof vals[0], "true");
      snprintf(vals[nv++], sizeof vals[0], "false");
    } else if (ty && !strcmp(ty, "array") && json_is_true(json_object_get(prop, "uniqueItems"))) {
      /* A list of object names: every object (null) and none at all. */
      snprintf(vals[nv++], sizeof vals[0], "null");
      snprintf(vals[nv++], sizeof vals[0], "[]");
    } else if (ty && (!strcmp(ty, "number") || !strcmp(ty, "integer"))) {
      double ends[2];
      int ne = numeric_ends(prop, ends);
      for (int k = 0; k < ne; k++)
        snprintf(vals[nv++], sizeof vals[0], !strcmp(ty, "integer") ? "%.0f" : "%.17g", ends[k]);
    }
    char with[128] = "";
    for (const char *const *c = end_companions(t->name); *c; c += 2)
      if (strcmp(c[0], key))
        snprintf(with + strlen(with), sizeof with - strlen(with), ",\"%s\":%s", c[0], c[1]);
    for (int k = 0; k < nv; k++) {
      char params[768], what[1024];
      snprintf(params, sizeof params, "{\"%s\":%s%s}", key, vals[k], with);
      snprintf(what, sizeof what, "%s/%s %s", t->name, obs_backend_name(be), params);
      if ((obs_test_sanitized() || obs_test_isa_variant()) &&
          release_only_end(t->name, key, vals[k]))
        printf("     %s: left to the release build at this CPU's own level\n", what);
      else
        bad += render_sane(t, be, params, key, what);
    }
  }
  json_decref(props);
  return bad;
}

int obs_conformance_param_ends(obs_backend be, int *ran) {
  return each_pair(be, ran, param_ends_pair);
}

static int threads_pair(const obs_technique *t, obs_backend be) {
  char *doc = scene_doc(t, be, "{}", 1, 1);
  obs_result res[3];
  obs_err err = OBS_ERR_INIT;
  int bad = 0;
  for (int k = 0; k < 3; k++) {
    if (render(doc, k + 1, &res[k], &err)) {
      printf("FAIL %s/%s with %d threads: %s\n", t->name, obs_backend_name(be), k + 1,
             obs_err_message(&err));
      bad++;
      continue;
    }
    if (k && !bad) {
      const obs_image *a = &res[0].image, *b = &res[k].image;
      size_t bytes = (size_t)a->width * (size_t)a->height * (size_t)a->nchannels * sizeof(float);
      if (a->nchannels != b->nchannels || memcmp(a->data, b->data, bytes))
        printf("FAIL %s/%s: %d threads differ from 1\n", t->name, obs_backend_name(be), k + 1),
            bad++;
    }
  }
  for (int k = 0; k < 3; k++) obs_result_free(&res[k]);
  obs_err_free(&err);
  free(doc);
  return bad;
}

int obs_conformance_threads(obs_backend be, int *ran) { return each_pair(be, ran, threads_pair); }

/* Loads and renders `doc`, expecting a failure whose message contains `word`. */
static int expect_refusal(const char *what, const char *doc, const char *word) {
  obs_result res;
  obs_err err = OBS_ERR_INIT;
  int rc = render(doc, 2, &res, &err), bad = 0;
  if (!rc) {
    printf("FAIL %s: accepted\n", what);
    bad++;
  } else if (!strstr(obs_err_message(&err), word)) {
    printf("FAIL %s: message does not name \"%s\": %s\n", what, word, obs_err_message(&err));
    bad++;
  }
  obs_result_free(&res);
  obs_err_free(&err);
  return bad;
}

static int refusals_pair(const obs_technique *t, obs_backend be) {
  int bad = 0;
  char what[128];
  for (int b = OBS_BACKEND_CPU; b < OBS_BACKEND_COUNT; b++) {
    if (t->run[b]) continue;
    char *doc = scene_doc(t, (obs_backend)b, "{}", 1, 1);
    snprintf(what, sizeof what, "%s on %s", t->name, obs_backend_name((obs_backend)b));
    bad += expect_refusal(what, doc, obs_backend_name((obs_backend)b));
    free(doc);
  }
  if (t->needs & OBS_NEED_MATERIALS) {
    char *doc = scene_doc(t, be, "{}", 0, 1);
    snprintf(what, sizeof what, "%s/%s without materials", t->name, obs_backend_name(be));
    bad += expect_refusal(what, doc, "material");
    free(doc);
  }
  if (t->needs & OBS_NEED_LIGHTS) {
    char *doc = scene_doc(t, be, "{}", 1, 0);
    snprintf(what, sizeof what, "%s/%s without lights", t->name, obs_backend_name(be));
    bad += expect_refusal(what, doc, "light");
    free(doc);
  }
  if (t->needs & OBS_NEED_MEDIUM) { /* the materials without their media */
    char *doc = scene_doc(t, be, "{}", 0, 1);
    snprintf(what, sizeof what, "%s/%s without media", t->name, obs_backend_name(be));
    bad += expect_refusal(what, doc, "medium");
    free(doc);
  }
  return bad;
}

int obs_conformance_refusals(obs_backend be, int *ran) { return each_pair(be, ran, refusals_pair); }

/* The schema default of parameter `key` of `t`, NaN when it has none or it is not a number. */
static double param_default(const obs_technique *t, const char *key) {
  json_t *props = params_schema(t);
  json_t *d = json_object_get(json_object_get(props, key), "default");
  double v = json_is_number(d) ? json_number_value(d) : NAN;
  json_decref(props);
  return v;
}

/* Into `out`, a params object of `extra` (members, may be "") and every length parameter of `rg`
 * with a default, at that default times s^size_power: the scale-1 scene's lengths scaled by s. */
static void scaled_params(const obs_technique *t, const obs_range *rg, const char *extra, double s,
                          char *out, size_t size) {
  size_t m = (size_t)snprintf(out, size, "{%s", extra);
  for (int i = 0; rg->params[i].name && m < size; i++) {
    double d = param_default(t, rg->params[i].name);
    if (!rg->params[i].size_power || isnan(d)) continue;
    m += (size_t)snprintf(out + m, size - m, "%s\"%s\":%.17g", m > 1 ? "," : "", rg->params[i].name,
                          d * pow(s, rg->params[i].size_power));
  }
  if (m < size) snprintf(out + m, size - m, "}");
}

/* `b` (scale 1) against `r` (scale s) on the primary output's channels: coverage equal, the mean
 * and the share of large differences within the declared tolerance. A depth primary scales with
 * the scene, so it is compared as r / s against b, relative to b. */
static int compare_scaled(const char *what, const obs_technique *t, const obs_image *b,
                          const obs_image *r, double s, const obs_tolerance *tol) {
  int depth = obs_technique_primary(t)->kind == OBS_OUTPUT_DEPTH;
  size_t n = (size_t)b->width * (size_t)b->height;
  const float *ba = obs_image_channel(b, "alpha"), *ra = obs_image_channel(r, "alpha");
  int bad = 0;
  for (size_t i = 0; ba && ra && i < n; i++)
    if ((ba[i] > 0) != (ra[i] > 0)) {
      printf("FAIL %s: coverage differs at pixel %zu\n", what, i);
      bad++;
      break;
    }
  const float *x[3], *y[3];
  double lo, hi;
  int nch = obs_test_primary_channels(t, b, x, &lo, &hi);
  if (!nch || obs_test_primary_channels(t, r, y, &lo, &hi) != nch)
    return printf("FAIL %s: no primary output to compare\n", what), bad + 1;
  for (int c = 0; c < nch; c++) {
    double sum = 0, worst = 0;
    size_t over = 0;
    for (size_t i = 0; i < n; i++) {
      double d = depth ? (x[c][i] != 0 ? fabs((double)y[c][i] / s / (double)x[c][i] - 1) : 0)
                       : fabs((double)x[c][i] - (double)y[c][i]);
      sum += d;
      worst = fmax(worst, d);
      over += d > tol->ao_pixel;
    }
    if (sum / (double)n > tol->ao_mean || (double)over > tol->share * (double)n)
      printf(
          "FAIL %s: primary channel %d mean |d| %.3g (allowed %g), %zu pixels over %g (max "
          "%.3g)\n",
          what, c, sum / (double)n, tol->ao_mean, over, tol->ao_pixel, worst),
          bad++;
  }
  return bad;
}

static int scales_pair(const obs_technique *t, obs_backend be) {
  const obs_range *rg = &t->range[be];
  static const double scales[3] = {1, 1e-4, 1e4};
  obs_result res[3];
  obs_err err = OBS_ERR_INIT;
  int bad = 0;
  memset(res, 0, sizeof res);
  for (int k = 0; k < 3; k++) {
    char params[512];
    scaled_params(t, rg, "", scales[k], params, sizeof params);
    char *doc = scene_doc_scaled(t, be, params, 1, 1, scales[k]);
    char what[160];
    snprintf(what, sizeof what, "%s/%s scaled by %g", t->name, obs_backend_name(be), scales[k]);
    if (render(doc, 2, &res[k], &err)) {
      printf("FAIL %s: %s\n", what, obs_err_message(&err));
      bad++;
    } else {
      bad += obs_test_check_sane(what, t, &res[k].image);
      if (k && res[0].image.data)
        bad += compare_scaled(what, t, &res[0].image, &res[k].image, scales[k] / scales[0],
                              &rg->tol);
    }
    free(doc);
  }
  for (int k = 0; k < 3; k++) obs_result_free(&res[k]);
  obs_err_free(&err);
  return bad;
}

int obs_conformance_scales(obs_backend be, int *ran) { return each_pair(be, ran, scales_pair); }

/* ---- scale invariance where normals cancel ------------------------------------------------
 * A room with leaning walls and a prism lying along z. Several of their triangles have two
 * vertices that differ only in one coordinate, so the edges from the third vertex are
 * (dx, dy, a) and (dx, dy, b) (or the like in another axis) and a normal component comes out as
 * dx dy - dy dx: exactly 0, whatever the scale and translation (equal coordinates stay equal
 * when rounded), but only if nothing fuses the products. A fused multiply-add leaves the rounding
 * error of dx dy instead, with a sign that changes with the scale, and a sampling frame that
 * turns with that sign (Duff et al.'s flips with the sign of z) then changes every direction
 * sampled on that wall. The axis-aligned sphere over a plane of the range check has no such
 * triangle. */

#define CANCEL_W 32
#define CANCEL_H 24
#define CANCEL_FACTORS 24

/* Faces of the room at scale 1: quads (4 vertices) and one triangle (the prism's front). */
typedef struct room_face {
  int n;
  double v[4][3];
} room_face;

static const room_face k_room[] = {
    /* floor, ceiling */
    {4, {{-1.0371, 0, 0}, {-1.0371, 0, 3.1187}, {0.9613, 0, 3.1187}, {0.9613, 0, 0}}},
    {4,
     {{-1.2119, 1.9273, 0},
      {1.1437, 1.9273, 0},
      {1.1437, 1.9273, 3.3719},
      {-1.2119, 1.9273, 3.3719}}},
    /* leaning walls: left and right (top edges along z), back (top edge along x) */
    {4, {{-1.0371, 0, 0}, {-1.2119, 1.9273, 0}, {-1.2119, 1.9273, 3.3719}, {-1.0371, 0, 3.1187}}},
    {4, {{0.9613, 0, 3.1187}, {1.1437, 1.9273, 3.3719}, {1.1437, 1.9273, 0}, {0.9613, 0, 0}}},
    {4,
     {{-1.0371, 0, 3.1187},
      {-1.2119, 1.9273, 3.3719},
      {1.1437, 1.9273, 3.3719},
      {0.9613, 0, 3.1187}}},
    /* the prism: two sloping sides along z and its front */
    {4,
     {{-0.6173, 0, 1.2113},
      {-0.2437, 0.7769, 1.2113},
      {-0.2437, 0.7769, 2.3291},
      {-0.6173, 0, 2.3291}}},
    {4,
     {{0.0911, 0, 2.3291},
      {-0.2437, 0.7769, 2.3291},
      {-0.2437, 0.7769, 1.2113},
      {0.0911, 0, 1.2113}}},
    {3, {{-0.6173, 0, 1.2113}, {0.0911, 0, 1.2113}, {-0.2437, 0.7769, 1.2113}}},
};

/* The room for technique t on backend be at scale s, every position shifted by `off` (volume
 * techniques, which ignore surfaces, see two procedural balls where the prism stands). */
static char *room_doc(const obs_technique *t, obs_backend be, const char *params, double s,
                      const double off[3]) {
  size_t cap = 8192, n = 0;
  char *doc = malloc(cap);
#define PUT(...) (n += (size_t)snprintf(doc + n, n < cap ? cap - n : 0, __VA_ARGS__))
#define P(x, y, z) s *(x) + off[0], s *(y) + off[1], s *(z) + off[2]
  PUT("{\"camera\":{\"type\":\"perspective\",\"fov_y\":55,\"position\":[%.17g,%.17g,%.17g],"
      "\"look_at\":[%.17g,%.17g,%.17g],\"up\":[0,1,0]},"
      "\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},\"objects\":[",
      P(0.1713, 1.2219, -0.9), P(-0.1, 0.6, 1.9), CANCEL_W, CANCEL_H);
  char mat[160];
  snprintf(mat, sizeof mat, "%s}", obs_test_medium_material(t));
  if (t->needs & OBS_NEED_VOLUME) {
    char ball[512];
    obs_test_ball(t, P(-0.3, 0.6, 1.7), 0.55 * s, ball, sizeof ball);
    PUT("{%s%s,", ball, mat);
    obs_test_ball(t, P(0.5, 0.35, 2.2), 0.35 * s, ball, sizeof ball);
    PUT("{%s%s", ball, mat);
  } else {
    for (size_t f = 0; f < sizeof k_room / sizeof k_room[0]; f++) {
      const room_face *q = &k_room[f];
      PUT("%s{\"shape\":{\"type\":\"%s\",\"vertices\":[", f ? "," : "",
          q->n == 4 ? "quad" : "triangle");
      for (int i = 0; i < q->n; i++)
        PUT("%s[%.17g,%.17g,%.17g]", i ? "," : "", P(q->v[i][0], q->v[i][1], q->v[i][2]));
      PUT("]}%s", mat);
    }
  }
  PUT("]");
  if (t->needs & OBS_NEED_MEDIUM) /* media are lit by punctual lights only */
    PUT(",\"lights\":[%s]", obs_test_punctual_light(t) + 1);
  else if (!(t->needs & OBS_NEED_VOLUME)) /* volume techniques light with points and directions */
    PUT(",\"lights\":[{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
        "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]],\"emission\":[4,4,4]}%s]",
        P(-0.31, 1.9, 1.3), P(0.29, 1.9, 1.3), P(0.29, 1.9, 1.9), P(-0.31, 1.9, 1.9), "");
  PUT(",\"environment\":{\"color\":[0.2,0.2,0.2]},"
      "\"technique\":{\"name\":\"%s\",\"backend\":\"%s\",\"params\":%s}}",
      t->name, obs_backend_name(be), params);
#undef P
#undef PUT
  if (n >= cap) doc[0] = 0; /* a truncated document fails to load, naming nothing false */
  return doc;
}

/* The range check's cheap settings, and coarser fields and maps: the room has eight objects. */
static void room_params(const obs_technique *t, const obs_range *rg, double s, char *out,
                        size_t size) {
  char extra[256];
  const char *fast = obs_extremes_fast_params(t->name), *more = "";
  if (!strcmp(t->name, "proximity_ao")) more = "\"volume_res\":48,\"min_res\":16";
  if (!strcmp(t->name, "obscurance_map"))
    more = "\"samples\":16,\"bundle_resolution\":32"; /* 16 directions: the fast params */
  snprintf(extra, sizeof extra, "%s%s%s", fast, *fast && *more ? "," : "", more);
  scaled_params(t, rg, extra, s, out, size);
}

/* Whether the primary output of a and b has the same bits. */
static int same_primary(const obs_technique *t, const obs_image *a, const obs_image *b) {
  const float *x[3], *y[3];
  double lo, hi;
  int nch = obs_test_primary_channels(t, a, x, &lo, &hi);
  if (!nch || obs_test_primary_channels(t, b, y, &lo, &hi) != nch) return 0;
  size_t bytes = (size_t)a->width * (size_t)a->height * sizeof(float);
  for (int c = 0; c < nch; c++)
    if (memcmp(x[c], y[c], bytes)) return 0;
  return 1;
}

/* Loads and renders `doc` with 2 threads; fills *size with the scene's size. */
static int render_sized(const char *doc, obs_result *res, double *size, obs_err *err) {
  obs_scene sc;
  memset(res, 0, sizeof *res);
  int rc = obs_scene_load_string(&sc, doc, "room.json", NULL, NULL, 0, err);
  if (rc) return rc;
  obs_extent ex = {0};
  rc = obs_scene_extent(&sc, &ex, err);
  *size = ex.size;
  obs_render_opts o = {.threads = 2};
  if (!rc) rc = obs_render(&sc, &o, res, err);
  obs_scene_free(&sc);
  return rc;
}

static int cancel_pair(const obs_technique *t, obs_backend be) {
  const obs_range *rg = &t->range[be];
  if (!(rg->size_max > 0))
    return printf("FAIL %s/%s declares no range\n", t->name, obs_backend_name(be)), 1;
  const double zero[3] = {0, 0, 0};
  char params[512], what[256];
  obs_err err = OBS_ERR_INIT;
  obs_result base;
  double size = 0, worst_mean = 0, worst_share = 0;
  int bad = 0, same = 0;
  snprintf(what, sizeof what, "%s/%s room at scale 1", t->name, obs_backend_name(be));
  room_params(t, rg, 1, params, sizeof params);
  char *doc = room_doc(t, be, params, 1, zero);
  int rc = render_sized(doc, &base, &size, &err);
  free(doc);
  if (rc || !(size > 0)) {
    printf("FAIL %s: %s\n", what, rc ? obs_err_message(&err) : "no size");
    obs_result_free(&base);
    obs_err_free(&err);
    return 1;
  }
  bad += obs_test_check_sane(what, t, &base.image) + obs_extremes_no_warnings(what, &base);
  /* Both ends of the size range (just inside) and 22 factors spaced evenly in log between them;
   * every other one also moved 3 sizes away from the origin. */
  const double lo = rg->size_min / size * (1 + 1e-6), hi = rg->size_max / size * (1 - 1e-6);
  for (int k = 0; k < CANCEL_FACTORS; k++) {
    double s = lo * pow(hi / lo, (double)k / (CANCEL_FACTORS - 1)), off[3] = {0, 0, 0};
    if (k & 1)
      for (int c = 0; c < 3; c++) off[c] = 3 * size * s * (c == 0 ? 0.36 : c == 1 ? 0.48 : 0.8);
    snprintf(what, sizeof what, "%s/%s room scaled by %.6g%s", t->name, obs_backend_name(be), s,
             k & 1 ? ", 3 sizes from the origin" : "");
    room_params(t, rg, s, params, sizeof params);
    doc = room_doc(t, be, params, s, off);
    obs_result res;
    double sz;
    obs_err_clear(&err);
    rc = render_sized(doc, &res, &sz, &err);
    free(doc);
    if (rc) {
      printf("FAIL %s: %s\n", what, obs_err_message(&err));
      bad++;
    } else {
      obs_extremes_dev dev;
      bad += obs_test_check_sane(what, t, &res.image) + obs_extremes_no_warnings(what, &res);
      bad += obs_extremes_compare(what, t, &base.image, &res.image, s, &rg->tol, &dev);
      same += same_primary(t, &base.image, &res.image);
      worst_mean = fmax(worst_mean, dev.mean);
      worst_share = fmax(worst_share, dev.share);
    }
    obs_result_free(&res);
  }
  printf(
      "     %s/%s room: %d of %d factors in [%.3g, %.3g] give scale 1's bits; worst mean |d| "
      "%.3g, worst share over %g %.3g\n",
      t->name, obs_backend_name(be), same, CANCEL_FACTORS, lo, hi, worst_mean, rg->tol.ao_pixel,
      worst_share);
  obs_result_free(&base);
  obs_err_free(&err);
  return bad;
}

int obs_conformance_cancellation(obs_backend be, int *ran) {
  return each_pair(be, ran, cancel_pair);
}
