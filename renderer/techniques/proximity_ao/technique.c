/* Descriptor of proximity_ao (Menexi and Papaioannou: ambient occlusion reconstructed from
 * pre-computed per-object proximity fields), its parameters, outputs, reference and ranges. */
#include "proximity_ao.h"

#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>

#include "proximity_vk.h"
#include "techniques.h"

static const obs_output proximity_ao_outputs[] = {
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Accessibility reconstructed from the proximity fields (1 = open)",
     .flags = OBS_OUTPUT_PRIMARY | OBS_OUTPUT_UNIT, .background = 1.0f},
    {.name = "fields", .kind = OBS_OUTPUT_SCALAR,
     .description = "How many objects' fields the surface point lies in"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space face normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

const char *const obs_proximity_ao_channels[OBS_PROX_CHANNELS] = {
    "ao", "fields", "depth.Z", "normal.X", "normal.Y", "normal.Z", "alpha"};

/* In OBS_PROX_BOX_* order. */
static const char *const boxes[] = {"maximal", "largest", "union", NULL};
static const char *const reconstructions[] = {"thesis_code", "corrected", NULL};
static const char *const combines[] = {"additive", "multiplicative", NULL};

#define P(member) offsetof(obs_proximity_ao_params, member)
static const obs_param proximity_ao_params[] = {
    {.name = "range", .type = OBS_PARAM_DOUBLE, .flags = OBS_PARAM_MIN_EXCLUSIVE, .min = 0,
     .max = 1, .def = 1,
     .description = "reconstruction range R as a fraction of the propagation radius r_p: the "
                    "walk along the normal reaches R (the fields hold nothing beyond r_p)",
     .offset = P(range)},
    {.name = "steps", .type = OBS_PARAM_INT, .min = 1, .max = OBS_PROX_MAX_STEPS, .def = 20,
     .description = "steps N of the walk; step i reads floor(i/2) points of a disc about the "
                    "normal",
     .offset = P(steps)},
    {.name = "volume_res", .type = OBS_PARAM_INT, .min = 1, .max = 512, .def = 128,
     .description = "voxels along the longest side of the largest grid; other sides and objects "
                    "take the nearest power of two to their share of it",
     .offset = P(volume_res)},
    {.name = "min_res", .type = OBS_PARAM_INT, .min = 1, .max = 512, .def = 32,
     .description = "the fewest voxels along any side of a grid (the thesis's 32; at most "
                    "volume_res)",
     .offset = P(min_res)},
    {.name = "propagation_fraction", .type = OBS_PARAM_DOUBLE, .min = 0, .max = 10, .def = 0.1,
     .description = "propagation radius r_p as a fraction of the diagonal of the reference box "
                    "(the thesis: 10-15 %)",
     .offset = P(propagation_fraction)},
    {.name = "propagation_box", .type = OBS_PARAM_ENUM, .choices = boxes,
     .def = OBS_PROX_BOX_MAXIMAL,
     .description = "the reference box of r_p: maximal = per axis the largest extent over all "
                    "objects (the thesis's maximal box); largest = the largest single object's "
                    "box; union = the box of all objects",
     .offset = P(propagation_box)},
    {.name = "reconstruction", .type = OBS_PARAM_ENUM, .choices = reconstructions, .def = 0,
     .description = "thesis_code: the listing as printed (samples at (i+2) steps, disc points "
                    "summed, weight 1); corrected: the text (samples at i steps, averaged, weight "
                    "1 - i/N)",
     .offset = P(reconstruction)},
    {.name = "combine", .type = OBS_PARAM_ENUM, .choices = combines, .def = 0,
     .description = "occlusion of several fields: additive (the thesis's sum, clamped) or "
                    "multiplicative 1 - (1-a)(1-b)",
     .offset = P(combine)},
    {.name = "self_occlusion", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "read the receiving object's own field too",
     .offset = P(self_occlusion)},
    {.name = "stop_value", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.95,
     .description = "a step whose value exceeds this ends the walk (a surface reached)",
     .offset = P(stop_value)},
    {.name = "scale_before", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1e6, .def = 0.8,
     .description = "the occlusion sum is scaled by this before it is divided by N and clamped",
     .offset = P(scale_before)},
    {.name = "scale_after", .type = OBS_PARAM_FLOAT, .min = 0, .max = 1, .def = 0.8,
     .description = "and by this after: each field's occlusion is at most scale_after, so "
                    "accessibility >= max(0, 1 - k scale_after) (additive) or (1 - "
                    "scale_after)^k (multiplicative) where k fields hold the point",
     .offset = P(scale_after)},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "seed of the disc points (the same for every pixel)", .offset = P(seed)},
};
#undef P

void obs_proximity_ao_layout(const obs_proximity_ao_params *p, obs_prox_layout *out) {
  out->fraction = p->propagation_fraction;
  out->box = p->propagation_box;
  out->res = p->volume_res;
  out->min_res = p->min_res;
}

void obs_proximity_ao_recon(const obs_proximity_ao_params *p, obs_prox_recon *out) {
  obs_prox_recon_init(out, p->steps, p->reconstruction, p->stop_value, p->scale_before,
                      p->scale_after, p->seed);
}

double obs_proximity_ao_reach(const obs_proximity_ao_params *p, double rp) {
  return p->range * rp;
}

double obs_proximity_ao_step(const obs_proximity_ao_params *p, double rp) {
  return obs_proximity_ao_reach(p, rp) / p->steps;
}

/* The fields, built once for every frame and backend: voxelised on the CPU, flooded where the
 * run reads them (the Vulkan flood gives the CPU's bits on the device). */
static int prepare_fields(obs_render_ctx *ctx, obs_backend backend, obs_prepared **out,
                          obs_err *err) {
  obs_prox_layout lay;
  obs_proximity_ao_layout(ctx->bound, &lay);
  obs_prepared *p = calloc(1, sizeof *p);
  if (!p) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  obs_prox_flood_fn flood = backend == OBS_BACKEND_VULKAN ? obs_prox_flood_vulkan : NULL;
  int rc = obs_prox_build(ctx->scene, &lay, ctx->threads, flood, NULL, &p->fields, err);
  if (rc) {
    free(p);
    return rc;
  }
  obs_driver_stage_add(ctx, "voxelise", p->fields.voxelise_ms);
  obs_driver_stage_add(ctx, "flood", p->fields.flood_ms);
  obs_prox_fields_built(&p->fields, ctx->built);
  *out = p;
  return 0;
}

static void release_fields(obs_prepared *p) {
  obs_prox_fields_free(&p->fields);
  free(p);
}

/* Field reads per pixel sample and object: floor(i/2) points at each of N steps. */
static double proximity_ao_cost(const void *bound) {
  int n = ((const obs_proximity_ao_params *)bound)->steps;
  return (double)((n / 2) * (n / 2 - 1) + (n % 2) * (n / 2)) + 1;
}

/* The reference: rt_ao (binary, cosine-weighted) out to the same range R (docs/techniques/
 * proximity_ao.md, "Reference"). */
static int proximity_ao_reference(const obs_scene *scene, const json_t *params,
                                  obs_reference_facts *facts, obs_reference_def *def,
                                  obs_err *err) {
  (void)facts;
  obs_proximity_ao_params p;
  int rc = obs_params_bind(&obs_technique_proximity_ao, params, &p, err);
  if (rc) return rc;
  obs_prox_layout lay;
  obs_proximity_ao_layout(&p, &lay);
  double r = obs_proximity_ao_reach(&p, obs_prox_radius(scene, &lay));
  if (!(r > 0) || !isfinite(r))
    return obs_err_set(err, OBS_EINVAL, "proximity_ao: the reference distance R = range x r_p "
                       "is not a positive number (got %g; is propagation_fraction 0?)", r);
  def->technique = &obs_technique_rt_ao;
  def->response = OBS_RESPONSE_IDENTITY;
  json_object_set_new(def->params, "falloff", json_string("binary"));
  json_object_set_new(def->params, "weighting", json_string("cosine"));
  json_object_set_new(def->params, "max_distance", json_real(r));
  return 0;
}

/* The guaranteed range (docs/accuracy.md, "Guaranteed ranges"): the fields live in object space
 * and the walk in grid coordinates, so the result is scale-free; the world-to-grid map is taken
 * in double from float hit points relative to the camera, so translation costs only the hit's
 * own rounding. Voxels flip where a triangle grazes a voxel face at another scale. */
#define PROXIMITY_AO_RANGE                                                      \
  {                                                                             \
    .size_min = 1e-6, .size_max = 1e6, .translation_max = 1e3, .fov_min = 1,    \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{"range", 0.01, 1, 0}, {NULL, 0, 0, 0}},                         \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_proximity_ao = {
    .name = "proximity_ao",
    .description = "Proximity-field ambient occlusion (Menexi and Papaioannou): per-object voxel "
                   "fields of proximity, voxelised and flooded once, read along each pixel's "
                   "normal; objects shade each other through their fields",
    .params = proximity_ao_params,
    .params_size = sizeof proximity_ao_params / sizeof proximity_ao_params[0],
    .bound_size = sizeof(obs_proximity_ao_params),
    .cost = proximity_ao_cost,
    .cost_rule = "floor(steps/2) summed over the steps, + 1",
    .ms_per_work = 1e-5,
    .needs = OBS_NEED_BVH | OBS_NEED_PROXIMITY | OBS_NEED_MOTION,
    .prepare = prepare_fields,
    .release = release_fields,
    .motion_backends = 1u << OBS_BACKEND_CPU,
    .outputs = proximity_ao_outputs,
    .reference = proximity_ao_reference,
    .run = {[OBS_BACKEND_CPU] = obs_proximity_ao_cpu,
            [OBS_BACKEND_VULKAN] = obs_proximity_ao_vulkan},
    .range = {[OBS_BACKEND_CPU] = PROXIMITY_AO_RANGE, [OBS_BACKEND_VULKAN] = PROXIMITY_AO_RANGE},
};
