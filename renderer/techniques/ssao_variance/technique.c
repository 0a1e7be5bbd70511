/* Descriptor of ssao_variance (Pesce, "Variance Methods for Screen-Space Ambient Occlusion",
 * ShaderX7 6.7): box-filtered depth and depth^2, Cantelli's bound on the share of the
 * neighbourhood in front of each pixel; and Luft et al.'s unsharp masking of the depth buffer. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>

#include "gbuffer.h"
#include "ssao_variance.h"
#include "techniques.h"

static const char *const svar_methods[] = {"variance", "depth_unsharp", NULL};

#define P(member) offsetof(obs_ssao_variance_params, member)
/* The defaults of variance_weight and strength are the values closest to the reference, rt_ao
 * within R (docs/techniques/ssao_variance.md, "Against rt_ao"); the radius derived for a scene
 * (size_default) is 0.2 scene sizes, rt_ao's derived max_distance, which is this technique's
 * reference radius (svar_reference). */
static const obs_param svar_params[] = {
    {.name = "method", .type = OBS_PARAM_ENUM, .choices = svar_methods, .def = OBS_SVAR_VARIANCE,
     .description = "variance: Cantelli's bound from the box's depth mean and variance (Pesce); "
                    "depth_unsharp: the depth buffer's unsharp mask (Luft et al.)",
     .offset = P(method)},
    {.name = "radius", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 1,
     .description = "neighbourhood radius R in scene units: the box's half-width is R projected "
                    "at the median depth of the covered pixels, in pixels",
     .offset = P(radius), .size_default = 0.2},
    {.name = "variance_weight", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0,
     .description = "variance: k in AO = saturate(1 - s (1 - p) + k sigma^2 / R^2) (p Cantelli's "
                    "bound, s the covered share of the box), lifting occlusion where the depths "
                    "spread far (distant occluders)",
     .offset = P(variance_weight)},
    {.name = "strength", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.3,
     .description = "depth_unsharp: lambda in AO = saturate(1 - s lambda (z - mean) / R)",
     .offset = P(strength)},
    {.name = "taps", .type = OBS_PARAM_INT, .min = 1, .max = OBS_SVAR_MAX_TAPS, .def = 8,
     .description = "the most taps per side of the box along each axis: a box wider than this "
                    "many pixels is read on a grid of (2 taps + 1)^2 evenly spaced depths",
     .offset = P(taps)},
};
#undef P

/* Depth taps per pixel at most: two passes of 2 taps + 1. */
static double svar_cost(const void *bound) {
  return 2.0 * (2.0 * ((const obs_ssao_variance_params *)bound)->taps + 1.0);
}

/* ssao_variance's reference (docs/techniques/ssao_variance.md, "Reference"): the box estimates
 * the share of a neighbourhood of radius R in front of the pixel, binary occlusion within R:
 * rt_ao with binary falloff at max_distance R, cosine weighting, no response. */
static int svar_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                          obs_reference_def *def, obs_err *err) {
  (void)scene;
  (void)facts;
  obs_ssao_variance_params p;
  int rc = obs_params_bind(&obs_technique_ssao_variance, params, &p, err);
  if (rc) return rc;
  def->technique = &obs_technique_rt_ao;
  json_object_set_new(def->params, "weighting", json_string("cosine"));
  json_object_set_new(def->params, "falloff", json_string("binary"));
  json_object_set_new(def->params, "max_distance", json_real(p.radius));
  def->response = OBS_RESPONSE_IDENTITY;
  return 0;
}

/* The reach (obs_screen_rule): R projects to R (W/2) / (half_w z) pixels at depth z (R (W/2) /
 * half_w orthographic); the box itself is R projected at the median depth, but where R covers
 * under a pixel at the pixel's own depth the box reads occluders farther than R. Depth
 * differences under OBS_SVAR_DEPTH_TOL z count as none, so R under that is below the depth
 * buffer's precision. */
static void svar_screen_reach(const void *bound, const obs_gbuffer *g, double z,
                              obs_screen_reach *out) {
  const obs_ssao_variance_params *p = bound;
  double num = p->radius * 0.5 * g->width;
  out->pixels = g->ortho ? num / g->half_w : num / (g->half_w * z);
  out->depth = p->radius / (OBS_SVAR_DEPTH_TOL * z);
}

static const obs_screen_rule svar_screen_rule = {
    .param = "radius",
    .reach = svar_screen_reach,
    .below_pixel = "occluded from farther than the radius: the box is wider there than R",
    .below_depth = "1 (open): the radius lies within the depth buffer's precision",
    .pixel_decides = 1,
};

/* The guaranteed range of both backends (docs/accuracy.md): the twins share the passes, so they
 * share the range. Depths are scaled by a power of two that brings the median to [1, 2) and every
 * comparison is relative to the pixel's depth or R, so the result is scale-free once the G-buffer
 * is; the box is a whole number of pixels, the same at every scale. */
#define SVAR_RANGE                                                              \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"radius", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},                      \
    .screen = &svar_screen_rule,                                                \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_ssao_variance = {
    .name = "ssao_variance",
    .description = "Variance screen-space AO (Pesce, ShaderX7 6.7): box-filtered depth and "
                   "depth^2, Cantelli's bound on the neighbourhood in front of each pixel; or the "
                   "depth buffer's unsharp mask (Luft et al.)",
    .params = svar_params,
    .params_size = sizeof svar_params / sizeof svar_params[0],
    .bound_size = sizeof(obs_ssao_variance_params),
    .cost = svar_cost,
    .cost_rule = "2 (2 taps + 1) (two passes of at most 2 taps + 1 depth taps)",
    .ms_per_work = 1e-6,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .check = NULL,
    .reference = svar_reference,
    .run = {[OBS_BACKEND_CPU] = obs_ssao_variance_cpu,
            [OBS_BACKEND_VULKAN] = obs_ssao_variance_vulkan},
    .range = {[OBS_BACKEND_CPU] = SVAR_RANGE, [OBS_BACKEND_VULKAN] = SVAR_RANGE},
};
