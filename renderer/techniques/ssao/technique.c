/* Descriptor of ssao (Crytek screen-space AO, Kajalin 2009), its parameters and reference. */
#include "ssao.h"

#include <float.h>
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "gbuffer.h"
#include "gbuffer_cpu.h"
#include "obscura/render.h"
#include "sampling.h"
#include "techniques.h"

static const int ssao_sample_counts[] = {8, 16, 24};

#define P(member) offsetof(obs_ssao_params, member)
static const obs_param ssao_params[] = {
    {.name = "samples", .type = OBS_PARAM_INT, .values = ssao_sample_counts, .nvalues = 3,
     .def = 16, .description = "offset points per pixel: samples/8 rounds of the 8 cube corners",
     .offset = P(samples)},
    {.name = "radius", .type = OBS_PARAM_FLOAT, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1e6, .def = 0.01,
     .description = "base offset length in texture coordinates (fraction of the image width and "
                    "height); sample k (from 1) reaches radius*(1+2.4/samples)^k",
     .offset = P(radius)},
    {.name = "normal_oriented", .type = OBS_PARAM_BOOL, .def = 0,
     .description = "flip offsets into the hemisphere about the G-buffer normal instead of using "
                    "the whole sphere",
     .offset = P(normal_oriented)},
    {.name = "blur", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "4x4 depth-aware box blur after the AO pass", .offset = P(blur)},
    {.name = "blur_depth_threshold", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.05,
     .description = "the blur mixes pixels whose depth differs from the centre's by at most this "
                    "fraction of the centre's depth",
     .offset = P(blur_depth_threshold)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the 4x4 random rotation texture", .offset = P(seed)},
};
#undef P

/* Depth-buffer taps per pixel. */
static double ssao_cost(const void *bound) {
  return (double)((const obs_ssao_params *)bound)->samples;
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
                          obs_reference_def *def, obs_err *err) {
  json_t *out = def->params;
  def->technique = &obs_technique_rt_ao;
  obs_ssao_params p;
  int rc = obs_params_bind(&obs_technique_ssao, params, &p, err);
  if (rc) return rc;
  double radius = json_number_value(json_object_get(params, "radius"));
  double reach = radius * pow(1.0 + 2.4 / p.samples, p.samples);
  if (scene->camera.type == OBS_CAMERA_PERSPECTIVE) {
    if (!facts->have_z_median) {
      rc = obs_gbuffer_median_depth(scene, obs_gbuffer_cpu, SSAO_REFERENCE_DEPTH_SIDE,
                                    obs_cpu_count(), &facts->z_median, err);
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
  def->response = p.normal_oriented ? OBS_RESPONSE_SSAO_HEMI : OBS_RESPONSE_SSAO_SPHERE;
  return 0;
}

/* ssao's reach (obs_screen_rule): the longest offset, r (1 + 2.4/N)^N in texture coordinates,
 * moves a sample at most that fraction of the image along either axis, so max(W, H) times it in
 * pixels; along the view axis it moves the sample's depth by 2 z r (1 + 2.4/N)^N at most, which
 * the depth test `z_s > d` resolves from z itself only above float's relative precision,
 * FLT_EPSILON (one ulp of z is between 2^-24 and 2^-23 of z). Neither depends on z. */
static void ssao_screen_reach(const void *bound, const obs_gbuffer *g, double z,
                              obs_screen_reach *out) {
  (void)z;
  const obs_ssao_params *p = bound;
  double reach = (double)p->radius * pow(1.0 + 2.4 / p->samples, p->samples);
  out->pixels = reach * (g->width > g->height ? g->width : g->height);
  out->depth = 2.0 * reach / FLT_EPSILON;
}

static const obs_screen_rule ssao_screen_rule = {
    .param = "radius",
    .reach = ssao_screen_reach,
    .below_pixel = "blind to the geometry: samples read only the pixel and its neighbours",
    .below_depth = "dark: sample depths round to the pixel's own and count as occluded",
};

/* The guaranteed range of both backends (docs/accuracy.md, "Guaranteed ranges";
 * tests/unit/test_extremes.c and tests/vulkan/test_extremes_vk.c check both ends). The twins
 * share the AO pass, so they share the range; the radius is a fraction of the image, so no
 * parameter depends on the scene's size. Depths are compared relative to the pixel's own depth,
 * so the result is scale-free once the G-buffer is: the per-pixel bound allows depth-quantised
 * samples that land on the other side of a surface. Its radius must reach a pixel and a depth
 * step (ssao_screen_rule): smaller ones render, with a warning. */
#define SSAO_RANGE                                                              \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-4, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{NULL, 0, 0, 0}},                                                \
    .screen = &ssao_screen_rule,                                                \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_ssao = {
    .name = "ssao",
    .description = "Crytek screen-space ambient occlusion (Kajalin, ShaderX7 6.1): depth-buffer "
                   "tests of rotated offsets around each pixel, a^2+a curve, depth-aware 4x4 blur",
    .params = ssao_params,
    .params_size = sizeof ssao_params / sizeof ssao_params[0],
    .bound_size = sizeof(obs_ssao_params),
    .cost = ssao_cost,
    .cost_rule = "samples",
    .ms_per_work = 3.5e-5,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .check = NULL,
    .reference = ssao_reference,
    .run = {[OBS_BACKEND_CPU] = obs_ssao_cpu, [OBS_BACKEND_VULKAN] = obs_ssao_vulkan},
    .range = {[OBS_BACKEND_CPU] = SSAO_RANGE, [OBS_BACKEND_VULKAN] = SSAO_RANGE},
};
