/* Descriptor of ss_radiosity (Briney, Ceitelis, Cremoux, ShaderX7 6.4, "Fast Fake Global
 * Illumination"): screen-space radiosity, a gather of the direct pass's colour around each pixel
 * with the article's normal-oriented sampling, its occlusion as AO, and direct + bounce. */
#include <jansson.h>
#include <stddef.h>

#include "ss_radiosity.h"
#include "techniques.h"

static const obs_output srad_outputs[] = {
    {.name = "final", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Direct light plus the screen-space bounce (exposure and sRGB in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "bounce", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "bounce.png",
     .description = "Screen-space bounce: the direct colour gathered around the pixel",
     .exposure = "exposure"},
    {.name = "direct", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "direct.png",
     .description = "Direct pass: emitters seen and lit by the emitters, with shadows",
     .exposure = "exposure"},
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Ambient occlusion of the same samples (white = open)",
     .flags = OBS_OUTPUT_UNIT},
    {.name = "ao_raw", .kind = OBS_OUTPUT_SCALAR,
     .description = "Ambient occlusion before the blur"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const probe_combines[] = {"multiply", "add", NULL};

#define P(member) offsetof(obs_ss_radiosity_params, member)
static const obs_param srad_params[] = {
    {.name = "samples", .type = OBS_PARAM_INT, .min = 1, .max = OBS_SRAD_MAX_SAMPLES, .def = 4,
     .description = "screen-space samples per pixel (the article's 4)", .offset = P(samples)},
    {.name = "kernel_size", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 0.5, .size_default = 0.1,
     .description = "radius of the sampling ball in scene units (the article's KernelSize)",
     .offset = P(kernel_size)},
    {.name = "directivity", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1, .def = 0.5,
     .description = "how far the samples lean on the normal: offset = r (d n + (1 - d) u), u in "
                    "the ball's half about n (the article's Directivity)",
     .offset = P(directivity)},
    {.name = "attenuation", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e30, .def = 0,
     .description = "per scene unit: the kernel shrinks with view depth z as "
                    "kernel_size / (1 + attenuation z) (the article's Attenuation)",
     .offset = P(attenuation)},
    {.name = "bias", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 0.5, .size_default = 0.1,
     .description = "depth difference (scene units) over which a sample's weight falls linearly "
                    "to 0 (the article's Bias)",
     .offset = P(bias)},
    {.name = "strength", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 1,
     .description = "scale of the gathered bounce", .offset = P(strength)},
    {.name = "exclude_self", .type = OBS_PARAM_BOOL, .def = 0,
     .description = "samples on the pixel's own object gather no colour and no occlusion",
     .offset = P(exclude_self)},
    {.name = "blur", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "4x4 depth-aware box blur of the bounce and the ao", .offset = P(blur)},
    {.name = "blur_depth_threshold", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.05,
     .description = "the blur mixes pixels whose depth differs from the centre's by at most this "
                    "fraction of the centre's depth",
     .offset = P(blur_depth_threshold)},
    {.name = "probe_combine", .type = OBS_PARAM_ENUM, .choices = probe_combines, .def = 0,
     .description = "how the scene's AO probes (its `probes`) combine into the ao: multiply, "
                    "AO = prod saturate(1 - Occ_i) (the article's listing), or add, "
                    "AO = saturate(1 - sum Occ_i); either multiplies the gathered ao",
     .offset = P(probe_add)},
    {.name = "light_samples", .type = OBS_PARAM_UINT, .min = 1, .max = 4096, .def = 16,
     .description = "emitter points (each with a shadow ray) per pixel of the direct pass",
     .offset = P(light_samples)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the sample tables and the direct pass's emitter points",
     .offset = P(seed)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to the radiance PNGs only (the EXR is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* The gather reads at most OBS_SRAD_MAX_PROBES probes: more are refused, not dropped. */
static void srad_check(const obs_scene *scene, const json_t *params, const char *doc,
                       obs_err *err) {
  (void)params;
  if (scene->nprobes > OBS_SRAD_MAX_PROBES)
    obs_err_set(err, OBS_EINVAL,
                "%s: /probes: technique \"ss_radiosity\" reads at most %d probes (got %zu)", doc,
                OBS_SRAD_MAX_PROBES, scene->nprobes);
}

/* Depth-buffer taps per pixel plus the direct pass's shadow rays. */
static double srad_cost(const void *bound) {
  const obs_ss_radiosity_params *p = bound;
  return (double)p->samples + (double)p->light_samples;
}

/* `final` approximates diffuse global illumination: path_trace on the same scene (its transport
 * at its defaults), the exposure copied so the PNGs match. The `ao` output against rt_ao on
 * request: its samples reach kernel_size, so that is rt_ao's max_distance. */
static const char *const srad_reference_keys[] = {"exposure", NULL};
static const char *const srad_ao_keys[] = {"kernel_size", "max_distance", NULL};
static const obs_reference_alt srad_alts[] = {{&obs_technique_rt_ao, "ao", srad_ao_keys, NULL},
                                              {NULL, NULL, NULL, NULL}};

/* Both backends gather with the same float passes from the same direct buffer, so they share the
 * range. Lengths (kernel_size, bias) are scene units scaled with the scene; positions are relative
 * to the camera, so the gather is scale-free up to texel snapping of rescaled floats; the direct
 * pass's rays are rt_ao's and path_trace's. */
#define SRAD_RANGE                                                                      \
  {                                                                                     \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4,         \
    .fov_max = 170, .orthographic = 1,                                                  \
    .params = {{"kernel_size", 1e-4, 10, 1}, {"bias", 1e-4, 10, 1},                     \
               {NULL, 0, 0, 0}},                                                       \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,           \
            .depth_rel = 3e-5}                                                          \
  }

const obs_technique obs_technique_ss_radiosity = {
    .name = "ss_radiosity",
    .description = "Screen-space radiosity (Briney, Ceitelis, Cremoux, ShaderX7 6.4): the direct "
                   "pass's colour gathered by normal-oriented screen-space samples into a bounce, "
                   "their occlusion as AO, direct + bounce as the image",
    .params = srad_params,
    .params_size = sizeof srad_params / sizeof srad_params[0],
    .bound_size = sizeof(obs_ss_radiosity_params),
    .cost = srad_cost,
    .cost_rule = "samples + light_samples",
    .ms_per_work = 1e-4,
    .needs = OBS_NEED_GBUFFER | OBS_NEED_MATERIALS,
    .outputs = srad_outputs,
    .check = srad_check,
    .reference_same = &obs_technique_path_trace,
    .reference_keys = srad_reference_keys,
    .reference_alts = srad_alts,
    .run = {[OBS_BACKEND_CPU] = obs_ss_radiosity_cpu,
            [OBS_BACKEND_VULKAN] = obs_ss_radiosity_vulkan},
    .range = {[OBS_BACKEND_CPU] = SRAD_RANGE, [OBS_BACKEND_VULKAN] = SRAD_RANGE},
};
