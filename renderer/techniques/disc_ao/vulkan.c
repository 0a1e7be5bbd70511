/* disc_ao on Vulkan: one point per disc through disc_ao.geom.glsl, which emits its proxy (quad or
 * pyramid), rasterised over the device G-buffer into a float target with additive blending
 * (disc_ao.frag.glsl: the occlusion in red, a fragment count in green), read back and finished
 * on the host as the CPU twin (cpu.c) finishes its sums. Blending follows primitive order, so a
 * pixel sums its discs in their order, as the CPU does. */
#include <stdlib.h>
#include <string.h>

#include "disc_ao.h"
#include "driver.h"
#include "layout.h"
#include "obscura/render.h"
#include "screen_vk.h"
#include "shaders.h"
#include "vk_internal.h"

_Static_assert(sizeof(obs_disc) == 32, "obs_disc is the vertex: two vec4");

typedef struct disc_vk {
  obs_vk *vk;
  VkDescriptorSetLayout dsl;
  VkPipelineLayout layout;
  VkRenderPass pass;
  VkPipeline pipe;
  VkDescriptorPool dpool;
  VkDescriptorSet set;
  VkFramebuffer fb;
  obs_vk_buffer verts;
  obs_vk_image *target;
} disc_vk;

static const VkShaderStageFlags PUSH_STAGES =
    VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;

static int create_layouts(disc_vk *d, obs_err *err) {
  obs_vk *vk = d->vk;
  VkDescriptorSetLayoutBinding b[OBS_DISC_BINDINGS];
  for (uint32_t i = 0; i < OBS_DISC_BINDINGS; i++)
    b[i] = (VkDescriptorSetLayoutBinding){i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1,
                                          VK_SHADER_STAGE_FRAGMENT_BIT, NULL};
  VkDescriptorSetLayoutCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
                                         .bindingCount = OBS_DISC_BINDINGS,
                                         .pBindings = b};
  int rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &dci, NULL, &d->dsl),
                        "vkCreateDescriptorSetLayout (disc_ao)", err);
  if (rc) return rc;
  VkPushConstantRange pr = {PUSH_STAGES, 0, sizeof(obs_disc_ao_push)};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 1,
                                     .pSetLayouts = &d->dsl,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  if ((rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &d->layout),
                         "vkCreatePipelineLayout (disc_ao)", err)))
    return rc;
  /* The target is a storage image in GENERAL layout that the pass clears and blends into. */
  return obs_vk_blend_pass(vk, VK_FORMAT_R32G32B32A32_SFLOAT, &d->pass, "disc_ao", err);
}

static int create_pipeline(disc_vk *d, obs_err *err) {
  obs_vk *vk = d->vk;
  VkShaderModule m[3] = {VK_NULL_HANDLE, VK_NULL_HANDLE, VK_NULL_HANDLE};
  int rc = obs_vk_shader(vk, obs_spv_disc_ao_vert, obs_spv_disc_ao_vert_size, &m[0], "disc_ao",
                         err);
  if (!rc)
    rc = obs_vk_shader(vk, obs_spv_disc_ao_geom, obs_spv_disc_ao_geom_size, &m[1], "disc_ao", err);
  if (!rc)
    rc = obs_vk_shader(vk, obs_spv_disc_ao_frag, obs_spv_disc_ao_frag_size, &m[2], "disc_ao", err);
  VkVertexInputBindingDescription vb = {0, sizeof(obs_disc), VK_VERTEX_INPUT_RATE_VERTEX};
  VkVertexInputAttributeDescription va[2] = {
      {0, 0, VK_FORMAT_R32G32B32A32_SFLOAT, offsetof(obs_disc, c)},
      {1, 0, VK_FORMAT_R32G32B32A32_SFLOAT, offsetof(obs_disc, n)}};
  VkPipelineVertexInputStateCreateInfo vi = {
      .sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO,
      .vertexBindingDescriptionCount = 1,
      .pVertexBindingDescriptions = &vb,
      .vertexAttributeDescriptionCount = 2,
      .pVertexAttributeDescriptions = va};
  /* Additive: the geometry shader emits only the faces it means (a pyramid's back faces). */
  obs_vk_blend bl = {.vs = m[0], .gs = m[1], .fs = m[2], .input = &vi,
                     .topology = VK_PRIMITIVE_TOPOLOGY_POINT_LIST, .src = VK_BLEND_FACTOR_ONE,
                     .dst = VK_BLEND_FACTOR_ONE, .op = VK_BLEND_OP_ADD,
                     .write = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                              VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT,
                     .layout = d->layout, .pass = d->pass, .what = "disc_ao"};
  if (!rc) rc = obs_vk_blend_pipeline(vk, &bl, &d->pipe, err);
  for (int i = 0; i < 3; i++)
    if (m[i]) vkDestroyShaderModule(vk->dev, m[i], NULL);
  return rc;
}

/* The descriptor set (the G-buffer's depth and normal) and the framebuffer of the target. */
static int create_bindings(disc_vk *d, obs_vk_gbuffer *g, obs_err *err) {
  obs_vk *vk = d->vk;
  VkDescriptorPoolSize size = {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, OBS_DISC_BINDINGS};
  VkDescriptorPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = 1,
                                    .poolSizeCount = 1,
                                    .pPoolSizes = &size};
  int rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &pci, NULL, &d->dpool),
                        "vkCreateDescriptorPool (disc_ao)", err);
  if (rc) return rc;
  VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                    .descriptorPool = d->dpool,
                                    .descriptorSetCount = 1,
                                    .pSetLayouts = &d->dsl};
  if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, &d->set),
                         "vkAllocateDescriptorSets (disc_ao)", err)))
    return rc;
  VkDescriptorImageInfo ii[OBS_DISC_BINDINGS] = {
      [OBS_DISC_B_DEPTH] = {VK_NULL_HANDLE, g->depth->view, VK_IMAGE_LAYOUT_GENERAL},
      [OBS_DISC_B_NORMAL] = {VK_NULL_HANDLE, g->normal->view, VK_IMAGE_LAYOUT_GENERAL}};
  VkWriteDescriptorSet w[OBS_DISC_BINDINGS];
  for (uint32_t i = 0; i < OBS_DISC_BINDINGS; i++)
    w[i] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                  .dstSet = d->set,
                                  .dstBinding = i,
                                  .descriptorCount = 1,
                                  .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                  .pImageInfo = &ii[i]};
  vkUpdateDescriptorSets(vk->dev, OBS_DISC_BINDINGS, w, 0, NULL);
  VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = d->pass,
                                 .attachmentCount = 1,
                                 .pAttachments = &d->target->view,
                                 .width = (uint32_t)g->width,
                                 .height = (uint32_t)g->height,
                                 .layers = 1};
  return obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, &d->fb),
                      "vkCreateFramebuffer (disc_ao)", err);
}

static void disc_vk_free(disc_vk *d) {
  obs_vk *vk = d->vk;
  if (!vk) return;
  if (d->fb) vkDestroyFramebuffer(vk->dev, d->fb, NULL);
  obs_vk_image_free(vk, d->target);
  obs_vk_buffer_free(vk, &d->verts);
  if (d->dpool) vkDestroyDescriptorPool(vk->dev, d->dpool, NULL);
  if (d->pipe) vkDestroyPipeline(vk->dev, d->pipe, NULL);
  if (d->pass) vkDestroyRenderPass(vk->dev, d->pass, NULL);
  if (d->layout) vkDestroyPipelineLayout(vk->dev, d->layout, NULL);
  if (d->dsl) vkDestroyDescriptorSetLayout(vk->dev, d->dsl, NULL);
  memset(d, 0, sizeof *d);
}

/* The pass: clear, draw every disc, submit and wait. */
static int record(disc_vk *d, const obs_disc_set *s, const obs_disc_ao_push *pc, int w, int h,
                  obs_err *err) {
  obs_vk *vk = d->vk;
  int rc = obs_vk_cmd_begin(vk, "disc_ao", err);
  if (rc) return rc;
  VkCommandBuffer cmd = vk->cmd;
  VkClearValue clear = {.color = {{0.0f, 0.0f, 0.0f, 0.0f}}};
  VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                               .renderPass = d->pass,
                               .framebuffer = d->fb,
                               .renderArea = {{0, 0}, {(uint32_t)w, (uint32_t)h}},
                               .clearValueCount = 1,
                               .pClearValues = &clear};
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, d->pipe);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, d->layout, 0, 1, &d->set, 0, NULL);
  vkCmdPushConstants(cmd, d->layout, PUSH_STAGES, 0, sizeof *pc, pc);
  VkViewport vp = {0, 0, (float)w, (float)h, 0, 1};
  VkRect2D sc = {{0, 0}, {(uint32_t)w, (uint32_t)h}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &sc);
  VkDeviceSize off = 0;
  vkCmdBindVertexBuffers(cmd, 0, 1, &d->verts.buffer, &off);
  if (s->n) vkCmdDraw(cmd, (uint32_t)s->n, 1, 0, 0);
  vkCmdEndRenderPass(cmd);
  obs_vk_cmd_barrier(cmd);
  return obs_vk_cmd_submit(vk, "disc_ao", err);
}

int obs_disc_ao_vk_apply(obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                         const obs_disc_set *s, const obs_disc_ao_params *p, float *ao,
                         float *ao_raw, obs_disc_ao_stats *stats, double *ms, obs_err *err) {
  if (!vk || !dev || !dev->depth || !dev->normal || !host || !s || !p || !ao || dev->width < 1 ||
      dev->height < 1)
    return obs_err_set(err, OBS_EINVAL, "disc_ao: missing device, G-buffer, discs or output");
  if (!vk->geometry_shader)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "disc_ao: the Vulkan device %s has no geometry shaders", vk->name);
  if (!obs_vk_blendable(vk, VK_FORMAT_R32G32B32A32_SFLOAT))
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "disc_ao: the Vulkan device %s cannot blend 32-bit float targets",
                       vk->name);
  if (s->n > UINT32_MAX) return obs_err_set(err, OBS_EINVAL, "disc_ao: %zu discs", s->n);
  const int w = dev->width, h = dev->height;
  disc_vk d = {.vk = vk};
  obs_disc_ao_push pc = {.width = w, .height = h, .half_w = host->half_w, .half_h = host->half_h,
                         .flags = (host->ortho ? OBS_DISC_FLAG_ORTHO : 0) |
                                  (p->proxy == OBS_DISC_PROXY_PYRAMID ? OBS_DISC_FLAG_PYRAMID : 0) |
                                  (p->side == OBS_DISC_SIDE_BACK ? OBS_DISC_FLAG_BACK : 0)};
  size_t npx = (size_t)w * (size_t)h;
  float *px = malloc(npx * 4 * sizeof *px);
  int rc = px ? 0 : obs_err_set(err, OBS_ENOMEM, "disc_ao: %dx%d: out of memory", w, h);
  if (!rc)
    rc = obs_vk_buffer_create(vk, (VkDeviceSize)(s->n ? s->n : 1) * sizeof(obs_disc),
                              VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, 1, &d.verts, "disc_ao discs",
                              err);
  if (!rc && s->n) memcpy(d.verts.map, s->d, s->n * sizeof(obs_disc));
  if (!rc)
    rc = obs_vk_image_create_usage(vk, w, h, 4, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, &d.target,
                                   err);
  if (!rc) rc = create_layouts(&d, err);
  if (!rc) rc = create_pipeline(&d, err);
  if (!rc) rc = create_bindings(&d, dev, err);
  double t0 = obs_now_ms();
  if (!rc) rc = record(&d, s, &pc, w, h, err);
  if (ms) *ms = obs_now_ms() - t0;
  if (!rc) rc = obs_vk_image_download(vk, d.target, px, err);
  if (!rc) {
    obs_disc_ao_stats st = {0};
    for (size_t i = 0; i < npx; i++) {
      const float sum = px[4 * i], count = px[4 * i + 1];
      obs_disc_ao_finish(sum, &ao[i], ao_raw ? &ao_raw[i] : NULL);
      st.fragments += (uint64_t)count;
      if ((uint32_t)count > st.max_overdraw) st.max_overdraw = (uint32_t)count;
      st.clamped += sum > 1.0f;
    }
    if (stats) *stats = st;
  }
  free(px);
  disc_vk_free(&d);
  return rc;
}

static int passes(obs_render_ctx *ctx, obs_vk *vk, obs_vk_gbuffer *dev, const obs_gbuffer *host,
                  const void *params, float *ao, float *ao_raw, obs_err *err) {
  const obs_disc_ao_params *p = params;
  obs_camera_rig rig;
  obs_camera_setup(&ctx->scene->camera, host->width, host->height, &rig);
  obs_disc_set s;
  double t0 = obs_now_ms();
  int rc = obs_disc_set_build(ctx->scene, &rig, p, &s, err);
  if (rc) return rc;
  double t1 = obs_now_ms();
  rc = obs_disc_ao_vk_apply(vk, dev, host, &s, p, ao, ao_raw, NULL, NULL, err);
  obs_disc_set_free(&s);
  if (rc) return rc;
  obs_driver_stage_add(ctx, "discs", t1 - t0);
  obs_driver_stage_add(ctx, "ao", obs_now_ms() - t1);
  return 0;
}

int obs_disc_ao_vulkan(obs_render_ctx *ctx, obs_image *out, obs_err *err) {
  return obs_screen_vk_run(ctx, "disc_ao", passes, ctx->bound, out, err);
}
