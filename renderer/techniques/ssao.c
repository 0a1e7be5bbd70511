/* Descriptor of ssao (Crytek screen-space AO, Kajalin 2009), its parameters and shared tables. */
#include "ssao.h"

#include <jansson.h>
#include <math.h>
#include <string.h>

#include "gbuffer.h"
#include "obscura/render.h"
#include "sampling.h"
#include "techniques.h"

static const obs_output ssao_outputs[] = {
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

/* Keep in step with $defs/ssao_params in schema/scene.schema.json. */
static const char ssao_params[] =
    "{\"type\":\"object\",\"additionalProperties\":false,\"properties\":{"
    "\"samples\":{\"type\":\"integer\",\"enum\":[8,16,24],\"default\":16,"
    "\"description\":\"offset points per pixel: samples/8 rounds of the 8 cube corners\"},"
    "\"radius\":{\"type\":\"number\",\"exclusiveMinimum\":0,\"maximum\":1000000,\"default\":0.01,"
    "\"description\":\"base offset length in texture coordinates (fraction of the image width "
    "and height); sample k (from 1) reaches radius*(1+2.4/samples)^k\"},"
    "\"normal_oriented\":{\"type\":\"boolean\",\"default\":false,"
    "\"description\":\"flip offsets into the hemisphere about the G-buffer normal instead of "
    "using the whole sphere\"},"
    "\"blur\":{\"type\":\"boolean\",\"default\":true,"
    "\"description\":\"4x4 depth-aware box blur after the AO pass\"},"
    "\"blur_depth_threshold\":{\"type\":\"number\",\"minimum\":0,\"maximum\":1000000,"
    "\"default\":0.05,\"description\":\"the blur mixes pixels whose depth differs from the "
    "centre's by at most this fraction of the centre's depth\"},"
    "\"seed\":{\"type\":\"integer\",\"minimum\":0,\"maximum\":4294967295,\"default\":1,"
    "\"description\":\"seed of the 4x4 random rotation texture\"}}}";

int obs_ssao_params_read(const json_t *js, obs_ssao_params *p) {
  memset(p, 0, sizeof *p);
  json_t *s = json_object_get(js, "samples"), *r = json_object_get(js, "radius");
  json_t *no = json_object_get(js, "normal_oriented"), *b = json_object_get(js, "blur");
  json_t *t = json_object_get(js, "blur_depth_threshold"), *sd = json_object_get(js, "seed");
  if (!json_is_integer(s) || !json_is_number(r) || !json_is_boolean(no) || !json_is_boolean(b) ||
      !json_is_number(t) || !json_is_integer(sd))
    return OBS_EINVAL;
  json_int_t n = json_integer_value(s), seed = json_integer_value(sd);
  double rad = json_number_value(r), thr = json_number_value(t);
  if ((n != 8 && n != 16 && n != 24) || !(rad > 0 && rad <= 1e6) || !(thr >= 0 && thr <= 1e6) ||
      seed < 0 || seed > 4294967295LL)
    return OBS_EINVAL;
  p->samples = (int)n;
  p->radius = (float)rad;
  p->normal_oriented = json_is_true(no);
  p->blur = json_is_true(b);
  p->blur_depth_threshold = (float)thr;
  p->seed = (uint32_t)seed;
  return 0;
}

void obs_ssao_tables_make(const obs_ssao_params *p, obs_ssao_tables *t) {
  memset(t, 0, sizeof *t);
  /* The article's loop: the length grows before each use, so sample k has radius * step^k. */
  const float k = 1.0f / sqrtf(3.0f), step = 1.0f + 2.4f / (float)p->samples;
  float scale = p->radius;
  int i = 0;
  for (int round = 0; round < p->samples / 8; round++)
    for (int x = -1; x <= 1; x += 2)
      for (int y = -1; y <= 1; y += 2)
        for (int z = -1; z <= 1; z += 2) {
          scale *= step;
          t->offsets[i][0] = (float)x * k * scale;
          t->offsets[i][1] = (float)y * k * scale;
          t->offsets[i][2] = (float)z * k * scale;
          i++;
        }
  /* Uniform directions by rejection from the cube [-1,1)^3 into the unit ball; a vector too short
   * to normalise safely is redrawn. reflect() needs a unit plane normal. */
  for (uint32_t j = 0; j < 16; j++) {
    uint32_t h = obs_hash_combine(p->seed, j);
    for (uint32_t attempt = 0;; attempt++) {
      float v[3], l2 = 0.0f;
      for (uint32_t c = 0; c < 3; c++) {
        v[c] = 2.0f * obs_u32_to_unit(obs_hash_combine(h, 3 * attempt + c)) - 1.0f;
        l2 += v[c] * v[c];
      }
      if (!(l2 > 1e-4f && l2 <= 1.0f)) continue;
      float inv = 1.0f / sqrtf(l2);
      for (int c = 0; c < 3; c++) t->rotation[j][c] = v[c] * inv;
      break;
    }
  }
  t->inv_samples = 1.0f / (float)p->samples;
  for (int n = 1; n <= 16; n++) t->inv_count[n] = 1.0f / (float)n;
}

/* Longest side of the coarse primary-ray pass that measures the median view depth: enough for a
 * stable median, cheap even for the million-triangle scenes. */
#define SSAO_REFERENCE_DEPTH_SIDE 320

/* ssao's reference (docs/techniques/ssao.md): uniform weighting, sqrt falloff, at half the
 * across-screen reach of the longest offset, r (1 + 2.4/N)^N, converted from texture coordinates to
 * scene units at the median view depth of the covered pixels; the reference is then mapped through
 * ssao's response (sphere or hemisphere variant). */
static int ssao_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                          json_t *out, obs_response *response, obs_err *err) {
  obs_ssao_params p;
  if (obs_ssao_params_read(params, &p))
    return obs_err_set(err, OBS_EINVAL, "ssao: parameters are not valid");
  double radius = json_number_value(json_object_get(params, "radius"));
  double reach = radius * pow(1.0 + 2.4 / p.samples, p.samples);
  if (scene->camera.type == OBS_CAMERA_PERSPECTIVE) {
    if (!facts->have_z_median) {
      int rc = obs_gbuffer_median_depth(scene, SSAO_REFERENCE_DEPTH_SIDE, obs_cpu_count(),
                                        &facts->z_median, err);
      if (rc) return rc;
      facts->have_z_median = 1;
    }
    reach *= 2.0 * tan(0.5 * scene->camera.fov_y * 3.14159265358979323846 / 180.0) *
             facts->z_median;
  } else {
    reach *= scene->camera.height;
  }
  double dmax = 0.5 * reach;
  if (!(dmax > 0) || !isfinite(dmax))
    return obs_err_set(err, OBS_EINVAL, "ssao: the reference distance 0.5 r (1+2.4/N)^N x view "
                       "height is not a positive number (got %g)", dmax);
  json_object_set_new(out, "weighting", json_string("uniform"));
  json_object_set_new(out, "falloff", json_string("sqrt"));
  json_object_set_new(out, "max_distance", json_real(dmax));
  *response = p.normal_oriented ? OBS_RESPONSE_SSAO_HEMI : OBS_RESPONSE_SSAO_SPHERE;
  return 0;
}

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges";
 * tests/unit/test_extremes.c and tests/vulkan/test_extremes_vk.c check both ends). The twins
 * share the AO pass, so they share the range; the radius is a fraction of the image, so no
 * parameter depends on the scene's size. Depths are compared relative to the pixel's own depth,
 * so the result is scale-free once the G-buffer is: the per-pixel bound allows depth-quantised
 * samples that land on the other side of a surface. */
#define SSAO_RANGE                                                              \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{NULL, 0, 0, 0}},                                                \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_ssao = {
    .name = "ssao",
    .description = "Crytek screen-space ambient occlusion (Kajalin, ShaderX7 6.1): depth-buffer "
                   "tests of rotated offsets around each pixel, a^2+a curve, depth-aware 4x4 blur",
    .params_schema = ssao_params,
    .needs = OBS_NEED_GBUFFER,
    .outputs = ssao_outputs,
    .check = NULL,
    .reference = ssao_reference,
    .run = {[OBS_BACKEND_CPU] = obs_ssao_cpu, [OBS_BACKEND_VULKAN] = obs_ssao_vulkan},
    .range = {[OBS_BACKEND_CPU] = SSAO_RANGE, [OBS_BACKEND_VULKAN] = SSAO_RANGE},
};
