/* The Vulkan device layer's compute passes: pipelines cached per shader and pipeline layout, and
 * runs of passes with per-pass device timings. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "vk_internal.h"

/* ---- compute passes ---- */

/* Whether a pass reads set 1 (textures or data). */
static int uses_set1(const obs_vk_pass *p) { return p->ntextures > 0 || p->data != NULL; }

static int pipeline_for(obs_vk *vk, const obs_vk_pass *p, VkPipelineLayout layout,
                        VkPipeline *out, obs_err *err) {
  for (int i = 0; i < vk->npipes; i++)
    if (vk->pipes[i].spirv == p->spirv && vk->pipes[i].layout == layout) {
      *out = vk->pipes[i].pipeline;
      return 0;
    }
  if (vk->npipes == vk->cappipes) {
    int cap = vk->cappipes ? 2 * vk->cappipes : 16;
    obs_vk_pipe *np = realloc(vk->pipes, (size_t)cap * sizeof *np);
    if (!np) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
    vk->pipes = np;
    vk->cappipes = cap;
  }
  VkShaderModuleCreateInfo mci = {.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
                                  .codeSize = p->spirv_size,
                                  .pCode = p->spirv};
  VkShaderModule mod;
  char buf[160];
  snprintf(buf, sizeof buf, "vkCreateShaderModule (pass \"%s\")", p->name);
  int rc = obs_vk_check(vk, vkCreateShaderModule(vk->dev, &mci, NULL, &mod), buf, err);
  if (rc) return rc;
  VkComputePipelineCreateInfo ci = {
      .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
      .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                .module = mod,
                .pName = "main"},
      .layout = layout};
  VkPipeline pipe;
  snprintf(buf, sizeof buf, "vkCreateComputePipelines (pass \"%s\")", p->name);
  rc = obs_vk_check(vk, vkCreateComputePipelines(vk->dev, VK_NULL_HANDLE, 1, &ci, NULL, &pipe), buf,
                    err);
  vkDestroyShaderModule(vk->dev, mod, NULL);
  if (rc) return rc;
  vk->pipes[vk->npipes++] = (obs_vk_pipe){p->spirv, layout, pipe};
  *out = pipe;
  return 0;
}

static int check_pass(const obs_vk *vk, const obs_vk_pass *p, int i, obs_err *err) {
  const char *name = p->name ? p->name : "(unnamed)";
  const uint32_t *lim = vk->props.limits.maxComputeWorkGroupCount;
  if (!p->spirv || p->spirv_size < 20 || p->spirv_size % 4 || p->spirv[0] != 0x07230203u)
    return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": not SPIR-V (%zu bytes)", i, name,
                       p->spirv_size);
  if (p->nimages < 0 || p->nimages > OBS_VK_MAX_BINDINGS)
    return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": %d images (at most %d)", i, name,
                       p->nimages, OBS_VK_MAX_BINDINGS);
  for (int k = 0; k < p->nimages; k++)
    if (!p->images[k])
      return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": image %d is NULL", i, name, k);
  if (p->ntextures < 0 || p->ntextures > OBS_VK_MAX_TEXTURES)
    return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": %d textures (at most %d)", i,
                       name, p->ntextures, OBS_VK_MAX_TEXTURES);
  for (int k = 0; k < p->ntextures; k++)
    if (!p->textures[k])
      return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": texture %d is NULL", i, name,
                         k);
  if (p->push_size > OBS_VK_PUSH_MAX || p->push_size % 4 || (p->push_size && !p->push))
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: pass %d \"%s\": push constants of %u bytes (a multiple of 4, at "
                       "most %u, with data)",
                       i, name, p->push_size, OBS_VK_PUSH_MAX);
  if (p->groups_x < 1 || p->groups_y < 1 || p->groups_x > lim[0] || p->groups_y > lim[1] ||
      p->groups_z > lim[2])
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: pass %d \"%s\": %ux%ux%u work groups (each 1..%ux%ux%u)", i, name,
                       p->groups_x, p->groups_y, p->groups_z ? p->groups_z : 1, lim[0], lim[1],
                       lim[2]);
  return 0;
}

/* Writes pass p's images into its set 0 and, when it has them, its textures and data into its
 * set 1. */
static void write_sets(obs_vk *vk, const obs_vk_pass *p, VkDescriptorSet set0,
                       VkDescriptorSet set1) {
  VkDescriptorImageInfo ii[OBS_VK_MAX_BINDINGS + OBS_VK_MAX_TEXTURES];
  VkDescriptorBufferInfo bi;
  VkWriteDescriptorSet w[OBS_VK_MAX_BINDINGS + OBS_VK_MAX_TEXTURES + 1];
  uint32_t n = 0;
  for (int k = 0; k < p->nimages; k++, n++) {
    ii[n] = (VkDescriptorImageInfo){.imageView = p->images[k]->view,
                                    .imageLayout = VK_IMAGE_LAYOUT_GENERAL};
    w[n] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                  .dstSet = set0,
                                  .dstBinding = (uint32_t)k,
                                  .descriptorCount = 1,
                                  .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                  .pImageInfo = &ii[n]};
  }
  for (int k = 0; k < p->ntextures; k++, n++) {
    ii[n] = (VkDescriptorImageInfo){.sampler = p->textures[k]->sampler,
                                    .imageView = p->textures[k]->view,
                                    .imageLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    w[n] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                  .dstSet = set1,
                                  .dstBinding = (uint32_t)k,
                                  .descriptorCount = 1,
                                  .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                  .pImageInfo = &ii[n]};
  }
  if (p->data) {
    bi = (VkDescriptorBufferInfo){p->data->buf.buffer, 0, VK_WHOLE_SIZE};
    w[n++] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                    .dstSet = set1,
                                    .dstBinding = OBS_VK_MAX_TEXTURES,
                                    .descriptorCount = 1,
                                    .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                    .pBufferInfo = &bi};
  }
  if (n) vkUpdateDescriptorSets(vk->dev, n, w, 0, NULL);
}

/* One descriptor pool for the run and each pass's sets: sets[2 i] (set 0) and, for passes that
 * read textures or data, sets[2 i + 1] (set 1, of layout set1[i]). */
static int alloc_sets(obs_vk *vk, const obs_vk_pass *passes, int npasses,
                      const VkDescriptorSetLayout *set1, VkDescriptorPool *dpool,
                      VkDescriptorSet *sets, obs_err *err) {
  uint32_t nimg = 0, ntex = 0, nbuf = 0, nset1 = 0;
  for (int i = 0; i < npasses; i++) {
    nimg += (uint32_t)passes[i].nimages;
    ntex += (uint32_t)passes[i].ntextures;
    nbuf += passes[i].data != NULL;
    nset1 += (uint32_t)uses_set1(&passes[i]);
  }
  VkDescriptorPoolSize ps[3] = {{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, nimg ? nimg : 1}};
  uint32_t nps = 1;
  if (ntex) ps[nps++] = (VkDescriptorPoolSize){VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, ntex};
  if (nbuf) ps[nps++] = (VkDescriptorPoolSize){VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, nbuf};
  VkDescriptorPoolCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = (uint32_t)npasses + nset1,
                                    .poolSizeCount = nps,
                                    .pPoolSizes = ps};
  int rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &dci, NULL, dpool),
                        "vkCreateDescriptorPool", err);
  if (rc) {
    *dpool = VK_NULL_HANDLE;
    return rc;
  }
  for (int i = 0; i < npasses; i++) {
    VkDescriptorSetLayout layouts[2] = {vk->set_layout, set1[i]};
    VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                      .descriptorPool = *dpool,
                                      .descriptorSetCount = uses_set1(&passes[i]) ? 2 : 1,
                                      .pSetLayouts = layouts};
    if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, &sets[2 * i]),
                           "vkAllocateDescriptorSets", err)))
      return rc;
    write_sets(vk, &passes[i], sets[2 * i], sets[2 * i + 1]);
  }
  return 0;
}

int obs_vk_run(obs_vk *vk, const obs_vk_pass *passes, int npasses, double *ms_per_pass,
               obs_err *err) {
  int rc = obs_vk_usable(vk, "run", err);
  if (rc) return rc;
  if (npasses <= 0) return 0;
  if (!passes) return obs_err_set(err, OBS_EINVAL, "vulkan: run: no passes");
  VkPipeline *pipes = calloc((size_t)npasses, sizeof *pipes);
  VkPipelineLayout *layouts = calloc((size_t)npasses, sizeof *layouts);
  VkDescriptorSetLayout *set1 = calloc((size_t)npasses, sizeof *set1);
  VkDescriptorSet *sets = calloc(2 * (size_t)npasses, sizeof *sets);
  VkDescriptorPool dpool = VK_NULL_HANDLE;
  if (!pipes || !layouts || !set1 || !sets) {
    rc = obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for %d passes", npasses);
    goto done;
  }
  for (int i = 0; i < npasses; i++) {
    if ((rc = check_pass(vk, &passes[i], i, err))) goto done;
    layouts[i] = vk->compute_layout;
    if (uses_set1(&passes[i]) &&
        (rc = obs_vk_tex_layout(vk, passes[i].ntextures, passes[i].data != NULL, &set1[i],
                                &layouts[i], err)))
      goto done;
    if ((rc = pipeline_for(vk, &passes[i], layouts[i], &pipes[i], err))) goto done;
  }
  if ((rc = alloc_sets(vk, passes, npasses, set1, &dpool, sets, err))) goto done;
  /* A CPU device (lavapipe) runs dispatches on its own threads after the bottom-of-pipe
   * timestamp is written, so its timestamps read ~0: there, each pass is submitted on its own and
   * timed on the host, where the work really happens. GPUs use timestamp queries in one submit. */
  int host_timing = vk->props.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU || !vk->ts_bits;
  int nsubmits = host_timing ? npasses : 1;
  if (!host_timing && (rc = obs_vk_queries_reserve(vk, 2 * (uint32_t)npasses, err))) goto done;
  for (int s = 0; s < nsubmits; s++) {
    int first = host_timing ? s : 0, last = host_timing ? s + 1 : npasses;
    const char *nm = passes[first].name ? passes[first].name : "(unnamed)";
    if ((rc = obs_vk_cmd_begin(vk, nm, err))) goto done;
    VkCommandBuffer cmd = vk->cmd;
    if (!host_timing) vkCmdResetQueryPool(cmd, vk->queries, 0, 2 * (uint32_t)npasses);
    for (int i = first; i < last; i++) {
      const obs_vk_pass *p = &passes[i];
      /* Also at the start of a later submit: the previous pass's writes must be visible. */
      if (i) obs_vk_cmd_barrier(cmd);
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipes[i]);
      vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layouts[i], 0,
                              uses_set1(p) ? 2 : 1, &sets[2 * i], 0, NULL);
      if (p->push_size)
        vkCmdPushConstants(cmd, layouts[i], VK_SHADER_STAGE_COMPUTE_BIT, 0, p->push_size,
                           p->push);
      if (!host_timing)
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, vk->queries, 2 * (uint32_t)i);
      vkCmdDispatch(cmd, p->groups_x, p->groups_y, p->groups_z ? p->groups_z : 1);
      if (!host_timing)
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, vk->queries,
                            2 * (uint32_t)i + 1);
    }
    char what[160];
    snprintf(what, sizeof what, "compute pass%s starting with \"%s\"",
             last - first == 1 ? "" : "es", nm);
    double t0 = obs_now_ms();
    if ((rc = obs_vk_cmd_submit(vk, what, err))) goto done;
    if (host_timing && ms_per_pass) ms_per_pass[s] = obs_now_ms() - t0;
  }
  if (!host_timing) rc = obs_vk_queries_ms(vk, (uint32_t)npasses, ms_per_pass, err);
done:
  if (dpool) vkDestroyDescriptorPool(vk->dev, dpool, NULL);
  free(pipes);
  free(layouts);
  free(set1);
  free(sets);
  return rc;
}
