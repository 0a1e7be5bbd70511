/* The rasterised G-buffer: scene triangles and tessellated spheres drawn into offscreen targets
 * with the definitions of renderer/core/gbuffer.h, then copied into storage images. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "gbuffer_clip.h"
#include "shaders.h"
#include "vk_internal.h"

#define PI 3.14159265358979323846
/* UV-sphere bounds: at most 1024 x 512 segments; at least one segment per 1.5 degrees, so facet
 * normals stay within ~1.5 degrees of the sphere's (the tests allow 2). */
#define SPHERE_MAX_LON 1024
#define SPHERE_NORMAL_STEP (1.5 * PI / 180.0)
/* Perspective near plane as a fraction of the farthest depth of the geometry in view. With
 * reversed float depth (near / z) precision does not depend on it, so it only decides what is
 * clipped: 2^-80 loses nothing nearer than ~1e-24 of that depth (a ground plane to a horizon 1e18
 * away keeps everything beyond 1e-6). The clipper bounds what the device computes from it: x / z
 * and y / z by the guard band, each triangle's depth ratio by its slabs, and near / z stays a
 * normal float for any depth the scene format allows. */
#define NEAR_FRACTION 0x1p-80

typedef struct gb_push {
  float proj[4]; /* half_w, half_h, k (near, or 1/far when orthographic), orthographic */
  float albedo[4];
} gb_push;

typedef struct gb_draw {
  uint32_t first, count;
  float albedo[3];
  float id; /* the scene object's index + 1, exact in float below 2^24 */
} gb_draw;

typedef struct gb_target {
  VkImage image;
  VkDeviceMemory memory;
  VkImageView view;
} gb_target;

enum { T_DEPTH, T_NORMAL, T_ALBEDO, T_ZBUF, T_COUNT };
static const VkFormat target_format[T_COUNT] = {VK_FORMAT_R32_SFLOAT, VK_FORMAT_R32G32B32A32_SFLOAT,
                                                VK_FORMAT_R32G32B32A32_SFLOAT,
                                                VK_FORMAT_D32_SFLOAT};

static int check_formats(obs_vk *vk, obs_err *err) {
  for (int t = 0; t < T_COUNT; t++) {
    VkFormatProperties fp;
    vkGetPhysicalDeviceFormatProperties(vk->phys, target_format[t], &fp);
    VkFormatFeatureFlags need =
        t == T_ZBUF ? VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT
                    : VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT | VK_FORMAT_FEATURE_TRANSFER_SRC_BIT;
    if ((fp.optimalTilingFeatures & need) != need)
      return obs_err_set(err, OBS_EUNSUPPORTED,
                         "vulkan: \"%s\" cannot render the G-buffer (format %d unsupported as an "
                         "attachment)",
                         vk->name, (int)target_format[t]);
  }
  return 0;
}

/* The render pass and pipeline do not depend on the image size, so they are built once. */
/* The G-buffer's render pass: three colour targets stored for readback and a depth buffer that
 * is not. Kept once made, so a retry after a failure neither leaks nor rebuilds it. */
static int ensure_render_pass(obs_vk *vk, obs_err *err) {
  if (vk->gb_pass) return 0;
  VkAttachmentDescription att[T_COUNT];
  VkAttachmentReference color[3];
  for (int t = 0; t < T_COUNT; t++) {
    att[t] = (VkAttachmentDescription){
        .format = target_format[t],
        .samples = VK_SAMPLE_COUNT_1_BIT,
        .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
        .storeOp = t == T_ZBUF ? VK_ATTACHMENT_STORE_OP_DONT_CARE : VK_ATTACHMENT_STORE_OP_STORE,
        .stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
        .stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
        .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
        .finalLayout = t == T_ZBUF ? VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL
                                   : VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL};
    if (t != T_ZBUF)
      color[t] = (VkAttachmentReference){(uint32_t)t, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  }
  VkAttachmentReference zref = {T_ZBUF, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub = {.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS,
                              .colorAttachmentCount = 3,
                              .pColorAttachments = color,
                              .pDepthStencilAttachment = &zref};
  VkPipelineStageFlags att_stages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                    VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                    VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  VkSubpassDependency dep[2] = {{.srcSubpass = VK_SUBPASS_EXTERNAL,
                                 .dstSubpass = 0,
                                 .srcStageMask = att_stages | VK_PIPELINE_STAGE_TRANSFER_BIT,
                                 .dstStageMask = att_stages,
                                 .srcAccessMask = VK_ACCESS_TRANSFER_READ_BIT,
                                 .dstAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT |
                                                  VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                                                  VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT},
                                {.srcSubpass = 0,
                                 .dstSubpass = VK_SUBPASS_EXTERNAL,
                                 .srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                                 .dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT,
                                 .srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                                 .dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT}};
  VkRenderPassCreateInfo rpci = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO,
                                 .attachmentCount = T_COUNT,
                                 .pAttachments = att,
                                 .subpassCount = 1,
                                 .pSubpasses = &sub,
                                 .dependencyCount = 2,
                                 .pDependencies = dep};
  int rc = obs_vk_check(vk, vkCreateRenderPass(vk->dev, &rpci, NULL, &vk->gb_pass),
                        "vkCreateRenderPass (G-buffer)", err);
  if (rc) vk->gb_pass = VK_NULL_HANDLE;
  return rc;
}

static int ensure_pipeline(obs_vk *vk, obs_err *err) {
  if (vk->gb_pipeline) return 0;
  int rc = check_formats(vk, err);
  if (!rc) rc = ensure_render_pass(vk, err);
  if (rc) return rc;
  VkPushConstantRange pr = {VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                            sizeof(gb_push)};
  VkPipelineLayoutCreateInfo plci = {.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
                                     .pushConstantRangeCount = 1,
                                     .pPushConstantRanges = &pr};
  if (!vk->gb_layout &&
      (rc = obs_vk_check(vk, vkCreatePipelineLayout(vk->dev, &plci, NULL, &vk->gb_layout),
                         "vkCreatePipelineLayout (G-buffer)", err))) {
    vk->gb_layout = VK_NULL_HANDLE;
    return rc;
  }
  VkShaderModule vs, fs;
  if ((rc = obs_vk_shader(vk, obs_spv_gbuffer_vert, obs_spv_gbuffer_vert_size, &vs, "G-buffer",
                          err)))
    return rc;
  if ((rc = obs_vk_shader(vk, obs_spv_gbuffer_frag, obs_spv_gbuffer_frag_size, &fs, "G-buffer",
                          err))) {
    vkDestroyShaderModule(vk->dev, vs, NULL);
    return rc;
  }
  /* Reversed depth: cleared to 0 (infinitely far), nearer is greater. */
  static const VkVertexInputAttributeDescription va[2] = {
      {0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0}, {1, 0, VK_FORMAT_R32G32B32_SFLOAT, 3 * sizeof(float)}};
  obs_vk_raster r = {.vs = vs,
                     .fs = fs,
                     .stride = OBS_VK_CLIP_FLOATS * sizeof(float),
                     .attrs = va,
                     .nattrs = 2,
                     .depth_op = VK_COMPARE_OP_GREATER,
                     .ncolor = 3,
                     .layout = vk->gb_layout,
                     .pass = vk->gb_pass,
                     .what = "G-buffer"};
  rc = obs_vk_raster_pipeline(vk, &r, &vk->gb_pipeline, err);
  vkDestroyShaderModule(vk->dev, vs, NULL);
  vkDestroyShaderModule(vk->dev, fs, NULL);
  return rc;
}

static void target_free(obs_vk *vk, gb_target *t) {
  vkDestroyImageView(vk->dev, t->view, NULL);
  vkDestroyImage(vk->dev, t->image, NULL);
  vkFreeMemory(vk->dev, t->memory, NULL);
  memset(t, 0, sizeof *t);
}

static int target_create(obs_vk *vk, int w, int h, int t, gb_target *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  int depth = t == T_ZBUF;
  VkImageCreateInfo ci = {
      .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
      .imageType = VK_IMAGE_TYPE_2D,
      .format = target_format[t],
      .extent = {(uint32_t)w, (uint32_t)h, 1},
      .mipLevels = 1,
      .arrayLayers = 1,
      .samples = VK_SAMPLE_COUNT_1_BIT,
      .tiling = VK_IMAGE_TILING_OPTIMAL,
      .usage = depth ? VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT
                     : VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
      .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
      .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  char what[96];
  snprintf(what, sizeof what, "a %dx%d G-buffer render target", w, h);
  int rc = obs_vk_check(vk, vkCreateImage(vk->dev, &ci, NULL, &out->image), what, err);
  if (rc) {
    out->image = VK_NULL_HANDLE;
    return rc;
  }
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(vk->dev, out->image, &req);
  if ((rc = obs_vk_memory_alloc(vk, &req, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &out->memory,
                                what, err)) ||
      (rc = obs_vk_check(vk, vkBindImageMemory(vk->dev, out->image, out->memory, 0),
                         "vkBindImageMemory (G-buffer)", err))) {
    target_free(vk, out);
    return rc;
  }
  VkImageViewCreateInfo vci = {
      .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
      .image = out->image,
      .viewType = VK_IMAGE_VIEW_TYPE_2D,
      .format = target_format[t],
      .subresourceRange = {depth ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0,
                           1}};
  if ((rc = obs_vk_check(vk, vkCreateImageView(vk->dev, &vci, NULL, &out->view),
                         "vkCreateImageView (G-buffer)", err))) {
    out->view = VK_NULL_HANDLE;
    target_free(vk, out);
  }
  return rc;
}

/* ---- spheres ---- */

/* Longitude segments for a UV sphere whose facets stay within a quarter of a raster cell of the
 * true surface, `ppu` cells per world unit near it, and whose steps are at most `max_step` radians.
 * The facet deviation is bounded by r (1 - cos step) (a corner's worth, conservative). */
int obs_vk_sphere_segments(double r, double ppu, double max_step) {
  double x = 0.25 / (r * ppu);
  double step = x >= 1.0 ? PI / 2 : acos(1.0 - x);
  if (step > max_step) step = max_step;
  double n = ceil(2.0 * PI / step / 4.0) * 4.0;
  return n > SPHERE_MAX_LON ? SPHERE_MAX_LON : (int)n;
}

/* The G-buffer's: a displacement delta at view depth z and distance d moves the image by at most
 * delta d / z^2 (the largest singular value of the projection's Jacobian), evaluated at the
 * sphere's nearest depth; facet normals within SPHERE_NORMAL_STEP of the sphere's. */
static int sphere_segments(const obs_camera_rig *rig, const obs_sphere *s, const double shift[3]) {
  double r = s->radius;
  double ppu = rig->height / (2.0 * rig->half_h); /* pixels per unit (orthographic) */
  if (!rig->ortho) {
    double c[3] = {s->center[0] + shift[0], s->center[1] + shift[1], s->center[2] + shift[2]};
    double z = c[0] * rig->forward[0] + c[1] * rig->forward[1] + c[2] * rig->forward[2] - r;
    double d = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) + r;
    if (!(z > 1e-3 * r)) return SPHERE_MAX_LON; /* reaches the camera's plane */
    ppu *= d / (z * z);
  }
  return obs_vk_sphere_segments(r, ppu, SPHERE_NORMAL_STEP);
}

/* Vertices of an n x n/2 UV sphere: caps are single triangles, other bands two per quad. */
size_t obs_vk_sphere_vertices(int n) {
  size_t lon = (size_t)n, lat = (size_t)n / 2;
  return 3 * (2 * lon + 2 * lon * (lat - 2));
}

/* `shift` takes the geometry's frame to the target's (e.g. geometry origin - camera origin). */
int obs_vk_sphere_fill(const obs_sphere *s, int n, const double shift[3], double *out) {
  int lat = n / 2;
  double *tab = malloc(((size_t)n + (size_t)lat + 1) * 2 * sizeof *tab);
  if (!tab) return OBS_ENOMEM;
  double *cp = tab, *sp = tab + n, *ct = tab + 2 * n, *st = tab + 2 * n + lat + 1;
  for (int i = 0; i < n; i++) {
    cp[i] = cos(2.0 * PI * i / n);
    sp[i] = sin(2.0 * PI * i / n);
  }
  for (int j = 0; j <= lat; j++) {
    ct[j] = cos(PI * j / lat);
    st[j] = sin(PI * j / lat);
  }
  /* Exact poles, so both caps close on one point. */
  ct[0] = 1, st[0] = 0, ct[lat] = -1, st[lat] = 0;
  double *o = out;
#define PUT(j, i)                                               \
  do {                                                          \
    o[0] = s->center[0] + shift[0] + s->radius * st[j] * cp[i]; \
    o[1] = s->center[1] + shift[1] + s->radius * ct[j];         \
    o[2] = s->center[2] + shift[2] + s->radius * st[j] * sp[i]; \
    o += 3;                                                     \
  } while (0)
  for (int j = 0; j < lat; j++)
    for (int i = 0; i < n; i++) {
      int i1 = (i + 1) % n; /* the seam reuses column 0 exactly: no cracks */
      if (j == 0) {
        PUT(0, 0);
        PUT(1, i);
        PUT(1, i1);
      } else if (j == lat - 1) {
        PUT(j, i);
        PUT(lat, 0);
        PUT(j, i1);
      } else {
        PUT(j, i);
        PUT(j + 1, i);
        PUT(j, i1);
        PUT(j, i1);
        PUT(j + 1, i);
        PUT(j + 1, i1);
      }
    }
#undef PUT
  free(tab);
  return 0;
}

/* ---- the pass ---- */

/* Every triangle of the draw list, camera-relative in double (the mesh's float vertices shifted,
 * exact when the geometry was built at the camera's origin; spheres tessellated in double),
 * through the clipper. With `out`,
 * writes the clipped vertices; with `d`, records each draw's first vertex and count. Returns the
 * number of vertices; *rc is OBS_ENOMEM when a sphere could not be tessellated. */
static size_t clip_all(const obs_geometry *geo, const int *seg, const double shift[3],
                       obs_vk_clip *c, gb_draw *d, float *out, int *rc) {
  size_t total = 0, k = 0;
  *rc = 0;
  for (size_t m = 0; m < geo->nmeshes; m++, k++) {
    const obs_mesh *me = &geo->meshes[m];
    if (d) d[k].first = (uint32_t)total;
    /* Each vertex is rotated and classified once, not once per triangle using it. */
    obs_vk_clip_vertex *cv = malloc((me->nverts ? me->nverts : 1) * sizeof *cv);
    if (!cv) {
      *rc = OBS_ENOMEM;
      return 0;
    }
    for (size_t i = 0; i < me->nverts; i++) {
      const float *p = me->pos + 3 * i;
      double q[3] = {(double)p[0] + shift[0], (double)p[1] + shift[1], (double)p[2] + shift[2]};
      obs_vk_clip_vertex_init(c, q, &cv[i]);
    }
    for (size_t t = 0; t < me->ntris; t++) {
      const uint32_t *ix = me->idx + 3 * t;
      total += obs_vk_clip_triangle(c, &cv[ix[0]], &cv[ix[1]], &cv[ix[2]],
                                    out ? out + OBS_VK_CLIP_FLOATS * total : NULL);
    }
    free(cv);
    if (d) d[k].count = (uint32_t)(total - d[k].first);
  }
  for (size_t s = 0; s < geo->nspheres; s++, k++) {
    if (d) d[k].first = (uint32_t)total;
    size_t nv = seg[s] ? obs_vk_sphere_vertices(seg[s]) : 0;
    double *tess = nv ? malloc(nv * 3 * sizeof *tess) : NULL;
    if (nv && (!tess || obs_vk_sphere_fill(&geo->spheres[s], seg[s], shift, tess))) {
      free(tess);
      *rc = OBS_ENOMEM;
      return 0;
    }
    for (size_t t = 0; t < nv; t += 3) {
      obs_vk_clip_vertex v[3];
      for (int j = 0; j < 3; j++) obs_vk_clip_vertex_init(c, tess + 3 * (t + (size_t)j), &v[j]);
      total += obs_vk_clip_triangle(c, &v[0], &v[1], &v[2],
                                    out ? out + OBS_VK_CLIP_FLOATS * total : NULL);
    }
    free(tess);
    if (d) d[k].count = (uint32_t)(total - d[k].first);
  }
  return total;
}

/* Fills the vertex buffer with the clipped triangles, and the draw list. The perspective near
 * plane comes from the geometry in view: NEAR_FRACTION of the largest depth there. zrange gets
 * the depths of what was emitted (min, max); *ndraws is 0 when nothing is in view. */
static int build_vertices(obs_vk *vk, const obs_scene *sc, const obs_geometry *geo,
                          const obs_camera_rig *rig, const double shift[3], obs_vk_buffer *vb,
                          gb_draw **draws, size_t *ndraws, double *znear, double zrange[2],
                          obs_err *err) {
  size_t nd = geo->nmeshes + geo->nspheres, total = 0;
  int *seg = calloc(geo->nspheres ? geo->nspheres : 1, sizeof *seg);
  gb_draw *d = calloc(nd ? nd : 1, sizeof *d);
  int rc = 0;
  *ndraws = 0;
  if (!seg || !d) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory for the G-buffer draw list", sc->name);
    goto fail;
  }
  for (size_t m = 0; m < geo->nmeshes; m++) {
    obs_gbuffer_albedo(&sc->objects[geo->meshes[m].object], d[m].albedo);
    d[m].id = (float)(geo->meshes[m].object + 1);
  }
  for (size_t s = 0; s < geo->nspheres; s++) {
    seg[s] = geo->spheres[s].radius > 0 ? sphere_segments(rig, &geo->spheres[s], shift) : 0;
    obs_gbuffer_albedo(&sc->objects[geo->spheres[s].object], d[geo->nmeshes + s].albedo);
    d[geo->nmeshes + s].id = (float)(geo->spheres[s].object + 1);
  }
  /* Three passes: the depth extent in view (near plane at the eye), the counts with the chosen
   * near plane, then the vertices. */
  obs_vk_clip clip;
  obs_vk_clip_init(&clip, rig, 0.0);
  clip_all(geo, seg, shift, &clip, NULL, NULL, &rc);
  if (rc) goto oom;
  if (!(clip.zmax > 0.0)) goto empty;
  *znear = rig->ortho ? 0.0 : clip.zmax * NEAR_FRACTION;
  obs_vk_clip_init(&clip, rig, *znear);
  total = clip_all(geo, seg, shift, &clip, d, NULL, &rc);
  if (rc) goto oom;
  if (!total) goto empty;
  if (total > UINT32_MAX) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: %zu G-buffer vertices (at most %u)", sc->name, total,
                     UINT32_MAX);
    goto fail;
  }
  char what[96];
  snprintf(what, sizeof what, "the G-buffer vertex buffer of %s", sc->name);
  if ((rc = obs_vk_buffer_create(vk, (VkDeviceSize)total * OBS_VK_CLIP_FLOATS * sizeof(float),
                                 VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, 1, vb, what, err)))
    goto fail;
  obs_vk_clip_init(&clip, rig, *znear);
  clip_all(geo, seg, shift, &clip, NULL, vb->map, &rc);
  if (rc) goto oom;
  zrange[0] = clip.zmin;
  zrange[1] = clip.zmax;
  *ndraws = nd;
empty:
  free(seg);
  *draws = d;
  return 0;
oom:
  rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory tessellating a sphere", sc->name);
fail:
  obs_vk_buffer_free(vk, vb);
  free(seg);
  free(d);
  *draws = NULL;
  return rc;
}

void obs_vk_gbuffer_free(obs_vk *vk, obs_vk_gbuffer *g) {
  if (!g) return;
  obs_vk_image_free(vk, g->depth);
  obs_vk_image_free(vk, g->normal);
  obs_vk_image_free(vk, g->albedo);
  memset(g, 0, sizeof *g);
}

static int gbuffer_create(obs_vk *vk, int w, int h, obs_vk_gbuffer *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  out->width = w;
  out->height = h;
  int rc;
  if ((rc = obs_vk_image_create(vk, w, h, 1, &out->depth, err)) ||
      (rc = obs_vk_image_create(vk, w, h, 4, &out->normal, err)) ||
      (rc = obs_vk_image_create(vk, w, h, 4, &out->albedo, err)))
    obs_vk_gbuffer_free(vk, out);
  return rc;
}

int obs_vk_gbuffer_render(obs_vk *vk, const obs_scene *sc, const obs_geometry *geo,
                          obs_vk_gbuffer *out, double *ms, obs_err *err) {
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  return obs_vk_gbuffer_render_rig(vk, sc, geo, &rig, out, ms, err);
}

int obs_vk_gbuffer_render_rig(obs_vk *vk, const obs_scene *sc, const obs_geometry *geo,
                              const obs_camera_rig *view, obs_vk_gbuffer *out, double *ms,
                              obs_err *err) {
  memset(out, 0, sizeof *out);
  int rc = obs_vk_usable(vk, "G-buffer render", err);
  if (rc) return rc;
  obs_camera_rig rig = *view;
  int w = rig.width, h = rig.height;
  if ((rc = ensure_pipeline(vk, err))) return rc;
  if ((rc = gbuffer_create(vk, w, h, out, err))) return rc;

  gb_target tg[T_COUNT];
  memset(tg, 0, sizeof tg);
  VkFramebuffer fb = VK_NULL_HANDLE;
  obs_vk_buffer vb;
  memset(&vb, 0, sizeof vb);
  gb_draw *draws = NULL;
  size_t ndraws = 0;
  for (int t = 0; t < T_COUNT; t++)
    if ((rc = target_create(vk, w, h, t, &tg[t], err))) goto done;
  VkImageView views[T_COUNT] = {tg[0].view, tg[1].view, tg[2].view, tg[3].view};
  VkFramebufferCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO,
                                 .renderPass = vk->gb_pass,
                                 .attachmentCount = T_COUNT,
                                 .pAttachments = views,
                                 .width = (uint32_t)w,
                                 .height = (uint32_t)h,
                                 .layers = 1};
  if ((rc = obs_vk_check(vk, vkCreateFramebuffer(vk->dev, &fci, NULL, &fb),
                         "vkCreateFramebuffer (G-buffer)", err))) {
    fb = VK_NULL_HANDLE;
    goto done;
  }
  double shift[3];
  for (int k = 0; k < 3; k++) shift[k] = geo->origin[k] - rig.origin[k];
  double znear = 0, zrange[2] = {0, 0};
  if ((rc = build_vertices(vk, sc, geo, &rig, shift, &vb, &draws, &ndraws, &znear, zrange, err)))
    goto done;
  int visible = ndraws > 0;

  gb_push pc;
  memset(&pc, 0, sizeof pc);
  pc.proj[0] = (float)rig.half_w;
  pc.proj[1] = (float)rig.half_h;
  /* Orthographic: far just beyond the farthest point emitted. Perspective: half the clipper's
   * near plane, so the device (whose float depth may round a vertex on that plane inwards) clips
   * nothing more. */
  if (visible)
    pc.proj[2] = rig.ortho ? (float)(1.0 / (zrange[1] * (1.0 + 1.0 / 1024))) : (float)(0.5 * znear);
  pc.proj[3] = rig.ortho ? 1.0f : 0.0f;

  if ((rc = obs_vk_queries_reserve(vk, 2, err))) goto done;
  if ((rc = obs_vk_cmd_begin(vk, "G-buffer render", err))) goto done;
  VkCommandBuffer cmd = vk->cmd;
  if (vk->ts_bits) {
    vkCmdResetQueryPool(cmd, vk->queries, 0, 2);
    vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, vk->queries, 0);
  }
  /* Everything clears to 0: depth 0 / normal 0 / coverage 0 / albedo 0 for uncovered pixels, and
   * reversed depth 0 = infinitely far. */
  VkClearValue clear[T_COUNT];
  memset(clear, 0, sizeof clear);
  VkRenderPassBeginInfo rbi = {.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO,
                               .renderPass = vk->gb_pass,
                               .framebuffer = fb,
                               .renderArea = {{0, 0}, {(uint32_t)w, (uint32_t)h}},
                               .clearValueCount = T_COUNT,
                               .pClearValues = clear};
  vkCmdBeginRenderPass(cmd, &rbi, VK_SUBPASS_CONTENTS_INLINE);
  if (visible && ndraws) {
    /* Pixel centres sample at (x + 0.5, y + 0.5), where the ray caster shoots its rays. */
    VkViewport vp = {0, 0, (float)w, (float)h, 0, 1};
    VkRect2D sc2 = {{0, 0}, {(uint32_t)w, (uint32_t)h}};
    vkCmdSetViewport(cmd, 0, 1, &vp);
    vkCmdSetScissor(cmd, 0, 1, &sc2);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, vk->gb_pipeline);
    VkDeviceSize off = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &vb.buffer, &off);
    for (size_t i = 0; i < ndraws; i++) {
      if (!draws[i].count) continue;
      memcpy(pc.albedo, draws[i].albedo, sizeof draws[i].albedo);
      pc.albedo[3] = draws[i].id;
      vkCmdPushConstants(cmd, vk->gb_layout,
                         VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof pc,
                         &pc);
      vkCmdDraw(cmd, draws[i].count, 1, draws[i].first, 0);
    }
  }
  vkCmdEndRenderPass(cmd);
  obs_vk_image *dst[3] = {out->depth, out->normal, out->albedo};
  VkImageCopy region = {.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                        .dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                        .extent = {(uint32_t)w, (uint32_t)h, 1}};
  for (int t = 0; t < 3; t++) {
    obs_vk_cmd_layout(cmd, dst[t]->image, VK_IMAGE_LAYOUT_GENERAL,
                      VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL);
    vkCmdCopyImage(cmd, tg[t].image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, dst[t]->image,
                   VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    obs_vk_cmd_layout(cmd, dst[t]->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                      VK_IMAGE_LAYOUT_GENERAL);
  }
  if (vk->ts_bits) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, vk->queries, 1);
  char what[160];
  snprintf(what, sizeof what, "G-buffer render of %s (%dx%d)", sc->name, w, h);
  if ((rc = obs_vk_cmd_submit(vk, what, err))) goto done;
  rc = obs_vk_queries_ms(vk, 1, ms, err);
done:
  if (vk->recording) obs_vk_cmd_abort(vk);
  vkDestroyFramebuffer(vk->dev, fb, NULL);
  for (int t = 0; t < T_COUNT; t++) target_free(vk, &tg[t]);
  obs_vk_buffer_free(vk, &vb);
  free(draws);
  if (rc) obs_vk_gbuffer_free(vk, out);
  return rc;
}

/* ---- host <-> device ---- */

int obs_vk_gbuffer_upload(obs_vk *vk, const obs_gbuffer *host, obs_vk_gbuffer *out, obs_err *err) {
  memset(out, 0, sizeof *out);
  int rc = obs_vk_usable(vk, "G-buffer upload", err);
  if (rc) return rc;
  if (!host->depth)
    return obs_err_set(err, OBS_EINVAL, "vulkan: G-buffer upload: host buffer not allocated");
  size_t n = (size_t)host->width * (size_t)host->height;
  float *rgba = malloc(n * 4 * sizeof *rgba);
  if (!rgba) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for a G-buffer upload");
  if ((rc = gbuffer_create(vk, host->width, host->height, out, err))) goto done;
  if ((rc = obs_vk_image_upload(vk, out->depth, host->depth, err))) goto done;
  for (size_t i = 0; i < n; i++) {
    memcpy(rgba + 4 * i, host->normal + 3 * i, 3 * sizeof(float));
    rgba[4 * i + 3] = host->coverage[i];
  }
  if ((rc = obs_vk_image_upload(vk, out->normal, rgba, err))) goto done;
  for (size_t i = 0; i < n; i++) {
    memcpy(rgba + 4 * i, host->albedo + 3 * i, 3 * sizeof(float));
    rgba[4 * i + 3] = 0.0f;
  }
  rc = obs_vk_image_upload(vk, out->albedo, rgba, err);
done:
  free(rgba);
  if (rc) obs_vk_gbuffer_free(vk, out);
  return rc;
}

int obs_vk_gbuffer_download(obs_vk *vk, const obs_vk_gbuffer *dev, obs_gbuffer *host, int albedo,
                            obs_err *err) {
  int rc = obs_vk_usable(vk, "G-buffer download", err);
  if (rc) return rc;
  if (!dev->depth || !dev->normal || !dev->albedo || !host->depth)
    return obs_err_set(err, OBS_EINVAL, "vulkan: G-buffer download: buffers not allocated");
  if (host->width != dev->width || host->height != dev->height)
    return obs_err_set(err, OBS_EINVAL,
                       "vulkan: G-buffer download: host buffer is %dx%d, device buffer %dx%d",
                       host->width, host->height, dev->width, dev->height);
  size_t n = (size_t)host->width * (size_t)host->height;
  float *rgba = malloc(n * 4 * sizeof *rgba);
  if (!rgba) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for a G-buffer download");
  if ((rc = obs_vk_image_download(vk, dev->depth, host->depth, err))) goto done;
  if ((rc = obs_vk_image_download(vk, dev->normal, rgba, err))) goto done;
  for (size_t i = 0; i < n; i++) {
    memcpy(host->normal + 3 * i, rgba + 4 * i, 3 * sizeof(float));
    host->coverage[i] = rgba[4 * i + 3];
  }
  /* Albedo is a third of the readback and only colour bleeding needs it. */
  if (!albedo) goto done;
  if ((rc = obs_vk_image_download(vk, dev->albedo, rgba, err))) goto done;
  for (size_t i = 0; i < n; i++) memcpy(host->albedo + 3 * i, rgba + 4 * i, 3 * sizeof(float));
done:
  free(rgba);
  return rc;
}
