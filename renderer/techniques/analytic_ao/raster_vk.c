/* analytic_ao's rasterised proxies on Vulkan (the article's own method, Shopf et al., ShaderX7
 * 6.3): one instance of 36 vertices per occluder, its bounding cube's faces that face away from
 * the camera (analytic_ao_raster.vert.glsl; a full-screen triangle when unbounded), rasterised
 * over the device G-buffer with no depth test. The fragment shader evaluates that occluder's
 * closed form at the pixel's G-buffer point (analytic_ao_raster.frag.glsl) and writes 1 - occ;
 * multiplicative blending (source factor DST_COLOR, destination ZERO) folds it into an R32F target
 * cleared to 1. Blending follows primitive order, instances in order, so each pixel multiplies
 * its factors in the order the compute pass (vulkan.c) and the CPU (cpu.c) do. */
#include <stdlib.h>
#include <string.h>

#include "analytic_ao.h"
#include "layout.h"
#include "obscura/render.h"
#include "shaders.h"
#include "vk_internal.h"

static const VkShaderStageFlags PUSH_STAGES =
    VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;

/* The pipeline and its bindings (the G-buffer's depth and normal, the occluders), blending into
 * `target`. */
static int open_blender(obs_vk *vk, obs_vk_gbuffer *g, const obs_vk_buffer *occ,
                        obs_vk_image *target, obs_vk_blender *b, obs_err *err) {
  VkShaderModule m[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};
  int rc = obs_vk_shader(vk, obs_spv_analytic_ao_raster_vert, obs_spv_analytic_ao_raster_vert_size,
                         &m[0], "analytic_ao raster", err);
  if (!rc)
    rc = obs_vk_shader(vk, obs_spv_analytic_ao_raster_frag, obs_spv_analytic_ao_raster_frag_size,
                       &m[1], "analytic_ao raster", err);
  const VkDescriptorSetLayoutBinding bind[OBS_AAO_RB_BINDINGS] = {
      {OBS_AAO_RB_DEPTH, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
      {OBS_AAO_RB_NORMAL, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
      {OBS_AAO_RB_OCC, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, PUSH_STAGES, NULL}};
  VkDescriptorImageInfo ii[2] = {{VK_NULL_HANDLE, g->depth->view, VK_IMAGE_LAYOUT_GENERAL},
                                 {VK_NULL_HANDLE, g->normal->view, VK_IMAGE_LAYOUT_GENERAL}};
  VkDescriptorBufferInfo bi = {occ->buffer, 0, VK_WHOLE_SIZE};
  const VkWriteDescriptorSet w[OBS_AAO_RB_BINDINGS] = {
      {.pImageInfo = &ii[0]}, {.pImageInfo = &ii[1]}, {.pBufferInfo = &bi}};
  /* dst = src * dst + dst * 0: the product, rounded once as the compute pass rounds it. The
   * vertex shader keeps only the faces that face away, whatever their winding on screen. */
  obs_vk_blender_def d = {
      .bindings = bind, .nbindings = OBS_AAO_RB_BINDINGS, .writes = w,
      .push_stages = PUSH_STAGES, .push_size = sizeof(obs_aao_raster_push),
      .format = VK_FORMAT_R32_SFLOAT, .target = target, .width = g->width, .height = g->height,
      .pipeline = {.vs = m[0], .fs = m[1], .topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                   .src = VK_BLEND_FACTOR_DST_COLOR, .dst = VK_BLEND_FACTOR_ZERO,
                   .op = VK_BLEND_OP_ADD, .write = VK_COLOR_COMPONENT_R_BIT,
                   .what = "analytic_ao raster"}};
  if (!rc) rc = obs_vk_blender_open(vk, &d, b, err);
  for (int i = 0; i < 2; i++)
    if (m[i]) vkDestroyShaderModule(vk->dev, m[i], NULL);
  return rc;
}

int obs_analytic_ao_vk_raster(obs_vk *vk, obs_vk_gbuffer *g, const obs_gbuffer *host,
                              const obs_aao_occluder *occ, size_t nocc, float *ao_host,
                              double *ms, obs_err *err) {
  if (!vk || !g || !g->depth || !g->normal || !host || !ao_host || g->width < 1 ||
      g->height < 1 || (nocc && !occ))
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: missing device, G-buffer or output");
  if (nocc > UINT32_MAX / OBS_AAO_VEC4S)
    return obs_err_set(err, OBS_EINVAL, "analytic_ao: %zu occluders (at most %u)", nocc,
                       UINT32_MAX / OBS_AAO_VEC4S);
  if (!obs_vk_blendable(vk, VK_FORMAT_R32_SFLOAT))
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "analytic_ao: method \"raster\": the Vulkan device %s cannot blend 32-bit "
                       "float targets (use method \"compute\")",
                       vk->name);
  obs_aao_raster_push pc = {.width = g->width, .height = g->height, .ortho = host->ortho,
                            .half_w = host->half_w, .half_h = host->half_h};
  obs_vk_buffer buf = {0};
  obs_vk_image *target = NULL;
  obs_vk_blender b = {0};
  /* The shaders always bind the buffer; without occluders it holds one unread entry. */
  size_t bytes = (nocc ? nocc : 1) * sizeof *occ;
  int rc = obs_vk_buffer_create(vk, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 1, &buf,
                                "analytic_ao occluders", err);
  if (!rc) nocc ? memcpy(buf.map, occ, bytes) : memset(buf.map, 0, bytes);
  if (!rc)
    rc = obs_vk_image_create_usage(vk, g->width, g->height, 1, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                                   &target, err);
  if (!rc) rc = open_blender(vk, g, &buf, target, &b, err);
  static const float ones[4] = {1, 1, 1, 1};
  double t0 = obs_now_ms();
  if (!rc)
    rc = obs_vk_blender_draw(&b, &pc, sizeof pc, ones, VK_NULL_HANDLE, 36, (uint32_t)nocc, err);
  if (ms) *ms = obs_now_ms() - t0;
  if (!rc) rc = obs_vk_image_download(vk, target, ao_host, err);
  obs_vk_blender_free(&b);
  obs_vk_image_free(vk, target);
  obs_vk_buffer_free(vk, &buf);
  return rc;
}
