/* Descriptor of ss_obscurance: screen-space obscurance with importance-sampled offsets (Toth,
 * Szirmay-Kalos and Umenhoffer, ShaderX7 3.1), its parameters, reference and range. */
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "gbuffer.h"
#include "obscurance.h"
#include "ss_obscurance.h"
#include "techniques.h"

static const char *const sso_samplings[] = {"importance", "uniform", NULL};

#define P(member) offsetof(obs_sso_params, member)
/* The radius derived for a scene (size_default) is rt_ao's derived max_distance, 0.2 scene
 * sizes: the reference is rt_ao at max_distance = R. */
static const obs_param sso_params[] = {
    {.name = "samples", .type = OBS_PARAM_INT, .min = 4, .max = OBS_SSO_MAX_SAMPLES, .def = 16,
     .description = "offsets (depth-buffer tests) per pixel", .offset = P(samples)},
    {.name = "radius", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 1,
     .description = "neighbourhood R in scene units: occluders beyond it leave a direction open",
     .offset = P(radius), .size_default = 0.2},
    {.name = "membership", .type = OBS_PARAM_ENUM, .choices = obs_falloff_names,
     .def = OBS_FALLOFF_SQRT,
     .description = "fuzzy openness mu(d) of an occluder at distance d < R (1 from R on): binary "
                    "= 0 (ambient occlusion), sqrt = sqrt(d/R) (the article's), exp = "
                    "1-exp(-tau d/R); rt_ao's falloffs",
     .offset = P(membership)},
    {.name = "tau", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e4, .def = 3,
     .description = "decay of the exp membership per radius (rt_ao's tau times R)",
     .offset = P(tau)},
    {.name = "sampling", .type = OBS_PARAM_ENUM, .choices = sso_samplings, .def = 0,
     .description = "importance: cosine directions, distances from d mu / dr, each sample "
                    "weighing 1; uniform: uniform directions and distances, each sample weighing "
                    "the kernel (sqrt membership only)",
     .offset = P(sampling)},
    {.name = "interleave", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "16 offset sets over a 4x4 pixel pattern, then a depth-aware 4x4 average",
     .offset = P(interleave)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the offset sets' random shifts", .offset = P(seed)},
};
#undef P

/* Depth-buffer tests per pixel. */
static double sso_cost(const void *bound) {
  return (double)((const obs_sso_params *)bound)->samples;
}

/* Uniform distances never draw the mass mu puts at R (all of binary's, exp(-tau) of exp's), so
 * they estimate W only for the sqrt membership. */
static void sso_check(const obs_scene *scene, const json_t *params, const char *doc,
                      obs_err *err) {
  (void)scene;
  const char *sampling = json_string_value(json_object_get(params, "sampling"));
  const char *membership = json_string_value(json_object_get(params, "membership"));
  if (sampling && membership && !strcmp(sampling, "uniform") && strcmp(membership, "sqrt"))
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/sampling: \"uniform\" needs membership \"sqrt\": uniform "
                "distances never draw the share of mu at R (got membership \"%s\")",
                doc, membership);
}

/* ss_obscurance's reference (docs/techniques/ss_obscurance.md): the same W, (1/pi) int mu(d)
 * cos(theta), traced: rt_ao with cosine weighting, the membership as its falloff, max_distance R
 * and, for exp, its rate per scene unit tau / R. */
static int sso_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                         obs_reference_def *def, obs_err *err) {
  (void)scene;
  (void)facts;
  obs_sso_params p;
  int rc = obs_params_bind(&obs_technique_ss_obscurance, params, &p, err);
  if (rc) return rc;
  /* The radius as given, before its rounding to float. */
  json_t *r = json_object_get(params, "radius");
  double radius = json_is_number(r) ? json_number_value(r) : (double)p.radius;
  json_t *out = def->params;
  def->technique = &obs_technique_rt_ao;
  json_object_set_new(out, "weighting", json_string("cosine"));
  json_object_set_new(out, "falloff", json_string(obs_falloff_names[p.membership]));
  json_object_set_new(out, "max_distance", json_real(radius));
  if (p.membership == OBS_FALLOFF_EXP) {
    double tau = p.tau / radius;
    if (!(tau > 0) || !isfinite(tau))
      return obs_err_set(err, OBS_EINVAL,
                         "ss_obscurance: the reference's rate tau / radius is not a positive "
                         "number (got %g / %g)",
                         p.tau, radius);
    json_object_set_new(out, "tau", json_real(tau));
  }
  def->response = OBS_RESPONSE_IDENTITY;
  return 0;
}

/* ss_obscurance's reach (obs_screen_rule): an offset is at most R long, which projects to
 * R (W/2) / (half_w z) pixels at depth z (R (W/2) / half_w orthographic; the larger of the two
 * axes); the plane test resolves a displacement from the surface down to its slack, 2^-20 of
 * the magnitudes involved (about z), so R under that is within the depth buffer's precision. */
static void sso_screen_reach(const void *bound, const obs_gbuffer *g, double z,
                             obs_screen_reach *out) {
  const obs_sso_params *p = bound;
  double R = p->radius;
  double ax = 0.5 * g->width / g->half_w, ay = 0.5 * g->height / g->half_h;
  double a = ax > ay ? ax : ay;
  out->pixels = g->ortho ? R * a : R * a / z;
  out->depth = R / (0x1p-20 * z);
}

static const obs_screen_rule sso_screen_rule = {
    .param = "radius",
    .reach = sso_screen_reach,
    .below_pixel = "1 (open): samples land on the pixel's own surface",
    .below_depth = "noise: the radius lies within the depth buffer's precision",
};

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges";
 * tests/unit/test_extremes.c and tests/vulkan/test_extremes_vk.c check both ends). The twins
 * share the passes, so they share the range. The radius is stated in scene sizes: far below a
 * pixel's footprint every pixel reads 1, far beyond the scene every sample leaves the screen, and
 * both ends hold at every scale. */
#define SSO_RANGE                                                               \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"radius", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},                      \
    .screen = &sso_screen_rule,                                                 \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_ss_obscurance = {
    .name = "ss_obscurance",
    .description = "Screen-space obscurance with importance sampling (Toth, Szirmay-Kalos, "
                   "Umenhoffer, ShaderX7 3.1): offsets drawn from the cosine and membership "
                   "kernel, tested against the depth buffer, 4x4 interleaved",
    .params = sso_params,
    .params_size = sizeof sso_params / sizeof sso_params[0],
    .bound_size = sizeof(obs_sso_params),
    .cost = sso_cost,
    .cost_rule = "samples",
    .ms_per_work = 6e-5,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .check = sso_check,
    .reference = sso_reference,
    .run = {[OBS_BACKEND_CPU] = obs_ss_obscurance_cpu,
            [OBS_BACKEND_VULKAN] = obs_ss_obscurance_vulkan},
    .range = {[OBS_BACKEND_CPU] = SSO_RANGE, [OBS_BACKEND_VULKAN] = SSO_RANGE},
};
