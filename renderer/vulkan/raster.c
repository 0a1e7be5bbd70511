/* The Vulkan device layer's raster pipelines (the G-buffer, depth peeling, the blending passes
 * of blend.c, the depth maps of depth_maps.c), their render passes' dependencies and shader
 * modules: the fixed-function state they share, written once. */
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

/* A pipeline of `n` stages over triangles or points with no culling (occlusion sees both sides
 * of every surface, as the ray caster does; depth peeling decides by the facing cosine who
 * transfers; the proxies emit only the faces they mean), one sample, viewport and scissor
 * dynamic; `ds` NULL: no depth test. */
static int build(obs_vk *vk, const VkPipelineShaderStageCreateInfo *st, uint32_t n,
                 const VkPipelineVertexInputStateCreateInfo *vi, VkPrimitiveTopology topology,
                 const VkPipelineDepthStencilStateCreateInfo *ds,
                 const VkPipelineColorBlendAttachmentState *cba, uint32_t ncba,
                 VkPipelineLayout layout, VkRenderPass pass, const char *what, VkPipeline *out,
                 obs_err *err) {
  VkPipelineInputAssemblyStateCreateInfo ia = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO, .topology = topology};
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
  VkPipelineColorBlendStateCreateInfo cb = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
      .attachmentCount = ncba,
      .pAttachments = cba};
  VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dy = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO,
      .dynamicStateCount = 2,
      .pDynamicStates = dyn};
  VkGraphicsPipelineCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
                                     .stageCount = n,
                                     .pStages = st,
                                     .pVertexInputState = vi,
                                     .pInputAssemblyState = &ia,
                                     .pViewportState = &vps,
                                     .pRasterizationState = &rs,
                                     .pMultisampleState = &ms,
                                     .pDepthStencilState = ds,
                                     .pColorBlendState = &cb,
                                     .pDynamicState = &dy,
                                     .layout = layout,
                                     .renderPass = pass};
  char buf[128];
  snprintf(buf, sizeof buf, "vkCreateGraphicsPipelines (%s)", what);
  int rc = obs_vk_check(vk, vkCreateGraphicsPipelines(vk->dev, VK_NULL_HANDLE, 1, &ci, NULL, out),
                        buf, err);
  if (rc) *out = VK_NULL_HANDLE;
  return rc;
}

/* The shader stages among vs, gs, fs that are set, in order, into st; returns their count. */
static uint32_t stages_of(VkShaderModule vs, VkShaderModule gs, VkShaderModule fs,
                          VkPipelineShaderStageCreateInfo st[3]) {
  const VkShaderModule m[3] = {vs, gs, fs};
  static const VkShaderStageFlagBits kinds[3] = {
      VK_SHADER_STAGE_VERTEX_BIT, VK_SHADER_STAGE_GEOMETRY_BIT, VK_SHADER_STAGE_FRAGMENT_BIT};
  uint32_t n = 0;
  for (int i = 0; i < 3; i++)
    if (m[i])
      st[n++] = (VkPipelineShaderStageCreateInfo){
          .sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
          .stage = kinds[i],
          .module = m[i],
          .pName = "main"};
  return n;
}

int obs_vk_raster_pipeline(obs_vk *vk, const obs_vk_raster *r, VkPipeline *out, obs_err *err) {
  VkPipelineShaderStageCreateInfo st[3];
  uint32_t n = stages_of(r->vs, VK_NULL_HANDLE, r->fs, st);
  VkVertexInputBindingDescription vb = {0, r->stride, VK_VERTEX_INPUT_RATE_VERTEX};
  VkPipelineVertexInputStateCreateInfo vi = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
      .vertexBindingDescriptionCount = 1,
      .pVertexBindingDescriptions = &vb,
      .vertexAttributeDescriptionCount = r->nattrs,
      .pVertexAttributeDescriptions = r->attrs};
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
  return build(vk, st, n, &vi, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, &ds, cba,
               r->ncolor < 4 ? r->ncolor : 4, r->layout, r->pass, r->what, out, err);
}

int obs_vk_blend_pipeline(obs_vk *vk, const obs_vk_blend *b, VkPipeline *out, obs_err *err) {
  VkPipelineShaderStageCreateInfo st[3];
  uint32_t n = stages_of(b->vs, b->gs, b->fs, st);
  VkPipelineVertexInputStateCreateInfo none = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineColorBlendAttachmentState cba = {.blendEnable = VK_TRUE,
                                             .srcColorBlendFactor = b->src,
                                             .dstColorBlendFactor = b->dst,
                                             .colorBlendOp = b->op,
                                             .srcAlphaBlendFactor = b->src,
                                             .dstAlphaBlendFactor = b->dst,
                                             .alphaBlendOp = b->op,
                                             .colorWriteMask = b->write};
  return build(vk, st, n, b->input ? b->input : &none, b->topology, NULL, &cba, 1, b->layout,
               b->pass, b->what, out, err);
}

void obs_vk_pass_deps(VkSubpassDependency dep[2]) {
  const VkAccessFlags all = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  dep[0] = (VkSubpassDependency){.srcSubpass = VK_SUBPASS_EXTERNAL,
                                 .dstSubpass = 0,
                                 .srcStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                                 .dstStageMask = VK_PIPELINE_STAGE_ALL_GRAPHICS_BIT,
                                 .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
                                 .dstAccessMask = all};
  dep[1] = (VkSubpassDependency){.srcSubpass = 0,
                                 .dstSubpass = VK_SUBPASS_EXTERNAL,
                                 .srcStageMask = VK_PIPELINE_STAGE_ALL_GRAPHICS_BIT,
                                 .dstStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                                 .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
                                 .dstAccessMask = all};
}
