/* Descriptor of obscurance: per-pixel obscurances with colour bleeding (Mendez-Feliu, Sbert et
 * al.), the ambient term of a local, distance-limited interreflection model added to direct light. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "obscurance.h"
#include "obscurance_params.h"
#include "techniques.h"

static const obs_output obscurance_outputs[] = {
    {.name = "final", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Direct light plus the obscurance ambient term (exposure and sRGB in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "final_stderr", .kind = OBS_OUTPUT_RGB,
     .description = "Standard error of the per-pixel final estimate", .stderr_of = "final"},
    {.name = "obscurance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP,
     .png = "obscurance.png",
     .description = "Obscurance W (RGB with colour bleeding; 1 = open, 0 = enclosed)"},
    {.name = "obscurance_stderr", .kind = OBS_OUTPUT_RGB,
     .description = "Standard error of the per-pixel obscurance estimate",
     .stderr_of = "obscurance"},
    {.name = "indirect", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "indirect.png",
     .description = "Indirect term R(P) I_A W(P)", .exposure = "exposure"},
    {.name = "direct", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "direct.png",
     .description = "Direct light: emitters seen and lit by the emitters, with shadows",
     .exposure = "exposure"},
    {.name = "constant_ambient", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP,
     .png = "constant_ambient.png",
     .description = "Direct light plus a constant ambient term (W of an open point)",
     .exposure = "exposure"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const sequences[] = {"halton", "sobol", NULL};

#define P(member) offsetof(obs_obscurance_params, member)
static const obs_param obscurance_params[] = {
    {.name = "samples", .type = OBS_PARAM_UINT, .min = 1, .max = 65536, .def = 64,
     .description = "cosine-distributed obscurance rays per pixel sample (eq. 6)",
     .offset = P(samples)},
    OBS_OBSCURANCE_MODEL_PARAMS(P),
    {.name = "ambient", .type = OBS_PARAM_RGB,
     .flags = OBS_PARAM_NULLABLE | OBS_PARAM_DEFAULT_NULL, .min = 0, .max = 1e30,
     .null_value = -1,
     .description = "ambient intensity I_A (RGB radiance) for open scenes; null = the sky's "
                    "environment.color when above zero, else the closed environment's I_A "
                    "from the scene's areas, reflectivities and emitters",
     .offset = P(ambient)},
    {.name = "light_samples", .type = OBS_PARAM_UINT, .min = 1, .max = 4096, .def = 4,
     .description = "emitter points (each with a shadow ray) per pixel sample for the direct "
                    "term",
     .offset = P(light_samples)},
    {.name = "sequence", .type = OBS_PARAM_ENUM, .choices = sequences, .def = 0,
     .description = "low-discrepancy sequence of the directions and light points, scrambled per "
                    "pixel: halton (the article's) or sobol",
     .offset = P(sequence)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "random seed; images depend only on (pixel, sample, seed)", .offset = P(seed)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to the radiance PNGs only (the EXR is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* The rays of one pixel sample: obscurance rays and shadow rays (the camera ray left out, as for
 * rt_ao). */
static double obscurance_cost(const void *bound) {
  const obs_obscurance_params *p = bound;
  return (double)p->samples + (double)p->light_samples;
}

static int positive(const obs_vec3 *v) { return v->x + v->y + v->z > 0; }

/* Without an emitter the closed-environment I_A and the direct term are both 0: refused unless
 * `ambient` or a sky (environment.color) supplies I_A. */
static void obscurance_check(const obs_scene *scene, const json_t *params, const char *doc,
                             obs_err *err) {
  json_t *ambient = json_object_get(params, "ambient");
  int lit = (ambient && json_is_array(ambient)) ||
            (scene->has_environment && positive(&scene->environment));
  for (size_t i = 0; !lit && i < scene->nlights; i++) lit = positive(&scene->lights[i].emission);
  for (size_t i = 0; !lit && i < scene->nobjects; i++) lit = positive(&scene->objects[i].emission);
  if (!lit)
    obs_err_set(err, OBS_EINVAL,
                "%s: /lights: technique \"obscurance\" needs an emitter (a light or an object "
                "with material.emission, emission above zero), an environment.color or "
                "/technique/params/ambient",
                doc);
}

/* The quantity `final` approximates is the diffuse global illumination path_trace computes with
 * its full transport (the article's reference): the same scene, emitters and reflectivities,
 * max_bounces and roulette at their defaults. The exposure is copied so the PNGs match. (path_trace
 * with max_bounces 1 computes `direct` alone.) */
static const char *const obscurance_reference_keys[] = {"exposure", NULL};

static const char *const w_alt_keys[] = {"d_max", "max_distance", "falloff", "falloff",
                                         "tau",   "tau",          NULL};
const obs_reference_alt obs_obscurance_w_alts[] = {
    {&obs_technique_rt_ao, "obscurance", w_alt_keys, "color_bleeding"}, {NULL, NULL, NULL, NULL}};

/* The guaranteed range below (docs/accuracy.md; tests/unit/test_extremes.c checks both ends on a
 * sphere over a plane with `ambient` set). The rays are rt_ao's and path_trace's, so are their
 * limits; I_A is a ratio of areas and W depends on d / d_max only, so the outputs are
 * scale-invariant up to rays that graze an edge. d_max is a length (relative bounds as rt_ao's
 * max_distance). */
const obs_technique obs_technique_obscurance = {
    .name = "obscurance",
    .description = "Obscurances with colour bleeding per pixel (Embree): direct light plus the "
                   "ambient term R(P) I_A W(P) of a distance-limited interreflection model",
    .params = obscurance_params,
    .params_size = sizeof obscurance_params / sizeof obscurance_params[0],
    .bound_size = sizeof(obs_obscurance_params),
    .cost = obscurance_cost,
    .cost_rule = "samples + light_samples",
    /* rt_ao's 9e-5 ms per ray times the 1.3 measured against it on the Cornell box
     * (docs/performance.md). */
    .ms_per_work = 1.2e-4,
    .needs = OBS_NEED_BVH | OBS_NEED_BVH_FRAME_GEOMETRY | OBS_NEED_MATERIALS,
    .outputs = obscurance_outputs,
    .check = obscurance_check,
    .reference_same = &obs_technique_path_trace,
    .reference_keys = obscurance_reference_keys,
    .reference_alts = obs_obscurance_w_alts,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_obscurance_cpu},
    .range = {[OBS_BACKEND_CPU] = {.size_min = 1e-9,
                                   .size_max = 1e9,
                                   .translation_max = 1e9,
                                   .fov_min = 1e-4,
                                   .fov_max = 170,
                                   .orthographic = 1,
                                   .params = {{"d_max", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},
                                   .tol = {.ao_mean = 1e-3,
                                           .ao_pixel = 1e-4,
                                           .share = 0.02,
                                           .normal = 1e-4,
                                           .depth_rel = 3e-5}}},
};
