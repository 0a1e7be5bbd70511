/* Descriptor of hbao (Bavoil & Sainz, horizon-based ambient occlusion) and the parameter reading
 * and direction table shared by its CPU and Vulkan backends. */
#include "hbao.h"

#include <jansson.h>
#include <math.h>
#include <string.h>

#include "sampling.h"
#include "techniques.h"

static const obs_output hbao_outputs[] = {
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Ambient occlusion (white = open, black = fully occluded)",
     .flags = OBS_OUTPUT_PRIMARY},
    {.name = "ao_raw", .kind = OBS_OUTPUT_SCALAR,
     .description = "Ambient occlusion before the blur"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

const char *const obs_hbao_pass_names[OBS_HBAO_PASS_COUNT] = {"downsample", "ao", "upsample",
                                                              "blur"};

/* Keep in step with $defs/hbao_params in schema/scene.schema.json. */
const char obs_hbao_params_schema[] =
    "{\"type\":\"object\",\"additionalProperties\":false,\"properties\":{"
    "\"radius\":{\"type\":\"number\",\"exclusiveMinimum\":0,\"maximum\":1e30,\"default\":1,"
    "\"description\":\"occlusion radius R in scene units (view space)\"},"
    "\"directions\":{\"type\":\"integer\",\"minimum\":1,\"maximum\":32,\"default\":8,"
    "\"description\":\"horizon directions per pixel, evenly spaced, randomly rotated per pixel\"},"
    "\"steps\":{\"type\":\"integer\",\"minimum\":1,\"maximum\":32,\"default\":8,"
    "\"description\":\"texel-snapped samples marched per direction\"},"
    "\"angle_bias\":{\"type\":\"number\",\"minimum\":0,\"exclusiveMaximum\":1.5707963267948966,"
    "\"default\":0.5235987755982988,\"description\":\"radians added to the tangent angle; hides "
    "tessellation and depth-quantisation artefacts\"},"
    "\"scale\":{\"type\":\"number\",\"minimum\":0,\"maximum\":1e6,\"default\":1,"
    "\"description\":\"AO = 1 - scale * (sum over directions) / directions\"},"
    "\"blur_radius\":{\"type\":\"integer\",\"minimum\":0,\"maximum\":16,\"default\":4,"
    "\"description\":\"separable cross-bilateral blur radius in pixels; 0 = no blur\"},"
    "\"blur_sharpness\":{\"type\":\"number\",\"minimum\":0,\"maximum\":1e6,\"default\":16,"
    "\"description\":\"blur depth weight exp(-sharpness (dz/z)^2); 0 = plain Gaussian\"},"
    "\"half_res\":{\"type\":\"boolean\",\"default\":false,"
    "\"description\":\"AO at half resolution, bilateral upsampling before the blur\"},"
    "\"seed\":{\"type\":\"integer\",\"minimum\":0,\"maximum\":4294967295,\"default\":1,"
    "\"description\":\"seed of the 4x4 per-pixel rotation and jitter table\"}}}";

void obs_hbao_params_default(obs_hbao_params *p) {
  p->radius = 1.0f;
  p->directions = 8;
  p->steps = 8;
  p->angle_bias = 0.5235987755982988f;
  p->scale = 1.0f;
  p->blur_radius = 4;
  p->blur_sharpness = 16.0f;
  p->half_res = 0;
  p->seed = 1;
}

static int read_num(const json_t *o, const char *key, double lo, int lo_excl, double hi,
                    int hi_excl, double *out) {
  json_t *v = json_object_get(o, key);
  if (!v) return 0;
  if (!json_is_number(v)) return OBS_EINVAL;
  double d = json_number_value(v);
  if (!(lo_excl ? d > lo : d >= lo) || !(hi_excl ? d < hi : d <= hi)) return OBS_EINVAL;
  *out = d;
  return 0;
}

static int read_int(const json_t *o, const char *key, double lo, double hi, double *out) {
  json_t *v = json_object_get(o, key);
  if (!v) return 0;
  double d;
  if (json_is_integer(v)) d = (double)json_integer_value(v);
  else if (json_is_real(v) && floor(json_real_value(v)) == json_real_value(v)) d = json_real_value(v);
  else return OBS_EINVAL;
  if (!(d >= lo && d <= hi)) return OBS_EINVAL;
  *out = d;
  return 0;
}

int obs_hbao_params_read(const json_t *js, obs_hbao_params *out) {
  obs_hbao_params p;
  obs_hbao_params_default(&p);
  if (js && !json_is_object(js)) return OBS_EINVAL;
  double radius = p.radius, dirs = p.directions, steps = p.steps, bias = p.angle_bias;
  double scale = p.scale, blur = p.blur_radius, sharp = p.blur_sharpness, seed = p.seed;
  if (read_num(js, "radius", 0, 1, 1e30, 0, &radius) ||
      read_int(js, "directions", 1, OBS_HBAO_MAX_DIRECTIONS, &dirs) ||
      read_int(js, "steps", 1, OBS_HBAO_MAX_STEPS, &steps) ||
      read_num(js, "angle_bias", 0, 0, 1.5707963267948966, 1, &bias) ||
      read_num(js, "scale", 0, 0, 1e6, 0, &scale) ||
      read_int(js, "blur_radius", 0, OBS_HBAO_MAX_BLUR_RADIUS, &blur) ||
      read_num(js, "blur_sharpness", 0, 0, 1e6, 0, &sharp) ||
      read_int(js, "seed", 0, 4294967295.0, &seed))
    return OBS_EINVAL;
  json_t *hr = json_object_get(js, "half_res");
  if (hr && !json_is_boolean(hr)) return OBS_EINVAL;
  p.radius = (float)radius; /* a radius below FLT_TRUE_MIN becomes 0: AO 1 everywhere */
  p.directions = (int)dirs;
  p.steps = (int)steps;
  p.angle_bias = (float)bias;
  /* pi/2 rounds up in float; keep the bias strictly below it as the schema promises. */
  if (p.angle_bias >= 1.5707963267948966f) p.angle_bias = nextafterf(1.5707963267948966f, 0.0f);
  p.scale = (float)scale;
  p.blur_radius = (int)blur;
  p.blur_sharpness = (float)sharp;
  if (hr) p.half_res = json_is_true(hr);
  p.seed = (uint32_t)seed;
  *out = p;
  return 0;
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
                          json_t *out, obs_response *response, obs_err *err) {
  (void)scene;
  (void)facts;
  obs_hbao_params p;
  if (obs_hbao_params_read(params, &p))
    return obs_err_set(err, OBS_EINVAL, "hbao: parameters are not valid");
  json_t *r = json_object_get(params, "radius");
  double radius = json_is_number(r) ? json_number_value(r) : (double)p.radius;
  json_object_set_new(out, "weighting", json_string("uniform"));
  json_object_set_new(out, "falloff", json_string("binary"));
  json_object_set_new(out, "max_distance", json_real(2.0 * radius / 3.0));
  *response = OBS_RESPONSE_IDENTITY;
  return 0;
}

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges";
 * tests/unit/test_extremes.c and tests/vulkan/test_extremes_vk.c check both ends). The twins
 * share the AO pass, so they share the range. The radius is stated in scene sizes: far below a
 * pixel's footprint every pixel reads 1, far beyond the scene the falloff saturates, and both
 * ends hold at every scale; the bounds keep the sample distances within float's range. */
#define HBAO_RANGE                                                              \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"radius", 1e-6, 1e6, 1}, {NULL, 0, 0, 0}},                      \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_hbao = {
    .name = "hbao",
    .description = "Horizon-based ambient occlusion (Bavoil & Sainz, ShaderX7 6.2): screen-space "
                   "horizon search over a G-buffer, cross-bilateral blur",
    .params_schema = obs_hbao_params_schema,
    .needs = OBS_NEED_GBUFFER,
    .outputs = hbao_outputs,
    .check = NULL,
    .reference = hbao_reference,
    .run = {[OBS_BACKEND_CPU] = obs_hbao_cpu, [OBS_BACKEND_VULKAN] = obs_hbao_vulkan},
    .range = {[OBS_BACKEND_CPU] = HBAO_RANGE, [OBS_BACKEND_VULKAN] = HBAO_RANGE},
};
