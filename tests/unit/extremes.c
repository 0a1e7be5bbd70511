/* The guaranteed-range conformance check (see extremes.h): a sphere over a plane, built in memory,
 * seen straight down; every case is rendered at scale 1 at the origin and again scaled to each end
 * of the declared size range, translated to the declared limit, and both, with the length
 * parameters scaled along; then compared within the declared tolerance. The sanitizer builds
 * render a subset (run_case, check_pair). */
#include "extremes.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "extent.h"
#include "testutil.h"

#define EXT_W 32
#define EXT_H 32
/* Inside an end by this factor, so rounding of the extent cannot put the case outside. */
#define EXT_MARGIN 1e-6
#define DEG (3.14159265358979323846 / 180)

/* A view of the test scene at scale 1: a perspective camera (fov_y degrees) or an orthographic
 * one, at height h straight above the plane, which reaches P to every side. */
typedef struct camcfg {
  int ortho;
  double fov;
  const char *label;
} camcfg;

typedef struct ext_case {
  const obs_technique *t;
  obs_backend be;
  const obs_range *r;
  camcfg cam;
  /* Length parameters at scale 1 (size_power != 0): value = rel * size^power; NaN = default. */
  double rel[OBS_MAX_PARAM_RANGES];
  char label[160];
} ext_case;

const char *obs_extremes_fast_params(const char *name) {
  if (!strcmp(name, "rt_ao")) return "\"samples\":16";
  if (!strcmp(name, "ssao")) return "\"samples\":8";
  if (!strcmp(name, "hbao")) return "\"directions\":4,\"steps\":4";
  if (!strcmp(name, "path_trace")) return "\"samples\":16,\"max_bounces\":4";
  if (!strcmp(name, "obscurance")) return "\"samples\":16,\"light_samples\":1";
  /* 16 directions: the fewest whose standard errors are calibrated (fewer warn). */
  if (!strcmp(name, "obscurance_map")) return "\"directions\":16";
  if (!strcmp(name, "ibl_shadows")) return "\"shadow_maps\":8,\"map_size\":64";
  if (!strcmp(name, "sss_single")) return "\"map_size\":128";
  return "";
}

static void cam_geometry(const camcfg *c, double *h, double *half, double *P) {
  *half = c->ortho ? 2.5 : fmax(2.5, 5 * tan(c->fov * DEG / 2));
  *h = c->ortho ? 5 : fmax(5, *half / tan(c->fov * DEG / 2));
  *P = fmax(6, 1.6 * *half);
}

/* The document of case `c` at scale s with every world position shifted by `off`. */
static char *scene_json(const ext_case *c, double s, const double off[3], double size) {
  double h, half, P;
  cam_geometry(&c->cam, &h, &half, &P);
  char params[512];
  int n = snprintf(params, sizeof params, "%s", obs_extremes_fast_params(c->t->name));
  for (int i = 0; c->r->params[i].name; i++) {
    if (isnan(c->rel[i])) continue;
    double v = c->rel[i] * pow(size * s, c->r->params[i].size_power);
    n += snprintf(params + n, sizeof params - (size_t)n, "%s\"%s\":%.17g", n ? "," : "",
                  c->r->params[i].name, v);
  }
  char cam[512];
  if (c->cam.ortho)
    snprintf(cam, sizeof cam, "\"type\":\"orthographic\",\"height\":%.17g", 2 * half * s);
  else
    snprintf(cam, sizeof cam, "\"type\":\"perspective\",\"fov_y\":%.17g", c->cam.fov);
#define X(x) ((x) * s + off[0])
#define Y(y) ((y) * s + off[1])
#define Z(z) ((z) * s + off[2])
  /* Techniques that shade with materials see grey surfaces under a white sky. */
  int lit = (c->t->needs & OBS_NEED_MATERIALS) != 0;
  const char *mat = lit ? ",\"material\":{\"reflectivity\":[0.5,0.5,0.5]}" : "";
  /* Techniques that scatter inside media see a marble ball under a directional light. */
  int medium = (c->t->needs & OBS_NEED_MEDIUM) != 0;
  const char *ball_mat = medium ? obs_test_medium_material(c->t) : mat;
  char ball[512], ground[512];
  obs_test_ball(c->t, X(0.5), Y(1.25), Z(0.3), 1.0 * s, ball, sizeof ball);
  /* Volume techniques see a big sphere volume touching y = 0 in place of the ground quad. */
  if (c->t->needs & OBS_NEED_VOLUME)
    obs_test_ball(c->t, X(0), Y(-P), Z(0), P * s, ground, sizeof ground);
  else
    snprintf(ground, sizeof ground,
             "\"shape\":{\"type\":\"quad\",\"vertices\":[[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g],"
             "[%.17g,%.17g,%.17g],[%.17g,%.17g,%.17g]]}",
             X(-P), Y(0), Z(-P), X(-P), Y(0), Z(P), X(P), Y(0), Z(P), X(P), Y(0), Z(-P));
  char *doc = malloc(4096);
  snprintf(doc, 4096,
           "{\"camera\":{%s,\"position\":[%.17g,%.17g,%.17g],\"look_at\":[%.17g,%.17g,%.17g],"
           "\"up\":[0,0,-1]},\"image\":{\"width\":%d,\"height\":%d,\"spp\":1},"
           "\"objects\":[{%s%s},{%s%s}],%s"
           "%s\"technique\":{\"name\":\"%s\",\"backend\":\"%s\",\"params\":{%s}}}",
           cam, X(0), Y(h), Z(0), X(0), Y(0), Z(0), EXT_W, EXT_H, ground, mat, ball, ball_mat,
           medium ? "\"lights\":[{\"type\":\"directional\",\"direction\":[0.3,-1,0.2],"
                    "\"emission\":[3,3,3]}],"
                  : "",
           lit ? "\"environment\":{\"color\":[1,1,1]}," : "", c->t->name,
           obs_backend_name(c->be), params);
#undef X
#undef Y
#undef Z
  return doc;
}

/* Loads and renders; returns the render's rc (the load must succeed), filling *ex. */
static int render_doc(const char *doc, obs_result *res, obs_extent *ex, obs_err *err) {
  obs_scene sc;
  int rc = obs_scene_load_string(&sc, doc, "extremes.json", NULL, NULL, 0, err);
  if (rc) return rc;
  rc = obs_scene_extent(&sc, ex, err);
  obs_render_opts o = {.threads = 2};
  if (!rc) rc = obs_render(&sc, &o, res, err);
  obs_scene_free(&sc);
  return rc;
}

int obs_extremes_compare(const char *what, const obs_technique *t, const obs_image *b,
                         const obs_image *r, double s, const obs_tolerance *tol,
                         obs_extremes_dev *dev) {
  size_t n = (size_t)b->width * (size_t)b->height, cov = 0, ao_out = 0, n_out = 0, z_out = 0;
  const float *ba = obs_image_channel(b, "alpha"), *ra = obs_image_channel(r, "alpha");
  const float *bo[3], *ro[3];
  double lo, hi;
  int nch = obs_test_primary_channels(t, b, bo, &lo, &hi);
  if (obs_test_primary_channels(t, r, ro, &lo, &hi) != nch || !nch)
    return printf("FAIL %s: no primary output to compare\n", what), 1;
  /* A depth primary scales with the scene: r / s against b, relative to b. */
  int depth = obs_technique_primary(t)->kind == OBS_OUTPUT_DEPTH;
  const float *bz = obs_image_channel(b, "depth.Z"), *rz = obs_image_channel(r, "depth.Z");
  const char *nn[3] = {"normal.X", "normal.Y", "normal.Z"};
  int bad = 0;
  size_t alpha_diff = 0;
  double sum = 0, worst = 0, worst_n = 0, worst_z = 0;
  for (size_t i = 0; i < n; i++) {
    if (ba && ra && (ba[i] > 0) != (ra[i] > 0)) alpha_diff++;
    if (ba && !(ba[i] > 0)) continue;
    cov++;
    double d = 0; /* the largest difference over the primary output's channels */
    for (int k = 0; k < nch; k++)
      d = fmax(d, depth ? (bo[k][i] != 0 ? fabs((double)ro[k][i] / s / (double)bo[k][i] - 1) : 0)
                        : fabs((double)bo[k][i] - (double)ro[k][i]));
    sum += d;
    worst = fmax(worst, d);
    ao_out += d > tol->ao_pixel;
    double dn = 0;
    for (int k = 0; k < 3; k++) {
      const float *x = obs_image_channel(b, nn[k]), *y = obs_image_channel(r, nn[k]);
      if (x && y) dn = fmax(dn, fabs((double)x[i] - (double)y[i]));
    }
    worst_n = fmax(worst_n, dn);
    n_out += dn > tol->normal;
    if (bz && rz) {
      double dz = fabs((double)rz[i] / s - (double)bz[i]) / fabs((double)bz[i]);
      worst_z = fmax(worst_z, dz);
      z_out += !(dz <= tol->depth_rel);
    }
  }
  double allowed = tol->share * (double)cov;
  if (dev)
    *dev =
        (obs_extremes_dev){cov ? sum / (double)cov : 0.0, worst, cov ? (double)ao_out / cov : 0.0};
  if (getenv("OBS_EXTREMES_VERBOSE"))
    printf("     %s: primary mean %.3g max %.3g (%zu over), normal max %.3g, depth max %.3g\n",
           what, cov ? sum / (double)cov : 0.0, worst, ao_out, worst_n, worst_z);
  if (alpha_diff) printf("FAIL %s: coverage differs on %zu pixels\n", what, alpha_diff), bad++;
  if (cov && sum / (double)cov > tol->ao_mean)
    printf("FAIL %s: primary mean |d| %.3g > %g\n", what, sum / (double)cov, tol->ao_mean), bad++;
  if ((double)ao_out > allowed)
    printf("FAIL %s: primary |d| > %g on %zu of %zu pixels (max %.3g)\n", what, tol->ao_pixel,
           ao_out, cov, worst),
        bad++;
  if ((double)n_out > allowed)
    printf("FAIL %s: normal |d| > %g on %zu of %zu pixels (max %.3g)\n", what, tol->normal, n_out,
           cov, worst_n),
        bad++;
  if ((double)z_out > allowed)
    printf("FAIL %s: depth/s relative |d| > %g on %zu of %zu pixels (max %.3g)\n", what,
           tol->depth_rel, z_out, cov, worst_z),
        bad++;
  return bad;
}

int obs_extremes_no_warnings(const char *what, const obs_result *res) {
  int n = 0;
  for (int i = 0; i < res->nwarnings; i++) {
    if (strstr(res->warnings[i], "so the image is likely")) continue;
    if (strstr(res->warnings[i], "pixels across the screen (under one)")) continue;
    printf("FAIL %s: warned: %s\n", what, res->warnings[i]);
    n++;
  }
  return n ? 1 : 0;
}

/* The scale-1 size of case `c`'s scene. */
static double base_size(const ext_case *c) {
  static const double zero[3] = {0, 0, 0};
  char *doc = scene_json(c, 1, zero, 1);
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  obs_extent ex = {0};
  if (obs_scene_load_string(&sc, doc, "extremes.json", NULL, NULL, 0, &err) == 0) {
    obs_scene_extent(&sc, &ex, &err);
    obs_scene_free(&sc);
  }
  obs_err_free(&err);
  free(doc);
  return ex.size;
}

/* The offset along (1,1,1) that puts the camera or the bounds centre `trans` sizes from the
 * origin, less what the scene itself adds. */
static void offset_for(const ext_case *c, double s, double size, double trans, double off[3]) {
  double h, half, P;
  cam_geometry(&c->cam, &h, &half, &P);
  double m = trans > 0 ? trans * size * s - (h + 2) * s : 0;
  for (int k = 0; k < 3; k++) off[k] = m / sqrt(3.0);
}

/* One case: scale 1 at the origin, then each end of size and translation. */
static int run_case(ext_case *c) {
  const obs_range *r = c->r;
  double size = base_size(c), zero[3] = {0, 0, 0};
  if (!(size > 0)) return printf("FAIL %s: no scene size\n", c->label), 1;
  int bad = 0;
  obs_result base;
  obs_extent ex;
  obs_err err = OBS_ERR_INIT;
  char *doc = scene_json(c, 1, zero, size);
  int rc = render_doc(doc, &base, &ex, &err);
  free(doc);
  if (rc) {
    printf("FAIL %s at scale 1: %s\n", c->label, obs_err_message(&err));
    obs_err_free(&err);
    return 1;
  }
  bad +=
      obs_test_check_sane(c->label, c->t, &base.image) + obs_extremes_no_warnings(c->label, &base);
  double smin = r->size_min / size * (1 + EXT_MARGIN), smax = r->size_max / size * (1 - EXT_MARGIN);
  double tmax = r->translation_max * (1 - EXT_MARGIN);
  const struct {
    double s, t;
  } at[] = {{smin, tmax}, {smax, tmax}, {smin, 0}, {smax, 0}, {1, tmax}};
  /* Under the sanitizers the question is memory, not numbers (the release build holds every
   * case to its tolerance): the two ends that stretch the arithmetic most, smallest and largest
   * scale each at the largest translation, walk the same code as the other three. */
  size_t nat = obs_test_sanitized() ? 2 : sizeof at / sizeof at[0];
  for (size_t k = 0; k < nat; k++) {
    char what[256];
    snprintf(what, sizeof what, "%s, scale %.3g, translation %.3g sizes", c->label, at[k].s,
             at[k].t);
    double off[3];
    offset_for(c, at[k].s, size, at[k].t, off);
    doc = scene_json(c, at[k].s, off, size);
    obs_result res;
    obs_err_free(&err);
    rc = render_doc(doc, &res, &ex, &err);
    free(doc);
    if (rc) {
      printf("FAIL %s: %s\n", what, obs_err_message(&err));
      bad++;
      continue;
    }
    if (!(ex.translation <= r->translation_max) || !(ex.size >= r->size_min) ||
        !(ex.size <= r->size_max))
      printf("FAIL %s: the case lies outside the range (size %.17g, translation %.17g)\n", what,
             ex.size, ex.translation),
          bad++;
    bad += obs_test_check_sane(what, c->t, &res.image) + obs_extremes_no_warnings(what, &res);
    bad += obs_extremes_compare(what, c->t, &base.image, &res.image, at[k].s, &r->tol, NULL);
    obs_result_free(&res);
  }
  obs_result_free(&base);
  obs_err_free(&err);
  return bad;
}

/* The schema default of a parameter, NaN when it has none or it is not a number. */
static double schema_default(const obs_technique *t, const char *name) {
  json_t *s = obs_technique_params_schema(t);
  json_t *d = json_object_get(json_object_get(json_object_get(s, "properties"), name), "default");
  double v = json_is_number(d) ? json_number_value(d) : NAN;
  json_decref(s);
  return v;
}

static void case_init(ext_case *c, const obs_technique *t, obs_backend be, camcfg cam) {
  memset(c, 0, sizeof *c);
  c->t = t, c->be = be, c->r = &t->range[be], c->cam = cam;
  for (int i = 0; i < OBS_MAX_PARAM_RANGES; i++) c->rel[i] = NAN;
}

/* The parameter `name` of t's table, or NULL. */
static const obs_param *param_of(const obs_technique *t, const char *name) {
  for (size_t k = 0; k < t->params_size; k++)
    if (!strcmp(t->params[k].name, name)) return &t->params[k];
  return NULL;
}

/* Sets every length parameter to its default at scale 1, as a share of the scene's size so it
 * scales with the scene: the share a scene of any size is given (size_default) where the
 * parameter declares one and its schema default is a number, else the schema default. A fixed
 * schema default is a length in no particular scene's units: on this scene seen at the narrowest
 * field of view, hbao's radius 1 lies within the depth precision (its screen-space rule), outside
 * the range, while 0.3 scene sizes does not. */
static void default_params(ext_case *c) {
  double size = base_size(c);
  for (int i = 0; c->r->params[i].name; i++) {
    const obs_param_range *pr = &c->r->params[i];
    double d = schema_default(c->t, pr->name);
    const obs_param *def = param_of(c->t, pr->name);
    if (!isnan(d) && def && def->size_default > 0 && pr->size_power == 1)
      c->rel[i] = def->size_default;
    else
      c->rel[i] = pr->size_power ? d / pow(size, pr->size_power) : d;
  }
}

static int check_pair(const obs_technique *t, obs_backend be) {
  const obs_range *r = &t->range[be];
  if (!(r->size_max > 0)) return printf("FAIL %s/%s declares no range\n", t->name,
                                        obs_backend_name(be)), 1;
  int bad = 0, ncam = 0;
  camcfg cams[4] = {{0, 60, "fov 60"}, {0, r->fov_min, "fov min"}, {0, r->fov_max, "fov max"}};
  ncam = 3;
  if (r->orthographic) cams[ncam++] = (camcfg){1, 0, "orthographic"};
  for (int k = 0; k < ncam; k++) {
    ext_case c;
    case_init(&c, t, be, cams[k]);
    default_params(&c);
    snprintf(c.label, sizeof c.label, "%s/%s %s (fov %g)", t->name, obs_backend_name(be),
             cams[k].label, cams[k].fov);
    bad += run_case(&c);
  }
  /* Parameter ends are numbers on code paths the cameras' cases already walk: the sanitizer
   * builds leave them to the release build (the conformance suite renders every parameter end
   * under the sanitizers too). */
  for (int i = 0; !obs_test_sanitized() && r->params[i].name; i++)
    for (int end = 0; end < 2; end++) {
      ext_case c;
      case_init(&c, t, be, cams[0]);
      default_params(&c);
      c.rel[i] = end ? r->params[i].max * (1 - EXT_MARGIN) : r->params[i].min * (1 + EXT_MARGIN);
      snprintf(c.label, sizeof c.label, "%s/%s %s at its %s (%g)", t->name, obs_backend_name(be),
               r->params[i].name, end ? "max" : "min", c.rel[i]);
      bad += run_case(&c);
    }
  return bad;
}

int obs_extremes_check_backend(obs_backend be, int *ran) {
  int bad = 0, n = 0;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    if (!obs_technique_has_backend(t, be)) continue;
    n++;
    int b = check_pair(t, be);
    printf("%s/%s: %s\n", t->name, obs_backend_name(be), b ? "FAILED" : "held");
    bad += b;
  }
  if (ran) *ran = n;
  return bad;
}

/* Renders case `c` at scale s, `trans` sizes from the origin; checks for a warning naming `word`. */
static int expect_warning(ext_case *c, double s, double trans, const char *word) {
  double size = base_size(c), off[3];
  offset_for(c, s, size, trans, off);
  char *doc = scene_json(c, s, off, size);
  obs_result res;
  obs_extent ex;
  obs_err err = OBS_ERR_INIT;
  int rc = render_doc(doc, &res, &ex, &err), bad = 0;
  free(doc);
  if (rc) { /* refusing is allowed outside the range, as long as it is an error, not a crash */
    obs_err_free(&err);
    return 0;
  }
  int found = 0;
  for (int i = 0; i < res.nwarnings; i++) found |= strstr(res.warnings[i], word) != NULL;
  if (!found)
    printf("FAIL %s, scale %g, translation %g: no warning naming \"%s\"\n", c->label, s, trans,
           word),
        bad++;
  obs_result_free(&res);
  obs_err_free(&err);
  return bad;
}

int obs_extremes_check_warnings(obs_backend be) {
  int bad = 0;
  for (size_t i = 0; i < obs_technique_count(); i++) {
    const obs_technique *t = obs_technique_at(i);
    if (!obs_technique_has_backend(t, be)) continue;
    const obs_range *r = &t->range[be];
    ext_case c;
    case_init(&c, t, be, (camcfg){0, 60, "fov 60"});
    default_params(&c);
    snprintf(c.label, sizeof c.label, "%s/%s outside", t->name, obs_backend_name(be));
    double size = base_size(&c);
    bad += expect_warning(&c, r->size_max * 10 / size, 0, "scene size");
    bad += expect_warning(&c, r->size_min / 10 / size, 0, "scene size");
    bad += expect_warning(&c, 1, r->translation_max * 10, "translation");
    for (int k = 0; r->params[k].name; k++)
      for (int end = 0; end < 2; end++) {
        ext_case p = c;
        p.rel[k] = end ? r->params[k].max * 10 : r->params[k].min / 10;
        bad += expect_warning(&p, 1, 0, r->params[k].name);
      }
    double fovs[2] = {r->fov_min / 10, (r->fov_max + 180) / 2};
    for (int k = 0; k < 2; k++) {
      if (fovs[k] <= 0 || fovs[k] >= 180 || (k == 1 && r->fov_max >= 180)) continue;
      ext_case f = c;
      f.cam.fov = fovs[k];
      bad += expect_warning(&f, 1, 0, "fov_y");
    }
    if (!r->orthographic) {
      ext_case o = c;
      o.cam = (camcfg){1, 0, "orthographic"};
      bad += expect_warning(&o, 1, 0, "orthographic");
    }
  }
  return bad;
}
