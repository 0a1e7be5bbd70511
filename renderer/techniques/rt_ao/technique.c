/* Descriptor of rt_ao: Monte-Carlo ray-traced ambient occlusion / obscurance, the reference. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "rt_ao.h"
#include "sampling.h"
#include "techniques.h"

static const obs_output rt_ao_outputs[] = {
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Ambient occlusion (white = open, black = fully occluded)",
     .flags = OBS_OUTPUT_PRIMARY | OBS_OUTPUT_UNIT},
    {.name = "ao_stderr", .kind = OBS_OUTPUT_SCALAR,
     .description = "Standard error of the per-pixel AO estimate", .stderr_of = "ao"},
    {.name = "bent_normal", .kind = OBS_OUTPUT_VECTOR, .show = OBS_SHOW_NORMAL,
     .png = "bent_normal.png",
     .description = "Bent normals as colours (X, Y, Z \u2192 red, green, blue)"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const weightings[] = {"cosine", "uniform", NULL};
/* In the order of obs_sampler_kind. */
static const char *const samplers[] = {"sobol", "halton", "random", NULL};

#define P(member) offsetof(obs_rt_ao_params, member)
static const obs_param rt_ao_params[] = {
    {.name = "samples", .type = OBS_PARAM_UINT, .min = 1, .max = 65536, .def = 64,
     .description = "occlusion rays per pixel sample", .offset = P(samples)},
    {.name = "max_distance", .type = OBS_PARAM_DOUBLE,
     .flags = OBS_PARAM_MIN_EXCLUSIVE | OBS_PARAM_NULLABLE | OBS_PARAM_DEFAULT_NULL, .min = 0,
     .max = 1e30, .null_value = INFINITY,
     .description = "occlusion distance d_max in scene units; null = unbounded (binary and exp "
                    "falloff only)",
     .offset = P(max_distance), .size_default = 0.2},
    {.name = "falloff", .type = OBS_PARAM_ENUM, .choices = obs_falloff_names,
     .def = OBS_FALLOFF_BINARY,
     .description = "obscurance function rho(d): binary = classic AO, sqrt = sqrt(d/d_max) "
                    "(Mendez-Feliu et al.), exp = 1-exp(-tau d) (Iones et al.)",
     .offset = P(falloff)},
    {.name = "tau", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 1, .description = "decay rate of the exp falloff, per scene unit",
     .offset = P(tau)},
    {.name = "weighting", .type = OBS_PARAM_ENUM, .choices = weightings, .def = 0,
     .description = "cosine: W = 1/pi int rho cos; uniform: W = 1/(2 pi) int rho",
     .offset = P(uniform)},
    {.name = "sampler", .type = OBS_PARAM_ENUM, .choices = samplers, .def = OBS_SAMPLER_SOBOL,
     .description = "sample sequence, scrambled per pixel", .offset = P(sampler)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "random seed; images depend only on (pixel, sample, seed)", .offset = P(seed)},
};
#undef P

/* The occlusion rays of one pixel sample; the primary ray is left out, as the server's built-in
 * rates were measured that way (docs/server.md). */
static double rt_ao_cost(const void *bound) {
  return (double)((const obs_rt_ao_params *)bound)->samples;
}

/* The sqrt falloff's rho(d) = sqrt(d / d_max) needs a finite d_max. */
static const obs_param_rule rt_ao_rules[] = {{"falloff", "sqrt", "max_distance"},
                                             {NULL, NULL, NULL}};

/* The reference of an rt_ao candidate is rt_ao with the same AO definition: only the sample count,
 * sampler and seed differ (the comparison sets them). */
/* The bent normal (the mean unoccluded direction) against the reference's: same estimator, more
 * samples. */
static const obs_output_pair rt_ao_compared[] = {{"bent_normal", "bent_normal"}, {NULL, NULL}};

static const char *const rt_ao_reference_keys[] = {"weighting", "falloff", "max_distance", "tau",
                                                   NULL};


/* The guaranteed range below (docs/accuracy.md, "Guaranteed ranges"; tests/unit/test_extremes.c
 * checks both ends). Geometry is built around the camera in double and rays carry no epsilon, so
 * the limits are float's range for the squared lengths of hit normals and the double shift.
 * Monte-Carlo noise does not enter: the same seed traces the same directions at every scale, and
 * only rays that graze an edge may turn, hence a per-pixel bound on all but a small share of
 * pixels. A narrow field of view puts the camera far from the scene (about 1 / tan(fov_y / 2)
 * sizes); the ray tracer then moves its float frame from the camera to the geometry and starts
 * camera rays at the geometry's box in double (OBS_RT_FRAME_GEOMETRY), so the narrowest field of
 * view is the screen-space techniques' one. tau has no subrange: exp(-tau d) is evaluated in double at any rate, and a default tau
 * left beside another falloff must not warn. */
const obs_technique obs_technique_rt_ao = {
    .name = "rt_ao",
    .description = "Monte-Carlo ray-traced ambient occlusion / obscurance (Embree); the reference "
                   "every other technique is measured against",
    .params = rt_ao_params,
    .params_size = sizeof rt_ao_params / sizeof rt_ao_params[0],
    .bound_size = sizeof(obs_rt_ao_params),
    .rules = rt_ao_rules,
    .cost = rt_ao_cost,
    .cost_rule = "samples",
    .ms_per_work = 9e-5,
    .needs = OBS_NEED_BVH | OBS_NEED_BVH_FRAME_GEOMETRY,
    .outputs = rt_ao_outputs,
    .reference_same = &obs_technique_rt_ao,
    .reference_keys = rt_ao_reference_keys,
    .compared_outputs = rt_ao_compared,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_rt_ao_cpu},
    .range = {[OBS_BACKEND_CPU] = {.size_min = 1e-9,
                                   .size_max = 1e9,
                                   .translation_max = 1e9,
                                   .fov_min = 1e-4,
                                   .fov_max = 170,
                                   .orthographic = 1,
                                   .params = {{"max_distance", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},
                                   .tol = {.ao_mean = 1e-3,
                                           .ao_pixel = 1e-4,
                                           .share = 0.02,
                                           .normal = 1e-4,
                                           .depth_rel = 3e-5}}},
};
