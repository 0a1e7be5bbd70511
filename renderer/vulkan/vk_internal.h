/* Private to renderer/vulkan: the obs_vk, obs_vk_image, obs_vk_texture and obs_vk_data structs and
 * the device helpers shared by the device layer's files. Techniques use vk.h only. */
#ifndef OBS_VK_INTERNAL_H
#define OBS_VK_INTERNAL_H

#include <stdatomic.h>
#include <vulkan/vulkan.h>

#include "vk.h"

typedef struct obs_vk_pipe {
  const uint32_t *spirv;   /* cache key: the embedded array's address ... */
  VkPipelineLayout layout; /* ... and the layout it was made for (with or without set 1) */
  VkPipeline pipeline;
} obs_vk_pipe;

/* A buffer with its memory; `map` is non-NULL for host-visible buffers (mapped for life). */
typedef struct obs_vk_buffer {
  VkBuffer buffer;
  VkDeviceMemory memory;
  VkDeviceSize size;
  void *map;
} obs_vk_buffer;

struct obs_vk {
  VkInstance instance;
  VkDebugUtilsMessengerEXT messenger;
  PFN_vkDestroyDebugUtilsMessengerEXT destroy_messenger;
  VkPhysicalDevice phys;
  VkPhysicalDeviceProperties props;
  VkPhysicalDeviceMemoryProperties memprops;
  VkDeviceSize max_alloc; /* maxMemoryAllocationSize */
  VkDevice dev;
  VkQueue queue;
  uint32_t family;
  uint32_t ts_bits; /* timestampValidBits of the queue family; 0: no timestamps */
  VkCommandPool pool;
  VkCommandBuffer cmd;
  int recording;
  VkFence fence;
  VkQueryPool queries;
  uint32_t nqueries;
  obs_vk_buffer staging;
  VkDescriptorSetLayout set_layout; /* OBS_VK_MAX_BINDINGS storage images */
  VkPipelineLayout compute_layout;  /* that set + 128 bytes of push constants */
  /* Set 1 of the passes that read textures or data (texture.c), built on first use, one per
   * [number of textures][whether there is data] (a set must have exactly the bindings a pass
   * writes: lavapipe reads every binding of a bound set), and the pipeline layouts with both
   * sets. */
  VkDescriptorSetLayout tex_set_layout[OBS_VK_MAX_TEXTURES + 1][2];
  VkPipelineLayout tex_compute_layout[OBS_VK_MAX_TEXTURES + 1][2];
  obs_vk_pipe *pipes;
  int npipes, cappipes;
  /* The G-buffer rasteriser's objects (gbuffer_vk.c), built on first use. */
  VkRenderPass gb_pass;
  VkPipelineLayout gb_layout;
  VkPipeline gb_pipeline;
  int validation;
  int geometry_shader; /* the geometryShader feature is enabled */
  atomic_uint messages;
  int lost; /* VK_ERROR_DEVICE_LOST seen: every later call fails */
  char name[VK_MAX_PHYSICAL_DEVICE_NAME_SIZE];
};

struct obs_vk_image {
  VkImage image;
  VkDeviceMemory memory;
  VkImageView view;
  VkFormat format;
  int width, height, channels;
  int depth; /* slices of a 3D image; 1 for a 2D one */
  int is3d;
};

struct obs_vk_texture {
  VkImage image;
  VkDeviceMemory memory;
  VkImageView view;
  VkSampler sampler;
  VkFormat format;
  obs_vk_texture_desc desc;
};

struct obs_vk_data {
  obs_vk_buffer buf;
};

/* Turns a failed VkResult into an obs error naming `what` (0 on VK_SUCCESS): out-of-memory results
 * give OBS_ENOMEM, device loss marks the device lost, anything else OBS_EINTERNAL. */
int obs_vk_check(obs_vk *vk, VkResult r, const char *what, obs_err *err);
const char *obs_vk_result_name(VkResult r);
/* Fails with a message once the device was lost, so callers stop before recording anything. */
int obs_vk_usable(obs_vk *vk, const char *what, obs_err *err);

int obs_vk_buffer_create(obs_vk *vk, VkDeviceSize size, VkBufferUsageFlags usage, int host,
                         obs_vk_buffer *out, const char *what, obs_err *err);
void obs_vk_buffer_free(obs_vk *vk, obs_vk_buffer *b);
/* Memory for `req` with `want` properties, preferring `prefer` too. */
int obs_vk_memory_alloc(obs_vk *vk, const VkMemoryRequirements *req, VkMemoryPropertyFlags want,
                        VkMemoryPropertyFlags prefer, VkDeviceMemory *out, const char *what,
                        obs_err *err);

/* obs_vk_image_create with `extra` usage (e.g. a colour attachment, for a render pass that writes
 * a storage image in GENERAL layout). */
int obs_vk_image_create_usage(obs_vk *vk, int width, int height, int channels,
                              VkImageUsageFlags extra, obs_vk_image **out, obs_err *err);

/* Makes the host-visible staging buffer at least `size` bytes (memory.c). */
int obs_vk_staging_reserve(obs_vk *vk, VkDeviceSize size, obs_err *err);
/* Transfers of 3D data (images, textures) move through the staging buffer in slabs of whole
 * slices of at most this many bytes, so it stays modest even for a volume of gigabytes. */
#define OBS_VK_SLAB_BYTES ((VkDeviceSize)64 << 20)
/* Slices of `slice` bytes per slab, at least 1 and at most `depth` (memory.c). */
int obs_vk_slab_slices(VkDeviceSize slice, int depth);
/* Set 1's layout for `ntextures` textures with or without data, and the pipeline layout with
 * sets 0 and 1 (texture.c), created on first use. */
int obs_vk_tex_layout(obs_vk *vk, int ntextures, int data, VkDescriptorSetLayout *set,
                      VkPipelineLayout *out, obs_err *err);

/* The sampler of texture t (texture.c): clamp to edge, t->desc.linear or nearest filtering. */
int obs_vk_texture_sampler(obs_vk *vk, obs_vk_texture *t, obs_err *err);

/* A shader module from SPIR-V; errors name `what`. */
int obs_vk_shader(obs_vk *vk, const uint32_t *code, size_t size, VkShaderModule *out,
                  const char *what, obs_err *err);

/* A raster pipeline of the device layer: triangle lists from one vertex binding, both faces
 * drawn, depth test and write with `depth_op`, `ncolor` colour attachments written whole, one
 * sample, viewport and scissor dynamic. */
typedef struct obs_vk_raster {
  VkShaderModule vs, fs;
  uint32_t stride; /* bytes per vertex */
  const VkVertexInputAttributeDescription *attrs;
  uint32_t nattrs;
  VkCompareOp depth_op;
  uint32_t ncolor; /* at most 4 */
  VkPipelineLayout layout;
  VkRenderPass pass;
  const char *what; /* names the pipeline in errors */
} obs_vk_raster;
int obs_vk_raster_pipeline(obs_vk *vk, const obs_vk_raster *r, VkPipeline *out, obs_err *err);

/* The raster passes' UV spheres (gbuffer_vk.c): longitude segments for facets within a quarter
 * of a cell of the surface at `ppu` cells per world unit, steps of at most `max_step` radians;
 * the vertex count of such an n x n/2 sphere; its triangles (3 doubles a vertex, positions
 * shifted by `shift`) into `out`. OBS_ENOMEM from the fill. */
int obs_vk_sphere_segments(double radius, double ppu, double max_step);
size_t obs_vk_sphere_vertices(int n);
int obs_vk_sphere_fill(const obs_sphere *s, int n, const double shift[3], double *out);

/* A single-subpass render pass's two dependencies (raster.c): on everything before it and
 * everything after it, full memory access both ways (these passes sit between whole passes). */
void obs_vk_pass_deps(VkSubpassDependency dep[2]);
/* The render pass of a blending pass into a storage image: one subpass, one colour attachment
 * of `format` kept in GENERAL layout, cleared on load and stored, fully ordered against the work
 * before and after it; errors name `what`. */
int obs_vk_blend_pass(obs_vk *vk, VkFormat format, VkRenderPass *out, const char *what,
                      obs_err *err);
/* The same pass over one attachment of `format` (blend.c): with `depth`, a depth attachment
 * cleared and stored, undefined before and SHADER_READ_ONLY_OPTIMAL after (sampled next). */
int obs_vk_single_pass(obs_vk *vk, VkFormat format, int depth, VkRenderPass *out,
                       const char *what, obs_err *err);
/* A blending pipeline of the device layer over such a pass: vertex, optional geometry and
 * fragment shaders, no culling (the shaders emit only the faces they mean), no depth test, one
 * sample, one attachment blended with the same factors for colour and alpha, viewport and
 * scissor dynamic. */
typedef struct obs_vk_blend {
  VkShaderModule vs, gs, fs; /* gs: VK_NULL_HANDLE for none */
  const VkPipelineVertexInputStateCreateInfo *input; /* NULL: no vertex input */
  VkPrimitiveTopology topology;
  VkBlendFactor src, dst;
  VkBlendOp op;
  VkColorComponentFlags write;
  VkPipelineLayout layout;
  VkRenderPass pass;
  const char *what; /* names the pipeline in errors */
} obs_vk_blend;
int obs_vk_blend_pipeline(obs_vk *vk, const obs_vk_blend *b, VkPipeline *out, obs_err *err);
/* A blending pass (blend.c): the set layout, pipeline layout, render pass (obs_vk_blend_pass),
 * pipeline (obs_vk_blend_pipeline), descriptor set and framebuffer of a target image. */
#define OBS_VK_BLEND_BINDINGS 8
typedef struct obs_vk_blender_def {
  const VkDescriptorSetLayoutBinding *bindings; /* at most OBS_VK_BLEND_BINDINGS */
  uint32_t nbindings;
  /* One per binding, in the same order: its pImageInfo or pBufferInfo (the rest is filled in). */
  const VkWriteDescriptorSet *writes;
  VkShaderStageFlags push_stages;
  uint32_t push_size; /* 0: no push constants */
  VkFormat format;    /* the target's */
  obs_vk_image *target;
  int width, height;
  obs_vk_blend pipeline; /* its layout and pass are filled in */
} obs_vk_blender_def;
typedef struct obs_vk_blender {
  obs_vk *vk;
  const char *what;
  VkShaderStageFlags push_stages;
  int width, height;
  VkDescriptorSetLayout dsl;
  VkPipelineLayout layout;
  VkRenderPass pass;
  VkPipeline pipe;
  VkDescriptorPool dpool;
  VkDescriptorSet set;
  VkFramebuffer fb;
} obs_vk_blender;
/* Creates it all (freeing what it made on failure); the shader modules may go afterwards. */
int obs_vk_blender_open(obs_vk *vk, const obs_vk_blender_def *d, obs_vk_blender *b, obs_err *err);
/* One submission: clear the target to `clear`, draw nvertices x ninstances (from `vertices` at
 * binding 0, or VK_NULL_HANDLE for none) with the push constants, submit and wait. */
int obs_vk_blender_draw(obs_vk_blender *b, const void *push, uint32_t push_size,
                        const float clear[4], VkBuffer vertices, uint32_t nvertices,
                        uint32_t ninstances, obs_err *err);
void obs_vk_blender_free(obs_vk_blender *b);
/* Whether the device can render to and blend into `format` with optimal tiling. */
int obs_vk_blendable(obs_vk *vk, VkFormat format);

/* One-shot command recording into vk->cmd: begin (with a full barrier against earlier
 * submissions), then submit-and-wait. abort discards a recording after an error. */
int obs_vk_cmd_begin(obs_vk *vk, const char *what, obs_err *err);
int obs_vk_cmd_submit(obs_vk *vk, const char *what, obs_err *err);
void obs_vk_cmd_abort(obs_vk *vk);
void obs_vk_cmd_barrier(VkCommandBuffer cmd);
/* Layout transition of a whole single-level colour image (every array layer), with a full memory
 * dependency. */
void obs_vk_cmd_layout(VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to);
/* Ensures `n` timestamp queries exist (call before obs_vk_cmd_begin) and reads them afterwards as
 * milliseconds between consecutive pairs: ms[i] = t[2i+1] - t[2i]. */
int obs_vk_queries_reserve(obs_vk *vk, uint32_t n, obs_err *err);
int obs_vk_queries_ms(obs_vk *vk, uint32_t npairs, double *ms, obs_err *err);

#endif
