/* Descriptor of instant_radiosity (Szecsi, ShaderX7 6.6, "Instant Radiosity with GPU Photon
 * Tracing and Approximate Indirect Shadows"): virtual point lights from photon walks, gathered
 * with interleaved sampling, a geometry-aware 4x4 filter and the article's clamped form factor. */
#include <jansson.h>
#include <stddef.h>
#include <string.h>

#include "instant_radiosity.h"
#include "techniques.h"

static const obs_output irad_outputs[] = {
    {.name = "radiance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Radiance: emission seen directly plus the VPLs' light reflected (exposure and "
                    "sRGB in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "visibility.png",
     .description = "Share of the VPLs' irradiance (luminance) the visibility test kept, after the "
                    "filter (1 = nothing occluded; 1 everywhere without visibility)",
     .flags = OBS_OUTPUT_UNIT},
    {.name = "ao_raw", .kind = OBS_OUTPUT_SCALAR,
     .description = "The same share before the filter: the pixel's own VPL class"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const visibilities[] = {"none", "approximate", "exact", NULL};

#define P(member) offsetof(obs_instant_radiosity_params, member)
static const obs_param irad_params[] = {
    {.name = "vpls", .type = OBS_PARAM_INT, .min = 1, .max = 16384, .def = 512,
     .description = "virtual point lights: vpls / max_bounces photon paths (at least 1), each "
                    "leaving one VPL on the emitter and one per bounce (the article's 512)",
     .offset = P(vpls)},
    {.name = "max_bounces", .type = OBS_PARAM_INT, .min = 0, .max = 16, .def = 3,
     .description = "diffuse reflections of a camera path, as path_trace's: 0 = emission only, "
                    "1 = direct light (the emitter VPLs), n = photon paths of n - 1 bounces",
     .offset = P(max_bounces)},
    {.name = "renew", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1, .def = 0.125,
     .description = "share of the photon paths walked anew each frame, round robin (the article's "
                    "64 of 512); with `frame`, which set a single image shows",
     .offset = P(renew)},
    {.name = "frame", .type = OBS_PARAM_UINT, .min = 0, .max = 1e9, .def = 0,
     .description = "the animation frame whose VPLs are rendered: every path renewed as often as "
                    "`renew` renews it by then, reseeded deterministically",
     .offset = P(frame)},
    {.name = "clamp_distance", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e18, .def = 0.1, .size_default = 0.02,
     .description = "N_c in scene units: receivers nearer than this to a VPL's plane are moved "
                    "onto it (the article's spike clamp); the form factor stays below 1 / N_c^2",
     .offset = P(clamp_distance)},
    {.name = "visibility", .type = OBS_PARAM_ENUM, .choices = visibilities, .def = 0,
     .description = "none: every VPL lights every receiver in front of it; approximate: the "
                    "article's march over the depth buffer's min-pyramid and its distance cube of "
                    "the geometry outside the view; exact: a shadow ray per receiver and VPL (cpu "
                    "backend only)",
     .offset = P(visibility)},
    {.name = "shadow_bias", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1, .def = 0.01,
     .description = "approximate visibility: a sample occludes from this fraction of its depth "
                    "(or its distance from the cube's centre) in front of the segment, fully "
                    "from twice that (the article's smooth step)",
     .offset = P(shadow_bias)},
    {.name = "shadow_thickness", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE,
     .min = 0, .max = 1e6, .def = 0.04,
     .description = "approximate visibility: a sample lying more than this fraction of its depth "
                    "behind the depth buffer stops counting (fully from twice that), as if each "
                    "occluder were that thick; large values are the article's solid height field",
     .offset = P(shadow_thickness)},
    {.name = "filter", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "geometry-aware 4x4 filter that gathers the 16 interleaved VPL classes into "
                    "every pixel",
     .offset = P(filter)},
    {.name = "filter_depth", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.02,
     .description = "the filter takes pixels whose distance from the centre's tangent plane is "
                    "at most this fraction of the centre's view depth",
     .offset = P(filter_depth)},
    {.name = "filter_normal", .type = OBS_PARAM_FLOAT, .min = -1, .max = 1, .def = 0.9,
     .description = "and whose normal has at least this cosine with the centre's",
     .offset = P(filter_normal)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the photon walk; images depend only on (seed, frame, renew)",
     .offset = P(seed)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to final.png only (radiance is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* Shadow rays need the BVH, which only the CPU backend has. */
static void irad_check(const obs_scene *scene, const json_t *params, const char *doc,
                       obs_err *err) {
  const char *v = json_string_value(json_object_get(params, "visibility"));
  if (v && !strcmp(v, "exact") && scene->backend == OBS_BACKEND_VULKAN)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/visibility: \"exact\" runs on the cpu backend only (on the "
                "vulkan backend use \"none\")",
                doc);
}

/* VPLs evaluated per pixel: one class of the 16. */
static double irad_cost(const void *bound) {
  const obs_instant_radiosity_params *p = bound;
  return (double)p->vpls / OBS_IRAD_CLASSES;
}

/* `radiance` estimates what path_trace computes with the same number of bounces: emission seen
 * directly, direct light and max_bounces - 1 interreflections. */
static const char *const irad_reference_keys[] = {"max_bounces", "exposure", NULL};

/* Both backends gather in float from the same VPLs over view-space positions (relative to the
 * camera), so they share the range; the photon walk is path_trace's ray tracing. clamp_distance
 * is a length, scaled with the scene. */
#define IRAD_RANGE                                                                      \
  {                                                                                     \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4,         \
    .fov_max = 170, .orthographic = 1,                                                  \
    .params = {{"clamp_distance", 1e-4, 10, 1}, {NULL, 0, 0, 0}},                       \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,           \
            .depth_rel = 3e-5}                                                          \
  }

const obs_technique obs_technique_instant_radiosity = {
    .name = "instant_radiosity",
    .description = "Instant radiosity (Szecsi, ShaderX7 6.6): virtual point lights from photon "
                   "walks (Embree), gathered with 4x4 interleaved sampling, a geometry-aware "
                   "filter and the article's clamped form factor",
    .params = irad_params,
    .params_size = sizeof irad_params / sizeof irad_params[0],
    .bound_size = sizeof(obs_instant_radiosity_params),
    .cost = irad_cost,
    .cost_rule = "vpls / 16",
    .ms_per_work = 1e-4,
    .needs = OBS_NEED_GBUFFER | OBS_NEED_MATERIALS,
    /* The photon walk that places the virtual lights traces with Embree on both. */
    .embree_backends = 1u << OBS_BACKEND_CPU | 1u << OBS_BACKEND_VULKAN,
    .outputs = irad_outputs,
    .check = irad_check,
    .reference_same = &obs_technique_path_trace,
    .reference_keys = irad_reference_keys,
    .run = {[OBS_BACKEND_CPU] = obs_instant_radiosity_cpu,
            [OBS_BACKEND_VULKAN] = obs_instant_radiosity_vulkan},
    .range = {[OBS_BACKEND_CPU] = IRAD_RANGE, [OBS_BACKEND_VULKAN] = IRAD_RANGE},
};
