/* The Vulkan backend's device layer: a headless device (lavapipe in tests), the rasterised
 * G-buffer, and generic compute passes over 2D float images, which may also read sampled
 * textures and a parameter buffer. Techniques build on these only.
 *
 * Ownership: obs_vk owns every pipeline and pool it creates; images, textures, data buffers and
 * G-buffers are owned by the caller and freed with their _free functions before obs_vk_close.
 * All calls on one obs_vk must come from one thread at a time. */
#ifndef OBS_VK_H
#define OBS_VK_H

#include <stddef.h>
#include <stdint.h>

#include "gbuffer.h"
#include "geometry.h"
#include "obscura/error.h"
#include "obscura/scene.h"

typedef struct obs_vk obs_vk;
typedef struct obs_vk_image obs_vk_image;

/* Opens a device: the first whose name contains `filter` (NULL: $OBSCURA_VK_DEVICE, else the first
 * device). With `validation` nonzero the Khronos validation layer is enabled and every message it
 * emits is counted (and printed to stderr). Returns OBS_EUNSUPPORTED with a clear message when no
 * Vulkan device exists. */
int obs_vk_open(obs_vk **out, const char *filter, int validation, obs_err *err);
void obs_vk_close(obs_vk *vk);
/* The process's shared render device (the default device, with or without validation): opened on
 * first use and kept, because opening an instance and device and compiling the pipelines costs
 * lavapipe tens of milliseconds, more than a small render. The caller has it exclusively until
 * obs_vk_release (renders on Vulkan are serialised per process); the validation message count
 * restarts at 0 for each acquisition. A lost device is closed at release and reopened next time.
 * Shared devices are closed at exit. */
int obs_vk_acquire(obs_vk **out, int validation, obs_err *err);
void obs_vk_release(obs_vk *vk);
const char *obs_vk_device_name(const obs_vk *vk);
/* The device's kind from its VkPhysicalDeviceType (backend.h, device_kind): "software" for
 * VK_PHYSICAL_DEVICE_TYPE_CPU, "gpu" for the GPU types, else "other". */
const char *obs_vk_device_kind(const obs_vk *vk);
/* The most loop iterations one shader invocation may run, all its loops together, before the
 * device silently ends them; 0 where no such limit is known. Mesa's llvmpipe (lavapipe) has one:
 * gallivm counts every iteration of every loop the compiler left in an invocation and, past 65535,
 * leaves each loop after one pass (LP_MAX_TGSI_LOOP_ITERATIONS, a guard against hung shaders).
 * Loops with a constant trip count are unrolled and do not count. Passes whose work per invocation
 * is data-dependent split it across dispatches under this limit. */
uint32_t obs_vk_loop_limit(const obs_vk *vk);
/* Number of validation-layer messages (warnings and errors) seen so far. */
uint32_t obs_vk_validation_messages(const obs_vk *vk);
/* With `validation` on, fails work the layer complained about (its result is not trusted,
 * whatever it holds): OBS_EINTERNAL naming "<who>: <what> on <device>"; otherwise 0. */
int obs_vk_validation_verdict(const obs_vk *vk, int validation, const char *who, const char *what,
                              obs_err *err);
/* Whether a Vulkan device can be opened here (probed once per process, cached). */
int obs_vk_available(void);
/* The name of the device obs_vk_available found (what renders will use), or NULL when none. */
const char *obs_vk_available_device_name(void);
/* Whether tests and renders should enable validation: $OBSCURA_VK_VALIDATION=1. */
int obs_vk_validation_requested(void);

/* A w x h storage image of 1 (R32_SFLOAT) or 4 (R32G32B32A32_SFLOAT) float channels, resident on
 * the device, in GENERAL layout between calls. Host data is row-major, row 0 at the top, channels
 * interleaved. */
int obs_vk_image_create(obs_vk *vk, int width, int height, int channels, obs_vk_image **out,
                        obs_err *err);
/* The same as a 3D storage image of `depth` slices (sides up to maxImageDimension3D), for passes
 * over voxel grids: bound like the 2D ones, declared `image3D` in the shader. Host data is x
 * fastest, then y, then z; transfers go through the staging buffer in slabs of whole slices. */
int obs_vk_image_create_3d(obs_vk *vk, int width, int height, int depth, int channels,
                           obs_vk_image **out, obs_err *err);
int obs_vk_image_upload(obs_vk *vk, obs_vk_image *img, const float *data, obs_err *err);
int obs_vk_image_download(obs_vk *vk, const obs_vk_image *img, float *data, obs_err *err);
void obs_vk_image_free(obs_vk *vk, obs_vk_image *img);

/* The G-buffer on the device: depth (1 channel: linear view depth, 0 = uncovered),
 * normal (4 channels: view-space face normal xyz, coverage in w), albedo (4 channels: rgb, and
 * in w the index of the scene object seen + 1 as a float, 0 = uncovered; uploaded host buffers
 * carry no object and have 0 there). */
typedef struct obs_vk_gbuffer {
  obs_vk_image *depth, *normal, *albedo;
  int width, height;
} obs_vk_gbuffer;

/* Rasterises `geo` (world space, from obs_geometry_build) seen by the scene's camera into a
 * G-buffer with the same definitions as obs_gbuffer (renderer/core/gbuffer.h): linear view depth,
 * face normals from position derivatives, albedo, coverage at pixel centres. Analytic spheres are
 * tessellated finely enough that their facets deviate by < 0.25 pixel at this image size.
 * `ms` (may be NULL) receives the device time of the pass. */
int obs_vk_gbuffer_render(obs_vk *vk, const obs_scene *scene, const obs_geometry *geo,
                          obs_vk_gbuffer *out, double *ms, obs_err *err);
/* The same seen by `rig` (its width x height) instead of the scene's camera: a light's view. */
int obs_vk_gbuffer_render_rig(obs_vk *vk, const obs_scene *scene, const obs_geometry *geo,
                              const obs_camera_rig *rig, obs_vk_gbuffer *out, double *ms,
                              obs_err *err);
/* Uploads a host G-buffer (so both backends can run on identical inputs), and downloads one
 * into `host`, which must come from obs_gbuffer_alloc with the same size; `albedo` zero leaves
 * host->albedo untouched (saves a third of the readback for techniques that do not use it). */
int obs_vk_gbuffer_upload(obs_vk *vk, const obs_gbuffer *host, obs_vk_gbuffer *out, obs_err *err);
int obs_vk_gbuffer_download(obs_vk *vk, const obs_vk_gbuffer *dev, obs_gbuffer *host, int albedo,
                            obs_err *err);
void obs_vk_gbuffer_free(obs_vk *vk, obs_vk_gbuffer *g);

/* A read-only float texture that compute passes sample through its own sampler (clamp to edge,
 * normalised coordinates, no mipmaps, linear or nearest filtering): a 3D image (volumes, grids)
 * or a 2D array image (e.g. the six faces of a cube map as layers), 1 (R32_SFLOAT) or 4
 * (R32G32B32A32_SFLOAT) channels, zeroed at creation, in SHADER_READ_ONLY_OPTIMAL layout between
 * calls. Large data travels as read-only images rather than storage buffers, whose range is
 * limited (128 MiB on lavapipe). */
typedef struct obs_vk_texture obs_vk_texture;
typedef enum { OBS_VK_TEXTURE_3D, OBS_VK_TEXTURE_2D_ARRAY } obs_vk_texture_type;
typedef struct obs_vk_texture_desc {
  obs_vk_texture_type type;
  int width, height, depth; /* depth: the 3D image's depth, or the array's layers */
  int channels;             /* 1 or 4 */
  int linear;               /* linear filtering; needs obs_vk_texture_filterable */
} obs_vk_texture_desc;
/* Whether float textures of `channels` can be filtered linearly on this device. */
int obs_vk_texture_filterable(obs_vk *vk, int channels);
/* The largest side (width, height, depth or layers) a texture of `type` may have here. */
int obs_vk_texture_max_side(const obs_vk *vk, obs_vk_texture_type type);
/* OBS_EINVAL for a bad description (sizes past the device's limits, linear filtering it lacks),
 * OBS_ENOMEM past what one image may hold, both before anything is allocated. */
int obs_vk_texture_create(obs_vk *vk, const obs_vk_texture_desc *d, obs_vk_texture **out,
                          obs_err *err);
/* Writes the box of size[0] x size[1] x size[2] texels at at[] (x, y, and z or the first layer)
 * from `data`: tightly packed, x fastest, then y, then z or layer, channels interleaved. Goes
 * through the staging buffer in slabs of whole slices (at most ~64 MiB each). */
int obs_vk_texture_upload(obs_vk *vk, obs_vk_texture *t, const int at[3], const int size[3],
                          const float *data, obs_err *err);
/* Copies a 2D storage image of the same size and channels into `layer` of a 2D array texture:
 * what a pass wrote becomes a texture without a trip through the host. */
int obs_vk_texture_copy_image(obs_vk *vk, obs_vk_texture *t, int layer, const obs_vk_image *img,
                              obs_err *err);
void obs_vk_texture_free(obs_vk *vk, obs_vk_texture *t);

/* Orthographic depth maps of a geometry (shadow maps), rasterised by depth-only render passes,
 * one a layer of a 1-channel 2D array texture of size x size x n that compute passes then read
 * like any texture (texelFetch; .r is the depth). With p a world position minus `centre`, map i
 * puts p at x_ndc = rows[i][0] . (p, 1) and y_ndc = rows[i][1] . (p, 1) (texel (x, y) covers
 * x_ndc in [2x / size - 1, 2(x + 1) / size - 1], sampled at its centre, y likewise) and at depth
 * rows[i][2] . (p, 1); the nearest depth in [0, 1] is kept, and texels with nothing there read 1.
 * Both faces of every triangle are drawn; spheres as UV spheres whose facets stay within a
 * quarter of `texel` (world units per texel) of the surface. `ms` (may be NULL): device time. */
int obs_vk_depth_maps(obs_vk *vk, const obs_geometry *geo, const double centre[3],
                      const double (*rows)[3][4], int n, int size, double texel,
                      obs_vk_texture **out, double *ms, obs_err *err);

/* A small read-only storage buffer (a pass's parameters: per-object transforms, lights, tables),
 * copied to device memory at creation. At most the device's maxStorageBufferRange. */
typedef struct obs_vk_data obs_vk_data;
int obs_vk_data_create(obs_vk *vk, const void *bytes, size_t size, obs_vk_data **out,
                       obs_err *err);
void obs_vk_data_free(obs_vk *vk, obs_vk_data *d);

/* One compute dispatch. The shader (SPIR-V, entry "main", local size chosen by the shader) sees
 * images[i] as `layout(binding = i, r32f or rgba32f) uniform image2D` (set 0) and the push
 * constants (at most 128 bytes). A pass with textures or data also has set 1: textures[i] at
 * `layout(set = 1, binding = i) uniform sampler3D or sampler2DArray` and the data at
 * `layout(set = 1, binding = OBS_VK_MAX_TEXTURES, std430) readonly buffer`; passes without them
 * have set 0 alone. */
#define OBS_VK_MAX_BINDINGS 8
#define OBS_VK_MAX_TEXTURES 4
#define OBS_VK_PUSH_MAX 128u /* bytes of push constants a pass may use */
typedef struct obs_vk_pass {
  const char *name;           /* for timings and messages */
  const uint32_t *spirv;      /* embedded SPIR-V (see shaders.h); pipelines are cached per pointer */
  size_t spirv_size;          /* bytes */
  obs_vk_image *images[OBS_VK_MAX_BINDINGS];
  int nimages;
  const void *push;
  uint32_t push_size;
  uint32_t groups_x, groups_y;
  uint32_t groups_z; /* 0 or 1: one layer of work groups */
  obs_vk_texture *textures[OBS_VK_MAX_TEXTURES]; /* set 1 (optional) */
  int ntextures;
  obs_vk_data *data; /* set 1, binding OBS_VK_MAX_TEXTURES (optional) */
} obs_vk_pass;

/* Records the passes in order into one command buffer with full memory barriers between them,
 * submits, and waits. ms_per_pass (may be NULL; npasses entries) receives each pass's device time
 * from timestamp queries. */
int obs_vk_run(obs_vk *vk, const obs_vk_pass *passes, int npasses, double *ms_per_pass,
               obs_err *err);

#endif
