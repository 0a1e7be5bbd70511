/* The Vulkan device layer: a headless instance and device, float storage images moved through a
 * staging buffer, and compute passes with cached pipelines and per-pass device timings. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "vk_internal.h"
#include "techniques.h"

#define NO_DEVICE_HINT "install mesa-vulkan-drivers for lavapipe"
#define VALIDATION_LAYER "VK_LAYER_KHRONOS_validation"
#define PUSH_MAX 128u

const char *obs_vk_result_name(VkResult r) {
  // clang-format off
  switch (r) {
#define C(x) case x: return #x;
    C(VK_SUCCESS) C(VK_NOT_READY) C(VK_TIMEOUT) C(VK_EVENT_SET) C(VK_EVENT_RESET) C(VK_INCOMPLETE)
    C(VK_ERROR_OUT_OF_HOST_MEMORY) C(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    C(VK_ERROR_INITIALIZATION_FAILED) C(VK_ERROR_DEVICE_LOST) C(VK_ERROR_MEMORY_MAP_FAILED)
    C(VK_ERROR_LAYER_NOT_PRESENT) C(VK_ERROR_EXTENSION_NOT_PRESENT)
    C(VK_ERROR_FEATURE_NOT_PRESENT) C(VK_ERROR_INCOMPATIBLE_DRIVER) C(VK_ERROR_TOO_MANY_OBJECTS)
    C(VK_ERROR_FORMAT_NOT_SUPPORTED) C(VK_ERROR_FRAGMENTED_POOL) C(VK_ERROR_OUT_OF_POOL_MEMORY)
    C(VK_ERROR_INVALID_EXTERNAL_HANDLE) C(VK_ERROR_FRAGMENTATION)
    C(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS) C(VK_ERROR_UNKNOWN)
#undef C
    default: return "VkResult (unknown)";
  }
  // clang-format on
}

int obs_vk_check(obs_vk *vk, VkResult r, const char *what, obs_err *err) {
  if (r == VK_SUCCESS) return 0;
  int code = OBS_EINTERNAL;
  const char *hint = "";
  if (r == VK_ERROR_OUT_OF_HOST_MEMORY || r == VK_ERROR_OUT_OF_DEVICE_MEMORY ||
      r == VK_ERROR_OUT_OF_POOL_MEMORY || r == VK_ERROR_FRAGMENTED_POOL ||
      r == VK_ERROR_FRAGMENTATION) {
    code = OBS_ENOMEM;
  } else if (r == VK_ERROR_DEVICE_LOST) {
    /* Nothing submitted to a lost device completes; later calls must fail fast, not hang. */
    if (vk) vk->lost = 1;
    hint = " (the device is lost: close it and open it again)";
  }
  return obs_err_set(err, code, "vulkan: %s failed: %s%s", what, obs_vk_result_name(r), hint);
}

int obs_vk_usable(obs_vk *vk, const char *what, obs_err *err) {
  if (!vk) return obs_err_set(err, OBS_EINVAL, "vulkan: %s: no device", what);
  if (vk->lost)
    return obs_err_set(err, OBS_EINTERNAL, "vulkan: %s: device \"%s\" was lost earlier", what,
                       vk->name);
  return 0;
}

static VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                 VkDebugUtilsMessageTypeFlagsEXT type,
                                                 const VkDebugUtilsMessengerCallbackDataEXT *data,
                                                 void *user) {
  (void)type;
  obs_vk *vk = user;
  if (!(severity & (VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                    VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT)))
    return VK_FALSE;
  atomic_fetch_add(&vk->messages, 1u);
  fprintf(stderr, "obscura: vulkan validation %s: %s\n",
          severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning",
          data && data->pMessage ? data->pMessage : "(no message)");
  return VK_FALSE;
}

static int has_layer(const char *name) {
  uint32_t n = 0;
  if (vkEnumerateInstanceLayerProperties(&n, NULL) != VK_SUCCESS || n == 0) return 0;
  VkLayerProperties *p = calloc(n, sizeof *p);
  if (!p) return 0;
  int found = 0;
  if (vkEnumerateInstanceLayerProperties(&n, p) == VK_SUCCESS)
    for (uint32_t i = 0; i < n && !found; i++) found = !strcmp(p[i].layerName, name);
  free(p);
  return found;
}

static int create_instance(obs_vk *vk, int validation, obs_err *err) {
  uint32_t version = 0;
  if (vkEnumerateInstanceVersion(&version) != VK_SUCCESS || version < VK_API_VERSION_1_1)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: the Vulkan loader is older than 1.1 (" NO_DEVICE_HINT ")");
  VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
                           .pApplicationName = "obscura",
                           .pEngineName = "obscura",
                           .apiVersion = VK_API_VERSION_1_1};
  /* Headless: no surface extensions; debug utils only to count validation messages. */
  const char *layers[] = {VALIDATION_LAYER};
  const char *exts[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
  VkDebugUtilsMessengerCreateInfoEXT msg = {
      .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
      .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                         VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
      .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT,
      .pfnUserCallback = on_message,
      .pUserData = vk};
  VkInstanceCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                             .pApplicationInfo = &app};
  if (validation) {
    if (!has_layer(VALIDATION_LAYER))
      return obs_err_set(err, OBS_EUNSUPPORTED,
                         "vulkan: validation was requested but the layer " VALIDATION_LAYER
                         " is not installed (install vulkan-validationlayers)");
    ci.enabledLayerCount = 1;
    ci.ppEnabledLayerNames = layers;
    ci.enabledExtensionCount = 1;
    ci.ppEnabledExtensionNames = exts;
    /* Chained here too, so messages from instance creation and destruction are counted. */
    ci.pNext = &msg;
  }
  VkResult r = vkCreateInstance(&ci, NULL, &vk->instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: no Vulkan device found (" NO_DEVICE_HINT ")");
  if (r != VK_SUCCESS) {
    vk->instance = VK_NULL_HANDLE;
    return obs_vk_check(vk, r, "vkCreateInstance", err);
  }
  if (validation) {
    PFN_vkCreateDebugUtilsMessengerEXT create =
        (PFN_vkCreateDebugUtilsMessengerEXT)(void (*)(void))vkGetInstanceProcAddr(
            vk->instance, "vkCreateDebugUtilsMessengerEXT");
    vk->destroy_messenger =
        (PFN_vkDestroyDebugUtilsMessengerEXT)(void (*)(void))vkGetInstanceProcAddr(
            vk->instance, "vkDestroyDebugUtilsMessengerEXT");
    if (!create || !vk->destroy_messenger)
      return obs_err_set(err, OBS_EUNSUPPORTED, "vulkan: VK_EXT_debug_utils is not available");
    msg.pNext = NULL;
    if ((r = create(vk->instance, &msg, NULL, &vk->messenger)))
      return obs_vk_check(vk, r, "vkCreateDebugUtilsMessengerEXT", err);
  }
  return 0;
}

/* A queue family that can both draw (the G-buffer) and dispatch (every technique). */
static int pick_family(VkPhysicalDevice pd, uint32_t *family, uint32_t *ts_bits) {
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, NULL);
  VkQueueFamilyProperties *q = calloc(n ? n : 1, sizeof *q);
  if (!q) return 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, q);
  int found = 0;
  for (uint32_t i = 0; i < n && !found; i++) {
    VkQueueFlags need = VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT;
    if ((q[i].queueFlags & need) == need && q[i].queueCount > 0) {
      *family = i;
      *ts_bits = q[i].timestampValidBits;
      found = 1;
    }
  }
  free(q);
  return found;
}

static int pick_device(obs_vk *vk, const char *filter, obs_err *err) {
  uint32_t n = 0;
  VkResult r = vkEnumeratePhysicalDevices(vk->instance, &n, NULL);
  if (r != VK_SUCCESS && r != VK_INCOMPLETE)
    return obs_vk_check(vk, r, "vkEnumeratePhysicalDevices", err);
  if (n == 0)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: no Vulkan device found (" NO_DEVICE_HINT ")");
  VkPhysicalDevice *pds = calloc(n, sizeof *pds);
  if (!pds) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory listing devices");
  r = vkEnumeratePhysicalDevices(vk->instance, &n, pds);
  if (r != VK_SUCCESS && r != VK_INCOMPLETE) {
    free(pds);
    return obs_vk_check(vk, r, "vkEnumeratePhysicalDevices", err);
  }
  char names[1024] = "";
  size_t len = 0;
  int found = 0;
  for (uint32_t i = 0; i < n && !found; i++) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(pds[i], &p);
    int w = snprintf(names + len, sizeof names - len, "%s\"%s\"", i ? ", " : "", p.deviceName);
    if (w > 0 && (size_t)w < sizeof names - len) len += (size_t)w;
    if (filter && *filter && !strstr(p.deviceName, filter)) continue;
    if (p.apiVersion < VK_API_VERSION_1_1) continue;
    if (!pick_family(pds[i], &vk->family, &vk->ts_bits)) continue;
    vk->phys = pds[i];
    vk->props = p;
    found = 1;
  }
  free(pds);
  if (!found) {
    if (filter && *filter)
      return obs_err_set(err, OBS_EUNSUPPORTED,
                         "vulkan: no Vulkan 1.1 device with graphics and compute has a name "
                         "containing \"%s\" (devices: %s)",
                         filter, names);
    return obs_err_set(
        err, OBS_EUNSUPPORTED,
        "vulkan: no Vulkan 1.1 device with graphics and compute (devices: %s; " NO_DEVICE_HINT ")",
        names);
  }
  snprintf(vk->name, sizeof vk->name, "%s", vk->props.deviceName);
  vkGetPhysicalDeviceMemoryProperties(vk->phys, &vk->memprops);
  VkPhysicalDeviceMaintenance3Properties m3 = {
      .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
  VkPhysicalDeviceProperties2 p2 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2,
                                    .pNext = &m3};
  vkGetPhysicalDeviceProperties2(vk->phys, &p2);
  vk->max_alloc = m3.maxMemoryAllocationSize ? m3.maxMemoryAllocationSize : (VkDeviceSize)1 << 31;
  if (!vk->props.limits.timestampComputeAndGraphics) vk->ts_bits = 0;
  return 0;
}

static int create_device(obs_vk *vk, obs_err *err) {
  float prio = 1.0f;
  VkDeviceQueueCreateInfo q = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                               .queueFamilyIndex = vk->family,
                               .queueCount = 1,
                               .pQueuePriorities = &prio};
  VkDeviceCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                           .queueCreateInfoCount = 1,
                           .pQueueCreateInfos = &q};
  int rc;
  if ((rc = obs_vk_check(vk, vkCreateDevice(vk->phys, &ci, NULL, &vk->dev), "vkCreateDevice",
                         err))) {
    vk->dev = VK_NULL_HANDLE;
    return rc;
  }
  vkGetDeviceQueue(vk->dev, vk->family, 0, &vk->queue);
  VkCommandPoolCreateInfo pci = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
                                 .flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT,
                                 .queueFamilyIndex = vk->family};
  if ((rc = obs_vk_check(vk, vkCreateCommandPool(vk->dev, &pci, NULL, &vk->pool),
                         "vkCreateCommandPool", err)))
    return rc;
  VkCommandBufferAllocateInfo cai = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                     .commandPool = vk->pool,
                                     .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                     .commandBufferCount = 1};
  if ((rc = obs_vk_check(vk, vkAllocateCommandBuffers(vk->dev, &cai, &vk->cmd),
                         "vkAllocateCommandBuffers", err)))
    return rc;
  VkFenceCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  if ((rc = obs_vk_check(vk, vkCreateFence(vk->dev, &fci, NULL, &vk->fence), "vkCreateFence", err)))
    return rc;
  VkDescriptorSetLayoutBinding b[OBS_VK_MAX_BINDINGS];
  for (uint32_t i = 0; i < OBS_VK_MAX_BINDINGS; i++)
    b[i] = (VkDescriptorSetLayoutBinding){.binding = i,
                                          .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                          .descriptorCount = 1,
                                          .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
  VkDescriptorSetLayoutCreateInfo lci = {
      .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
      .bindingCount = OBS_VK_MAX_BINDINGS,
      .pBindings = b};
  if ((rc = obs_vk_check(vk, vkCreateDescriptorSetLayout(vk->dev, &lci, NULL, &vk->set_layout),
                         "vkCreateDescriptorSetLayout", err)))
    return rc;
  VkPushConstantRange pr = {.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT, .size = PUSH_MAX};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .setLayoutCount = 1,
                                     .pSetLayouts = &vk->set_layout,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  return obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &vk->compute_layout),
                      "vkCreatePipelineLayout", err);
}

int obs_vk_open(obs_vk **out, const char *filter, int validation, obs_err *err) {
  *out = NULL;
  obs_vk *vk = calloc(1, sizeof *vk);
  if (!vk) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
  atomic_init(&vk->messages, 0u);
  vk->validation = validation != 0;
  if (!filter) filter = getenv("OBSCURA_VK_DEVICE");
  int rc = create_instance(vk, vk->validation, err);
  if (!rc) rc = pick_device(vk, filter, err);
  if (!rc) rc = create_device(vk, err);
  if (rc) {
    obs_vk_close(vk);
    return rc;
  }
  *out = vk;
  return 0;
}

void obs_vk_close(obs_vk *vk) {
  if (!vk) return;
  if (vk->dev) {
    /* A lost device reports the loss here too; everything is destroyed regardless. */
    (void)vkDeviceWaitIdle(vk->dev);
    for (int i = 0; i < vk->npipes; i++) vkDestroyPipeline(vk->dev, vk->pipes[i].pipeline, NULL);
    vkDestroyPipeline(vk->dev, vk->gb_pipeline, NULL);
    vkDestroyPipelineLayout(vk->dev, vk->gb_layout, NULL);
    vkDestroyRenderPass(vk->dev, vk->gb_pass, NULL);
    vkDestroyPipelineLayout(vk->dev, vk->compute_layout, NULL);
    vkDestroyDescriptorSetLayout(vk->dev, vk->set_layout, NULL);
    obs_vk_buffer_free(vk, &vk->staging);
    vkDestroyQueryPool(vk->dev, vk->queries, NULL);
    vkDestroyFence(vk->dev, vk->fence, NULL);
    vkDestroyCommandPool(vk->dev, vk->pool, NULL);
    vkDestroyDevice(vk->dev, NULL);
  }
  if (vk->instance) {
    if (vk->messenger) vk->destroy_messenger(vk->instance, vk->messenger, NULL);
    vkDestroyInstance(vk->instance, NULL);
  }
  free(vk->pipes);
  free(vk);
}

static pthread_mutex_t shared_mu = PTHREAD_MUTEX_INITIALIZER;
static obs_vk *shared[2]; /* [validation] */
static pthread_once_t shared_once = PTHREAD_ONCE_INIT;

/* Runs before the drivers' own destructors (those are registered earlier, at load). */
static void shared_close(void) {
  for (int i = 0; i < 2; i++) {
    obs_vk_close(shared[i]);
    shared[i] = NULL;
  }
}
static void shared_init(void) { atexit(shared_close); }

int obs_vk_acquire(obs_vk **out, int validation, obs_err *err) {
  *out = NULL;
  pthread_once(&shared_once, shared_init);
  pthread_mutex_lock(&shared_mu);
  obs_vk **slot = &shared[validation ? 1 : 0];
  if (!*slot) {
    int rc = obs_vk_open(slot, NULL, validation, err);
    if (rc) {
      pthread_mutex_unlock(&shared_mu);
      return rc;
    }
  }
  atomic_store(&(*slot)->messages, 0u);
  *out = *slot;
  return 0;
}

void obs_vk_release(obs_vk *vk) {
  if (!vk) return;
  if (vk->lost) {
    for (int i = 0; i < 2; i++)
      if (shared[i] == vk) shared[i] = NULL;
    obs_vk_close(vk);
  }
  pthread_mutex_unlock(&shared_mu);
}

const char *obs_vk_device_name(const obs_vk *vk) { return vk ? vk->name : ""; }

uint32_t obs_vk_validation_messages(const obs_vk *vk) {
  return vk ? atomic_load(&((obs_vk *)vk)->messages) : 0;
}

static int available;
static char available_name[256];
static pthread_once_t available_once = PTHREAD_ONCE_INIT;

static void probe(void) {
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  available = obs_vk_open(&vk, NULL, 0, &err) == 0;
  if (available) snprintf(available_name, sizeof available_name, "%s", obs_vk_device_name(vk));
  obs_vk_close(vk);
  obs_err_free(&err);
}

int obs_vk_available(void) {
  pthread_once(&available_once, probe);
  return available;
}

const char *obs_vk_available_device_name(void) {
  return obs_vk_available() ? available_name : NULL;
}

const obs_backend_ops obs_backend_vulkan_ops = {
    .id = OBS_BACKEND_VULKAN,
    .name = "vulkan",
    .available = obs_vk_available,
    .device_name = obs_vk_available_device_name,
    .gbuffer = NULL,
};

int obs_vk_validation_requested(void) {
  const char *v = getenv("OBSCURA_VK_VALIDATION");
  return v && !strcmp(v, "1");
}

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
      .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1}};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       0, 0, NULL, 0, NULL, 1, &ib);
}

static VkFormat image_format(int channels) {
  return channels == 1 ? VK_FORMAT_R32_SFLOAT : VK_FORMAT_R32G32B32A32_SFLOAT;
}

int obs_vk_image_create(obs_vk *vk, int width, int height, int channels, obs_vk_image **out,
                        obs_err *err) {
  *out = NULL;
  int rc = obs_vk_usable(vk, "image create", err);
  if (rc) return rc;
  uint32_t maxdim = vk->props.limits.maxImageDimension2D;
  if (channels != 1 && channels != 4)
    return obs_err_set(err, OBS_EINVAL, "vulkan: image %dx%d: %d channels (must be 1 or 4)", width,
                       height, channels);
  if (width < 1 || height < 1 || (uint32_t)width > maxdim || (uint32_t)height > maxdim)
    return obs_err_set(err, OBS_EINVAL, "vulkan: image %dx%d: each side must be 1..%u on \"%s\"",
                       width, height, maxdim, vk->name);
  VkFormat fmt = image_format(channels);
  VkFormatProperties fp;
  vkGetPhysicalDeviceFormatProperties(vk->phys, fmt, &fp);
  VkFormatFeatureFlags need = VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT |
                              VK_FORMAT_FEATURE_TRANSFER_SRC_BIT |
                              VK_FORMAT_FEATURE_TRANSFER_DST_BIT;
  if ((fp.optimalTilingFeatures & need) != need)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "vulkan: \"%s\" cannot use %d-channel float images as storage images",
                       vk->name, channels);
  VkImageFormatProperties ifp;
  VkImageUsageFlags usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT |
                            VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  if ((rc = obs_vk_check(
           vk,
           vkGetPhysicalDeviceImageFormatProperties(vk->phys, fmt, VK_IMAGE_TYPE_2D,
                                                    VK_IMAGE_TILING_OPTIMAL, usage, 0, &ifp),
           "vkGetPhysicalDeviceImageFormatProperties", err)))
    return rc;
  VkDeviceSize bytes = (VkDeviceSize)width * (VkDeviceSize)height * (VkDeviceSize)channels * 4;
  if (bytes > ifp.maxResourceSize || bytes > vk->max_alloc)
    return obs_err_set(
        err, OBS_ENOMEM,
        "vulkan: image %dx%d with %d channels needs %llu bytes, more than \"%s\" "
        "allows for one image (%llu)",
        width, height, channels, (unsigned long long)bytes, vk->name,
        (unsigned long long)(ifp.maxResourceSize < vk->max_alloc ? ifp.maxResourceSize
                                                                 : vk->max_alloc));
  obs_vk_image *img = calloc(1, sizeof *img);
  if (!img) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory");
  img->format = fmt;
  img->width = width;
  img->height = height;
  img->channels = channels;
  char what[96];
  snprintf(what, sizeof what, "a %dx%d %d-channel image", width, height, channels);
  VkImageCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                          .imageType = VK_IMAGE_TYPE_2D,
                          .format = fmt,
                          .extent = {(uint32_t)width, (uint32_t)height, 1},
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
                               .viewType = VK_IMAGE_VIEW_TYPE_2D,
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

void obs_vk_image_free(obs_vk *vk, obs_vk_image *img) {
  if (!img) return;
  if (vk && vk->dev) {
    vkDestroyImageView(vk->dev, img->view, NULL);
    vkDestroyImage(vk->dev, img->image, NULL);
    vkFreeMemory(vk->dev, img->memory, NULL);
  }
  free(img);
}

static int staging_reserve(obs_vk *vk, VkDeviceSize size, obs_err *err) {
  if (vk->staging.buffer && vk->staging.size >= size) return 0;
  obs_vk_buffer_free(vk, &vk->staging);
  VkDeviceSize cap = 1 << 20;
  while (cap < size) cap *= 2;
  if (cap > vk->max_alloc && size <= vk->max_alloc) cap = size;
  return obs_vk_buffer_create(vk, cap,
                              VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                              1, &vk->staging, "the staging buffer", err);
}

static VkDeviceSize image_bytes(const obs_vk_image *img) {
  return (VkDeviceSize)img->width * (VkDeviceSize)img->height * (VkDeviceSize)img->channels *
         sizeof(float);
}

static VkBufferImageCopy image_region(const obs_vk_image *img) {
  /* bufferRowLength 0: rows tightly packed, exactly the host layout. */
  return (VkBufferImageCopy){.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                             .imageExtent = {(uint32_t)img->width, (uint32_t)img->height, 1}};
}

int obs_vk_image_upload(obs_vk *vk, obs_vk_image *img, const float *data, obs_err *err) {
  int rc = obs_vk_usable(vk, "image upload", err);
  if (rc) return rc;
  if (!img || !data) return obs_err_set(err, OBS_EINVAL, "vulkan: image upload: no image or data");
  VkDeviceSize n = image_bytes(img);
  if ((rc = staging_reserve(vk, n, err))) return rc;
  memcpy(vk->staging.map, data, (size_t)n);
  if ((rc = obs_vk_cmd_begin(vk, "image upload", err))) return rc;
  VkBufferImageCopy reg = image_region(img);
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_GENERAL,
                    VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
  vkCmdCopyBufferToImage(vk->cmd, vk->staging.buffer, img->image,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &reg);
  obs_vk_cmd_layout(vk->cmd, img->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_IMAGE_LAYOUT_GENERAL);
  char what[96];
  snprintf(what, sizeof what, "upload of a %dx%d %d-channel image", img->width, img->height,
           img->channels);
  return obs_vk_cmd_submit(vk, what, err);
}

int obs_vk_image_download(obs_vk *vk, const obs_vk_image *img, float *data, obs_err *err) {
  int rc = obs_vk_usable(vk, "image download", err);
  if (rc) return rc;
  if (!img || !data)
    return obs_err_set(err, OBS_EINVAL, "vulkan: image download: no image or destination");
  VkDeviceSize n = image_bytes(img);
  if ((rc = staging_reserve(vk, n, err))) return rc;
  if ((rc = obs_vk_cmd_begin(vk, "image download", err))) return rc;
  VkBufferImageCopy reg = image_region(img);
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
  char what[96];
  snprintf(what, sizeof what, "download of a %dx%d %d-channel image", img->width, img->height,
           img->channels);
  if ((rc = obs_vk_cmd_submit(vk, what, err))) return rc;
  memcpy(data, vk->staging.map, (size_t)n);
  return 0;
}

/* ---- compute passes ---- */

static int pipeline_for(obs_vk *vk, const obs_vk_pass *p, VkPipeline *out, obs_err *err) {
  for (int i = 0; i < vk->npipes; i++)
    if (vk->pipes[i].spirv == p->spirv) {
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
      .layout = vk->compute_layout};
  VkPipeline pipe;
  snprintf(buf, sizeof buf, "vkCreateComputePipelines (pass \"%s\")", p->name);
  rc = obs_vk_check(vk, vkCreateComputePipelines(vk->dev, VK_NULL_HANDLE, 1, &ci, NULL, &pipe), buf,
                    err);
  vkDestroyShaderModule(vk->dev, mod, NULL);
  if (rc) return rc;
  vk->pipes[vk->npipes++] = (obs_vk_pipe){p->spirv, pipe};
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
  if (p->push_size > PUSH_MAX || p->push_size % 4 || (p->push_size && !p->push))
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: pass %d \"%s\": push constants of %u bytes (a multiple of 4, at "
                       "most %u, with data)",
                       i, name, p->push_size, PUSH_MAX);
  if (p->groups_x < 1 || p->groups_y < 1 || p->groups_x > lim[0] || p->groups_y > lim[1])
    return obs_err_set(err, OBS_EINVAL, "vulkan: pass %d \"%s\": %ux%u work groups (each 1..%ux%u)",
                       i, name, p->groups_x, p->groups_y, lim[0], lim[1]);
  return 0;
}

int obs_vk_run(obs_vk *vk, const obs_vk_pass *passes, int npasses, double *ms_per_pass,
               obs_err *err) {
  int rc = obs_vk_usable(vk, "run", err);
  if (rc) return rc;
  if (npasses <= 0) return 0;
  if (!passes) return obs_err_set(err, OBS_EINVAL, "vulkan: run: no passes");
  VkPipeline *pipes = calloc((size_t)npasses, sizeof *pipes);
  VkDescriptorSet *sets = calloc((size_t)npasses, sizeof *sets);
  VkDescriptorPool dpool = VK_NULL_HANDLE;
  if (!pipes || !sets) {
    rc = obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for %d passes", npasses);
    goto done;
  }
  uint32_t nimg = 0;
  for (int i = 0; i < npasses; i++) {
    if ((rc = check_pass(vk, &passes[i], i, err))) goto done;
    if ((rc = pipeline_for(vk, &passes[i], &pipes[i], err))) goto done;
    nimg += (uint32_t)passes[i].nimages;
  }
  VkDescriptorPoolSize ps = {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, nimg ? nimg : 1};
  VkDescriptorPoolCreateInfo dci = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
                                    .maxSets = (uint32_t)npasses,
                                    .poolSizeCount = 1,
                                    .pPoolSizes = &ps};
  if ((rc = obs_vk_check(vk, vkCreateDescriptorPool(vk->dev, &dci, NULL, &dpool),
                         "vkCreateDescriptorPool", err))) {
    dpool = VK_NULL_HANDLE;
    goto done;
  }
  for (int i = 0; i < npasses; i++) {
    VkDescriptorSetAllocateInfo ai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                      .descriptorPool = dpool,
                                      .descriptorSetCount = 1,
                                      .pSetLayouts = &vk->set_layout};
    if ((rc = obs_vk_check(vk, vkAllocateDescriptorSets(vk->dev, &ai, &sets[i]),
                           "vkAllocateDescriptorSets", err)))
      goto done;
    VkDescriptorImageInfo ii[OBS_VK_MAX_BINDINGS];
    VkWriteDescriptorSet w[OBS_VK_MAX_BINDINGS];
    for (int k = 0; k < passes[i].nimages; k++) {
      ii[k] = (VkDescriptorImageInfo){.imageView = passes[i].images[k]->view,
                                      .imageLayout = VK_IMAGE_LAYOUT_GENERAL};
      w[k] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                    .dstSet = sets[i],
                                    .dstBinding = (uint32_t)k,
                                    .descriptorCount = 1,
                                    .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
                                    .pImageInfo = &ii[k]};
    }
    if (passes[i].nimages) vkUpdateDescriptorSets(vk->dev, (uint32_t)passes[i].nimages, w, 0, NULL);
  }
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
      vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, vk->compute_layout, 0, 1,
                              &sets[i], 0, NULL);
      if (p->push_size)
        vkCmdPushConstants(cmd, vk->compute_layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, p->push_size,
                           p->push);
      if (!host_timing)
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, vk->queries, 2 * (uint32_t)i);
      vkCmdDispatch(cmd, p->groups_x, p->groups_y, 1);
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
  free(sets);
  return rc;
}
