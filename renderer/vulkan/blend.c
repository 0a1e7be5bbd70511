/* The Vulkan device layer's blending passes (disc_ao's and analytic_ao's proxies): a graphics
 * pipeline that blends into a storage image kept in GENERAL layout, with its descriptor set, push
 * constants and framebuffer, set up, recorded and freed in one place. */
#include <stdio.h>
#include <string.h>

#include "vk_internal.h"

/* The set layout and the pipeline layout (one set, one push-constant range). */
static int create_layouts(obs_vk_blender *b, const obs_vk_blender_def *d, obs_err *err) {
  obs_vk *vk = b->vk;
  char what[96];
  VkDescriptorSetLayoutCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
                                         .bindingCount = d->nbindings,
                                         .pBindings = d->bindings};
  snprintf(what, sizeof what, "vkCreateDescriptorSetLayout (%s)", b->what);
  int rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &dci, NULL, &b->dsl), what, err);
  if (rc) return rc;
  VkPushConstantRange pr = {d->push_stages, 0, d->push_size};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 1,
                                     .pSetLayouts = &b->dsl,
                                     .pushConstantRangeCount = d->push_size ? 1 : 0,
                                     .pPushConstantRanges = &pr};
  snprintf(what, sizeof what, "vkCreatePipelineLayout (%s)", b->what);
  return obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &b->layout), what, err);
}

/* The descriptor set, written with d->writes, and the target's framebuffer. */
static int create_bindings(obs_vk_blender *b, const obs_vk_blender_def *d, obs_err *err) {
  obs_vk *vk = b->vk;
  char what[96];
  VkDescriptorPoolSize size[OBS_VK_BLEND_BINDINGS];
  uint32_t nsize = 0;
  for (uint32_t i = 0; i < d->nbindings; i++) {
    uint32_t k = 0;
    while (k < nsize && size[k].type != d->bindings[i].descriptorType) k++;
    if (k == nsize) size[nsize++] = (VkDescriptorPoolSize){d->bindings[i].descriptorType, 0};
    size[k].descriptorCount += d->bindings[i].descriptorCount;
  }
  VkDescriptorPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = 1,
                                    .poolSizeCount = nsize,
                                    .pPoolSizes = size};
  snprintf(what, sizeof what, "vkCreateDescriptorPool (%s)", b->what);
  int rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &pci, NULL, &b->dpool), what, err);
  if (rc) return rc;
  VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                    .descriptorPool = b->dpool,
                                    .descriptorSetCount = 1,
                                    .pSetLayouts = &b->dsl};
  snprintf(what, sizeof what, "vkAllocateDescriptorSets (%s)", b->what);
  if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, &b->set), what, err)))
    return rc;
  VkWriteDescriptorSet w[OBS_VK_BLEND_BINDINGS];
  for (uint32_t i = 0; i < d->nbindings; i++) {
    w[i] = d->writes[i];
    w[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    w[i].dstSet = b->set;
    w[i].dstBinding = d->bindings[i].binding;
    w[i].descriptorCount = d->bindings[i].descriptorCount;
    w[i].descriptorType = d->bindings[i].descriptorType;
  }
  vkUpdateDescriptorSets(vk->dev, d->nbindings, w, 0, NULL);
  VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = b->pass,
                                 .attachmentCount = 1,
                                 .pAttachments = &d->target->view,
                                 .width = (uint32_t)d->width,
                                 .height = (uint32_t)d->height,
                                 .layers = 1};
  snprintf(what, sizeof what, "vkCreateFramebuffer (%s)", b->what);
  return obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, &b->fb), what, err);
}

int obs_vk_blender_open(obs_vk *vk, const obs_vk_blender_def *d, obs_vk_blender *b,
                        obs_err *err) {
  memset(b, 0, sizeof *b);
  b->vk = vk;
  b->what = d->pipeline.what;
  b->push_stages = d->push_stages;
  b->width = d->width;
  b->height = d->height;
  if (d->nbindings > OBS_VK_BLEND_BINDINGS)
    return obs_err_set(err, OBS_EINVAL, "%s: %u bindings (at most %d)", b->what, d->nbindings,
                       OBS_VK_BLEND_BINDINGS);
  int rc = create_layouts(b, d, err);
  if (!rc) rc = obs_vk_blend_pass(vk, d->format, &b->pass, b->what, err);
  obs_vk_blend pl = d->pipeline;
  pl.layout = b->layout;
  pl.pass = b->pass;
  if (!rc) rc = obs_vk_blend_pipeline(vk, &pl, &b->pipe, err);
  if (!rc) rc = create_bindings(b, d, err);
  if (rc) obs_vk_blender_free(b);
  return rc;
}

int obs_vk_blender_draw(obs_vk_blender *b, const void *push, uint32_t push_size,
                        const float clear[4], VkBuffer vertices, uint32_t nvertices,
                        uint32_t ninstances, obs_err *err) {
  obs_vk *vk = b->vk;
  int rc = obs_vk_cmd_begin(vk, b->what, err);
  if (rc) return rc;
  VkCommandBuffer cmd = vk->cmd;
  const uint32_t w = (uint32_t)b->width, h = (uint32_t)b->height;
  VkClearValue cv = {.color = {{clear[0], clear[1], clear[2], clear[3]}}};
  VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                               .renderPass = b->pass,
                               .framebuffer = b->fb,
                               .renderArea = {{0, 0}, {w, h}},
                               .clearValueCount = 1,
                               .pClearValues = &cv};
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, b->pipe);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, b->layout, 0, 1, &b->set, 0, NULL);
  if (push_size) vkCmdPushConstants(cmd, b->layout, b->push_stages, 0, push_size, push);
  VkViewport vp = {0, 0, (float)w, (float)h, 0, 1};
  VkRect2D sc = {{0, 0}, {w, h}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &sc);
  VkDeviceSize off = 0;
  if (vertices) vkCmdBindVertexBuffers(cmd, 0, 1, &vertices, &off);
  if (nvertices && ninstances) vkCmdDraw(cmd, nvertices, ninstances, 0, 0);
  vkCmdEndRenderPass(cmd);
  obs_vk_cmd_barrier(cmd);
  return obs_vk_cmd_submit(vk, b->what, err);
}

void obs_vk_blender_free(obs_vk_blender *b) {
  obs_vk *vk = b->vk;
  if (!vk) return;
  if (b->fb) vkDestroyFramebuffer(vk->dev, b->fb, NULL);
  if (b->dpool) vkDestroyDescriptorPool(vk->dev, b->dpool, NULL);
  if (b->pipe) vkDestroyPipeline(vk->dev, b->pipe, NULL);
  if (b->pass) vkDestroyRenderPass(vk->dev, b->pass, NULL);
  if (b->layout) vkDestroyPipelineLayout(vk->dev, b->layout, NULL);
  if (b->dsl) vkDestroyDescriptorSetLayout(vk->dev, b->dsl, NULL);
  memset(b, 0, sizeof *b);
}

int obs_vk_blend_pass(obs_vk *vk, VkFormat format, VkRenderPass *out, const char *what,
                      obs_err *err) {
  return obs_vk_single_pass(vk, format, 0, out, what, err);
}

/* One attachment cleared on load and stored, one subpass, full dependencies on the work around
 * it: a colour attachment that is a storage image kept in GENERAL layout, or a depth attachment
 * left for sampling (SHADER_READ_ONLY_OPTIMAL). */
int obs_vk_single_pass(obs_vk *vk, VkFormat format, int depth, VkRenderPass *out,
                       const char *what, obs_err *err) {
  VkAttachmentDescription att = {
      .format = format,
      .samples = VK_SAMPLE_COUNT_1_BIT,
      .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
      .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
      .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
      .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
      .initialLayout = depth ? VK_IMAGE_LAYOUT_UNDEFINED : VK_IMAGE_LAYOUT_GENERAL,
      .finalLayout = depth ? VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL : VK_IMAGE_LAYOUT_GENERAL};
  VkAttachmentReference ref = {
      0, depth ? VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL : VK_IMAGE_LAYOUT_GENERAL};
  VkSubpassDescription sub = {.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                              .colorAttachmentCount = depth ? 0 : 1,
                              .pColorAttachments = depth ? NULL : &ref,
                              .pDepthStencilAttachment = depth ? &ref : NULL};
  VkSubpassDependency dep[2];
  obs_vk_pass_deps(dep);
  VkRenderPassCreateInfo rpci = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                 .attachmentCount = 1,
                                 .pAttachments = &att,
                                 .subpassCount = 1,
                                 .pSubpasses = &sub,
                                 .dependencyCount = 2,
                                 .pDependencies = dep};
  char what_call[96];
  snprintf(what_call, sizeof what_call, "vkCreateRenderPass (%s)", what);
  return obs_vk_check(vk, vkCreateRenderPass(vk->dev, &rpci, NULL, out), what_call, err);
}

int obs_vk_blendable(obs_vk *vk, VkFormat format) {
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, format, &fp);
  VkFormatFeatureFlags need =
      VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT;
  return (fp.optimalTilingFeatures & need) == need;
}
