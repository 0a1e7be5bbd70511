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

typedef struct aao_raster {
  obs_vk *vk;
  VkDescriptorSetLayout dsl;
  VkPipelineLayout layout;
  VkRenderPass pass;
  VkPipeline pipe;
  VkDescriptorPool dpool;
  VkDescriptorSet set;
  VkFramebuffer fb;
  obs_vk_buffer occ;
  obs_vk_image *target;
} aao_raster;

static const VkShaderStageFlags PUSH_STAGES =
    VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;

/* The set layout (depth, normal, occluders), the pipeline layout and the render pass, whose
 * target is a storage image in GENERAL layout that the pass clears to 1 and blends into. */
static int create_layouts(aao_raster *r, obs_err *err) {
  obs_vk *vk = r->vk;
  VkDescriptorSetLayoutBinding b[OBS_AAO_RB_BINDINGS] = {
      {OBS_AAO_RB_DEPTH, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
      {OBS_AAO_RB_NORMAL, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
      {OBS_AAO_RB_OCC, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, PUSH_STAGES, NULL}};
  VkDescriptorSetLayoutCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
                                         .bindingCount = OBS_AAO_RB_BINDINGS,
                                         .pBindings = b};
  int rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &dci, NULL, &r->dsl),
                        "vkCreateDescriptorSetLayout (analytic_ao raster)", err);
  if (rc) return rc;
  VkPushConstantRange pr = {PUSH_STAGES, 0, sizeof(obs_aao_raster_push)};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 1,
                                     .pSetLayouts = &r->dsl,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  if ((rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &r->layout),
                         "vkCreatePipelineLayout (analytic_ao raster)", err)))
    return rc;
  return obs_vk_blend_pass(vk, VK_FORMAT_R32_SFLOAT, &r->pass, "analytic_ao raster", err);
}

static int create_pipeline(aao_raster *r, obs_err *err) {
  obs_vk *vk = r->vk;
  VkShaderModule m[2] = {VK_NULL_HANDLE, VK_NULL_HANDLE};
  int rc = obs_vk_shader(vk, obs_spv_analytic_ao_raster_vert, obs_spv_analytic_ao_raster_vert_size,
                         &m[0], "analytic_ao raster", err);
  if (!rc)
    rc = obs_vk_shader(vk, obs_spv_analytic_ao_raster_frag, obs_spv_analytic_ao_raster_frag_size,
                       &m[1], "analytic_ao raster", err);
  /* dst = src * dst + dst * 0: the product, rounded once as the compute pass rounds it. The
   * vertex shader keeps only the faces that face away, whatever their winding on screen. */
  obs_vk_blend bl = {.vs = m[0], .fs = m[1], .topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                     .src = VK_BLEND_FACTOR_DST_COLOR, .dst = VK_BLEND_FACTOR_ZERO,
                     .op = VK_BLEND_OP_ADD, .write = VK_COLOR_COMPONENT_R_BIT,
                     .layout = r->layout, .pass = r->pass, .what = "analytic_ao raster"};
  if (!rc) rc = obs_vk_blend_pipeline(vk, &bl, &r->pipe, err);
  for (int i = 0; i < 2; i++)
    if (m[i]) vkDestroyShaderModule(vk->dev, m[i], NULL);
  return rc;
}

/* The descriptor set (the G-buffer's depth and normal, the occluders) and the target's
 * framebuffer. */
static int create_bindings(aao_raster *r, obs_vk_gbuffer *g, obs_err *err) {
  obs_vk *vk = r->vk;
  VkDescriptorPoolSize size[2] = {{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 2},
                                  {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1}};
  VkDescriptorPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = 1,
                                    .poolSizeCount = 2,
                                    .pPoolSizes = size};
  int rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &pci, NULL, &r->dpool),
                        "vkCreateDescriptorPool (analytic_ao raster)", err);
  if (rc) return rc;
  VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                    .descriptorPool = r->dpool,
                                    .descriptorSetCount = 1,
                                    .pSetLayouts = &r->dsl};
  if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, &r->set),
                         "vkAllocateDescriptorSets (analytic_ao raster)", err)))
    return rc;
  VkDescriptorImageInfo ii[2] = {{VK_NULL_HANDLE, g->depth->view, VK_IMAGE_LAYOUT_GENERAL},
                                 {VK_NULL_HANDLE, g->normal->view, VK_IMAGE_LAYOUT_GENERAL}};
  VkDescriptorBufferInfo bi = {r->occ.buffer, 0, VK_WHOLE_SIZE};
  VkWriteDescriptorSet w[OBS_AAO_RB_BINDINGS];
  for (uint32_t i = 0; i < OBS_AAO_RB_BINDINGS; i++)
    w[i] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                  .dstSet = r->set,
                                  .dstBinding = i,
                                  .descriptorCount = 1,
                                  .descriptorType = i == OBS_AAO_RB_OCC
                                                        ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER
                                                        : VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                  .pImageInfo = i == OBS_AAO_RB_OCC ? NULL : &ii[i],
                                  .pBufferInfo = i == OBS_AAO_RB_OCC ? &bi : NULL};
  vkUpdateDescriptorSets(vk->dev, OBS_AAO_RB_BINDINGS, w, 0, NULL);
  VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = r->pass,
                                 .attachmentCount = 1,
                                 .pAttachments = &r->target->view,
                                 .width = (uint32_t)g->width,
                                 .height = (uint32_t)g->height,
                                 .layers = 1};
  return obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, &r->fb),
                      "vkCreateFramebuffer (analytic_ao raster)", err);
}

static void aao_raster_free(aao_raster *r) {
  obs_vk *vk = r->vk;
  if (r->fb) vkDestroyFramebuffer(vk->dev, r->fb, NULL);
  obs_vk_image_free(vk, r->target);
  obs_vk_buffer_free(vk, &r->occ);
  if (r->dpool) vkDestroyDescriptorPool(vk->dev, r->dpool, NULL);
  if (r->pipe) vkDestroyPipeline(vk->dev, r->pipe, NULL);
  if (r->pass) vkDestroyRenderPass(vk->dev, r->pass, NULL);
  if (r->layout) vkDestroyPipelineLayout(vk->dev, r->layout, NULL);
  if (r->dsl) vkDestroyDescriptorSetLayout(vk->dev, r->dsl, NULL);
  memset(r, 0, sizeof *r);
}

/* The pass: clear to 1, draw every occluder's proxy, submit and wait. */
static int record(aao_raster *r, size_t nocc, const obs_aao_raster_push *pc, obs_err *err) {
  obs_vk *vk = r->vk;
  int rc = obs_vk_cmd_begin(vk, "analytic_ao raster", err);
  if (rc) return rc;
  VkCommandBuffer cmd = vk->cmd;
  const uint32_t w = (uint32_t)pc->width, h = (uint32_t)pc->height;
  VkClearValue clear = {.color = {{1.0f, 1.0f, 1.0f, 1.0f}}};
  VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                               .renderPass = r->pass,
                               .framebuffer = r->fb,
                               .renderArea = {{0, 0}, {w, h}},
                               .clearValueCount = 1,
                               .pClearValues = &clear};
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipe);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->layout, 0, 1, &r->set, 0, NULL);
  vkCmdPushConstants(cmd, r->layout, PUSH_STAGES, 0, sizeof *pc, pc);
  VkViewport vp = {0, 0, (float)w, (float)h, 0, 1};
  VkRect2D sc = {{0, 0}, {w, h}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &sc);
  if (nocc) vkCmdDraw(cmd, 36, (uint32_t)nocc, 0, 0);
  vkCmdEndRenderPass(cmd);
  obs_vk_cmd_barrier(cmd);
  return obs_vk_cmd_submit(vk, "analytic_ao raster", err);
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
  aao_raster r = {.vk = vk};
  obs_aao_raster_push pc = {.width = g->width, .height = g->height, .ortho = host->ortho,
                            .half_w = host->half_w, .half_h = host->half_h};
  /* The shaders always bind the buffer; without occluders it holds one unread entry. */
  size_t bytes = (nocc ? nocc : 1) * sizeof *occ;
  int rc = obs_vk_buffer_create(vk, bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, 1, &r.occ,
                                "analytic_ao occluders", err);
  if (!rc) nocc ? memcpy(r.occ.map, occ, bytes) : memset(r.occ.map, 0, bytes);
  if (!rc)
    rc = obs_vk_image_create_usage(vk, g->width, g->height, 1, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                                   &r.target, err);
  if (!rc) rc = create_layouts(&r, err);
  if (!rc) rc = create_pipeline(&r, err);
  if (!rc) rc = create_bindings(&r, g, err);
  double t0 = obs_now_ms();
  if (!rc) rc = record(&r, nocc, &pc, err);
  if (ms) *ms = obs_now_ms() - t0;
  if (!rc) rc = obs_vk_image_download(vk, r.target, ao_host, err);
  aao_raster_free(&r);
  return rc;
}
