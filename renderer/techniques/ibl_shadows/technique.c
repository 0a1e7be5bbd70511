/* Descriptor of ibl_shadows (Colbert and Krivanek, ShaderX7 4.3): dynamic shadows for
 * image-based lighting from importance-sampled shadow maps fitted per texel by order-4 spherical
 * harmonics of visibility x cosine; diffuse radiance = SH visibility . environment SH. */
#include <jansson.h>
#include <stddef.h>

#include "ibl_shadows.h"
#include "techniques.h"

static const obs_output ibl_outputs[] = {
    {.name = "radiance", .kind = OBS_OUTPUT_RGB, .show = OBS_SHOW_TONEMAP, .png = "final.png",
     .description = "Diffuse radiance albedo / pi x SH(visibility x cosine) . SH(environment); the "
                    "environment on the background (exposure and sRGB in the PNG)",
     .flags = OBS_OUTPUT_PRIMARY, .exposure = "exposure"},
    {.name = "ao", .kind = OBS_OUTPUT_SCALAR, .show = OBS_SHOW_GREY, .png = "ao.png",
     .description = "Ambient occlusion from the fitted SH: 2 w_0 / sqrt(pi) (white = open)",
     .flags = OBS_OUTPUT_UNIT},
    {.name = "ao_raw", .kind = OBS_OUTPUT_SCALAR,
     .description = "The same before the blur"},
    {.name = "bent_normal", .kind = OBS_OUTPUT_VECTOR, .show = OBS_SHOW_NORMAL,
     .png = "bent_normal.png",
     .description = "Cosine-weighted bent normal from the fitted band 1 (world space)"},
    {.name = "depth", .kind = OBS_OUTPUT_DEPTH, .show = OBS_SHOW_DEPTH, .png = "depth.png",
     .description = "Depth (view distance, grey levels)"},
    {.name = "normal", .kind = OBS_OUTPUT_VECTOR, .description = "World-space surface normal"},
    {.name = "alpha", .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where a surface is hit, 0 on the background)"},
    {.name = NULL}};

#define P(member) offsetof(obs_ibl_shadows_params, member)
static const obs_param ibl_params[] = {
    {.name = "shadow_maps", .type = OBS_PARAM_INT, .min = 1, .max = OBS_IBL_MAX_MAPS, .def = 32,
     .description = "importance-sampled directions, one orthographic shadow map each (the "
                    "article's 16 or 32)",
     .offset = P(shadow_maps)},
    {.name = "sh_order", .type = OBS_PARAM_INT, .min = 1, .max = OBS_SH_MAX_BANDS, .def = 4,
     .description = "spherical-harmonic bands of the fit (order^2 coefficients; the article's 4)",
     .offset = P(sh_order)},
    {.name = "map_size", .type = OBS_PARAM_INT, .min = 8, .max = 1024, .def = 256,
     .description = "shadow-map side in texels, over the scene's bounding sphere",
     .offset = P(map_size)},
    {.name = "tikhonov", .type = OBS_PARAM_FLOAT, .min = 0, .max = 100, .def = 0.2,
     .description = "alpha of the regularised pseudo-inverse, sigma / (sigma^2 + alpha^2) "
                    "(Equation 4.3.7)",
     .offset = P(tikhonov)},
    {.name = "bias", .type = OBS_PARAM_FLOAT, .min = 0, .max = 100, .def = 1.5,
     .description = "shadow-map depth bias in texels, times 1 + tan of the receiver's angle to "
                    "the direction (at most 10)",
     .offset = P(bias)},
    {.name = "blur", .type = OBS_PARAM_BOOL, .def = 1,
     .description = "the article's 9 x 9 normal-weighted Gaussian blur of the coefficients, in "
                    "screen space",
     .offset = P(blur)},
    {.name = "exposure", .type = OBS_PARAM_DOUBLE, .min = -30, .max = 30, .def = 0,
     .description = "exposure in EV applied to final.png only (radiance is unscaled)",
     .offset = P(exposure)},
};
#undef P

/* Shadow-map rays plus per-pixel shadow tests and the fit. */
static double ibl_cost(const void *bound) {
  const obs_ibl_shadows_params *p = bound;
  return (double)p->shadow_maps * (1.0 + (double)(p->sh_order * p->sh_order) / 4.0);
}

/* The reference is path_trace with one bounce: direct environment light with visibility,
 * albedo / pi int L V cos, exactly what the fit approximates; its environment sampling is
 * obs_env_dist too. */
static const char *const ibl_reference_keys[] = {"exposure", NULL};
static int ibl_reference(const obs_scene *scene, const json_t *params, obs_reference_facts *facts,
                         obs_reference_def *def, obs_err *err) {
  (void)scene, (void)facts, (void)err;
  obs_reference_def_same(def, &obs_technique_path_trace, params, ibl_reference_keys);
  json_object_set_new(def->params, "max_bounces", json_integer(1));
  return 0;
}

/* Lengths are relative to the scene's bounding sphere (maps) and texels (bias), so the result
 * is scale-free up to float rounding of the G-buffer's positions against the shadow maps' depths;
 * a texel edge can move a shadow test, hence a bound on a share of pixels. */
#define IBL_RANGE                                                                       \
  {                                                                                     \
    .size_min = 1e-6, .size_max = 1e6, .translation_max = 1e6, .fov_min = 1e-2,         \
    .fov_max = 170, .orthographic = 1, .params = {{NULL, 0, 0, 0}},                     \
    .tol = {.ao_mean = 2e-3, .ao_pixel = 2e-2, .share = 0.03, .normal = 1e-4,           \
            .depth_rel = 3e-5}                                                          \
  }

const obs_technique obs_technique_ibl_shadows = {
    .name = "ibl_shadows",
    .description = "Dynamic shadows for image-based lighting (Colbert and Krivanek, ShaderX7 "
                   "4.3): importance-sampled shadow maps, a per-pixel least-squares SH fit of "
                   "visibility x cosine, a normal-weighted blur and SH diffuse shading",
    .params = ibl_params,
    .params_size = sizeof ibl_params / sizeof ibl_params[0],
    .bound_size = sizeof(obs_ibl_shadows_params),
    .cost = ibl_cost,
    .cost_rule = "shadow_maps x (1 + sh_order^2 / 4)",
    .ms_per_work = 2e-5,
    .needs = OBS_NEED_GBUFFER | OBS_NEED_BVH | OBS_NEED_BVH_FRAME_GEOMETRY | OBS_NEED_ENV_MAP |
             OBS_NEED_MATERIALS,
    .outputs = ibl_outputs,
    .reference = ibl_reference,
    .run = {[OBS_BACKEND_CPU] = obs_ibl_shadows_cpu, [OBS_BACKEND_VULKAN] = obs_ibl_shadows_vulkan},
    .range = {[OBS_BACKEND_CPU] = IBL_RANGE, [OBS_BACKEND_VULKAN] = IBL_RANGE},
};
