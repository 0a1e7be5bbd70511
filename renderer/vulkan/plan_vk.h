/* The Vulkan pass driver: a technique describes its compute work as data (a plan: its scratch
 * images, its passes, which images come back to which host buffers) and the driver does the rest
 * (creates the images and uploads their host data, binds them in order, sizes the dispatches, runs
 * the passes through obs_vk_run, times each under its stage, downloads, frees every image on every
 * path, and fails a run the validation layer complained about). The Vulkan twin of the CPU's
 * obs_screen_cpu_tiles: a technique's Vulkan file is its push blocks (its layout.h, shared with
 * its shaders) and one plan. Internal to the Vulkan backend.
 *
 * A plan, for a blurred AO over the G-buffer's depth and normals:
 *
 *   enum { RAW = OBS_VK_PLAN_IMAGE0, AO };
 *   obs_vk_plan plan = {
 *       .technique = "example",
 *       .images = {[RAW] = {.channels = 1}, [AO] = {.channels = 1}},
 *       .passes = {{.stage = "ao", OBS_VK_SPIRV(example_comp), OBS_VK_PUSH(ap),
 *                   .images = {OBS_VK_PLAN_DEPTH, OBS_VK_PLAN_NORMAL, RAW}},
 *                  {.stage = "blur", OBS_VK_SPIRV(example_blur_comp), OBS_VK_PUSH(bp),
 *                   .images = {OBS_VK_PLAN_DEPTH, RAW, AO}, .skip = !p->blur}},
 *       .downloads = {{p->blur ? AO : RAW, ao_host}, {RAW, ao_raw_host}}};
 *   obs_vk_plan_times t;
 *   int rc = obs_vk_plan_run(vk, gbuffer, &plan, &t, err);
 *
 * Images are named by handles: 1..3 are the G-buffer's (given to obs_vk_plan_run), the
 * technique's own start at OBS_VK_PLAN_IMAGE0 and index plan.images directly; 0 is none, so a
 * pass's binding list ends at its first 0. Only the images an enabled pass binds or an active
 * download reads are made, so a skipped pass's scratch costs nothing. */
#ifndef OBS_PLAN_VK_H
#define OBS_PLAN_VK_H

#include "obscura/technique.h"
#include "vk.h"

enum {
  OBS_VK_PLAN_NONE,
  OBS_VK_PLAN_DEPTH, /* the G-buffer's images (vk.h, obs_vk_gbuffer) */
  OBS_VK_PLAN_NORMAL,
  OBS_VK_PLAN_ALBEDO,
  OBS_VK_PLAN_IMAGE0, /* the technique's first own image */
};
#define OBS_VK_PLAN_IMAGES 16 /* handles, the G-buffer's included */
#define OBS_VK_PLAN_PASSES 8
#define OBS_VK_PLAN_DOWNLOADS 4
#define OBS_VK_PLAN_LOCAL 8 /* the shaders' default local size, 8 x 8 */

/* A 2D scratch image the driver makes (obs_vk_image_create: zeroed), or one the caller owns. */
typedef struct obs_vk_plan_image {
  int width, height; /* texels; both 0: the frame's size */
  int channels;      /* 1 (r32f) or 4 (rgba32f) */
  const float *data; /* uploaded once made (width x height x channels floats); NULL: zeros */
  obs_vk_image *use; /* a caller's image, bound as it is: not made, uploaded or freed */
} obs_vk_plan_image;

/* One compute dispatch over an image (vk.h, obs_vk_pass, for what the shader sees). */
typedef struct obs_vk_plan_pass {
  const char *stage;     /* the timing stage it adds to (passes may share one), a static string (the
                          * times and the render keep the pointer); NULL ends the list */
  const uint32_t *spirv; /* embedded SPIR-V (OBS_VK_SPIRV) */
  size_t spirv_size;
  int images[OBS_VK_MAX_BINDINGS]; /* handles in binding order, up to the first 0 */
  const void *push;                /* its push-constant block (OBS_VK_PUSH), may be NULL */
  uint32_t push_size;
  int grid;     /* the handle whose size the dispatch covers; 0: the frame */
  int local[2]; /* the shader's local size; 0: OBS_VK_PLAN_LOCAL */
  int skip;     /* nonzero: the pass does not run */
  obs_vk_texture *textures[OBS_VK_MAX_TEXTURES]; /* set 1, as in obs_vk_pass (optional) */
  int ntextures;
  obs_vk_data *data;
} obs_vk_plan_pass;

/* Image `image` downloaded into `to` (width x height x channels floats); `to` NULL: not wanted. */
typedef struct obs_vk_plan_download {
  int image;
  float *to;
} obs_vk_plan_download;

typedef struct obs_vk_plan {
  const char *technique; /* names the plan in messages and its passes in obs_vk_run's */
  int width, height;     /* the frame; 0: the G-buffer's */
  obs_vk_plan_image images[OBS_VK_PLAN_IMAGES];
  obs_vk_plan_pass passes[OBS_VK_PLAN_PASSES];
  obs_vk_plan_download downloads[OBS_VK_PLAN_DOWNLOADS];
} obs_vk_plan;

#define OBS_VK_SPIRV(name) .spirv = obs_spv_##name, .spirv_size = obs_spv_##name##_size
#define OBS_VK_PUSH(block) .push = &(block), .push_size = (uint32_t)sizeof(block)

/* What a run took, per stage in the order the passes first name them, then "readback" (the
 * downloads' wall time). Device time per pass (vk.h, obs_vk_run). */
typedef struct obs_vk_plan_times {
  int n;
  const char *stage[OBS_VK_PLAN_PASSES + 1];
  double ms[OBS_VK_PLAN_PASSES + 1];
} obs_vk_plan_times;

/* Runs `plan` over the G-buffer `g` (may be NULL when no pass binds it and the plan gives its
 * frame): obs_vk_plan_open, obs_vk_plan_dispatch and obs_vk_plan_close. A bad plan (a handle out
 * of range or undescribed, channels not 1 or 4, an image of no texels, a pass binding nothing) is
 * OBS_EINVAL naming the technique, the pass or image and the offence, before anything is made.
 * Validation-layer messages during the run fail it (OBS_EINTERNAL). `times` (may be NULL) is
 * filled on success, zeroed on failure. */
int obs_vk_plan_run(obs_vk *vk, const obs_vk_gbuffer *g, const obs_vk_plan *plan,
                    obs_vk_plan_times *times, obs_err *err);

/* The same in steps, for work split across submissions (a pass whose work per invocation must
 * stay under obs_vk_loop_limit, with cancellation and progress between the parts): open checks
 * the plan and makes its images; each dispatch runs the enabled passes once, reading the push
 * blocks as they are then (the caller changes them between dispatches); close downloads (when rc
 * is 0), fails on validation messages, frees everything whatever rc was, fills `times` as
 * obs_vk_plan_run does and returns the final code. Close must follow every open, failed ones
 * included; the plan must outlive them. */
typedef struct obs_vk_plan_state { /* the driver's */
  obs_vk *vk;
  const obs_vk_plan *plan;
  const char *who;
  int fw, fh;                    /* the frame */
  uint32_t seen;                 /* validation messages before open */
  int used[OBS_VK_PLAN_IMAGES];  /* bound by an enabled pass or read by an active download */
  int owned[OBS_VK_PLAN_IMAGES]; /* made by open, freed by close */
  obs_vk_image *img[OBS_VK_PLAN_IMAGES];
  obs_vk_plan_times times;
} obs_vk_plan_state;
int obs_vk_plan_open(obs_vk *vk, const obs_vk_gbuffer *g, const obs_vk_plan *plan,
                     obs_vk_plan_state *s, obs_err *err);
int obs_vk_plan_dispatch(obs_vk_plan_state *s, obs_err *err);
int obs_vk_plan_close(obs_vk_plan_state *s, int rc, obs_vk_plan_times *times, obs_err *err);

/* The time of `stage` in `t` (0 when no pass ran under it). */
double obs_vk_plan_ms(const obs_vk_plan_times *t, const char *stage);
/* stage_ms[i] = obs_vk_plan_ms(t, names[i]) for i < n: the fixed stage arrays of the apply
 * functions. `stage_ms` may be NULL. */
void obs_vk_plan_stage_ms(const obs_vk_plan_times *t, const char *const *names, int n,
                          double *stage_ms);
/* Adds every stage of `t` to the render's (obs_driver_stage_add). */
void obs_vk_plan_record(obs_render_ctx *ctx, const obs_vk_plan_times *t);

#endif
