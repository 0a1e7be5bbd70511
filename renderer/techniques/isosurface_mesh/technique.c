/* Descriptor of isosurface_mesh (ShaderX7 1.1, hybrid marching cubes / marching tetrahedra): each
 * volume's isosurface extracted into a triangle mesh (renderer/core/isosurface.h) and ray cast,
 * measured against the exact isosurface that volume_ao bisects. */
#include <jansson.h>
#include <stddef.h>

#include "isosurface.h"
#include "isosurface_mesh.h"
#include "techniques.h"

static const obs_output isosurface_mesh_outputs[] = {
    {.name = "depth",
     .kind = OBS_OUTPUT_DEPTH,
     .show = OBS_SHOW_DEPTH,
     .png = "depth.png",
     .description = "View depth of the extracted mesh's first hit (grey levels); compared with "
                    "the exact isosurface's",
     .flags = OBS_OUTPUT_PRIMARY},
    {.name = "normal",
     .kind = OBS_OUTPUT_VECTOR,
     .show = OBS_SHOW_NORMAL,
     .png = "normal.png",
     .description = "World-space face normal of the mesh, toward the viewer (X, Y, Z \u2192 red, "
                    "green, blue); compared with the field's gradient by the mean angle"},
    {.name = "alpha",
     .kind = OBS_OUTPUT_SCALAR,
     .description = "Coverage (1 where the mesh is hit, 0 on the background)",
     .flags = OBS_OUTPUT_UNIT},
    {.name = NULL}};

const char *const obs_isosurface_mesh_channels[ISO_CH_COUNT] = {"normal.X", "normal.Y", "normal.Z",
                                                                "depth.Z", "alpha"};

#define P(member) offsetof(obs_isosurface_mesh_params, member)
static const obs_param isosurface_mesh_params[] = {
    {.name = "grid",
     .type = OBS_PARAM_INT,
     .min = 4,
     .max = 256,
     .def = 64,
     .description = "extraction cells along each volume's longest side (the article's grid: 32 "
                    "or 64); the other sides get as many as keep the cells nearest to cubes",
     .offset = P(grid)},
    {.name = "refine",
     .type = OBS_PARAM_INT,
     .min = 0,
     .max = OBS_ISO_REFINE_MAX,
     .def = 0,
     .description = "longest-edge bisection levels of each cell's six tetrahedra: 1 bisects "
                    "their shared diagonal at a sample of the cell's centre (the article's "
                    "twelve tetrahedra), 2 and 3 go on bisecting every tetrahedron at its "
                    "longest edge (face centres, then edge midpoints), in every cell whose "
                    "samples differ in sign, so the surface stays closed; finds surface the "
                    "corners miss. Vulkan extracts levels 0 and 1; 0 off",
     .offset = P(refine)},
};
#undef P

/* Extraction grows with the lattice, the ray cast with the pixels; per pixel sample, one ray. */
static double isosurface_mesh_cost(const void *bound) {
  (void)bound;
  return 1.0;
}

/* The exact isosurface: volume_ao's ray cast bisects the trilinear field's crossing to a
 * thousandth of a voxel, and its `normal` is the field's gradient there. Its AO and lighting are
 * not compared; ibl none keeps it cheap. */
static int isosurface_mesh_reference(const obs_scene *scene, const json_t *params,
                                     obs_reference_facts *facts, obs_reference_def *def,
                                     obs_err *err) {
  (void)scene, (void)params, (void)facts, (void)err;
  static const char *const none[] = {NULL};
  obs_reference_def_same(def, &obs_technique_volume_ao, params, none);
  json_object_set_new(def->params, "ibl", json_string("none"));
  return 0;
}

static const obs_output_pair isosurface_mesh_compared[] = {{"normal", "normal"}, {NULL, NULL}};

/* The guaranteed range (docs/accuracy.md): the mesh is extracted in each volume's data space and
 * carried to the camera's frame in double before it is rounded to float, so scale and place
 * cancel as they do for rt_ao's meshes, and each hit is refined on its triangle's plane in
 * double. What float's rounding of the vertices still moves is the rare pixel whose ray passes
 * within that rounding of a silhouette edge: it sees the surface behind, a relative depth change
 * of order 1. The mean tolerance allows about one such pixel in 500 (the extremes suite saw one
 * in 1024 at the smallest scale, orthographic); the rest are within 3e-7. */
#define ISO_RANGE(mean_, depth_rel_, fov_min_, normal_)                                    \
  {                                                                                        \
    .size_min = 1e-9, .size_max = 1e9, .translation_max = 1e6, .fov_min = fov_min_,        \
    .fov_max = 170, .orthographic = 1, .params = {{NULL, 0, 0, 0}},                        \
    .tol = {.ao_mean = mean_, .ao_pixel = 1e-4, .share = 0.02, .normal = normal_,          \
            .depth_rel = depth_rel_}                                                       \
  }

/* The device extractor's tables hold the six and the twelve tetrahedra of levels 0 and 1; deeper
 * bisection is the CPU's. */
static void isosurface_mesh_check(const obs_scene *scene, const json_t *params, const char *doc,
                                  obs_err *err) {
  json_int_t r = json_integer_value(json_object_get(params, "refine"));
  if (scene->backend == OBS_BACKEND_VULKAN && r > 1)
    obs_err_set(err, OBS_EINVAL,
                "%s: /technique/params/refine: %lld levels run on the cpu backend only (the "
                "vulkan extractor bisects at most 1 level)",
                doc, (long long)r);
}

const obs_technique obs_technique_isosurface_mesh = {
    .name = "isosurface_mesh",
    .description =
        "Isosurface extraction by hybrid marching cubes / marching tetrahedra "
        "(ShaderX7 1.1): each volume's isosurface as a triangle mesh, ray cast, "
        "against the exact isosurface",
    .params = isosurface_mesh_params,
    .params_size = sizeof isosurface_mesh_params / sizeof isosurface_mesh_params[0],
    .bound_size = sizeof(obs_isosurface_mesh_params),
    .cost = isosurface_mesh_cost,
    .cost_rule = "1 (one ray per pixel sample; the extraction grows with grid^2 surface cells)",
    .ms_per_work = 1e-4,
    .needs = OBS_NEED_VOLUME,
    /* The CPU ray casts the extracted meshes with Embree on its own scene. */
    .embree_backends = 1u << OBS_BACKEND_CPU,
    .outputs = isosurface_mesh_outputs,
    .reference = isosurface_mesh_reference,
    .compared_outputs = isosurface_mesh_compared,
    .check = isosurface_mesh_check,
    .run = {[OBS_BACKEND_CPU] = obs_isosurface_mesh_cpu,
            [OBS_BACKEND_VULKAN] = obs_isosurface_mesh_vulkan},
    .range = {[OBS_BACKEND_CPU] = ISO_RANGE(2.5e-3, 3e-5, 1e-3, 1e-4),
              /* The device rasterises the float mesh in the camera's frame, and the G-buffer
               * pass takes face normals from the derivatives of float camera-relative positions:
               * the mesh's small faces seen from the distance a narrow field of view needs lose
               * their normals to float's rounding (at 1e-2 degrees nothing of them is left; at
               * 1 degree, 3e-3 between scales in the extremes suite). The range stops at 1
               * degree with that normal tolerance. */
              [OBS_BACKEND_VULKAN] = ISO_RANGE(2.5e-3, 1e-4, 1, 5e-3)},
};
