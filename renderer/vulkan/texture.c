/* The Vulkan device layer's read-only inputs of compute passes: sampled float textures (3D images
 * and 2D array images, each with its own clamp-to-edge sampler), small parameter buffers, and the
 * descriptor set 1 and pipeline layout that passes reading them use. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vk_internal.h"

int obs_vk_tex_layout(obs_vk *vk, int ntextures, int data, VkDescriptorSetLayout *set,
                      VkPipelineLayout *out, obs_err *err) {
  VkDescriptorSetLayout *sl = &vk->tex_set_layout[ntextures][data != 0];
  VkPipelineLayout *pl = &vk->tex_compute_layout[ntextures][data != 0];
  if (*pl) {
    *set = *sl;
    *out = *pl;
    return 0;
  }
  VkDescriptorSetLayoutBinding b[OBS_VK_MAX_TEXTURES + 1];
  uint32_t n = 0;
  for (; n < (uint32_t)ntextures; n++)
    b[n] =
        (VkDescriptorSetLayoutBinding){.binding = n,
                                       .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                       .descriptorCount = 1,
                                       .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
  if (data)
    b[n++] = (VkDescriptorSetLayoutBinding){.binding = OBS_VK_MAX_TEXTURES,
                                            .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                            .descriptorCount = 1,
                                            .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
  VkDescriptorSetLayoutCreateInfo lci = {
      .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
      .bindingCount = n,
      .pBindings = b};
  int rc;
  if (!*sl && (rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &lci, NULL, sl),
                                 "vkCreateDescriptorSetLayout (textures)", err))) {
    *sl = VK_NULL_HANDLE;
    return rc;
  }
  /* Set 0 and the push-constant range exactly as the plain compute layout has them. */
  VkDescriptorSetLayout sets[2] = {vk->set_layout, *sl};
  VkPushConstantRange pr = {.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT, .size = OBS_VK_PUSH_MAX};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 2,
                                     .pSetLayouts = sets,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  if ((rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, pl),
                         "vkCreatePipelineLayout (textures)", err))) {
    *pl = VK_NULL_HANDLE;
    return rc;
  }
  *set = *sl;
  *out = *pl;
  return 0;
}

/* ---- textures ---- */

static VkFormat tex_format(int channels) {
  return channels == 1 ? VK_FORMAT_R32_SFLOAT : VK_FORMAT_R32G32B32A32_SFLOAT;
}

int obs_vk_texture_filterable(obs_vk *vk, int channels) {
  if (!vk || (channels != 1 && channels != 4)) return 0;
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, tex_format(channels), &fp);
  return (fp.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT) != 0;
}

int obs_vk_texture_max_side(const obs_vk *vk, obs_vk_texture_type type) {
  const VkPhysicalDeviceLimits *l = &vk->props.limits;
  if (type == OBS_VK_TEXTURE_3D)
    return (int)(l->maxImageDimension3D > 65536 ? 65536 : l->maxImageDimension3D);
  uint32_t m = l->maxImageDimension2D < l->maxImageArrayLayers ? l->maxImageDimension2D
                                                               : l->maxImageArrayLayers;
  return (int)(m > 65536 ? 65536 : m);
}

/* The description checked against the device before anything is allocated. */
static int check_desc(obs_vk *vk, const obs_vk_texture_desc *d, VkImageCreateInfo *ci,
                      obs_err *err) {
  int is3d = d->type == OBS_VK_TEXTURE_3D, max = obs_vk_texture_max_side(vk, d->type);
  if (d->channels != 1 && d->channels != 4)
    return obs_err_set(err, OBS_EINVAL, "vulkan: texture: %d channels (must be 1 or 4)",
                       d->channels);
  if (d->width < 1 || d->height < 1 || d->depth < 1 || d->width > max || d->height > max ||
      d->depth > max)
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: %s texture %dx%dx%d: each side must be 1..%d on \"%s\"",
                       is3d ? "3D" : "2D array", d->width, d->height, d->depth, max, vk->name);
  if (d->linear && !obs_vk_texture_filterable(vk, d->channels))
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: \"%s\" cannot filter %d-channel float textures linearly", vk->name,
                       d->channels);
  *ci = (VkImageCreateInfo){
      .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
      .imageType = is3d ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D,
      .format = tex_format(d->channels),
      .extent = {(uint32_t)d->width, (uint32_t)d->height, is3d ? (uint32_t)d->depth : 1},
      .mipLevels = 1,
      .arrayLayers = is3d ? 1 : (uint32_t)d->depth,
      .samples = VK_SAMPLE_COUNT_1_BIT,
      .tiling = VK_IMAGE_TILING_OPTIMAL,
      .usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT,
      .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
      .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  VkImageFormatProperties ifp;
  int rc = obs_vk_check(vk,
                        vkGetPhysicalDeviceImageFormatProperties(
                            vk->phys, ci->format, ci->imageType, ci->tiling, ci->usage, 0, &ifp),
                        "vkGetPhysicalDeviceImageFormatProperties (texture)", err);
  if (rc) return rc;
  VkDeviceSize bytes = (VkDeviceSize)d->width * (VkDeviceSize)d->height * (VkDeviceSize)d->depth *
                       (VkDeviceSize)d->channels * 4;
  VkDeviceSize lim = ifp.maxResourceSize < vk->max_alloc ? ifp.maxResourceSize : vk->max_alloc;
  if (bytes > lim)
    return obs_err_set(err, OBS_ENOMEM,
                       "vulkan: texture %dx%dx%d with %d channels needs %llu bytes, more than "
                       "\"%s\" allows for one image (%llu)",
                       d->width, d->height, d->depth, d->channels, (unsigned long long)bytes,
                       vk->name, (unsigned long long)lim);
  return 0;
}

/* The view and sampler of a texture whose image is bound. */
static int make_view(obs_vk *vk, obs_vk_texture *t, obs_err *err) {
  int is3d = t->desc.type == OBS_VK_TEXTURE_3D;
  VkImageViewCreateInfo vci = {
      .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
      .image = t->image,
      .viewType = is3d ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D_ARRAY,
      .format = t->format,
      .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, VK_REMAINING_ARRAY_LAYERS}};
  int rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &t->view),
                        "vkCreateImageView (texture)", err);
  if (rc) {
    t->view = VK_NULL_HANDLE;
    return rc;
  }
  return obs_vk_texture_sampler(vk, t, err);
}

int obs_vk_texture_sampler(obs_vk *vk, obs_vk_texture *t, obs_err *err) {
  VkFilter f = t->desc.linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST;
  VkSamplerCreateInfo sci = {.sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
                             .magFilter = f,
                             .minFilter = f,
                             .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
                             .addressModeU = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                             .addressModeV = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                             .addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE,
                             .maxLod = 0};
  int rc = obs_vk_check(vk, vkCreateSampler(vk->dev, &sci, NULL, &t->sampler), "vkCreateSampler",
                        err);
  if (rc) t->sampler = VK_NULL_HANDLE;
  return rc;
}

int obs_vk_texture_create(obs_vk *vk, const obs_vk_texture_desc *d, obs_vk_texture **out,
                          obs_err *err) {
  *out = NULL;
  int rc = obs_vk_usable(vk, "texture create", err);
  if (rc) return rc;
  VkImageCreateInfo ci;
  if ((rc = check_desc(vk, d, &ci, err))) return rc;
  obs_vk_texture *t = calloc(1, sizeof *t);
  if (!t) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
  t->desc = *d;
  t->format = ci.format;
  char what[96];
  snprintf(what, sizeof what, "a %dx%dx%d %d-channel texture", d->width, d->height, d->depth,
           d->channels);
  char buf[160];
  snprintf(buf, sizeof buf, "vkCreateImage (%s)", what);
  if ((rc = obs_vk_check(vk, vkCreateImage(vk->dev, &ci, NULL, &t->image), buf, err))) {
    t->image = VK_NULL_HANDLE;
    goto fail;
  }
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(vk->dev, t->image, &req);
  if ((rc = obs_vk_memory_alloc(vk, &req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &t->memory, what,
                                err)))
    goto fail;
  if ((rc = obs_vk_check(vk, vkBindImageMemory(vk->dev, t->image, t->memory, 0),
                         "vkBindImageMemory (texture)", err)))
    goto fail;
  if ((rc = make_view(vk, t, err))) goto fail;
  /* Zeroed and in the layout passes read it in, so no pass sees garbage. */
  if ((rc = obs_vk_cmd_begin(vk, "texture create", err))) goto fail;
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  VkClearColorValue zero = {{0, 0, 0, 0}};
  VkImageSubresourceRange all = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, VK_REMAINING_ARRAY_LAYERS};
  vkCmdClearColorImage(vk->cmd, t->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1, &all);
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  if ((rc = obs_vk_cmd_submit(vk, what, err))) goto fail;
  *out = t;
  return 0;
fail:
  obs_vk_texture_free(vk, t);
  return rc;
}

void obs_vk_texture_free(obs_vk *vk, obs_vk_texture *t) {
  if (!t) return;
  if (vk && vk->dev) {
    vkDestroySampler(vk->dev, t->sampler, NULL);
    vkDestroyImageView(vk->dev, t->view, NULL);
    vkDestroyImage(vk->dev, t->image, NULL);
    vkFreeMemory(vk->dev, t->memory, NULL);
  }
  free(t);
}

/* One slab: slices [z, z + nz) of the box, already in the staging buffer. */
static int upload_slab(obs_vk *vk, obs_vk_texture *t, const int at[3], const int size[3], int z,
                       int nz, obs_err *err) {
  int is3d = t->desc.type == OBS_VK_TEXTURE_3D;
  VkBufferImageCopy reg = {
      .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, is3d ? 0 : (uint32_t)(at[2] + z),
                           is3d ? 1 : (uint32_t)nz},
      .imageOffset = {at[0], at[1], is3d ? at[2] + z : 0},
      .imageExtent = {(uint32_t)size[0], (uint32_t)size[1], is3d ? (uint32_t)nz : 1}};
  int rc = obs_vk_cmd_begin(vk, "texture upload", err);
  if (rc) return rc;
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  vkCmdCopyBufferToImage(vk->cmd, vk->staging.buffer, t->image,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &reg);
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  char what[128];
  snprintf(what, sizeof what, "upload of %dx%dx%d texels into a texture", size[0], size[1], nz);
  return obs_vk_cmd_submit(vk, what, err);
}

int obs_vk_texture_upload(obs_vk *vk, obs_vk_texture *t, const int at[3], const int size[3],
                          const float *data, obs_err *err) {
  int rc = obs_vk_usable(vk, "texture upload", err);
  if (rc) return rc;
  if (!t || !data)
    return obs_err_set(err, OBS_EINVAL, "vulkan: texture upload: no texture or data");
  const int dims[3] = {t->desc.width, t->desc.height, t->desc.depth};
  for (int a = 0; a < 3; a++)
    if (at[a] < 0 || size[a] < 1 || size[a] > dims[a] - at[a])
      return obs_err_set(err, OBS_EINVAL,
                         "vulkan: texture upload: box of %dx%dx%d at (%d, %d, %d) is not inside "
                         "the %dx%dx%d texture",
                         size[0], size[1], size[2], at[0], at[1], at[2], dims[0], dims[1], dims[2]);
  VkDeviceSize slice = (VkDeviceSize)size[0] * (VkDeviceSize)size[1] *
                       (VkDeviceSize)t->desc.channels * sizeof(float);
  int per = obs_vk_slab_slices(slice, size[2]);
  if ((rc = obs_vk_staging_reserve(vk, slice * (VkDeviceSize)per, err))) return rc;
  for (int z = 0; z < size[2] && !rc; z += per) {
    int nz = size[2] - z < per ? size[2] - z : per;
    memcpy(vk->staging.map, (const char *)data + slice * (VkDeviceSize)z,
           (size_t)(slice * (VkDeviceSize)nz));
    rc = upload_slab(vk, t, at, size, z, nz, err);
  }
  return rc;
}

int obs_vk_texture_copy_image(obs_vk *vk, obs_vk_texture *t, int layer, const obs_vk_image *img,
                              obs_err *err) {
  int rc = obs_vk_usable(vk, "texture copy", err);
  if (rc) return rc;
  if (!t || !img || t->desc.type != OBS_VK_TEXTURE_2D_ARRAY || img->is3d ||
      img->width != t->desc.width || img->height != t->desc.height ||
      img->channels != t->desc.channels || layer < 0 || layer >= t->desc.depth)
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: texture copy: the image does not match layer %d of the texture",
                       layer);
  if ((rc = obs_vk_cmd_begin(vk, "texture copy", err))) return rc;
  VkImageCopy reg = {.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                     .dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, (uint32_t)layer, 1},
                     .extent = {(uint32_t)img->width, (uint32_t)img->height, 1}};
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_GENERAL,
                    VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  vkCmdCopyImage(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t->image,
                 VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &reg);
  obs_vk_cmd_layout(vk->cmd, t->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                    VK_IMAGE_LAYOUT_GENERAL);
  return obs_vk_cmd_submit(vk, "copy of an image into a texture layer", err);
}

/* ---- parameter buffers ---- */

int obs_vk_data_create(obs_vk *vk, const void *bytes, size_t size, obs_vk_data **out,
                       obs_err *err) {
  *out = NULL;
  int rc = obs_vk_usable(vk, "data create", err);
  if (rc) return rc;
  if (!bytes || size == 0 || size % 4)
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: data buffer of %zu bytes (a positive multiple of 4)", size);
  if (size > vk->props.limits.maxStorageBufferRange)
    return obs_err_set(err, OBS_ENOMEM,
                       "vulkan: data buffer of %zu bytes is more than \"%s\" lets a shader read "
                       "(%u)",
                       size, vk->name, vk->props.limits.maxStorageBufferRange);
  obs_vk_data *d = calloc(1, sizeof *d);
  if (!d) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
  if ((rc = obs_vk_buffer_create(
           vk, size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, 0,
           &d->buf, "a data buffer", err)) ||
      (rc = obs_vk_staging_reserve(vk, size, err)))
    goto fail;
  memcpy(vk->staging.map, bytes, size);
  if ((rc = obs_vk_cmd_begin(vk, "data upload", err))) goto fail;
  VkBufferCopy reg = {0, 0, size};
  vkCmdCopyBuffer(vk->cmd, vk->staging.buffer, d->buf.buffer, 1, &reg);
  if ((rc = obs_vk_cmd_submit(vk, "data upload", err))) goto fail;
  *out = d;
  return 0;
fail:
  obs_vk_data_free(vk, d);
  return rc;
}

void obs_vk_data_free(obs_vk *vk, obs_vk_data *d) {
  if (!d) return;
  obs_vk_buffer_free(vk, &d->buf);
  free(d);
}
