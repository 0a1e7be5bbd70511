/* The Vulkan device layer: a headless instance and device, the process's shared device, and the
 * backend's operations table. Memory, buffers and images are in memory.c, compute passes in
 * compute.c. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscura/render.h"
#include "vk_internal.h"

#define NO_DEVICE_HINT "install mesa-vulkan-drivers for lavapipe"
#define VALIDATION_LAYER "VK_LAYER_KHRONOS_validation"

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
  /* Geometry shaders where the device has them (disc_ao's proxies); every other feature stays
   * off. */
  VkPhysicalDeviceFeatures have, want = {0};
  vkGetPhysicalDeviceFeatures(vk->phys, &have);
  want.geometryShader = have.geometryShader;
  vk->geometry_shader = have.geometryShader == VK_TRUE;
  VkDeviceCreateInfo ci = {.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
                           .queueCreateInfoCount = 1,
                           .pQueueCreateInfos = &q,
                           .pEnabledFeatures = &want};
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
  VkPushConstantRange pr = {.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT, .size = OBS_VK_PUSH_MAX};
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
    for (int i = 0; i <= OBS_VK_MAX_TEXTURES; i++)
      for (int j = 0; j < 2; j++) {
        vkDestroyPipelineLayout(vk->dev, vk->tex_compute_layout[i][j], NULL);
        vkDestroyDescriptorSetLayout(vk->dev, vk->tex_set_layout[i][j], NULL);
      }
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

const char *obs_vk_device_kind(const obs_vk *vk) {
  if (!vk) return "other";
  switch (vk->props.deviceType) {
  case VK_PHYSICAL_DEVICE_TYPE_CPU: return "software";
  case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
  case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
  case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "gpu";
  default: return "other";
  }
}

uint32_t obs_vk_loop_limit(const obs_vk *vk) {
  if (!vk || vk->props.deviceType != VK_PHYSICAL_DEVICE_TYPE_CPU) return 0;
  /* Measured on Mesa 22.3; tests/vulkan/test_volume_ao_vk.c renders past it. */
  return strstr(vk->name, "llvmpipe") ? 65535u : 0u;
}

uint32_t obs_vk_validation_messages(const obs_vk *vk) {
  return vk ? atomic_load(&((obs_vk *)vk)->messages) : 0;
}

int obs_vk_validation_verdict(const obs_vk *vk, int validation, const char *who, const char *what,
                              obs_err *err) {
  uint32_t n = validation ? obs_vk_validation_messages(vk) : 0;
  if (!n) return 0;
  return obs_err_set(err, OBS_EINTERNAL,
                     "%s: %s on \"%s\": %u Vulkan validation message(s) (printed above)", who, what,
                     obs_vk_device_name(vk), n);
}

static int available;
static char available_name[256];
static const char *available_kind;
static pthread_once_t available_once = PTHREAD_ONCE_INIT;

static void probe(void) {
  obs_vk *vk = NULL;
  obs_err err = OBS_ERR_INIT;
  available = obs_vk_open(&vk, NULL, 0, &err) == 0;
  if (available) {
    snprintf(available_name, sizeof available_name, "%s", obs_vk_device_name(vk));
    available_kind = obs_vk_device_kind(vk);
  }
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

static const char *available_device_kind(void) {
  return obs_vk_available() ? available_kind : NULL;
}

const obs_backend_ops obs_backend_vulkan_ops = {
    .id = OBS_BACKEND_VULKAN,
    .name = "vulkan",
    .available = obs_vk_available,
    .device_name = obs_vk_available_device_name,
    .device_kind = available_device_kind,
    .gbuffer = NULL,
};

int obs_vk_validation_requested(void) {
  const char *v = getenv("OBSCURA_VK_VALIDATION");
  return v && !strcmp(v, "1");
}
