/* Descriptor of volume_ao: isosurface ray casting of scalar volumes with ray-marched ambient
 * occlusion, bent normals and environment lighting (the RTPara report's method). */
#include <jansson.h>
#include <stddef.h>
#include <string.h>

#include "techniques.h"
#include "volume_ao.h"
#include "volume_march.h"

static const obs_output volume_ao_outputs[] = {
    {.name = "final",
     .kind = OBS_OUTPUT_RGB,
     .show = OBS_SHOW_TONEMAP,
     .png = "final.png",
     .description = "Shaded isosurface: direct lights plus the environment (exposure and sRGB "
                    "applied in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY,
     .exposure = "exposure"},
    {.name = "ao",
     .kind = OBS_OUTPUT_SCALAR,
     .show = OBS_SHOW_GREY,
     .png = "ao.png",
     .description = "Ambient occlusion of the isosurface (white = open)",
     .flags = OBS_OUTPUT_UNIT,
     .background = 1},
    {.name = "ao_stderr",
     .kind = OBS_OUTPUT_SCALAR,
     .description = "Standard error of the per-pixel AO estimate",
     .stderr_of = "ao"},
    {.name = "bent_normal",
     .kind = OBS_OUTPUT_VECTOR,
     .show = OBS_SHOW_NORMAL,
     .png = "bent_normal.png",
     .description = "Bent normals as colours (X, Y, Z \u2192 red, green, blue)"},
    {.name = "normal",
     .kind = OBS_OUTPUT_VECTOR,
     .description = "World-space normal from the field's gradient, toward the viewer"},
    {.name = "depth",
     .kind = OBS_OUTPUT_DEPTH,
     .show = OBS_SHOW_DEPTH,
     .png = "depth.png",
     .description = "Depth of the first isosurface hit (view distance, grey levels)"},
    {.name = "alpha",
     .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where the isosurface is hit, 0 on the background)",
     .flags = OBS_OUTPUT_UNIT},
    {.name = NULL}};

const char *const obs_volume_ao_channels[CH_COUNT] = {
    "final.R",  "final.G",  "final.B",  "ao",      "ao_stderr", "bent_normal.X", "bent_normal.Y",
    "bent_normal.Z", "normal.X", "normal.Y", "normal.Z", "depth.Z",   "alpha"};

const int obs_volume_ao_se[1] = {CH_AOSE}, obs_volume_ao_value[1] = {CH_AO};

static const char *const crossings[] = {"rising", "any", NULL}; /* obs_volume_crossing */
static const char *const shadings[] = {"lambert", "blinn_phong", NULL};
static const char *const ibls[] = {"none", "bent_normal_lookup", "irradiance", "reference", NULL};
static const char *const samplers[] = {"sobol", "halton", "random", NULL}; /* obs_sampler_kind */

#define P(member) offsetof(obs_volume_ao_tparams, member)
static const obs_param volume_ao_params[] = {
    {.name = "samples",
     .type = OBS_PARAM_UINT,
     .min = 1,
     .max = 65536,
     .def = 32,
     .description = "AO directions per hit, cosine-distributed about the normal",
     .offset = P(samples)},
    {.name = "start",
     .type = OBS_PARAM_DOUBLE,
     .min = 0,
     .max = 1e3,
     .def = 0.01,
     .description = "where each AO direction's march starts, in the object space of the volume "
                    "hit (its longest side is 1)",
     .offset = P(start)},
    {.name = "step",
     .type = OBS_PARAM_DOUBLE,
     .flags = OBS_PARAM_MIN_EXCLUSIVE,
     .min = 0,
     .max = 1e3,
     .def = 0.01,
     .description = "the AO march's step, in the same units",
     .offset = P(step)},
    {.name = "max_distance",
     .type = OBS_PARAM_DOUBLE,
     .min = 0,
     .max = 1e3,
     .def = 0.9,
     .description = "how far each AO direction is marched, in the same units",
     .offset = P(max_distance)},
    {.name = "crossing",
     .type = OBS_PARAM_ENUM,
     .choices = crossings,
     .def = 0,
     .description = "rising: occluded where the field rises through the isovalue between two "
                    "samples (the report's test); any: where it crosses either way",
     .offset = P(crossing)},
    {.name = "shading",
     .type = OBS_PARAM_ENUM,
     .choices = shadings,
     .def = 0,
     .description = "direct lighting by the scene's point and directional lights: lambert, or "
                    "lambert plus a normalised Blinn-Phong highlight",
     .offset = P(blinn_phong)},
    {.name = "shininess",
     .type = OBS_PARAM_DOUBLE,
     .min = 1,
     .max = 1e4,
     .def = 32,
     .description = "Blinn-Phong exponent",
     .offset = P(shininess)},
    {.name = "specular",
     .type = OBS_PARAM_DOUBLE,
     .min = 0,
     .max = 1,
     .def = 0.3,
     .description = "Blinn-Phong highlight weight",
     .offset = P(specular)},
    {.name = "ibl",
     .type = OBS_PARAM_ENUM,
     .choices = ibls,
     .def = 1,
     .description = "environment light: bent_normal_lookup = AO x environment at the bent "
                    "normal (the report's), irradiance = AO x the environment's diffuse SH9 "
                    "convolution at the bent normal, reference = Monte-Carlo integral of "
                    "environment x visibility over the AO directions (the ground truth), none",
     .offset = P(ibl)},
    {.name = "sampler",
     .type = OBS_PARAM_ENUM,
     .choices = samplers,
     .def = 0,
     .description = "sample sequence of the AO directions, scrambled per pixel",
     .offset = P(sampler)},
    {.name = "seed",
     .type = OBS_PARAM_UINT,
     .min = 0,
     .max = 4294967295.0,
     .def = 1,
     .description = "random seed; images depend only on (pixel, sample, seed)",
     .offset = P(seed)},
    {.name = "exposure",
     .type = OBS_PARAM_DOUBLE,
     .min = -30,
     .max = 30,
     .def = 0,
     .description = "exposure in EV applied to final.png only",
     .offset = P(exposure)},
};
#undef P

/* A hit marches `samples` directions of (max_distance - start) / step samples each (at most
 * OBS_VOLUME_AO_MAX_STEPS), in units of the report's 90-sample march; the camera ray's march
 * is about one more. */
/* The AO march ends max_distance from the hit. */
static double volume_ao_reach(const void *bound) {
  return ((const obs_volume_ao_tparams *)bound)->max_distance;
}

static double volume_ao_cost(const void *bound) {
  const obs_volume_ao_tparams *p = bound;
  double steps = (p->max_distance - p->start) / p->step;
  if (!(steps >= 1)) steps = 1; /* NaN too */
  if (steps > OBS_VOLUME_AO_MAX_STEPS) steps = OBS_VOLUME_AO_MAX_STEPS;
  return 1.0 + (double)p->samples * steps / 90.0;
}

/* What defines the shaded quantity; the reference swaps the ibl method for its ground truth. */
static const char *const volume_ao_reference_keys[] = {"start",    "step",     "max_distance",
                                                       "crossing", "shading",  "shininess",
                                                       "specular", "exposure", NULL};

/* The bent normal against the reference's (the Monte-Carlo integral's mean open direction). */
static const obs_output_pair volume_ao_compared[] = {{"bent_normal", "bent_normal"}, {NULL, NULL}};

static int volume_ao_reference(const obs_scene *scene, const json_t *params,
                               obs_reference_facts *facts, obs_reference_def *def, obs_err *err) {
  (void)scene, (void)facts, (void)err;
  obs_reference_def_same(def, &obs_technique_volume_ao, params, volume_ao_reference_keys);
  json_object_set_new(def->params, "ibl", json_string("reference"));
  return 0;
}

void obs_volume_ao_warn(obs_render_ctx *ctx, const obs_scene *sc, const obs_volume_ao_tparams *p) {
  size_t quads = 0;
  for (size_t i = 0; i < sc->nlights; i++) quads += sc->lights[i].type == OBS_LIGHT_QUAD;
  if (quads)
    obs_render_ctx_warn(ctx,
                        "volume_ao lights with point and directional lights: it ignores the "
                        "scene's %zu quad light%s",
                        quads, quads > 1 ? "s" : "");
  double steps = (p->max_distance - p->start) / p->step;
  if (p->max_distance < p->start)
    obs_render_ctx_warn(ctx,
                        "volume_ao: max_distance %g is below start %g: every direction is open "
                        "(AO = 1)",
                        p->max_distance, p->start);
  else if (steps > OBS_VOLUME_AO_MAX_STEPS)
    obs_render_ctx_warn(ctx,
                        "volume_ao: (max_distance - start) / step = %.3g steps; each AO "
                        "direction stops after %d",
                        steps, OBS_VOLUME_AO_MAX_STEPS);
  else if (steps < 1)
    obs_render_ctx_warn(ctx,
                        "volume_ao: the step %g is longer than the march (%g): each AO direction "
                        "takes at most one step",
                        p->step, p->max_distance - p->start);
}

/* The guaranteed range (docs/accuracy.md; tests/unit/test_volume_ao.c checks both ends). The
 * marcher works in the volume's data space in double from camera rays mapped into it, and every
 * AO length is in that space, so the result does not depend on the object's scale or place until
 * double's relative precision (1e-16) times the translation over the size reaches a thousandth
 * of a voxel of a 4096-sample axis: 1e9 sizes. */
/* Both backends' range: the same sizes, translation and fields of view; only the depth
 * tolerance differs (float on Vulkan). */
#define VOLUME_AO_RANGE(depth_rel_)                                                          \
  {                                                                                          \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e6, .fov_min = 1e-3,              \
    .fov_max = 170, .orthographic = 1, .params = {{NULL, 0, 0, 0}},                          \
    .tol = {.ao_mean = 1e-3, .ao_pixel = 1e-4, .share = 0.02, .normal = 1e-4,                \
            .depth_rel = depth_rel_}                                                         \
  }

const obs_technique obs_technique_volume_ao = {
    .name = "volume_ao",
    .description =
        "Isosurface ray casting of volumes with ray-marched ambient occlusion, bent "
        "normals and environment lighting (RTPara)",
    .params = volume_ao_params,
    .params_size = sizeof volume_ao_params / sizeof volume_ao_params[0],
    .bound_size = sizeof(obs_volume_ao_tparams),
    .cost = volume_ao_cost,
    .volume_reach = volume_ao_reach,
    .cost_rule = "1 + samples x (max_distance - start) / step / 90",
    .ms_per_work = 5e-4,
    .needs = OBS_NEED_VOLUME | OBS_NEED_PUNCTUAL_LIGHTS | OBS_NEED_ENV_MAP,
    .outputs = volume_ao_outputs,
    .reference = volume_ao_reference,
    .compared_outputs = volume_ao_compared,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_volume_ao_cpu, [OBS_BACKEND_VULKAN] = obs_volume_ao_vulkan},
    .range = {[OBS_BACKEND_CPU] = VOLUME_AO_RANGE(3e-5),
              /* The shader computes in float, but in each volume's data space, from maps the
               * host composes in double relative to a point on the view axis at the volumes'
               * depth, and camera rays start where they cross that point's depth plane
               * (vulkan.c): scale, translation and the eye's distance
               * (3e5 sizes at fov_y 1e-3) cancel before anything is rounded to float, so the
               * range is the CPU's. Float sets the tolerance instead: the rounded maps move the
               * bisected hit within its thousandth of a voxel, and over both ends of this range
               * (tests/vulkan/test_extremes_vk.c) depth moved by up to 7.8e-5 of itself and
               * normals by 6.2e-5, while AO and colour did not change on any pixel. */
              [OBS_BACKEND_VULKAN] = VOLUME_AO_RANGE(1e-4)},
};
