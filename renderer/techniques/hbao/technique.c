/* Descriptor of hbao (Bavoil & Sainz, horizon-based ambient occlusion) with its parameter table,
 * and the direction table shared by its CPU and Vulkan backends. */
#include "hbao.h"

#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "gbuffer.h"
#include "sampling.h"
#include "techniques.h"

const char *const obs_hbao_pass_names[OBS_HBAO_PASS_COUNT] = {"downsample", "ao", "upsample",
                                                              "blur"};

#define P(member) offsetof(obs_hbao_params, member)
/* The radius derived for a scene (size_default) is 0.3 scene sizes: hbao's reference (below) is
 * rt_ao at 2R/3, so it matches rt_ao's derived max_distance of 0.2 scene sizes. */
static const obs_param hbao_params[] = {
    {.name = "radius", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e30, .def = 1, .description = "occlusion radius R in scene units (view space)",
     .offset = P(radius), .size_default = 0.3},
    {.name = "directions", .type = OBS_PARAM_INT, .min = 1, .max = OBS_HBAO_MAX_DIRECTIONS,
     .def = 8,
     .description = "horizon directions per pixel, evenly spaced, randomly rotated per pixel",
     .offset = P(directions)},
    {.name = "steps", .type = OBS_PARAM_INT, .min = 1, .max = OBS_HBAO_MAX_STEPS, .def = 8,
     .description = "texel-snapped samples marched per direction", .offset = P(steps)},
    {.name = "angle_bias", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MAX_EXCLUSIVE, .min = 0,
     .max = 1.5707963267948966, .def = 0.5235987755982988,
     .description = "radians added to the tangent angle; hides tessellation and "
                    "depth-quantisation artefacts",
     .offset = P(angle_bias)},
    {.name = "scale", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 1,
     .description = "AO = 1 - scale * (sum over directions) / directions", .offset = P(scale)},
    {.name = "blur_radius", .type = OBS_PARAM_INT, .min = 0, .max = OBS_HBAO_MAX_BLUR_RADIUS,
     .def = 4, .description = "separable cross-bilateral blur radius in pixels; 0 = no blur",
     .offset = P(blur_radius)},
    {.name = "blur_sharpness", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 16,
     .description = "blur depth weight exp(-sharpness (dz/z)^2); 0 = plain Gaussian",
     .offset = P(blur_sharpness)},
    {.name = "half_res", .type = OBS_PARAM_BOOL, .def = 0,
     .description = "AO at half resolution, bilateral upsampling before the blur",
     .offset = P(half_res)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the 4x4 per-pixel rotation and jitter table", .offset = P(seed)},
};
#undef P

/* Depth-buffer taps per pixel: every step of every direction (half_res not discounted, so the
 * figure stays comparable with stored runs). */
static double hbao_cost(const void *bound) {
  const obs_hbao_params *p = bound;
  return (double)p->directions * (double)p->steps;
}

void obs_hbao_directions(const obs_hbao_params *p, float *table) {
  int nd = p->directions;
  for (int c = 0; c < OBS_HBAO_NOISE_CELLS; c++) {
    uint32_t h = obs_hash_combine(p->seed, (uint32_t)c);
    double rot = obs_u32_to_unit(obs_hash32(h ^ 0x68bc21ebU));
    float jitter = obs_u32_to_unit(obs_hash32(h ^ 0x02e5be93U));
    for (int i = 0; i < nd; i++) {
      /* Double, then rounded once: the table is data, so libm's accuracy is all that matters. */
      double a = 6.283185307179586476925 * ((double)i + rot) / (double)nd;
      float *t = table + ((size_t)c * (size_t)nd + (size_t)i) * 4;
      t[0] = (float)cos(a);
      t[1] = (float)sin(a);
      t[2] = jitter;
      t[3] = 0.0f;
    }
  }
}

void obs_hbao_level_size(const obs_hbao_params *p, int width, int height, int *lw, int *lh) {
  *lw = p->half_res ? (width + 1) / 2 : width;
  *lh = p->half_res ? (height + 1) / 2 : height;
}

/* hbao's reference (docs/techniques/hbao.md, "the closest single setting"): hbao estimates
 * unweighted horizon occlusion within its radius R with a linear distance attenuation; binary
 * falloff at 2R/3 has the same mean when occluder distances spread evenly over [0, R]. */
static int hbao_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                          obs_reference_def *def, obs_err *err) {
  json_t *out = def->params;
  def->technique = &obs_technique_rt_ao;
  (void)scene;
  (void)facts;
  obs_hbao_params p;
  int rc = obs_params_bind(&obs_technique_hbao, params, &p, err);
  if (rc) return rc;
  /* The radius as given, before its rounding to float. */
  json_t *r = json_object_get(params, "radius");
  double radius = json_is_number(r) ? json_number_value(r) : (double)p.radius;
  json_object_set_new(out, "weighting", json_string("uniform"));
  json_object_set_new(out, "falloff", json_string("binary"));
  json_object_set_new(out, "max_distance", json_real(2.0 * radius / 3.0));
  def->response = OBS_RESPONSE_IDENTITY;
  return 0;
}

/* hbao's reach (obs_screen_rule): R projects to R (W/2) / (half_w z) pixels at depth z (R (W/2) /
 * half_w orthographic), divided by the level's s = 2 at half resolution, which is the radius
 * in texels the AO pass marches (under one it returns 1 at once); every sample is moved away by
 * its depth's uncertainty, OBS_HBAO_DEPTH_EPS (z_s + z), about 2 eps z, before its distance is
 * measured in units of R, so R under that is within the depth buffer's precision. */
static void hbao_screen_reach(const void *bound, const obs_gbuffer *g, double z,
                              obs_screen_reach *out) {
  const obs_hbao_params *p = bound;
  double R = p->radius, s = p->half_res ? 2.0 : 1.0;
  double num = R * 0.5 * g->width;
  out->pixels = (g->ortho ? num / g->half_w : num / (g->half_w * z)) / s;
  out->depth = R / (2.0 * (double)OBS_HBAO_DEPTH_EPS * z);
}

static const obs_screen_rule hbao_screen_rule = {
    .param = "radius",
    .reach = hbao_screen_reach,
    .below_pixel = "1 (open): no other texel lies within the radius",
    .below_depth = "noise: the radius lies within the depth buffer's precision",
    .pixel_decides = 1,
};

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges";
 * tests/unit/test_extremes.c and tests/vulkan/test_extremes_vk.c check both ends). The twins
 * share the AO pass, so they share the range. The radius is stated in scene sizes: far below a
 * pixel's footprint every pixel reads 1, far beyond the scene the falloff saturates, and both
 * ends hold at every scale; the bounds keep the sample distances within float's range. Where
 * the radius misses a pixel or a depth step on screen (hbao_screen_rule) the render warns. */
#define HBAO_RANGE                                                              \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"radius", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},                      \
    .screen = &hbao_screen_rule,                                                \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_hbao = {
    .name = "hbao",
    .description = "Horizon-based ambient occlusion (Bavoil & Sainz, ShaderX7 6.2): screen-space "
                   "horizon search over a G-buffer, cross-bilateral blur",
    .params = hbao_params,
    .params_size = sizeof hbao_params / sizeof hbao_params[0],
    .bound_size = sizeof(obs_hbao_params),
    .cost = hbao_cost,
    .cost_rule = "directions x steps",
    .ms_per_work = 1e-5,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .check = NULL,
    .reference = hbao_reference,
    .run = {[OBS_BACKEND_CPU] = obs_hbao_cpu, [OBS_BACKEND_VULKAN] = obs_hbao_vulkan},
    .range = {[OBS_BACKEND_CPU] = HBAO_RANGE, [OBS_BACKEND_VULKAN] = HBAO_RANGE},
};
