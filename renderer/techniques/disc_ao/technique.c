/* Descriptor of disc_ao (Bookout, ShaderX7 6.8: per-pixel AO from one disc per triangle, splatted
 * with geometry-shader proxies), its parameters, range and reference. */
#include "disc_ao.h"

#include <stddef.h>

#include "techniques.h"

static const char *const proxies[] = {"quad", "pyramid", NULL};
static const char *const sides[] = {"front", "back", NULL};

#define P(member) offsetof(obs_disc_ao_params, member)
static const obs_param disc_ao_params[] = {
    {.name = "proxy", .type = OBS_PARAM_ENUM, .choices = proxies, .def = OBS_DISC_PROXY_QUAD,
     .description = "what the Vulkan geometry shader rasterises per disc: quad = the screen "
                    "rectangle of its influence sphere; pyramid = the smallest square pyramid "
                    "holding the occluded half of it (back faces only). The CPU visits the same "
                    "receivers through a grid; the image does not depend on it",
     .offset = P(proxy)},
    {.name = "area_over_pi", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "use A/pi in the form factor 1 - 1/sqrt(A/d^2 + 1), the squared radius of a "
                    "disc of area A (exact on the disc's axis); false: A itself, as the listing",
     .offset = P(area_over_pi)},
    {.name = "influence_scale", .type = OBS_PARAM_FLOAT, .min = 0.5, .max = 64, .def = 4,
     .description = "a disc of area A occludes receivers within influence_scale * sqrt(A) of its "
                    "centre (a length, so the image does not change with the scene's scale)",
     .offset = P(influence_scale)},
    {.name = "side", .type = OBS_PARAM_ENUM, .choices = sides, .def = OBS_DISC_SIDE_FRONT,
     .description = "front: a disc occludes receivers its normal faces (the article's text); "
                    "back: receivers behind it (the article's listing, saturate(n_e . v))",
     .offset = P(side)},
    {.name = "subdivide", .type = OBS_PARAM_FLOAT, .min = 0.01, .max = 1, .def = 0.05,
     .description = "triangles whose longest edge passes this fraction of the scene's diagonal "
                    "are split into m^2 equal ones that do not (1: never split)",
     .offset = P(subdivide)},
};
#undef P

/* Work per pixel: the discs within reach grow with the square of the reach. */
static double disc_ao_cost(const void *bound) {
  const obs_disc_ao_params *p = bound;
  return (double)p->influence_scale * (double)p->influence_scale;
}

/* rt_ao with its defaults: cosine weighting, binary falloff, unbounded range. */
static const char *const disc_ao_reference_keys[] = {NULL};

/* The guaranteed range of both backends (docs/accuracy.md; tests/unit/test_extremes.c and
 * tests/vulkan/test_extremes_vk.c check both ends). Every parameter is scale-free (the reach is
 * influence_scale sqrt(A), the subdivision a fraction of the scene), the discs are made in view
 * space in double, so only the G-buffer's float positions and a disc sitting on the edge of a
 * receiver's reach after rounding separate a scaled scene from the scale-1 one. The field of view
 * stops at 0.01 degree: the camera then stands ~10^4 scene sizes away and the G-buffer's float
 * depth (relative error 6e-8) moves receivers by ~10^-3 scene sizes, past which discs that sit
 * near a receiver's reach come and go (at 0.001 degree the mean error reaches 3e-3). */
#define DISC_AO_RANGE                                                           \
  {                                                                             \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e9, .fov_min = 1e-2, \
    .fov_max = 170, .orthographic = 1,                                          \
    .params = {{NULL, 0, 0, 0}},                                                \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 1e-2, .share = 0.02, .normal = 1e-4,   \
            .depth_rel = 3e-5}                                                  \
  }

const obs_technique obs_technique_disc_ao = {
    .name = "disc_ao",
    .description = "Per-pixel disc ambient occlusion (Bookout, ShaderX7 6.8): one disc per "
                   "triangle occludes the G-buffer's receivers within its reach, summed without "
                   "visibility; on Vulkan through geometry-shader quads or pyramids",
    .params = disc_ao_params,
    .params_size = sizeof disc_ao_params / sizeof disc_ao_params[0],
    .bound_size = sizeof(obs_disc_ao_params),
    .cost = disc_ao_cost,
    .cost_rule = "influence_scale^2",
    .ms_per_work = 2e-5,
    .needs = OBS_NEED_GBUFFER,
    .outputs = obs_screen_outputs,
    .reference_same = &obs_technique_rt_ao,
    .reference_keys = disc_ao_reference_keys,
    .run = {[OBS_BACKEND_CPU] = obs_disc_ao_cpu, [OBS_BACKEND_VULKAN] = obs_disc_ao_vulkan},
    .range = {[OBS_BACKEND_CPU] = DISC_AO_RANGE, [OBS_BACKEND_VULKAN] = DISC_AO_RANGE},
};
