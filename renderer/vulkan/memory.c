/* The Vulkan device layer's memory: allocations, buffers, one-shot command submission, timestamp
 * queries, and float storage images moved through a staging buffer. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "vk_internal.h"

/* ---- memory, buffers, command submission ---- */

int obs_vk_memory_alloc(obs_vk *vk, const VkMemoryRequirements *req, VkMemoryPropertyFlags want,
                        VkMemoryPropertyFlags prefer, VkDeviceMemory *out, const char *what,
                        obs_err *err) {
  *out = VK_NULL_HANDLE;
  if (req->size > vk->max_alloc)
    return obs_err_set(err, OBS_ENOMEM,
                       "vulkan: %s needs %llu bytes, more than the device allows in one "
                       "allocation (%llu)",
                       what, (unsigned long long)req->size, (unsigned long long)vk->max_alloc);
  int best = -1;
  for (uint32_t i = 0; i < vk->memprops.memoryTypeCount; i++) {
    VkMemoryPropertyFlags f = vk->memprops.memoryTypes[i].propertyFlags;
    if (!(req->memoryTypeBits & (1u << i)) || (f & want) != want) continue;
    if (best < 0 || ((f & prefer) == prefer &&
                     (vk->memprops.memoryTypes[best].propertyFlags & prefer) != prefer))
      best = (int)i;
  }
  if (best < 0)
    return obs_err_set(err, OBS_EUNSUPPORTED, "vulkan: %s: no suitable memory type", what);
  VkMemoryAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO,
                             .allocationSize = req->size,
                             .memoryTypeIndex = (uint32_t)best};
  char buf[256];
  snprintf(buf, sizeof buf, "vkAllocateMemory (%llu bytes for %s)", (unsigned long long)req->size,
           what);
  int rc = obs_vk_check(vk, vkAllocateMemory(vk->dev, &ai, NULL, out), buf, err);
  if (rc) *out = VK_NULL_HANDLE;
  return rc;
}

int obs_vk_buffer_create(obs_vk *vk, VkDeviceSize size, VkBufferUsageFlags usage, int host,
                         obs_vk_buffer *out, const char *what, obs_err *err) {
  memset(out, 0, sizeof *out);
  VkBufferCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                           .size = size ? size : 4,
                           .usage = usage,
                           .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
  char buf[256];
  snprintf(buf, sizeof buf, "vkCreateBuffer (%llu bytes for %s)", (unsigned long long)size, what);
  int rc = obs_vk_check(vk, vkCreateBuffer(vk->dev, &ci, NULL, &out->buffer), buf, err);
  if (rc) {
    out->buffer = VK_NULL_HANDLE;
    return rc;
  }
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(vk->dev, out->buffer, &req);
  VkMemoryPropertyFlags want =
      host ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
           : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  VkMemoryPropertyFlags prefer = host ? VK_MEMORY_PROPERTY_HOST_CACHED_BIT : 0;
  if ((rc = obs_vk_memory_alloc(vk, &req, want, prefer, &out->memory, what, err))) goto fail;
  if ((rc = obs_vk_check(vk, vkBindBufferMemory(vk->dev, out->buffer, out->memory, 0),
                         "vkBindBufferMemory", err)))
    goto fail;
  if (host &&
      (rc = obs_vk_check(vk, vkMapMemory(vk->dev, out->memory, 0, VK_WHOLE_SIZE, 0, &out->map),
                         "vkMapMemory", err)))
    goto fail;
  out->size = ci.size;
  return 0;
fail:
  obs_vk_buffer_free(vk, out);
  return rc;
}

void obs_vk_buffer_free(obs_vk *vk, obs_vk_buffer *b) {
  if (!vk || !vk->dev) return;
  vkDestroyBuffer(vk->dev, b->buffer, NULL);
  vkFreeMemory(vk->dev, b->memory, NULL); /* unmaps implicitly */
  memset(b, 0, sizeof *b);
}

void obs_vk_cmd_barrier(VkCommandBuffer cmd) {
  VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                        .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
                        .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 1, &mb, 0, NULL, 0, NULL);
}

int obs_vk_cmd_begin(obs_vk *vk, const char *what, obs_err *err) {
  int rc = obs_vk_usable(vk, what, err);
  if (rc) return rc;
  if ((rc = obs_vk_check(vk, vkResetCommandPool(vk->dev, vk->pool, 0), "vkResetCommandPool", err)))
    return rc;
  VkCommandBufferBeginInfo bi = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                 .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
  if ((rc = obs_vk_check(vk, vkBeginCommandBuffer(vk->cmd, &bi), "vkBeginCommandBuffer", err)))
    return rc;
  vk->recording = 1;
  /* Earlier submissions' writes (uploads, passes) become visible to this one. */
  obs_vk_cmd_barrier(vk->cmd);
  return 0;
}

void obs_vk_cmd_abort(obs_vk *vk) {
  if (!vk->recording) return;
  vk->recording = 0;
  /* Cleanup after an error already reported: these results add nothing the caller can act on. */
  (void)vkEndCommandBuffer(vk->cmd);
  (void)vkResetCommandPool(vk->dev, vk->pool, 0);
}

int obs_vk_cmd_submit(obs_vk *vk, const char *what, obs_err *err) {
  char buf[256];
  vk->recording = 0;
  snprintf(buf, sizeof buf, "vkEndCommandBuffer (%s)", what);
  int rc = obs_vk_check(vk, vkEndCommandBuffer(vk->cmd), buf, err);
  if (rc) {
    (void)vkResetCommandPool(vk->dev, vk->pool, 0);
    return rc;
  }
  VkSubmitInfo si = {
      .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &vk->cmd};
  snprintf(buf, sizeof buf, "vkQueueSubmit (%s)", what);
  if ((rc = obs_vk_check(vk, vkQueueSubmit(vk->queue, 1, &si, vk->fence), buf, err))) return rc;
  snprintf(buf, sizeof buf, "vkWaitForFences (%s)", what);
  rc = obs_vk_check(vk, vkWaitForFences(vk->dev, 1, &vk->fence, VK_TRUE, UINT64_MAX), buf, err);
  /* After a loss the fence may never signal; leave it for obs_vk_close. */
  if (!rc) rc = obs_vk_check(vk, vkResetFences(vk->dev, 1, &vk->fence), "vkResetFences", err);
  return rc;
}

int obs_vk_queries_reserve(obs_vk *vk, uint32_t n, obs_err *err) {
  if (!vk->ts_bits || n <= vk->nqueries) return 0;
  vkDestroyQueryPool(vk->dev, vk->queries, NULL);
  vk->queries = VK_NULL_HANDLE;
  vk->nqueries = 0;
  VkQueryPoolCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
                              .queryType = VK_QUERY_TYPE_TIMESTAMP,
                              .queryCount = n < 64 ? 64 : n};
  int rc = obs_vk_check(vk, vkCreateQueryPool(vk->dev, &ci, NULL, &vk->queries),
                        "vkCreateQueryPool", err);
  if (rc) {
    vk->queries = VK_NULL_HANDLE;
    return rc;
  }
  vk->nqueries = ci.queryCount;
  return 0;
}

int obs_vk_queries_ms(obs_vk *vk, uint32_t npairs, double *ms, obs_err *err) {
  if (!ms || npairs == 0) return 0;
  if (!vk->ts_bits) {
    /* No timestamps on this queue: report zeros rather than invent host-side times. */
    for (uint32_t i = 0; i < npairs; i++) ms[i] = 0;
    return 0;
  }
  uint64_t *t = calloc(2 * (size_t)npairs, sizeof *t);
  if (!t) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory reading timestamps");
  int rc = obs_vk_check(
      vk,
      vkGetQueryPoolResults(vk->dev, vk->queries, 0, 2 * npairs, 2 * npairs * sizeof *t, t,
                            sizeof *t, VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT),
      "vkGetQueryPoolResults", err);
  if (!rc) {
    uint64_t mask = vk->ts_bits >= 64 ? ~(uint64_t)0 : (((uint64_t)1 << vk->ts_bits) - 1);
    for (uint32_t i = 0; i < npairs; i++) {
      uint64_t d = ((t[2 * i + 1] & mask) - (t[2 * i] & mask)) & mask;
      ms[i] = (double)d * (double)vk->props.limits.timestampPeriod * 1e-6;
    }
  }
  free(t);
  return rc;
}

/* ---- images ---- */

void obs_vk_cmd_layout(VkCommandBuffer cmd, VkImage image, VkImageLayout from, VkImageLayout to) {
  /* Full access masks on both sides: these sit between whole passes, where finer scopes would
   * buy nothing measurable and risk a missed hazard. */
  VkImageMemoryBarrier ib = {
      .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
      .srcAccessMask = VK_ACCESS_MEMORY_WRITE_BIT,
      .dstAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT,
      .oldLayout = from,
      .newLayout = to,
      .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
      .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
      .image = image,
      .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, VK_REMAINING_ARRAY_LAYERS}};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 0, NULL, 0, NULL, 1, &ib);
}

static VkFormat image_format(int channels) {
  return channels == 1 ? VK_FORMAT_R32_SFLOAT : VK_FORMAT_R32G32B32A32_SFLOAT;
}

int obs_vk_image_create(obs_vk *vk, int width, int height, int channels, obs_vk_image **out,
                        obs_err *err) {
  return obs_vk_image_create_usage(vk, width, height, channels, 0, out, err);
}

/* A 2D image (depth 0) or a 3D one of `depth` slices. */
static int image_make(obs_vk *vk, int width, int height, int depth, int channels,
                      VkImageUsageFlags extra, obs_vk_image **out, obs_err *err) {
  *out = NULL;
  int rc = obs_vk_usable(vk, "image create", err);
  if (rc) return rc;
  int is3d = depth > 0;
  uint32_t maxdim =
      is3d ? vk->props.limits.maxImageDimension3D : vk->props.limits.maxImageDimension2D;
  char dims[64];
  if (is3d)
    snprintf(dims, sizeof dims, "%dx%dx%d", width, height, depth);
  else
    snprintf(dims, sizeof dims, "%dx%d", width, height);
  if (channels != 1 && channels != 4)
    return obs_err_set(err, OBS_EINVAL, "vulkan: image %s: %d channels (must be 1 or 4)", dims,
                       channels);
  if (width < 1 || height < 1 || (uint32_t)width > maxdim || (uint32_t)height > maxdim ||
      (is3d && (uint32_t)depth > maxdim))
    return obs_err_set(err, OBS_EINVAL, "vulkan: image %s: each side must be 1..%u on \"%s\"", dims,
                       maxdim, vk->name);
  VkFormat fmt = image_format(channels);
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, fmt, &fp);
  VkFormatFeatureFlags need = VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT |
                              VK_FORMAT_FEATURE_TRANSFER_SRC_BIT |
                              VK_FORMAT_FEATURE_TRANSFER_DST_BIT;
  if (extra & VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT) need |= VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT;
  if ((fp.optimalTilingFeatures & need) != need)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: \"%s\" cannot use %d-channel float images as storage images",
                       vk->name, channels);
  VkImageFormatProperties ifp;
  VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                            VK_IMAGE_USAGE_TRANSFER_DST_BIT | extra;
  VkImageType type = is3d ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D;
  if ((rc = obs_vk_check(vk,
                         vkGetPhysicalDeviceImageFormatProperties(
                             vk->phys, fmt, type, VK_IMAGE_TILING_OPTIMAL, usage, 0, &ifp),
                         "vkGetPhysicalDeviceImageFormatProperties", err)))
    return rc;
  VkDeviceSize bytes = (VkDeviceSize)width * (VkDeviceSize)height *
                       (VkDeviceSize)(is3d ? depth : 1) * (VkDeviceSize)channels * 4;
  if (bytes > ifp.maxResourceSize || bytes > vk->max_alloc)
    return obs_err_set(
        err, OBS_ENOMEM,
        "vulkan: image %s with %d channels needs %llu bytes, more than \"%s\" "
        "allows for one image (%llu)",
        dims, channels, (unsigned long long)bytes, vk->name,
        (unsigned long long)(ifp.maxResourceSize < vk->max_alloc ? ifp.maxResourceSize
                                                                 : vk->max_alloc));
  obs_vk_image *img = calloc(1, sizeof *img);
  if (!img) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
  img->format = fmt;
  img->width = width;
  img->height = height;
  img->depth = is3d ? depth : 1;
  img->is3d = is3d;
  img->channels = channels;
  char what[96];
  snprintf(what, sizeof what, "a %s %d-channel image", dims, channels);
  VkImageCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                          .imageType = type,
                          .format = fmt,
                          .extent = {(uint32_t)width, (uint32_t)height, (uint32_t)img->depth},
                          .mipLevels = 1,
                          .arrayLayers = 1,
                          .samples = VK_SAMPLE_COUNT_1_BIT,
                          .tiling = VK_IMAGE_TILING_OPTIMAL,
                          .usage = usage,
                          .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
                          .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  char buf[160];
  snprintf(buf, sizeof buf, "vkCreateImage (%s)", what);
  if ((rc = obs_vk_check(vk, vkCreateImage(vk->dev, &ci, NULL, &img->image), buf, err))) {
    img->image = VK_NULL_HANDLE;
    goto fail;
  }
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(vk->dev, img->image, &req);
  if ((rc = obs_vk_memory_alloc(vk, &req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &img->memory,
                                what, err)))
    goto fail;
  if ((rc = obs_vk_check(vk, vkBindImageMemory(vk->dev, img->image, img->memory, 0),
                         "vkBindImageMemory", err)))
    goto fail;
  VkImageViewCreateInfo vci = {.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
                               .image = img->image,
                               .viewType = is3d ? VK_IMAGE_VIEW_TYPE_3D : VK_IMAGE_VIEW_TYPE_2D,
                               .format = fmt,
                               .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1}};
  if ((rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &img->view),
                         "vkCreateImageView", err))) {
    img->view = VK_NULL_HANDLE;
    goto fail;
  }
  /* Into GENERAL (the layout every call expects) and zeroed, so no caller sees garbage. */
  if ((rc = obs_vk_cmd_begin(vk, "image create", err))) goto fail;
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_UNDEFINED,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  VkClearColorValue zero = {{0, 0, 0, 0}};
  vkCmdClearColorImage(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &zero, 1,
                       &vci.subresourceRange);
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_GENERAL);
  if ((rc = obs_vk_cmd_submit(vk, what, err))) goto fail;
  *out = img;
  return 0;
fail:
  obs_vk_image_free(vk, img);
  return rc;
}

int obs_vk_image_create_usage(obs_vk *vk, int width, int height, int channels,
                              VkImageUsageFlags extra, obs_vk_image **out, obs_err *err) {
  return image_make(vk, width, height, 0, channels, extra, out, err);
}

int obs_vk_image_create_3d(obs_vk *vk, int width, int height, int depth, int channels,
                           obs_vk_image **out, obs_err *err) {
  if (depth < 1) {
    *out = NULL;
    return obs_err_set(err, OBS_EINVAL, "vulkan: image %dx%dx%d: each side must be at least 1",
                       width, height, depth);
  }
  return image_make(vk, width, height, depth, channels, 0, out, err);
}

void obs_vk_image_free(obs_vk *vk, obs_vk_image *img) {
  if (!img) return;
  if (vk && vk->dev) {
    vkDestroyImageView(vk->dev, img->view, NULL);
    vkDestroyImage(vk->dev, img->image, NULL);
    vkFreeMemory(vk->dev, img->memory, NULL);
  }
  free(img);
}

int obs_vk_staging_reserve(obs_vk *vk, VkDeviceSize size, obs_err *err) {
  if (vk->staging.buffer && vk->staging.size >= size) return 0;
  obs_vk_buffer_free(vk, &vk->staging);
  VkDeviceSize cap = 1 << 20;
  while (cap < size) cap *= 2;
  if (cap > vk->max_alloc && size <= vk->max_alloc) cap = size;
  return obs_vk_buffer_create(vk, cap,
                              VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                              1, &vk->staging, "the staging buffer", err);
}

/* Bytes of one z slice of an image (the whole of a 2D one). */
static VkDeviceSize slice_bytes(const obs_vk_image *img) {
  return (VkDeviceSize)img->width * (VkDeviceSize)img->height * (VkDeviceSize)img->channels *
         sizeof(float);
}

/* Slices [z, z + nz) of an image, from or to the start of the staging buffer. */
static VkBufferImageCopy image_region(const obs_vk_image *img, int z, int nz) {
  /* bufferRowLength 0: rows tightly packed, exactly the host layout. */
  return (VkBufferImageCopy){
      .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
      .imageOffset = {0, 0, z},
      .imageExtent = {(uint32_t)img->width, (uint32_t)img->height, (uint32_t)nz}};
}

int obs_vk_slab_slices(VkDeviceSize slice, int depth) {
  int per = slice >= OBS_VK_SLAB_BYTES ? 1 : (int)(OBS_VK_SLAB_BYTES / slice);
  return per < depth ? per : depth;
}

static void image_what(const obs_vk_image *img, const char *verb, char *what, size_t size) {
  if (img->is3d)
    snprintf(what, size, "%s of a %dx%dx%d %d-channel image", verb, img->width, img->height,
             img->depth, img->channels);
  else
    snprintf(what, size, "%s of a %dx%d %d-channel image", verb, img->width, img->height,
             img->channels);
}

int obs_vk_image_upload(obs_vk *vk, obs_vk_image *img, const float *data, obs_err *err) {
  int rc = obs_vk_usable(vk, "image upload", err);
  if (rc) return rc;
  if (!img || !data) return obs_err_set(err, OBS_EINVAL, "vulkan: image upload: no image or data");
  VkDeviceSize slice = slice_bytes(img);
  int per = obs_vk_slab_slices(slice, img->depth);
  if ((rc = obs_vk_staging_reserve(vk, slice * (VkDeviceSize)per, err))) return rc;
  char what[96];
  image_what(img, "upload", what, sizeof what);
  for (int z = 0; z < img->depth && !rc; z += per) {
    int nz = img->depth - z < per ? img->depth - z : per;
    memcpy(vk->staging.map, (const char *)data + slice * (VkDeviceSize)z,
           (size_t)(slice * (VkDeviceSize)nz));
    if ((rc = obs_vk_cmd_begin(vk, "image upload", err))) return rc;
    VkBufferImageCopy reg = image_region(img, z, nz);
    obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_GENERAL,
                      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    vkCmdCopyBufferToImage(vk->cmd, vk->staging.buffer, img->image,
                           VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &reg);
    obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                      VK_IMAGE_LAYOUT_GENERAL);
    rc = obs_vk_cmd_submit(vk, what, err);
  }
  return rc;
}

int obs_vk_image_download(obs_vk *vk, const obs_vk_image *img, float *data, obs_err *err) {
  int rc = obs_vk_usable(vk, "image download", err);
  if (rc) return rc;
  if (!img || !data)
    return obs_err_set(err, OBS_EINVAL, "vulkan: image download: no image or destination");
  VkDeviceSize slice = slice_bytes(img);
  int per = obs_vk_slab_slices(slice, img->depth);
  if ((rc = obs_vk_staging_reserve(vk, slice * (VkDeviceSize)per, err))) return rc;
  char what[96];
  image_what(img, "download", what, sizeof what);
  for (int z = 0; z < img->depth && !rc; z += per) {
    int nz = img->depth - z < per ? img->depth - z : per;
    if ((rc = obs_vk_cmd_begin(vk, "image download", err))) return rc;
    VkBufferImageCopy reg = image_region(img, z, nz);
    obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_GENERAL,
                      VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
    vkCmdCopyImageToBuffer(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                           vk->staging.buffer, 1, &reg);
    obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                      VK_IMAGE_LAYOUT_GENERAL);
    VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                          .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                          .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
    vkCmdPipelineBarrier(vk->cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                         &mb, 0, NULL, 0, NULL);
    if ((rc = obs_vk_cmd_submit(vk, what, err))) return rc;
    memcpy((char *)data + slice * (VkDeviceSize)z, vk->staging.map,
           (size_t)(slice * (VkDeviceSize)nz));
  }
  return rc;
}
