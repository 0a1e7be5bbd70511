/* obscurance_map's depth_peeling estimator on Vulkan (omap_peel.h): the vertices (scene
 * triangles normalised to the bounding sphere, with their patch numbering), the peel and transfer
 * pipelines (shaders/peel.*.glsl, shaders/peel_transfer.comp.glsl), the loop over directions and
 * layers, and the per-patch sums turned into values. The push blocks, the descriptor bindings and
 * the sums' words are layout.h's, which the shaders include too. */
#include "omap_peel.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcerr.h"
#include "obscura/render.h"
#include "obscurance.h"
#include "layout.h"
#include "obscurance_lines.h"
#include "shaders.h"
#include "vk_internal.h"

#define PI 3.14159265358979323846
/* Spheres have no patches; they only occlude and reflect, as UV spheres of this many segments. */
#define SPHERE_LON 48

typedef struct peel_vertex {
  float pos[3], bary[2], nrm[3];
  int32_t first, split, robj;
} peel_vertex;

_Static_assert(sizeof(obs_peel_draw_push) <= OBS_VK_PUSH_MAX &&
                   sizeof(obs_peel_transfer_push) <= OBS_VK_PUSH_MAX,
               "push constants past the pipeline layout's range");

enum { B_VERT, B_ACC, B_REFL, B_COVERED, B_N };
enum { I_L0, I_L1, I_SHOW, I_N };

typedef struct peel {
  obs_vk *vk;
  VkDescriptorSetLayout dsl;
  VkPipelineLayout layout;
  VkRenderPass pass;
  VkPipeline draw, transfer;
  VkDescriptorPool dpool;
  VkDescriptorSet sets[2]; /* [c]: layer c ^ 1 at binding 0 (A, the previous), layer c at 1 */
  obs_vk_buffer buf[B_N];
  obs_vk_image *img[I_N];
  VkImage zimg[2];
  VkDeviceMemory zmem[2];
  VkImageView zview[2];
  VkFramebuffer fb[3];
  uint32_t nverts;
} peel;

/* ---- vertices ---- */

/* One triangle (normalised corners a, b, c) into v[0..2]; returns 0 when it has no area. */
static int put_tri(peel_vertex *v, const double a[3], const double b[3], const double c[3],
                   int32_t first, int32_t split, int32_t robj) {
  double e1[3], e2[3], n[3];
  for (int k = 0; k < 3; k++) e1[k] = b[k] - a[k], e2[k] = c[k] - a[k];
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(l > 0) || !isfinite(l)) return 0;
  const double *p[3] = {a, b, c};
  static const float bary[3][2] = {{0, 0}, {1, 0}, {0, 1}};
  for (int i = 0; i < 3; i++) {
    for (int k = 0; k < 3; k++) v[i].pos[k] = (float)p[i][k], v[i].nrm[k] = (float)(n[k] / l);
    v[i].bary[0] = bary[i][0], v[i].bary[1] = bary[i][1];
    v[i].first = first, v[i].split = split, v[i].robj = robj;
  }
  return 1;
}

/* Scene triangles with their first patch and split (the fragment shader finds the sub-triangle,
 * as the CPU does from a hit's barycentric weights), then the spheres' facets; *n receives the
 * vertex count. Degenerate triangles are left out (the CPU's ray tracer never hits them). */
static peel_vertex *build_vertices(const obs_geometry *geo, const obs_patch_mesh *pm,
                                   const obs_bound_sphere *bs, uint32_t *n) {
  size_t max = 3 * geo->ntris + geo->nspheres * 6 * SPHERE_LON * (SPHERE_LON / 2);
  peel_vertex *v = malloc((max ? max : 1) * sizeof *v);
  if (!v) return NULL;
  size_t k = 0;
  for (size_t m = 0; m < geo->nmeshes; m++) {
    const obs_mesh *me = &geo->meshes[m];
    for (size_t t = 0; t < me->ntris; t++) {
      double q[3][3];
      for (int i = 0; i < 3; i++) {
        const float *p = me->pos + 3 * (size_t)me->idx[3 * t + (size_t)i];
        for (int c = 0; c < 3; c++) q[i][c] = ((double)p[c] - bs->center[c]) / bs->radius;
      }
      size_t tri = obs_patch_mesh_tri(pm, (unsigned)m, (unsigned)t);
      k += 3 * (size_t)put_tri(v + k, q[0], q[1], q[2], (int32_t)pm->first[tri], pm->split[tri],
                               (int32_t)m);
    }
  }
  for (size_t s = 0; s < geo->nspheres; s++) {
    const obs_sphere *sp = &geo->spheres[s];
    const int lat = SPHERE_LON / 2;
    for (int j = 0; j < lat; j++)
      for (int i = 0; i < SPHERE_LON; i++) {
        double c[4][3];
        for (int corner = 0; corner < 4; corner++) {
          double th = PI * (j + (corner >> 1)) / lat, ph = 2 * PI * (i + (corner & 1)) / SPHERE_LON;
          double p[3] = {sp->center[0] + sp->radius * sin(th) * cos(ph),
                         sp->center[1] + sp->radius * cos(th),
                         sp->center[2] + sp->radius * sin(th) * sin(ph)};
          for (int d = 0; d < 3; d++) c[corner][d] = (p[d] - bs->center[d]) / bs->radius;
        }
        int32_t robj = (int32_t)(geo->nmeshes + s);
        /* Outward winding: (0, 1, 2) and (1, 3, 2) run counter-clockwise seen from outside. */
        k += 3 * (size_t)put_tri(v + k, c[0], c[2], c[1], -2, 1, robj);
        k += 3 * (size_t)put_tri(v + k, c[1], c[2], c[3], -2, 1, robj);
      }
  }
  *n = (uint32_t)k;
  return v;
}

/* ---- device objects ---- */

static int create_layouts(peel *pl, obs_err *err) {
  obs_vk *vk = pl->vk;
  VkDescriptorSetLayoutBinding b[OBS_PEEL_BINDINGS];
  for (uint32_t i = 0; i < OBS_PEEL_BINDINGS; i++)
    b[i] = (VkDescriptorSetLayoutBinding){
        i,
        i < OBS_PEEL_IMAGES ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
        1,
        VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT, NULL};
  VkDescriptorSetLayoutCreateInfo dci = {
      .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
      .bindingCount = OBS_PEEL_BINDINGS,
      .pBindings = b};
  int rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &dci, NULL, &pl->dsl),
                        "vkCreateDescriptorSetLayout (depth peeling)", err);
  if (rc) return rc;
  VkPushConstantRange pr = {
      VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT, 0,
      OBS_VK_PUSH_MAX};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 1,
                                     .pSetLayouts = &pl->dsl,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  if ((rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &pl->layout),
                         "vkCreatePipelineLayout (depth peeling)", err)))
    return rc;
  /* The layer is a storage image in GENERAL layout that the render pass clears and writes. */
  VkAttachmentDescription att[2] = {
      {.format = VK_FORMAT_R32G32B32A32_SFLOAT,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_GENERAL,
       .finalLayout = VK_IMAGE_LAYOUT_GENERAL},
      {.format = VK_FORMAT_D32_SFLOAT,
       .samples = VK_SAMPLE_COUNT_1_BIT,
       .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
       .storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
       .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
       .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
       .finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL}};
  VkAttachmentReference cref = {0, VK_IMAGE_LAYOUT_GENERAL};
  VkAttachmentReference zref = {1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub = {.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                              .colorAttachmentCount = 1,
                              .pColorAttachments = &cref,
                              .pDepthStencilAttachment = &zref};
  VkSubpassDependency dep[2];
  obs_vk_pass_deps(dep);
  VkRenderPassCreateInfo rpci = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                 .attachmentCount = 2,
                                 .pAttachments = att,
                                 .subpassCount = 1,
                                 .pSubpasses = &sub,
                                 .dependencyCount = 2,
                                 .pDependencies = dep};
  return obs_vk_check(vk, vkCreateRenderPass(vk->dev, &rpci, NULL, &pl->pass),
                      "vkCreateRenderPass (depth peeling)", err);
}

static int create_draw(peel *pl, obs_err *err) {
  obs_vk *vk = pl->vk;
  VkShaderModule vs, fs;
  int rc = obs_vk_shader(vk, obs_spv_peel_vert, obs_spv_peel_vert_size, &vs, "depth peeling", err);
  if (rc) return rc;
  if ((rc = obs_vk_shader(vk, obs_spv_peel_frag, obs_spv_peel_frag_size, &fs, "depth peeling",
                          err))) {
    vkDestroyShaderModule(vk->dev, vs, NULL);
    return rc;
  }
  VkVertexInputAttributeDescription va[6] = {
      {0, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(peel_vertex, pos)},
      {1, 0, VK_FORMAT_R32G32_SFLOAT, offsetof(peel_vertex, bary)},
      {2, 0, VK_FORMAT_R32G32B32_SFLOAT, offsetof(peel_vertex, nrm)},
      {3, 0, VK_FORMAT_R32_SINT, offsetof(peel_vertex, first)},
      {4, 0, VK_FORMAT_R32_SINT, offsetof(peel_vertex, split)},
      {5, 0, VK_FORMAT_R32_SINT, offsetof(peel_vertex, robj)}};
  obs_vk_raster r = {.vs = vs,
                     .fs = fs,
                     .stride = sizeof(peel_vertex),
                     .attrs = va,
                     .nattrs = 6,
                     .depth_op = VK_COMPARE_OP_LESS,
                     .ncolor = 1,
                     .layout = pl->layout,
                     .pass = pl->pass,
                     .what = "depth peeling"};
  rc = obs_vk_raster_pipeline(vk, &r, &pl->draw, err);
  vkDestroyShaderModule(vk->dev, vs, NULL);
  vkDestroyShaderModule(vk->dev, fs, NULL);
  if (rc) return rc;
  VkShaderModule cs;
  if ((rc = obs_vk_shader(vk, obs_spv_peel_transfer_comp, obs_spv_peel_transfer_comp_size, &cs,
                          "depth peeling", err)))
    return rc;
  VkComputePipelineCreateInfo cci = {
      .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
      .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                .module = cs,
                .pName = "main"},
      .layout = pl->layout};
  rc = obs_vk_check(vk,
                    vkCreateComputePipelines(vk->dev, VK_NULL_HANDLE, 1, &cci, NULL, &pl->transfer),
                    "vkCreateComputePipelines (depth peeling)", err);
  vkDestroyShaderModule(vk->dev, cs, NULL);
  return rc;
}

/* The framebuffer of colour image `img` with depth buffer z (made on first use, of img's size). */
static int create_target(peel *pl, int z, obs_vk_image *img, VkFramebuffer *fb, obs_err *err) {
  obs_vk *vk = pl->vk;
  int rc = 0;
  if (pl->zview[z]) goto framebuffer;
  VkImageCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                          .imageType = VK_IMAGE_TYPE_2D,
                          .format = VK_FORMAT_D32_SFLOAT,
                          .extent = {(uint32_t)img->width, (uint32_t)img->height, 1},
                          .mipLevels = 1,
                          .arrayLayers = 1,
                          .samples = VK_SAMPLE_COUNT_1_BIT,
                          .tiling = VK_IMAGE_TILING_OPTIMAL,
                          .usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                          .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  rc = obs_vk_check(vk, vkCreateImage(vk->dev, &ci, NULL, &pl->zimg[z]),
                    "vkCreateImage (depth peeling depth buffer)", err);
  if (rc) return rc;
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(vk->dev, pl->zimg[z], &req);
  if ((rc = obs_vk_memory_alloc(vk, &req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &pl->zmem[z],
                                "a depth peeling depth buffer", err)) ||
      (rc = obs_vk_check(vk, vkBindImageMemory(vk->dev, pl->zimg[z], pl->zmem[z], 0),
                         "vkBindImageMemory (depth peeling)", err)))
    return rc;
  VkImageViewCreateInfo vci = {.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
                               .image = pl->zimg[z],
                               .viewType = VK_IMAGE_VIEW_TYPE_2D,
                               .format = VK_FORMAT_D32_SFLOAT,
                               .subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, 0, 1}};
  if ((rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &pl->zview[z]),
                         "vkCreateImageView (depth peeling)", err)))
    return rc;
framebuffer:;
  VkImageView views[2] = {img->view, pl->zview[z]};
  VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = pl->pass,
                                 .attachmentCount = 2,
                                 .pAttachments = views,
                                 .width = (uint32_t)img->width,
                                 .height = (uint32_t)img->height,
                                 .layers = 1};
  return obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, fb),
                      "vkCreateFramebuffer (depth peeling)", err);
}

static int create_sets(peel *pl, obs_err *err) {
  obs_vk *vk = pl->vk;
  VkDescriptorPoolSize sizes[2] = {
      {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 2 * OBS_PEEL_IMAGES},
      {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2 * (OBS_PEEL_BINDINGS - OBS_PEEL_IMAGES)}};
  VkDescriptorPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = 2,
                                    .poolSizeCount = 2,
                                    .pPoolSizes = sizes};
  int rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &pci, NULL, &pl->dpool),
                        "vkCreateDescriptorPool (depth peeling)", err);
  if (rc) return rc;
  VkDescriptorSetLayout l[2] = {pl->dsl, pl->dsl};
  VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                    .descriptorPool = pl->dpool,
                                    .descriptorSetCount = 2,
                                    .pSetLayouts = l};
  if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, pl->sets),
                         "vkAllocateDescriptorSets (depth peeling)", err)))
    return rc;
  for (int c = 0; c < 2; c++) {
    VkDescriptorImageInfo ii[OBS_PEEL_BINDINGS] = {
        [OBS_PEEL_B_LAYER_A] = {VK_NULL_HANDLE, pl->img[c ^ 1]->view, VK_IMAGE_LAYOUT_GENERAL},
        [OBS_PEEL_B_LAYER_B] = {VK_NULL_HANDLE, pl->img[c]->view, VK_IMAGE_LAYOUT_GENERAL}};
    VkDescriptorBufferInfo bi[OBS_PEEL_BINDINGS] = {
        [OBS_PEEL_B_ACC] = {pl->buf[B_ACC].buffer, 0, VK_WHOLE_SIZE},
        [OBS_PEEL_B_REFL] = {pl->buf[B_REFL].buffer, 0, VK_WHOLE_SIZE},
        [OBS_PEEL_B_COVERED] = {pl->buf[B_COVERED].buffer, 0, VK_WHOLE_SIZE}};
    VkWriteDescriptorSet w[OBS_PEEL_BINDINGS];
    for (uint32_t i = 0; i < OBS_PEEL_BINDINGS; i++)
      w[i] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                    .dstSet = pl->sets[c],
                                    .dstBinding = i,
                                    .descriptorCount = 1,
                                    .descriptorType = i < OBS_PEEL_IMAGES
                                                          ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                                          : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                    .pImageInfo = i < OBS_PEEL_IMAGES ? &ii[i] : NULL,
                                    .pBufferInfo = i < OBS_PEEL_IMAGES ? NULL : &bi[i]};
    vkUpdateDescriptorSets(vk->dev, OBS_PEEL_BINDINGS, w, 0, NULL);
  }
  return 0;
}

static void peel_free(peel *pl) {
  obs_vk *vk = pl->vk;
  if (!vk) return;
  for (int i = 0; i < 3; i++)
    if (pl->fb[i]) vkDestroyFramebuffer(vk->dev, pl->fb[i], NULL);
  for (int z = 0; z < 2; z++) {
    if (pl->zview[z]) vkDestroyImageView(vk->dev, pl->zview[z], NULL);
    if (pl->zimg[z]) vkDestroyImage(vk->dev, pl->zimg[z], NULL);
    if (pl->zmem[z]) vkFreeMemory(vk->dev, pl->zmem[z], NULL);
  }
  for (int i = 0; i < I_N; i++) obs_vk_image_free(vk, pl->img[i]);
  for (int i = 0; i < B_N; i++) obs_vk_buffer_free(vk, &pl->buf[i]);
  if (pl->dpool) vkDestroyDescriptorPool(vk->dev, pl->dpool, NULL);
  if (pl->draw) vkDestroyPipeline(vk->dev, pl->draw, NULL);
  if (pl->transfer) vkDestroyPipeline(vk->dev, pl->transfer, NULL);
  if (pl->pass) vkDestroyRenderPass(vk->dev, pl->pass, NULL);
  if (pl->layout) vkDestroyPipelineLayout(vk->dev, pl->layout, NULL);
  if (pl->dsl) vkDestroyDescriptorSetLayout(vk->dev, pl->dsl, NULL);
  memset(pl, 0, sizeof *pl);
}

/* ---- recording ---- */

/* Draws every triangle into framebuffer `fb` (image `img`) with `dp`, reading layer set `set`. */
static void record_draw(peel *pl, VkFramebuffer fb, const obs_vk_image *img, int set,
                        const obs_peel_draw_push *dp) {
  VkCommandBuffer cmd = pl->vk->cmd;
  VkClearValue clear[2] = {{.color = {{-1.0f, -1.0f, 1.0f, 1.0f}}}, {.depthStencil = {1.0f, 0}}};
  VkRenderPassBeginInfo rbi = {
      .sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
      .renderPass = pl->pass,
      .framebuffer = fb,
      .renderArea = {{0, 0}, {(uint32_t)img->width, (uint32_t)img->height}},
      .clearValueCount = 2,
      .pClearValues = clear};
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pl->draw);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pl->layout, 0, 1, &pl->sets[set], 0,
                          NULL);
  vkCmdPushConstants(
      cmd, pl->layout,
      VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT, 0,
      sizeof *dp, dp);
  VkViewport vp = {0, 0, (float)img->width, (float)img->height, 0, 1};
  VkRect2D sc = {{0, 0}, {(uint32_t)img->width, (uint32_t)img->height}};
  vkCmdSetViewport(cmd, 0, 1, &vp);
  vkCmdSetScissor(cmd, 0, 1, &sc);
  VkDeviceSize off = 0;
  vkCmdBindVertexBuffers(cmd, 0, 1, &pl->buf[B_VERT].buffer, &off);
  if (pl->nverts) vkCmdDraw(cmd, pl->nverts, 1, 0, 0);
  vkCmdEndRenderPass(cmd);
}

static void record_transfer(peel *pl, int set, const obs_peel_transfer_push *tp, uint32_t res) {
  VkCommandBuffer cmd = pl->vk->cmd;
  obs_vk_cmd_barrier(cmd);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pl->transfer);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pl->layout, 0, 1, &pl->sets[set], 0,
                          NULL);
  vkCmdPushConstants(
      cmd, pl->layout,
      VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT, 0,
      sizeof *tp, tp);
  vkCmdDispatch(cmd, (res + 7) / 8, (res + 7) / 8, 1);
  /* The covered count and the sums are read by the host after the wait. */
  VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                        .srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT,
                        .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                       &mb, 0, NULL, 0, NULL);
}

/* The orthographic view of bundle b in normalised coordinates: pixel (i, j)'s centre on line
 * (i, j) of the bundle's grid, window depth 0 at the lines' start and 1 at their end. */
static void bundle_view(const obs_bundle *b, uint32_t res, obs_peel_draw_push *dp) {
  memset(dp, 0, sizeof *dp);
  double sx = (1 - 2 * b->offset[0]) / res, sy = (1 - 2 * b->offset[1]) / res;
  for (int c = 0; c < 3; c++) {
    dp->m[4 * c + 0] = (float)b->u[c];
    dp->m[4 * c + 1] = (float)b->v[c];
    dp->m[4 * c + 2] = (float)(0.5 * b->dir[c]);
    dp->dir[c] = (float)b->dir[c];
  }
  dp->m[12] = (float)sx, dp->m[13] = (float)sy, dp->m[14] = 0.5f, dp->m[15] = 1.0f;
  dp->eps = OBS_PEEL_EPS;
}

/* The scene camera in normalised coordinates, as renderer/vulkan's G-buffer projects it (pixel
 * centres where the ray caster shoots), with a near and far plane around the bounding sphere. */
static void camera_view(const obs_camera_rig *rig, const obs_geometry *geo,
                        const obs_bound_sphere *bs, obs_peel_draw_push *dp) {
  memset(dp, 0, sizeof *dp);
  double c0[3], dist = 0, r = bs->radius;
  for (int k = 0; k < 3; k++) {
    c0[k] = bs->center[k] + geo->origin[k] - rig->origin[k];
    dist += c0[k] * c0[k];
  }
  dist = sqrt(dist);
  double far = dist + 1.01 * r, near = fmax(dist - 1.01 * r, rig->ortho ? 0.0 : far * 1e-5);
  /* Rows of view space in q: x_v = r q.right + c0.right, and so on. */
  double rows[3][4];
  const double *ax[3] = {rig->right, rig->up, rig->forward};
  for (int i = 0; i < 3; i++) {
    rows[i][3] = 0;
    for (int k = 0; k < 3; k++) rows[i][k] = r * ax[i][k], rows[i][3] += c0[k] * ax[i][k];
  }
  double out[4][4];
  for (int k = 0; k < 4; k++) {
    out[0][k] = rows[0][k] / rig->half_w;
    out[1][k] = -rows[1][k] / rig->half_h;
    if (rig->ortho) {
      out[2][k] = (rows[2][k] - (k == 3 ? near : 0)) / (far - near);
      out[3][k] = k == 3;
    } else {
      out[2][k] = far / (far - near) * rows[2][k] - (k == 3 ? near * far / (far - near) : 0);
      out[3][k] = rows[2][k];
    }
  }
  for (int row = 0; row < 4; row++)
    for (int col = 0; col < 4; col++) dp->m[4 * col + row] = (float)out[row][col];
  dp->eps = -1.0f;
}

/* ---- the estimator ---- */

static int peel_setup(peel *pl, obs_vk *vk, const obs_geometry *geo, const obs_patch_mesh *pm,
                      const obs_bound_sphere *bs, const float (*refl)[4], uint32_t res,
                      const obs_camera_rig *show, obs_err *err) {
  memset(pl, 0, sizeof *pl);
  pl->vk = vk;
  peel_vertex *v = build_vertices(geo, pm, bs, &pl->nverts);
  if (!v) return obs_err_set(err, OBS_ENOMEM, "obscurance_map: out of memory for vertices");
  size_t nrefl = geo->nmeshes + geo->nspheres;
  VkBufferUsageFlags sb = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  int rc = obs_vk_buffer_create(vk, (VkDeviceSize)pl->nverts * sizeof *v,
                                VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, 1, &pl->buf[B_VERT],
                                "depth peeling vertices", err);
  if (!rc) memcpy(pl->buf[B_VERT].map, v, (size_t)pl->nverts * sizeof *v);
  free(v);
  if (!rc)
    rc = obs_vk_buffer_create(vk,
                              (VkDeviceSize)(pm->count ? pm->count : 1) * OBS_PEEL_ACC_WORDS * 4,
                              sb, 1, &pl->buf[B_ACC], "depth peeling per-patch sums", err);
  if (!rc)
    rc = obs_vk_buffer_create(vk, (VkDeviceSize)(nrefl ? nrefl : 1) * 16, sb, 1, &pl->buf[B_REFL],
                              "depth peeling reflectivities", err);
  if (!rc)
    rc = obs_vk_buffer_create(vk, OBS_PEEL_LAYERS_MAX * sizeof(uint32_t), sb, 1,
                              &pl->buf[B_COVERED], "depth peeling counts", err);
  if (rc) return rc;
  memset(pl->buf[B_ACC].map, 0, (size_t)pl->buf[B_ACC].size);
  memcpy(pl->buf[B_REFL].map, refl, nrefl * 16);
  for (int i = 0; i < 2 && !rc; i++)
    rc = obs_vk_image_create_usage(vk, (int)res, (int)res, 4, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                                   &pl->img[i], err);
  if (!rc && show)
    rc = obs_vk_image_create_usage(vk, show->width, show->height, 4,
                                   VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT, &pl->img[I_SHOW], err);
  if (!rc) rc = create_layouts(pl, err);
  if (!rc) rc = create_draw(pl, err);
  if (!rc) rc = create_sets(pl, err);
  for (int i = 0; i < 2 && !rc; i++) rc = create_target(pl, 0, pl->img[i], &pl->fb[i], err);
  if (!rc && show) rc = create_target(pl, 1, pl->img[I_SHOW], &pl->fb[2], err);
  return rc;
}

/* One direction: layers until one covers no pixel. Layer 0 is peeled against nothing and
 * transfers against the virtual empty layer in front (the other image, cleared to background);
 * the empty layer that ends the loop is the virtual one behind the last. Layers are recorded in
 * batches of *batch (the previous direction's count: one submit and wait per direction as a
 * rule); each counts its covered pixels into its own slot, and layers recorded past the first
 * empty one peel nothing (every fragment lies at or before the background's depth 1) and
 * transfer nothing. */
static int peel_direction(peel *pl, const obs_bundle *b, uint32_t res,
                          const obs_peel_transfer_push *tp, int *batch, uint64_t *layers,
                          int *capped, obs_err *err) {
  obs_vk *vk = pl->vk;
  obs_peel_draw_push dp;
  bundle_view(b, res, &dp);
  uint32_t *covered = pl->buf[B_COVERED].map;
  for (int first = 0; first < OBS_PEEL_LAYERS_MAX;) {
    int last = first + *batch;
    if (last > OBS_PEEL_LAYERS_MAX) last = OBS_PEEL_LAYERS_MAX;
    memset(covered + first, 0, (size_t)(last - first) * sizeof *covered);
    int rc = obs_vk_cmd_begin(vk, "depth peeling", err);
    if (rc) return rc;
    for (int layer = first; layer < last; layer++) {
      int cur = layer & 1;
      if (layer == 0) {
        VkClearColorValue bg = {{-1.0f, -1.0f, -1.0f, -1.0f}};
        VkImageSubresourceRange range = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        vkCmdClearColorImage(vk->cmd, pl->img[cur ^ 1]->image, VK_IMAGE_LAYOUT_GENERAL, &bg, 1,
                             &range);
      }
      if (layer) obs_vk_cmd_barrier(vk->cmd);
      dp.eps = layer == 0 ? -1.0f : OBS_PEEL_EPS;
      record_draw(pl, pl->fb[cur], pl->img[cur], cur, &dp);
      obs_peel_transfer_push t = *tp;
      t.layer = (uint32_t)layer;
      record_transfer(pl, cur, &t, res);
    }
    if ((rc = obs_vk_cmd_submit(vk, "depth peeling", err))) return rc;
    for (int layer = first; layer < last; layer++) {
      (*layers)++;
      if (!covered[layer]) {
        *batch = layer + 1 > 2 ? layer + 1 : 2;
        return 0;
      }
    }
    first = last;
    *batch *= 2;
  }
  (*capped)++;
  return 0;
}

/* The patch ids each pixel of the camera sees: the nearest layer of a camera view. */
static int peel_show(peel *pl, const obs_camera_rig *rig, const obs_geometry *geo,
                     const obs_bound_sphere *bs, int32_t *ids, obs_err *err) {
  obs_vk *vk = pl->vk;
  obs_peel_draw_push dp;
  camera_view(rig, geo, bs, &dp);
  int rc = obs_vk_cmd_begin(vk, "depth peeling: patch ids", err);
  if (rc) return rc;
  record_draw(pl, pl->fb[2], pl->img[I_SHOW], 0, &dp);
  obs_vk_cmd_barrier(vk->cmd);
  if ((rc = obs_vk_cmd_submit(vk, "depth peeling: patch ids", err))) return rc;
  size_t npx = (size_t)rig->width * (size_t)rig->height;
  float *px = malloc(npx * 4 * sizeof *px);
  if (!px) return obs_err_set(err, OBS_ENOMEM, "obscurance_map: out of memory for patch ids");
  rc = obs_vk_image_download(vk, pl->img[I_SHOW], px, err);
  for (size_t i = 0; !rc && i < npx; i++) ids[i] = px[4 * i] >= 0 ? (int32_t)px[4 * i] : -1;
  free(px);
  return rc;
}

static uint64_t word64(const uint32_t *w) { return (uint64_t)w[0] | (uint64_t)w[1] << 32; }

/* One group of directions' sums (obs_bundle_groups) from the device into every patch's groups,
 * the device's sums cleared for the next group. */
static void fold_group(uint32_t *acc, int64_t count, obs_mcerr_ratio *groups) {
  for (int64_t i = 0; i < count; i++) {
    uint32_t *a = acc + (size_t)i * OBS_PEEL_ACC_WORDS;
    double n = (double)word64(a + OBS_PEEL_ACC_SAMPLES);
    for (int c = 0; c < 3; c++)
      obs_mcerr_ratio_add(&groups[3 * (size_t)i + (size_t)c],
                          (double)word64(a + OBS_PEEL_ACC_SUM + 2 * c) / OBS_PEEL_FIXED_ONE, n);
    memset(a, 0, OBS_PEEL_ACC_WORDS * sizeof *a);
  }
}

/* The groups' sums into values and standard errors, as the CPU's bundles make them (there without
 * the test of an open patch: an agreeing patch has the floor). */
static int finish(const obs_mcerr_ratio *groups, const double bg[3], obs_omap_peel *out) {
  obs_patch_err *e = calloc(out->pm.count ? (size_t)out->pm.count : 1, sizeof *e);
  if (!e) return OBS_ENOMEM;
  for (int64_t i = 0; i < out->pm.count; i++) {
    const obs_mcerr_ratio *g = groups + 3 * (size_t)i;
    double n = g[0].n;
    out->n[i] = (uint64_t)n;
    e[i] = (obs_patch_err){{0, 0, 0}, n, 0, 0};
    if (!(n > 0)) {
      for (int c = 0; c < 3; c++) out->w[3 * i + c] = (float)bg[c];
      out->unsampled += out->pm.area[i] > 0;
      continue;
    }
    for (int c = 0; c < 3; c++) {
      out->w[3 * i + c] = (float)fmin(1.0, fmax(0.0, g[c].s / n));
      e[i].var[c] = obs_mcerr_ratio_var(&g[c]);
    }
    e[i].df = g[0].groups - 1.0;
    e[i].floor = (float)obs_mcerr_floor((uint32_t)fmin(n, 4e9), 1.0);
  }
  obs_patch_mesh_errors(&out->pm, e, out->se);
  free(e);
  return 0;
}

/* Reflectivities of every mesh, then every sphere, from their objects (0 without material). */
static float (*reflectivities(const obs_scene *scene, const obs_geometry *geo))[4] {
  size_t n = geo->nmeshes + geo->nspheres;
  float(*r)[4] = calloc(n ? n : 1, sizeof *r);
  if (!r) return NULL;
  for (size_t k = 0; k < n; k++) {
    size_t oi = k < geo->nmeshes ? geo->meshes[k].object : geo->spheres[k - geo->nmeshes].object;
    const obs_object *o = &scene->objects[oi];
    if (!o->has_material) continue;
    r[k][0] = (float)o->reflectivity.x;
    r[k][1] = (float)o->reflectivity.y;
    r[k][2] = (float)o->reflectivity.z;
  }
  return r;
}

static float clamp_float(double x) { return x < 3e38 ? (float)x : 3e38f; }

int obs_omap_peel_compute(obs_vk *vk, const obs_scene *scene, const obs_geometry *geo,
                          const obs_obscurance_map_params *p, const obs_camera_rig *show,
                          const atomic_int *cancel, obs_progress_fn progress, void *progress_user,
                          obs_omap_peel *out, double *device_ms, obs_err *err) {
  memset(out, 0, sizeof *out);
  obs_obscurance_env env;
  int rc = obs_obscurance_env_compute(scene, geo, &env, err);
  if (!rc)
    rc = obs_patch_mesh_build(geo, p->patch_size, "/technique/params/patch_size", &out->pm, err);
  if (rc) return rc;
  memcpy(out->r_ave, env.r_ave, sizeof out->r_ave);
  size_t n1 = out->pm.count ? (size_t)out->pm.count : 1;
  out->w = malloc(3 * n1 * sizeof *out->w);
  out->se = malloc(3 * n1 * sizeof *out->se);
  out->n = malloc(n1 * sizeof *out->n);
  if (show) out->ids = malloc((size_t)show->width * (size_t)show->height * sizeof *out->ids);
  float(*refl)[4] = reflectivities(scene, geo);
  if (!out->w || !out->se || !out->n || (show && !out->ids) || !refl) {
    free(refl);
    obs_omap_peel_free(out);
    return obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory for %lld patches",
                       scene->name, (long long)out->pm.count);
  }
  obs_bound_sphere bs;
  obs_bound_sphere_of(geo, &bs);
  /* Distances in window depth: the depth range is the lines' length, 2 radii. */
  const double range = 2 * bs.radius;
  obs_peel_transfer_push tp = {.dmax = clamp_float(p->d_max / range),
                      .tau = clamp_float(p->tau * range),
                      .falloff = p->falloff,
                      .bleed = p->color_bleeding,
                      .res = (int32_t)p->bundle_resolution};
  for (int c = 0; c < 3; c++) {
    double v = p->color_bleeding ? env.r_ave[c] : 1.0;
    tp.bg_s[c] = (uint32_t)(v * OBS_PEEL_FIXED_ONE + 0.5);
    tp.bg_q[c] = (uint32_t)(v * v * OBS_PEEL_FIXED_ONE + 0.5);
  }
  peel pl;
  double t0 = obs_now_ms();
  rc = peel_setup(&pl, vk, geo, &out->pm, &bs, (const float(*)[4])refl, p->bundle_resolution, show,
                  err);
  free(refl);
  int batch = 8;
  obs_mcerr_ratio *groups = calloc(3 * n1, sizeof *groups);
  if (!rc && !groups)
    rc = obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory", scene->name);
  for (uint32_t k = 0, g = 0; !rc && k < p->directions; k++) {
    if (cancel && atomic_load(cancel)) {
      rc = obs_err_set(err, OBS_ECANCELED, "%s: render cancelled", scene->name);
      break;
    }
    obs_bundle b;
    obs_bundle_get(&bs, p->seed, p->directions, k, p->bundle_resolution, &b);
    rc =
        peel_direction(&pl, &b, p->bundle_resolution, &tp, &batch, &out->layers, &out->capped, err);
    if (!rc && k + 1 == obs_bundle_group_first(p->directions, g + 1)) {
      fold_group(pl.buf[B_ACC].map, out->pm.count, groups);
      g++;
    }
    if (progress) progress(progress_user, (k + 1.0) / p->directions);
  }
  if (!rc && show) rc = peel_show(&pl, show, geo, &bs, out->ids, err);
  if (!rc) {
    double bg[3];
    for (int c = 0; c < 3; c++) bg[c] = p->color_bleeding ? env.r_ave[c] : 1.0;
    if (finish(groups, bg, out))
      rc = obs_err_set(err, OBS_ENOMEM, "%s: obscurance_map: out of memory", scene->name);
  }
  free(groups);
  if (device_ms) *device_ms = obs_now_ms() - t0;
  peel_free(&pl);
  if (rc) obs_omap_peel_free(out);
  return rc;
}

void obs_omap_peel_free(obs_omap_peel *m) {
  if (!m) return;
  obs_patch_mesh_free(&m->pm);
  free(m->w);
  free(m->se);
  free(m->n);
  free(m->ids);
  memset(m, 0, sizeof *m);
}
