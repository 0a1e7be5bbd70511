/* Descriptor of sss_single (Ki, ShaderX7 6.5, "Real-Time Subsurface Scattering Using Shadow
 * Maps"): single scattering inside homogeneous media lit by point and directional lights, by the
 * article's light-view maps or by ray tracing (the reference). */
#include <jansson.h>
#include <stddef.h>
#include <string.h>

#include "sss_single.h"
#include "techniques.h"

static const obs_output sss_outputs[] = {
    {.name = "radiance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Single-scattered radiance leaving the media (no surface reflection; objects "
                    "without a medium are black; exposure and sRGB in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "radiance_stderr", .kind = OBS_OUTPUT_RGB,
     .description = "Standard error of radiance: method trace's Monte-Carlo error; 0 for "
                    "shadow_maps, whose deterministic samples carry no random error (its error is "
                    "bias, measured against trace)",
     .stderr_of = "radiance"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const methods[] = {"shadow_maps", "trace", NULL};

#define P(member) offsetof(obs_sss_single_params, member)
static const obs_param sss_params[] = {
    {.name = "method", .type = OBS_PARAM_ENUM, .choices = methods, .def = OBS_SSS_SHADOW_MAPS,
     .description = "shadow_maps: the article's light-view maps (transmitted irradiance, "
                    "position and id, normal) read at M deterministic path samples per light; "
                    "trace (cpu only): the same integral by ray tracing, the reference",
     .offset = P(method)},
    {.name = "samples", .type = OBS_PARAM_UINT, .min = 1, .max = 4096, .def = 10,
     .description = "shadow_maps: path samples M per light and pixel sample (the article's 10); "
                    "trace: random path lengths per pixel sample, each connected to every light",
     .offset = P(samples)},
    {.name = "adaptive", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "shadow_maps: the article's adaptive refinement, 2M samples where 20 to 85 % "
                    "of the M samples are dim (light below 0.05 of the light's irradiance)",
     .offset = P(adaptive)},
    {.name = "jitter", .type = OBS_PARAM_DOUBLE, .min = 0, .max = 8, .def = 1,
     .description = "shadow_maps: each map lookup moved by up to this many texels in x and y "
                    "(fixed per pixel and seed); 0: none",
     .offset = P(jitter)},
    {.name = "map_size", .type = OBS_PARAM_UINT, .min = 16, .max = 1024, .def = 256,
     .description = "shadow_maps: light-view map resolution per light (the article renders with "
                    "2048; 1024 bounds the CPU's ray casting of the maps)",
     .offset = P(map_size)},
    {.name = "unit_length", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 1,
     .description = "scene length of the unit the media's coefficients are per (the presets are "
                    "per millimetre: the scene length of 1 mm); coefficients per scene unit are "
                    "sigma / unit_length",
     .offset = P(unit_length)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "random seed (trace's path lengths, shadow_maps' jitter)", .offset = P(seed)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to final.png only (radiance is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* Map lookups (shadow_maps) or connections (trace, three rays each) per pixel sample and light. */
static double sss_cost(const void *bound) {
  const obs_sss_single_params *p = bound;
  return p->method == OBS_SSS_TRACE ? 3.0 * p->samples : (double)p->samples;
}

/* trace needs Embree, which only the CPU has; both methods need a punctual light. */
static void sss_check(const obs_scene *scene, const json_t *params, const char *doc,
                      obs_err *err) {
  const char *m = json_string_value(json_object_get(params, "method"));
  if (m && !strcmp(m, "trace") && scene->backend == OBS_BACKEND_VULKAN)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/method: \"trace\" runs on the cpu backend only (on the "
                "vulkan backend use \"shadow_maps\")",
                doc);
  size_t punctual = 0;
  for (size_t i = 0; i < scene->nlights; i++) punctual += scene->lights[i].type != OBS_LIGHT_QUAD;
  if (!punctual)
    obs_err_set(err, OBS_EINVAL,
                "%s: /lights: technique \"sss_single\" lights with point or directional lights, "
                "and the scene has none",
                doc);
}

/* The reference: the same technique by ray tracing (the comparison turns samples up), with the
 * same medium scale and exposure. */
static int sss_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                         obs_reference_def *def, obs_err *err) {
  (void)scene;
  (void)facts;
  (void)err;
  static const char *const keys[] = {"unit_length", "exposure", NULL};
  obs_reference_def_same(def, &obs_technique_sss_single, params, keys);
  json_object_set_new(def->params, "method", json_string("trace"));
  return 0;
}

/* The guaranteed range (docs/accuracy.md; tests/unit/test_extremes.c checks both ends). The
 * medium scales with the scene through unit_length, so every optical depth is the same at every
 * scale; light-view maps cover the media's bounding box in the ray tracer's frame. */
#define SSS_RANGE                                                                        \
  {                                                                                      \
    .size_min = 1e-6, .size_max = 1e6, .translation_max = 1e6, .fov_min = 1e-2,          \
    .fov_max = 170, .orthographic = 1,                                                   \
    .params = {{"unit_length", 1e-3, 1e3, 1}, {NULL, 0, 0, 0}},                          \
    .tol = {.ao_mean = 2e-2, .ao_pixel = 5e-2, .share = 0.05, .normal = 1e-4,            \
            .depth_rel = 3e-5}                                                           \
  }

const obs_technique obs_technique_sss_single = {
    .name = "sss_single",
    .description = "Single scattering in translucent media (Ki, ShaderX7 6.5): light-view maps "
                   "of transmitted irradiance, position and normal read along the refracted view "
                   "ray, with jitter and adaptive refinement; or ray-traced (Embree), the "
                   "reference",
    .params = sss_params,
    .params_size = sizeof sss_params / sizeof sss_params[0],
    .bound_size = sizeof(obs_sss_single_params),
    .cost = sss_cost,
    .cost_rule = "samples (trace: 3 x samples)",
    .ms_per_work = 2e-4,
    .needs = OBS_NEED_BVH | OBS_NEED_PUNCTUAL_LIGHTS | OBS_NEED_MEDIUM,
    .outputs = sss_outputs,
    .check = sss_check,
    .reference = sss_reference,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_sss_single_cpu, [OBS_BACKEND_VULKAN] = obs_sss_single_vulkan},
    .range = {[OBS_BACKEND_CPU] = SSS_RANGE, [OBS_BACKEND_VULKAN] = SSS_RANGE},
};
