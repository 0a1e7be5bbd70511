/* Descriptor of analytic_ao (Shopf, Barczak, Scheuermann, Oat, ShaderX7 6.3, "Deferred Occlusion
 * from Analytic Surfaces"): its parameters, range and reference. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "analytic_ao.h"
#include "gbuffer.h"
#include "techniques.h"

static const char *const resolutions[] = {"full", "half", NULL};
static const char *const upsamples[] = {"bilateral", "push_pull", NULL};
static const char *const methods[] = {"compute", "raster", NULL};

#define P(member) offsetof(obs_analytic_ao_params, member)
static const obs_param analytic_ao_params[] = {
    {.name = "extent", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_NULLABLE, .min = 1,
     .max = 1e6, .def = 16, .null_value = INFINITY,
     .description = "half-size of each occluder's bounding cube (the article's proxy), in "
                    "occluder radii: a receiver outside it is not occluded by it, which drops "
                    "at most about 1/extent^2 of occlusion per occluder; null = unbounded",
     .offset = P(extent)},
    {.name = "resolution", .type = OBS_PARAM_ENUM, .choices = resolutions, .def = OBS_AAO_FULL,
     .description = "full: every pixel; half: every second pixel of every second row, then a "
                    "bilateral upsampling (bilinear weights times normal and depth agreement), "
                    "the pixels no neighbour agrees with evaluated at full resolution (upsample "
                    "push_pull then fills the rest from these samples instead)",
     .offset = P(resolution)},
    {.name = "occluders", .type = OBS_PARAM_NAMES,
     .description = "the objects that occlude, by name (the article splats only the occluders "
                    "a scene selects); every object receives. null: every sphere, quad, triangle "
                    "and box",
     .offset = P(occluders)},
    {.name = "method", .type = OBS_PARAM_ENUM, .choices = methods, .def = OBS_AAO_COMPUTE,
     .description = "Vulkan only. compute: one pass over the pixels, each 8x8 tile culling the "
                    "occluders' cubes; raster: the article's proxies, each occluder's bounding "
                    "cube rasterised over the G-buffer, its occlusion multiplied in by the blend "
                    "(full resolution only). The CPU runs compute",
     .offset = P(method)},
    {.name = "upsample", .type = OBS_PARAM_ENUM, .choices = upsamples, .def = OBS_AAO_BILATERAL,
     .description = "how resolution half fills the pixels it did not evaluate (ignored at "
                    "resolution full). bilateral: the bilateral upsampling; push_pull: the "
                    "article's second method [Guennebaud07]: the evaluated pixels (the half grid "
                    "and the pixels the bilateral test left to full resolution) with weight 1, "
                    "pushed down a pyramid (weighted means of 2x2 children, weight min(1, sum)) "
                    "and pulled back up (w own + (1 - w) the bilinear of the parents)",
     .offset = P(upsample)},
};
#undef P

/* One closed-form pass per pixel (times the occluders whose cubes reach it, which the bound
 * parameters do not know). */
static double analytic_ao_cost(const void *bound) {
  (void)bound;
  return 1.0;
}

/* The reference: rt_ao, binary and cosine-weighted, at unlimited range: the AO the form factors
 * compute exactly for one occluder above the horizon (docs/techniques/analytic_ao.md). */
static int analytic_ao_reference(const obs_scene *scene, const json_t *params,
                                 obs_reference_facts *facts, obs_reference_def *def,
                                 obs_err *err) {
  (void)facts;
  /* rt_ao lets every object occlude: it matches only a selection that names every object. */
  const json_t *only = json_object_get(params, "occluders");
  for (size_t i = 0; json_is_array(only) && i < scene->nobjects; i++) {
    size_t k = 0;
    while (k < json_array_size(only) &&
           strcmp(json_string_value(json_array_get(only, k)), scene->objects[i].name))
      k++;
    if (k == json_array_size(only))
      return obs_err_set(err, OBS_EINVAL,
                         "/technique/params/occluders: leaves out object \"%s\", and the "
                         "reference (rt_ao) lets every object occlude: a matched reference needs "
                         "occluders null or naming every object",
                         scene->objects[i].name);
  }
  def->technique = &obs_technique_rt_ao;
  def->response = OBS_RESPONSE_IDENTITY;
  json_object_set_new(def->params, "falloff", json_string("binary"));
  json_object_set_new(def->params, "weighting", json_string("cosine"));
  json_object_set_new(def->params, "max_distance", json_null());
  return 0;
}

/* The rasterised proxies are a Vulkan pipeline, at full resolution. */
static void analytic_ao_check(const obs_scene *scene, const json_t *params, const char *doc,
                              obs_err *err) {
  const char *m = json_string_value(json_object_get(params, "method"));
  const char *r = json_string_value(json_object_get(params, "resolution"));
  if (!m || strcmp(m, "raster")) return;
  if (scene->backend != OBS_BACKEND_VULKAN)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/method: \"raster\" runs on the vulkan backend only (set "
                "/technique/backend to \"vulkan\", or use method \"compute\")",
                doc);
  else if (r && !strcmp(r, "half"))
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/resolution: \"half\" runs with method \"compute\" only "
                "(the proxies draw at full resolution)",
                doc);
}

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges"): occluders are
 * placed in the camera's view space in double and rounded once, the closed forms take ratios of
 * lengths relative to the receiver (unit vectors before cross products, so nothing underflows at
 * 1e-9 or overflows at 1e9) and `extent` is in occluder radii, so the result is scale-free once
 * the G-buffer is. */
#define ANALYTIC_AO_RANGE                                                       \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-2, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"extent", 1, 1e6, 0}, {NULL, 0, 0, 0}},                         \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_analytic_ao = {
    .name = "analytic_ao",
    .description = "Deferred occlusion from analytic surfaces (Shopf et al., ShaderX7 6.3): the "
                   "closed-form occlusion of each sphere, quad, triangle and box at every "
                   "G-buffer pixel inside its bounding cube, combined as the product of (1 - occ)",
    .params = analytic_ao_params,
    .params_size = sizeof analytic_ao_params / sizeof analytic_ao_params[0],
    .bound_size = sizeof(obs_analytic_ao_params),
    .cost = analytic_ao_cost,
    .cost_rule = "1 (one closed-form pass per pixel over the occluders whose cubes reach it)",
    .ms_per_work = 1e-4,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .reference = analytic_ao_reference,
    .check = analytic_ao_check,
    .run = {[OBS_BACKEND_CPU] = obs_analytic_ao_cpu, [OBS_BACKEND_VULKAN] = obs_analytic_ao_vulkan},
    .range = {[OBS_BACKEND_CPU] = ANALYTIC_AO_RANGE, [OBS_BACKEND_VULKAN] = ANALYTIC_AO_RANGE},
};
