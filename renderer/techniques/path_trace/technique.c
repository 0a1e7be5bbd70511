/* Descriptor of path_trace: diffuse global illumination by path tracing, the RGB reference. */
#include <jansson.h>
#include <stddef.h>
#include <string.h>

#include "path_trace.h"
#include "techniques.h"

static const obs_output path_trace_outputs[] = {
    {.name = "radiance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Radiance (exposure and sRGB applied in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "radiance_stderr", .kind = OBS_OUTPUT_RGB,
     .description = "Standard error of the per-pixel radiance estimate",
     .stderr_of = "radiance"},
    {.name = "albedo", .kind = OBS_OUTPUT_RGB,
     .description = "Reflectivity at the first hit"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR,
     .description = "World-space shading normal at the first hit"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

static const char *const light_samplings[] = {"mis", "bsdf", NULL};
static const char *const samplers[] = {"sobol", "random", NULL};

#define P(member) offsetof(obs_path_trace_params, member)
static const obs_param path_trace_params[] = {
    {.name = "samples", .type = OBS_PARAM_INT, .min = 1, .max = 65536, .def = 64,
     .description = "paths per pixel sample (image.spp pixel samples, each through its point of "
                    "the pixel); at most 65536 paths per pixel in all",
     .offset = P(samples)},
    {.name = "max_bounces", .type = OBS_PARAM_INT, .min = 0, .max = 1024, .def = 64,
     .description = "diffuse reflections a path may take; 0 = emitters seen directly only",
     .offset = P(max_bounces)},
    {.name = "rr_depth", .type = OBS_PARAM_INT, .min = 0, .max = 1024, .def = 3,
     .description = "bounces before Russian roulette may end a path (survival probability: the "
                    "largest channel of the path's throughput)",
     .offset = P(rr_depth)},
    {.name = "light_sampling", .type = OBS_PARAM_ENUM, .choices = light_samplings, .def = 0,
     .description = "mis: next-event estimation and BSDF sampling combined by the power "
                    "heuristic; bsdf: BSDF sampling only (slower to converge; a check of mis)",
     .offset = P(bsdf_only)},
    {.name = "sampler", .type = OBS_PARAM_ENUM, .choices = samplers, .def = 0,
     .description = "sample sequence: one scrambled 2D sequence per pixel and dimension pair",
     .offset = P(random)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "random seed; images depend only on (pixel, sample, seed)", .offset = P(seed)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to final.png only (radiance is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* The paths of one pixel sample (each a few rays; docs/server.md's rate is per path). */
static double path_trace_cost(const void *bound) {
  return (double)((const obs_path_trace_params *)bound)->samples;
}

static int positive(const obs_vec3 *v) { return v->x + v->y + v->z > 0; }

/* A scene without any emitter could only render black: refused, naming what counts. */
static void path_trace_check(const obs_scene *scene, const json_t *params, const char *doc,
                             obs_err *err) {
  /* The sample streams index paths with 16 bits (cpu.c, pt_sample). */
  json_int_t samples = json_integer_value(json_object_get(params, "samples"));
  if ((json_int_t)scene->spp * samples > 65536)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/samples: image.spp x samples must be at most 65536 paths "
                "per pixel (got %d x %lld)",
                doc, scene->spp, (long long)samples);
  int lit = scene->has_environment &&
            (scene->env.kind == OBS_ENV_COLOR ? positive(&scene->environment)
                                              : scene->env.intensity > 0);
  for (size_t i = 0; !lit && i < scene->nlights; i++) lit = positive(&scene->lights[i].emission);
  for (size_t i = 0; !lit && i < scene->nobjects; i++) lit = positive(&scene->objects[i].emission);
  if (!lit)
    obs_err_set(err, OBS_EINVAL,
                "%s: /lights: technique \"path_trace\" needs an emitter: a light, an object with "
                "material.emission, an environment.color or an environment map, with emission above zero",
                doc);
}

/* path_trace is its own reference: the same light transport (bounces, roulette, light sampling)
 * with more paths and another seed (the caller sets samples and seed). The sampler is kept too:
 * a converged reference differs from another only by its noise. */
static const char *const path_trace_reference_keys[] = {"max_bounces", "rr_depth", "light_sampling",
                                                        "sampler", "exposure", NULL};

/* The guaranteed range below (docs/accuracy.md, "Guaranteed ranges"; tests/unit/test_extremes.c
 * checks both ends on the same sphere over a plane under a constant sky). The ray tracing is
 * rt_ao's, so are its limits; paths keep no length constant (shadow rays stop a relative 1e-4
 * short of the emitter), and a path changes with the scale only where a ray grazes an edge, hence
 * a per-pixel bound on all but a small share of pixels. Tolerances are on the radiance channels,
 * in units of the sky's radiance (1 in the check). */
const obs_technique obs_technique_path_trace = {
    .name = "path_trace",
    .description = "Diffuse global illumination by path tracing (Embree) with next-event "
                   "estimation and MIS; the RGB reference",
    .params = path_trace_params,
    .params_size = sizeof path_trace_params / sizeof path_trace_params[0],
    .bound_size = sizeof(obs_path_trace_params),
    .cost = path_trace_cost,
    .cost_rule = "samples",
    /* Measured on the Cornell box (docs/performance.md, bench_path_trace): 2.5 us per path. */
    .ms_per_work = 2.5e-3,
    .needs = OBS_NEED_BVH | OBS_NEED_BVH_FRAME_GEOMETRY | OBS_NEED_MATERIALS | OBS_NEED_ENV_MAP,
    .outputs = path_trace_outputs,
    .check = path_trace_check,
    .reference_same = &obs_technique_path_trace,
    .reference_keys = path_trace_reference_keys,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_path_trace_cpu},
    .range = {[OBS_BACKEND_CPU] = {.size_min = 1e-9,
                                   .size_max = 1e9,
                                   .translation_max = 1e9,
                                   .fov_min = 1e-4,
                                   .fov_max = 170,
                                   .orthographic = 1,
                                   .params = {{NULL, 0, 0, 0}},
                                   .tol = {.ao_mean = 1e-3,
                                           .ao_pixel = 1e-4,
                                           .share = 0.02,
                                           .normal = 1e-4,
                                           .depth_rel = 3e-5}}},
};
