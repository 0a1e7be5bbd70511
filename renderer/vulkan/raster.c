/* The Vulkan device layer's raster pipelines (the G-buffer, depth peeling), the render pass of
 * the passes that blend into a storage image, and shader modules: the fixed-function state they
 * share, written once. */
#include <stdio.h>

#include "vk_internal.h"

int obs_vk_shader(obs_vk *vk, const uint32_t *code, size_t size, VkShaderModule *out,
                  const char *what, obs_err *err) {
  VkShaderModuleCreateInfo ci = {
      .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO, .codeSize = size, .pCode = code};
  char buf[128];
  snprintf(buf, sizeof buf, "vkCreateShaderModule (%s)", what);
  int rc = obs_vk_check(vk, vkCreateShaderModule(vk->dev, &ci, NULL, out), buf, err);
  if (rc) *out = VK_NULL_HANDLE;
  return rc;
}

int obs_vk_raster_pipeline(obs_vk *vk, const obs_vk_raster *r, VkPipeline *out, obs_err *err) {
  VkPipelineShaderStageCreateInfo stages[2] = {
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_VERTEX_BIT,
       .module = r->vs,
       .pName = "main"},
      {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
       .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
       .module = r->fs,
       .pName = "main"}};
  VkVertexInputBindingDescription vb = {0, r->stride, VK_VERTEX_INPUT_RATE_VERTEX};
  VkPipelineVertexInputStateCreateInfo vi = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
      .vertexBindingDescriptionCount = 1,
      .pVertexBindingDescriptions = &vb,
      .vertexAttributeDescriptionCount = r->nattrs,
      .pVertexAttributeDescriptions = r->attrs};
  VkPipelineInputAssemblyStateCreateInfo ia = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
      .topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST};
  VkPipelineViewportStateCreateInfo vps = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
      .viewportCount = 1,
      .scissorCount = 1};
  /* No culling: occlusion sees both sides of every surface, as the ray caster does, and depth
   * peeling decides by the facing cosine who transfers. */
  VkPipelineRasterizationStateCreateInfo rs = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
      .polygonMode = VK_POLYGON_MODE_FILL,
      .cullMode = VK_CULL_MODE_NONE,
      .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
      .lineWidth = 1.0f};
  VkPipelineMultisampleStateCreateInfo ms = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
      .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT};
  VkPipelineDepthStencilStateCreateInfo ds = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
      .depthTestEnable = VK_TRUE,
      .depthWriteEnable = VK_TRUE,
      .depthCompareOp = r->depth_op};
  /* Identical for every target (no independentBlend needed); a one-channel format ignores the
   * unused components. */
  VkPipelineColorBlendAttachmentState cba[4];
  for (uint32_t i = 0; i < 4; i++)
    cba[i] = (VkPipelineColorBlendAttachmentState){
        .colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                          VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT};
  VkPipelineColorBlendStateCreateInfo cb = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
      .attachmentCount = r->ncolor < 4 ? r->ncolor : 4,
      .pAttachments = cba};
  VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dy = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO,
      .dynamicStateCount = 2,
      .pDynamicStates = dyn};
  VkGraphicsPipelineCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                     .stageCount = 2,
                                     .pStages = stages,
                                     .pVertexInputState = &vi,
                                     .pInputAssemblyState = &ia,
                                     .pViewportState = &vps,
                                     .pRasterizationState = &rs,
                                     .pMultisampleState = &ms,
                                     .pDepthStencilState = &ds,
                                     .pColorBlendState = &cb,
                                     .pDynamicState = &dy,
                                     .layout = r->layout,
                                     .renderPass = r->pass};
  char buf[128];
  snprintf(buf, sizeof buf, "vkCreateGraphicsPipelines (%s)", r->what);
  int rc = obs_vk_check(vk, vkCreateGraphicsPipelines(vk->dev, VK_NULL_HANDLE, 1, &ci, NULL, out),
                        buf, err);
  if (rc) *out = VK_NULL_HANDLE;
  return rc;
}

/* A one-subpass render pass over one colour attachment of `format` that is a storage image kept
 * in GENERAL layout: cleared on load, stored, with full dependencies on the work around it. */
int obs_vk_blend_pass(obs_vk *vk, VkFormat format, VkRenderPass *out, const char *what,
                      obs_err *err) {
  VkAttachmentDescription att = {.format = format,
                                 .samples = VK_SAMPLE_COUNT_1_BIT,
                                 .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
                                 .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
                                 .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                                 .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
                                 .initialLayout = VK_IMAGE_LAYOUT_GENERAL,
                                 .finalLayout = VK_IMAGE_LAYOUT_GENERAL};
  VkAttachmentReference cref = {0, VK_IMAGE_LAYOUT_GENERAL};
  VkSubpassDescription sub = {.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                              .colorAttachmentCount = 1,
                              .pColorAttachments = &cref};
  VkSubpassDependency dep[2] = {
      {.srcSubpass = VK_SUBPASS_EXTERNAL,
       .dstSubpass = 0,
       .srcStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
       .dstStageMask = VK_PIPELINE_STAGE_ALL_GRAPHICS_BIT,
       .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
       .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT},
      {.srcSubpass = 0,
       .dstSubpass = VK_SUBPASS_EXTERNAL,
       .srcStageMask = VK_PIPELINE_STAGE_ALL_GRAPHICS_BIT,
       .dstStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
       .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
       .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT}};
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

int obs_vk_blend_pipeline(obs_vk *vk, const obs_vk_blend *b, VkPipeline *out, obs_err *err) {
  VkPipelineShaderStageCreateInfo st[3];
  uint32_t n = 0;
  const VkShaderModule m[3] = {b->vs, b->gs, b->fs};
  static const VkShaderStageFlagBits kinds[3] = {
      VK_SHADER_STAGE_VERTEX_BIT, VK_SHADER_STAGE_GEOMETRY_BIT, VK_SHADER_STAGE_FRAGMENT_BIT};
  for (int i = 0; i < 3; i++)
    if (m[i])
      st[n++] = (VkPipelineShaderStageCreateInfo){
          .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
          .stage = kinds[i],
          .module = m[i],
          .pName = "main"};
  VkPipelineVertexInputStateCreateInfo none = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineInputAssemblyStateCreateInfo ia = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
      .topology = b->topology};
  VkPipelineViewportStateCreateInfo vps = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO,
      .viewportCount = 1,
      .scissorCount = 1};
  VkPipelineRasterizationStateCreateInfo rs = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
      .polygonMode = VK_POLYGON_MODE_FILL,
      .cullMode = VK_CULL_MODE_NONE,
      .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
      .lineWidth = 1.0f};
  VkPipelineMultisampleStateCreateInfo ms = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
      .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT};
  VkPipelineColorBlendAttachmentState cba = {.blendEnable = VK_TRUE,
                                             .srcColorBlendFactor = b->src,
                                             .dstColorBlendFactor = b->dst,
                                             .colorBlendOp = b->op,
                                             .srcAlphaBlendFactor = b->src,
                                             .dstAlphaBlendFactor = b->dst,
                                             .alphaBlendOp = b->op,
                                             .colorWriteMask = b->write};
  VkPipelineColorBlendStateCreateInfo cb = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
      .attachmentCount = 1,
      .pAttachments = &cba};
  VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dy = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO,
      .dynamicStateCount = 2,
      .pDynamicStates = dyn};
  VkGraphicsPipelineCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                     .stageCount = n,
                                     .pStages = st,
                                     .pVertexInputState = b->input ? b->input : &none,
                                     .pInputAssemblyState = &ia,
                                     .pViewportState = &vps,
                                     .pRasterizationState = &rs,
                                     .pMultisampleState = &ms,
                                     .pColorBlendState = &cb,
                                     .pDynamicState = &dy,
                                     .layout = b->layout,
                                     .renderPass = b->pass};
  char buf[128];
  snprintf(buf, sizeof buf, "vkCreateGraphicsPipelines (%s)", b->what);
  int rc = obs_vk_check(vk, vkCreateGraphicsPipelines(vk->dev, VK_NULL_HANDLE, 1, &ci, NULL, out),
                        buf, err);
  if (rc) *out = VK_NULL_HANDLE;
  return rc;
}

int obs_vk_blendable(obs_vk *vk, VkFormat format) {
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, format, &fp);
  VkFormatFeatureFlags need =
      VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT;
  return (fp.optimalTilingFeatures & need) == need;
}
