/* Descriptor of obscurance_map: per-patch obscurances with colour bleeding (Mendez-Feliu, Sbert
 * et al.) by cosine rays per patch, global lines or bundles of parallel lines on the CPU, depth
 * peeling on Vulkan. */
#include <jansson.h>
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "obscurance.h"
#include "obscurance_map.h"
#include "techniques.h"

static const obs_output obscurance_map_outputs[] = {
    {.name = "obscurance", .kind = OBS_OUTPUT_PATCH, .show = OBS_SHOW_GREY,
     .png = "obscurance.png",
     .description = "Obscurance W per patch (RGB in the .patches file; the image shows the mean "
                    "of the channels of the patch each pixel sees)",
     .flags = OBS_OUTPUT_PRIMARY | OBS_OUTPUT_UNIT},
    {.name = "obscurance_stderr", .kind = OBS_OUTPUT_PATCH,
     .description = "Standard error of each patch's W per channel (the image shows the mean of "
                    "the channels' errors of the patch each pixel sees; 1: no sample reached it)",
     .stderr_of = "obscurance"},
    {.name = "obscurance_rgb", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP,
     .png = "obscurance_rgb.png",
     .description = "Obscurance W per patch in colour (with colour bleeding), per pixel"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a patch is seen, 0 on the background and spheres)"},
    {.name = NULL}};

static const char *const methods[] = {"rays",          "global_lines", "bundles",
                                      "depth_peeling", "auto",         NULL};

static const char *const updates[] = {"full", "exact", "article", NULL};

#define P(member) offsetof(obs_obscurance_map_params, member)
static const obs_param obscurance_map_params[] = {
    {.name = "method", .type = OBS_PARAM_ENUM, .choices = methods, .def = OBS_OMAP_AUTO,
     .description = "estimator: rays = cosine rays from stratified points of each patch; "
                    "global_lines = lines through random point pairs of the bounding sphere; "
                    "bundles = parallel lines on a grid per direction; depth_peeling (vulkan "
                    "only) = the bundles' directions and grids rendered and peeled layer by "
                    "layer; auto = rays on the cpu, depth_peeling on vulkan",
     .offset = P(method)},
    OBS_OBSCURANCE_MODEL_PARAMS(P),
    {.name = "samples", .type = OBS_PARAM_UINT, .min = 1, .max = 65536, .def = 64,
     .description = "rays: rays per patch", .offset = P(samples)},
    {.name = "directions", .type = OBS_PARAM_UINT, .min = 1, .max = 4096, .def = 64,
     .description = "bundles, depth_peeling: directions; global_lines: with lines 0, the line "
                    "count is "
                    "directions x bundle_resolution^2",
     .offset = P(directions)},
    {.name = "bundle_resolution", .type = OBS_PARAM_UINT, .min = 2, .max = 512, .def = 64,
     .description = "bundles, depth_peeling: parallel lines (pixels) per side of the grid "
                    "covering the bounding sphere",
     .offset = P(bundle_resolution)},
    {.name = "lines", .type = OBS_PARAM_UINT, .min = 0, .max = 16777216, .def = 0,
     .description = "global_lines: lines; 0 = directions x bundle_resolution^2",
     .offset = P(lines)},
    {.name = "patch_size", .type = OBS_PARAM_DOUBLE,
     .flags = OBS_PARAM_MIN_EXCLUSIVE | OBS_PARAM_NULLABLE | OBS_PARAM_DEFAULT_NULL, .min = 0,
     .max = 1e30, .null_value = INFINITY,
     .description = "longest patch edge in scene units: each triangle is split into n x n "
                    "patches; null = one patch per triangle",
     .offset = P(patch_size), .size_default = 0.05},
    {.name = "seed", .type = OBS_PARAM_UINT, .min = 0, .max = 4294967295.0, .def = 1,
     .description = "random seed; the map depends only on (scene, parameters, seed)",
     .offset = P(seed)},
    {.name = "update", .type = OBS_PARAM_ENUM, .choices = updates, .def = OBS_OMAP_UPDATE_EXACT,
     .description = "scenes with moving objects: how each frame after the first is computed. "
                    "full = every patch again; exact (rays) = the patches within d_max of a "
                    "moving object's bounds in the frame before or this one, equal to full bit "
                    "for bit; article (rays) = the article's influenced list: the patches whose "
                    "samples hit a moving object and the objects' own, then those the objects' "
                    "samples hit (misses patches that only start to see an object)",
     .offset = P(update)},
    {.name = "measure_full", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "scenes with moving objects: also compute every frame in full, to report "
                    "each update's speed-up and error against it (summary.json frames)",
     .offset = P(measure_full)},
};
#undef P

/* Each estimator runs on one backend: depth_peeling on Vulkan, the others on the CPU. Moving
 * objects are updated patch by patch, which only the rays estimator does, on the CPU. */
static void obscurance_map_check(const obs_scene *scene, const json_t *params, const char *doc,
                                 obs_err *err) {
  const char *m = json_string_value(json_object_get(params, "method"));
  const char *u = json_string_value(json_object_get(params, "update"));
  int vk = scene->backend == OBS_BACKEND_VULKAN;
  if (scene->frames > 1 && m && u && strcmp(m, "rays") && strcmp(m, "auto") &&
      strcmp(u, "full"))
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/update: \"%s\" recomputes patch by patch, which method "
                "\"%s\" cannot (its lines cross every patch); use method \"rays\" or update "
                "\"full\"",
                doc, u, m);
  if (!m || !strcmp(m, "auto")) return;
  int peel = !strcmp(m, "depth_peeling");
  if (peel && !vk)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/method: \"depth_peeling\" runs on the vulkan backend only "
                "(set /technique/backend to \"vulkan\")",
                doc);
  else if (!peel && vk)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/method: \"%s\" runs on the cpu backend only (on the vulkan "
                "backend use \"depth_peeling\" or \"auto\")",
                doc, m);
}

/* Frame 0 in full, then per frame at most a full map, and a second with measure_full. */
static double obscurance_map_frames_cost(const void *bound, int frames) {
  const obs_obscurance_map_params *p = bound;
  return 1.0 + (frames - 1) * (p->measure_full ? 2.0 : 1.0);
}

/* Embree queries per pixel sample do not describe a per-patch map: the work counted is the line
 * or ray budget, in units of 2^16 lines (or rays per patch for `rays`). */
static double obscurance_map_cost(const void *bound) {
  const obs_obscurance_map_params *p = bound;
  switch (p->method) {
  case OBS_OMAP_RAYS: return p->samples;
  case OBS_OMAP_GLOBAL_LINES:
    return (p->lines ? (double)p->lines
                     : (double)p->directions * p->bundle_resolution * p->bundle_resolution) /
           65536.0;
  case OBS_OMAP_AUTO: /* rays on the cpu, depth_peeling on vulkan: the larger of the two */
    return fmax(p->samples,
                (double)p->directions * p->bundle_resolution * p->bundle_resolution / 65536.0);
  default: return (double)p->directions * p->bundle_resolution * p->bundle_resolution / 65536.0;
  }
}

/* The reference of a map is the same map by the `rays` estimator (the caller turns samples up):
 * the lines estimators and the rays one estimate the same per-patch W. */
static int obscurance_map_reference(const obs_scene *scene, const json_t *params,
                                    obs_reference_facts *facts, obs_reference_def *def,
                                    obs_err *err) {
  (void)scene;
  (void)facts;
  (void)err;
  static const char *const keys[] = {"d_max", "falloff", "tau", "color_bleeding", "patch_size",
                                     NULL};
  obs_reference_def_same(def, &obs_technique_obscurance_map, params, keys);
  json_object_set_new(def->params, "method", json_string("rays"));
  /* With moving objects, every frame of the reference is exact; nothing to measure it against. */
  json_object_set_new(def->params, "measure_full", json_false());
  return 0;
}

/* The guaranteed range (docs/accuracy.md; tests/unit/test_extremes.c checks both ends). Lines and
 * rays are placed relative to the geometry's bounding sphere and the same seed draws the same
 * lines at every scale, so only samples that graze an edge may change: a patch's value moves by
 * a few samples' worth, on every pixel of the patch. */
const obs_technique obs_technique_obscurance_map = {
    .name = "obscurance_map",
    .description = "Per-patch obscurances with colour bleeding (Mendez-Feliu, Sbert et al.) by "
                   "rays, global lines or bundles of parallel lines (Embree), or by depth "
                   "peeling along the bundles' directions (Vulkan)",
    .params = obscurance_map_params,
    .params_size = sizeof obscurance_map_params / sizeof obscurance_map_params[0],
    .bound_size = sizeof(obs_obscurance_map_params),
    .cost = obscurance_map_cost,
    .frames_cost = obscurance_map_frames_cost,
    .motion_backends = 1u << OBS_BACKEND_CPU,
    .cost_rule = "samples (rays); directions x bundle_resolution^2 / 65536 (bundles, "
                 "depth_peeling); lines / 65536 (global_lines)",
    .ms_per_work = 1e-4,
    .needs = OBS_NEED_BVH | OBS_NEED_BVH_FRAME_GEOMETRY | OBS_NEED_MATERIALS | OBS_NEED_MOTION,
    .outputs = obscurance_map_outputs,
    .check = obscurance_map_check,
    .reference = obscurance_map_reference,
    .reference_alts = obs_obscurance_w_alts,
    .reference_quality = "samples",
    .run = {[OBS_BACKEND_CPU] = obs_obscurance_map_cpu,
            [OBS_BACKEND_VULKAN] = obs_obscurance_map_vulkan},
    .range = {[OBS_BACKEND_CPU] = {.size_min = 1e-9,
                                   .size_max = 1e9,
                                   .translation_max = 1e9,
                                   .fov_min = 1e-4,
                                   .fov_max = 170,
                                   .orthographic = 1,
                                   .params = {{"d_max", 1e-6, 1e6, 1},
                                              {"patch_size", 0.01, 1e6, 1},
                                              {NULL, 0, 0, 0}},
                                   .tol = {.ao_mean = 1e-3,
                                           .ao_pixel = 1e-4,
                                           .share = 0.02,
                                           .normal = 1e-4,
                                           .depth_rel = 3e-5}},
              /* depth_peeling: the bundles' grid in coordinates normalised to the bounding
               * sphere, the patch ids of the image by a float projection of the camera. */
              [OBS_BACKEND_VULKAN] = {.size_min = 1e-4,
                                      .size_max = 1e4,
                                      .translation_max = 1e4,
                                      .fov_min = 1,
                                      .fov_max = 170,
                                      .orthographic = 1,
                                      .params = {{"d_max", 1e-6, 1e6, 1},
                                                 {"patch_size", 0.05, 1e6, 1},
                                                 {NULL, 0, 0, 0}},
                                      .tol = {.ao_mean = 1e-3,
                                              .ao_pixel = 1e-4,
                                              .share = 0.02,
                                              .normal = 1e-4,
                                              .depth_rel = 3e-5}}},
};
