/* The Vulkan device layer's orthographic depth maps (shadow maps): the geometry's triangles and
 * tessellated spheres drawn by a depth-only render pass (no fragment stage) once per map into
 * one layer of a sampled D32 array image, which compute passes then read as a texture. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shaders.h"
#include "vk_internal.h"

#define PI 3.14159265358979323846
#define DEPTH_FORMAT VK_FORMAT_D32_SFLOAT

typedef struct depth_push {
  float row[3][4];
} depth_push;

/* Everything one call makes besides the texture it returns. */
typedef struct depth_run {
  obs_vk *vk;
  VkRenderPass pass;
  VkPipelineLayout layout;
  VkPipeline pipe;
  VkImageView *views; /* one a layer */
  VkFramebuffer *fbs;
  int n;
  obs_vk_buffer vb;
  uint32_t nverts;
} depth_run;

static void run_free(depth_run *r) {
  obs_vk *vk = r->vk;
  for (int i = 0; i < r->n; i++) {
    if (r->fbs && r->fbs[i]) vkDestroyFramebuffer(vk->dev, r->fbs[i], NULL);
    if (r->views && r->views[i]) vkDestroyImageView(vk->dev, r->views[i], NULL);
  }
  free(r->fbs);
  free(r->views);
  if (r->pipe) vkDestroyPipeline(vk->dev, r->pipe, NULL);
  if (r->layout) vkDestroyPipelineLayout(vk->dev, r->layout, NULL);
  if (r->pass) vkDestroyRenderPass(vk->dev, r->pass, NULL);
  obs_vk_buffer_free(vk, &r->vb);
}

/* Positions relative to `centre`: every triangle of every mesh, then every sphere's facets, as
 * float triples into `out` (NULL: count only). Returns the vertex count; *rc is OBS_ENOMEM when
 * a sphere could not be tessellated. */
static size_t fill_vertices(const obs_geometry *geo, const double centre[3], double texel,
                            float *out, int *rc) {
  double shift[3];
  size_t k = 0;
  *rc = 0;
  for (int c = 0; c < 3; c++) shift[c] = geo->origin[c] - centre[c];
  for (size_t m = 0; m < geo->nmeshes; m++) {
    const obs_mesh *me = &geo->meshes[m];
    for (size_t t = 0; t < 3 * me->ntris; t++, k++)
      for (int c = 0; out && c < 3; c++)
        out[3 * k + (size_t)c] = (float)((double)me->pos[3 * (size_t)me->idx[t] + (size_t)c] + shift[c]);
  }
  for (size_t s = 0; s < geo->nspheres; s++) {
    const obs_sphere *sp = &geo->spheres[s];
    if (!(sp->radius > 0)) continue;
    int seg = obs_vk_sphere_segments(sp->radius, 1.0 / texel, PI / 2);
    size_t nv = obs_vk_sphere_vertices(seg);
    if (out) {
      double *tess = malloc(nv * 3 * sizeof *tess);
      if (!tess || obs_vk_sphere_fill(sp, seg, shift, tess)) {
        free(tess);
        *rc = OBS_ENOMEM;
        return 0;
      }
      for (size_t i = 0; i < 3 * nv; i++) out[3 * k + i] = (float)tess[i];
      free(tess);
    }
    k += nv;
  }
  return k;
}

/* A sampled array image of n layers that is also a depth attachment, its whole view and
 * nearest sampler (the obs_vk_texture a compute pass binds), and one view per layer. */
static int make_texture(depth_run *r, int n, int size, obs_vk_texture **out, obs_err *err) {
  obs_vk *vk = r->vk;
  obs_vk_texture *t = calloc(1, sizeof *t);
  r->views = calloc((size_t)n, sizeof *r->views);
  r->fbs = calloc((size_t)n, sizeof *r->fbs);
  if (!t || !r->views || !r->fbs) {
    free(t);
    free(r->views);
    free(r->fbs);
    r->views = NULL, r->fbs = NULL;
    return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for %d depth maps", n);
  }
  r->n = n;
  *out = t;
  t->desc = (obs_vk_texture_desc){.type = OBS_VK_TEXTURE_2D_ARRAY, .width = size, .height = size,
                                  .depth = n, .channels = 1};
  t->format = DEPTH_FORMAT;
  VkImageCreateInfo ci = {
      .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
      .imageType = VK_IMAGE_TYPE_2D,
      .format = DEPTH_FORMAT,
      .extent = {(uint32_t)size, (uint32_t)size, 1},
      .mipLevels = 1,
      .arrayLayers = (uint32_t)n,
      .samples = VK_SAMPLE_COUNT_1_BIT,
      .tiling = VK_IMAGE_TILING_OPTIMAL,
      .usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT,
      .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
      .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  char what[96];
  snprintf(what, sizeof what, "%d depth maps of %d^2", n, size);
  int rc = obs_vk_check(vk, vkCreateImage(vk->dev, &ci, NULL, &t->image), what, err);
  if (rc) return rc;
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(vk->dev, t->image, &req);
  if ((rc = obs_vk_memory_alloc(vk, &req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &t->memory, what,
                                err)) ||
      (rc = obs_vk_check(vk, vkBindImageMemory(vk->dev, t->image, t->memory, 0),
                         "vkBindImageMemory (depth maps)", err)))
    return rc;
  VkImageViewCreateInfo vci = {.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
                               .image = t->image,
                               .viewType = VK_IMAGE_VIEW_TYPE_2D_ARRAY,
                               .format = DEPTH_FORMAT,
                               .subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, 0,
                                                    (uint32_t)n}};
  if ((rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &t->view),
                         "vkCreateImageView (depth maps)", err)))
    return rc;
  for (int i = 0; i < n; i++) {
    vci.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vci.subresourceRange.baseArrayLayer = (uint32_t)i;
    vci.subresourceRange.layerCount = 1;
    if ((rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &r->views[i]),
                           "vkCreateImageView (a depth map)", err)))
      return rc;
  }
  return obs_vk_texture_sampler(vk, t, err);
}

/* The pipeline layout (push constants only) and the vertex-only raster pipeline. */
static int make_pipeline(depth_run *r, obs_err *err) {
  obs_vk *vk = r->vk;
  VkPushConstantRange pr = {VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(depth_push)};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  int rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &r->layout),
                        "vkCreatePipelineLayout (depth maps)", err);
  if (rc) return rc;
  VkShaderModule vs;
  if ((rc = obs_vk_shader(vk, obs_spv_depth_map_vert, obs_spv_depth_map_vert_size, &vs,
                          "depth maps", err)))
    return rc;
  VkVertexInputAttributeDescription va = {0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0};
  obs_vk_raster def = {.vs = vs,
                       .stride = 3 * sizeof(float),
                       .attrs = &va,
                       .nattrs = 1,
                       .depth_op = VK_COMPARE_OP_LESS,
                       .ncolor = 0,
                       .layout = r->layout,
                       .pass = r->pass,
                       .what = "depth maps"};
  rc = obs_vk_raster_pipeline(vk, &def, &r->pipe, err);
  vkDestroyShaderModule(vk->dev, vs, NULL);
  return rc;
}

/* One submission: per map, its render pass over its layer with its rows pushed. */
static int draw(depth_run *r, const double (*rows)[3][4], int size, double *ms, obs_err *err) {
  obs_vk *vk = r->vk;
  int rc = obs_vk_queries_reserve(vk, 2, err);
  if (rc || (rc = obs_vk_cmd_begin(vk, "depth maps", err))) return rc;
  VkCommandBuffer cmd = vk->cmd;
  if (vk->ts_bits) {
    vkCmdResetQueryPool(cmd, vk->queries, 0, 2);
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, vk->queries, 0);
  }
  const uint32_t s = (uint32_t)size;
  VkClearValue far = {.depthStencil = {1.0f, 0}};
  VkViewport vp = {0, 0, (float)size, (float)size, 0, 1};
  VkRect2D area = {{0, 0}, {s, s}};
  VkDeviceSize off = 0;
  for (int i = 0; i < r->n; i++) {
    VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                                 .renderPass = r->pass,
                                 .framebuffer = r->fbs[i],
                                 .renderArea = area,
                                 .clearValueCount = 1,
                                 .pClearValues = &far};
    vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
    if (r->nverts) {
      depth_push pc;
      for (int a = 0; a < 3; a++)
        for (int c = 0; c < 4; c++) pc.row[a][c] = (float)rows[i][a][c];
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipe);
      vkCmdSetViewport(cmd, 0, 1, &vp);
      vkCmdSetScissor(cmd, 0, 1, &area);
      vkCmdPushConstants(cmd, r->layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof pc, &pc);
      vkCmdBindVertexBuffers(cmd, 0, 1, &r->vb.buffer, &off);
      vkCmdDraw(cmd, r->nverts, 1, 0, 0);
    }
    vkCmdEndRenderPass(cmd);
  }
  obs_vk_cmd_barrier(cmd);
  if (vk->ts_bits) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, vk->queries, 1);
  char what[96];
  snprintf(what, sizeof what, "%d depth maps of %d^2", r->n, size);
  if ((rc = obs_vk_cmd_submit(vk, what, err))) return rc;
  double t = 0;
  rc = obs_vk_queries_ms(vk, 1, &t, err);
  if (ms) *ms = t;
  return rc;
}

int obs_vk_depth_maps(obs_vk *vk, const obs_geometry *geo, const double centre[3],
                      const double (*rows)[3][4], int n, int size, double texel,
                      obs_vk_texture **out, double *ms, obs_err *err) {
  *out = NULL;
  if (ms) *ms = 0;
  int rc = obs_vk_usable(vk, "depth maps", err);
  if (rc) return rc;
  int max = obs_vk_texture_max_side(vk, OBS_VK_TEXTURE_2D_ARRAY);
  if (n < 1 || size < 1 || n > max || size > max || !(texel > 0))
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: %d depth maps of %d^2 texels of %g (1..%d maps and sides, texels "
                       "> 0)",
                       n, size, texel, max);
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, DEPTH_FORMAT, &fp);
  VkFormatFeatureFlags need =
      VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
  if ((fp.optimalTilingFeatures & need) != need)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: \"%s\" cannot sample a 32-bit float depth image", vk->name);
  depth_run r = {.vk = vk};
  size_t nv = fill_vertices(geo, centre, texel, NULL, &rc);
  if (nv > UINT32_MAX)
    return obs_err_set(err, OBS_ENOMEM, "vulkan: %zu depth-map vertices (at most %u)", nv,
                       UINT32_MAX);
  r.nverts = (uint32_t)nv;
  rc = obs_vk_buffer_create(vk, (VkDeviceSize)(nv ? nv : 1) * 3 * sizeof(float),
                            VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, 1, &r.vb, "depth-map vertices",
                            err);
  if (!rc) {
    fill_vertices(geo, centre, texel, r.vb.map, &rc);
    if (rc) rc = obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory tessellating a sphere");
  }
  if (!rc) rc = make_texture(&r, n, size, out, err);
  if (!rc) rc = obs_vk_single_pass(vk, DEPTH_FORMAT, 1, &r.pass, "depth maps", err);
  if (!rc) rc = make_pipeline(&r, err);
  for (int i = 0; !rc && i < n; i++) {
    VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                   .renderPass = r.pass,
                                   .attachmentCount = 1,
                                   .pAttachments = &r.views[i],
                                   .width = (uint32_t)size,
                                   .height = (uint32_t)size,
                                   .layers = 1};
    rc = obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, &r.fbs[i]),
                      "vkCreateFramebuffer (a depth map)", err);
  }
  if (!rc) rc = draw(&r, rows, size, ms, err);
  if (vk->recording) obs_vk_cmd_abort(vk);
  run_free(&r);
  if (rc) {
    obs_vk_texture_free(vk, *out);
    *out = NULL;
  }
  return rc;
}
