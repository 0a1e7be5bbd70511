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

static const VkShaderStageFlags PUSH_STAGES =
    VK_SHADER_STAGE_GEOMETRY_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;

/* The pipeline and its bindings (the G-buffer's depth and normal), blending into `target`. */
static int open_blender(obs_vk *vk, obs_vk_gbuffer *g, obs_vk_image *target, obs_vk_blender *b,
                        obs_err *err) {
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
  VkDescriptorSetLayoutBinding bind[OBS_DISC_BINDINGS];
  for (uint32_t i = 0; i < OBS_DISC_BINDINGS; i++)
    bind[i] = (VkDescriptorSetLayoutBinding){i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1,
                                             VK_SHADER_STAGE_FRAGMENT_BIT, NULL};
  VkDescriptorImageInfo ii[OBS_DISC_BINDINGS] = {
      [OBS_DISC_B_DEPTH] = {VK_NULL_HANDLE, g->depth->view, VK_IMAGE_LAYOUT_GENERAL},
      [OBS_DISC_B_NORMAL] = {VK_NULL_HANDLE, g->normal->view, VK_IMAGE_LAYOUT_GENERAL}};
  VkWriteDescriptorSet w[OBS_DISC_BINDINGS];
  for (uint32_t i = 0; i < OBS_DISC_BINDINGS; i++)
    w[i] = (VkWriteDescriptorSet){.pImageInfo = &ii[i]};
  /* Additive; no culling: the geometry shader emits only the faces it means (a pyramid's back
   * faces). */
  obs_vk_blender_def d = {
      .bindings = bind, .nbindings = OBS_DISC_BINDINGS, .writes = w,
      .push_stages = PUSH_STAGES, .push_size = sizeof(obs_disc_ao_push),
      .format = VK_FORMAT_R32G32B32A32_SFLOAT, .target = target, .width = g->width,
      .height = g->height,
      .pipeline = {.vs = m[0], .gs = m[1], .fs = m[2], .input = &vi,
                   .topology = VK_PRIMITIVE_TOPOLOGY_POINT_LIST, .src = VK_BLEND_FACTOR_ONE,
                   .dst = VK_BLEND_FACTOR_ONE, .op = VK_BLEND_OP_ADD,
                   .write = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                            VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT,
                   .what = "disc_ao"}};
  if (!rc) rc = obs_vk_blender_open(vk, &d, b, err);
  for (int i = 0; i < 3; i++)
    if (m[i]) vkDestroyShaderModule(vk->dev, m[i], NULL);
  return rc;
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
  obs_vk_buffer verts = {0};
  obs_vk_image *target = NULL;
  obs_vk_blender b = {0};
  obs_disc_ao_push pc = {.width = w, .height = h, .half_w = host->half_w, .half_h = host->half_h,
                         .flags = (host->ortho ? OBS_DISC_FLAG_ORTHO : 0) |
                                  (p->proxy == OBS_DISC_PROXY_PYRAMID ? OBS_DISC_FLAG_PYRAMID : 0) |
                                  (p->side == OBS_DISC_SIDE_BACK ? OBS_DISC_FLAG_BACK : 0)};
  size_t npx = (size_t)w * (size_t)h;
  float *px = malloc(npx * 4 * sizeof *px);
  int rc = px ? 0 : obs_err_set(err, OBS_ENOMEM, "disc_ao: %dx%d: out of memory", w, h);
  if (!rc)
    rc = obs_vk_buffer_create(vk, (VkDeviceSize)(s->n ? s->n : 1) * sizeof(obs_disc),
                              VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, 1, &verts, "disc_ao discs",
                              err);
  if (!rc && s->n) memcpy(verts.map, s->d, s->n * sizeof(obs_disc));
  if (!rc)
    rc = obs_vk_image_create_usage(vk, w, h, 4, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, &target,
                                   err);
  if (!rc) rc = open_blender(vk, dev, target, &b, err);
  static const float zeros[4] = {0, 0, 0, 0};
  double t0 = obs_now_ms();
  if (!rc)
    rc = obs_vk_blender_draw(&b, &pc, sizeof pc, zeros, verts.buffer, (uint32_t)s->n, 1, err);
  if (ms) *ms = obs_now_ms() - t0;
  if (!rc) rc = obs_vk_image_download(vk, target, px, err);
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
  obs_vk_blender_free(&b);
  obs_vk_image_free(vk, target);
  obs_vk_buffer_free(vk, &verts);
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
