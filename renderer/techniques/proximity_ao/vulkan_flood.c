/* The proximity-field flood on Vulkan (proximity_vk.h): the field's values, a block-sum scratch
 * grid and the occupancy as 3D R32F storage images, and per iteration two passes
 * (shaders/prox_flood_xy.comp.glsl, prox_flood_z.comp.glsl) that repeat the CPU's separable sums
 * in its order of float operations (their push block and bindings in layout.h). The values are
 * updated in place by the second pass, so the device holds three grids, not the CPU's four. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "layout.h"
#include "proximity_vk.h"
#include "shaders.h"

/* Iterations recorded per obs_vk_run: a bounded pass list however many the field asks. */
#define BATCH 64

_Static_assert(sizeof(obs_prox_flood_push) <= OBS_VK_PUSH_MAX,
               "push constants past the device layer's");

/* The three grids: values, x-y block sums, occupancy. */
typedef struct flood_dev {
  obs_vk_image *val, *sxy, *occ;
} flood_dev;

static void dev_free(obs_vk *vk, flood_dev *d) {
  obs_vk_image_free(vk, d->val);
  obs_vk_image_free(vk, d->sxy);
  obs_vk_image_free(vk, d->occ);
  memset(d, 0, sizeof *d);
}

/* Creates the grids and uploads the values and the occupancy (as 0 or 1). */
static int dev_build(obs_vk *vk, const obs_prox_field *f, flood_dev *d, obs_err *err) {
  const int *n = f->dims;
  int max = obs_vk_texture_max_side(vk, OBS_VK_TEXTURE_3D);
  if (n[0] > max || n[1] > max || n[2] > max)
    return obs_err_set(err, OBS_EUNSUPPORTED,
                       "proximity field of object %zu: %dx%dx%d voxels do not fit one 3D image "
                       "on \"%s\" (sides at most %d); lower /technique/params/volume_res",
                       f->object, n[0], n[1], n[2], obs_vk_device_name(vk), max);
  int rc;
  if ((rc = obs_vk_image_create_3d(vk, n[0], n[1], n[2], 1, &d->val, err)) ||
      (rc = obs_vk_image_create_3d(vk, n[0], n[1], n[2], 1, &d->sxy, err)) ||
      (rc = obs_vk_image_create_3d(vk, n[0], n[1], n[2], 1, &d->occ, err)) ||
      (rc = obs_vk_image_upload(vk, d->val, f->value, err)))
    return rc;
  float *occ = malloc(f->count * sizeof *occ);
  if (!occ)
    return obs_err_set(err, OBS_ENOMEM,
                       "proximity field of object %zu: out of memory for the "
                       "flood (%zu voxels)",
                       f->object, f->count);
  for (size_t i = 0; i < f->count; i++) occ[i] = f->occupied[i] ? 1.0f : 0.0f;
  rc = obs_vk_image_upload(vk, d->occ, occ, err);
  free(occ);
  return rc;
}

/* Every iteration, BATCH to a run. */
static int iterate(obs_vk *vk, const obs_prox_field *f, const flood_dev *d, obs_err *err) {
  obs_prox_flood_push pc = {{f->dims[0], f->dims[1], f->dims[2]}, OBS_PROX_INV26};
  uint32_t gx = (uint32_t)(f->dims[0] + 7) / 8, gy = (uint32_t)(f->dims[1] + 7) / 8;
  obs_vk_pass *passes = calloc(2 * BATCH, sizeof *passes);
  if (!passes) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for the flood");
  for (int i = 0; i < BATCH; i++) {
    passes[2 * i] =
        (obs_vk_pass){.name = "prox_flood_xy",
                      .spirv = obs_spv_prox_flood_xy_comp,
                      .spirv_size = obs_spv_prox_flood_xy_comp_size,
                      .images = {[OBS_PROX_FLOOD_B_VAL] = d->val, [OBS_PROX_FLOOD_B_SXY] = d->sxy},
                      .nimages = 2,
                      .push = &pc,
                      .push_size = sizeof pc,
                      .groups_x = gx,
                      .groups_y = gy,
                      .groups_z = (uint32_t)f->dims[2]};
    passes[2 * i + 1] = (obs_vk_pass){.name = "prox_flood_z",
                                      .spirv = obs_spv_prox_flood_z_comp,
                                      .spirv_size = obs_spv_prox_flood_z_comp_size,
                                      .images = {[OBS_PROX_FLOOD_B_VAL] = d->val,
                                                 [OBS_PROX_FLOOD_B_SXY] = d->sxy,
                                                 [OBS_PROX_FLOOD_B_OCC] = d->occ},
                                      .nimages = 3,
                                      .push = &pc,
                                      .push_size = sizeof pc,
                                      .groups_x = gx,
                                      .groups_y = gy,
                                      .groups_z = (uint32_t)f->dims[2]};
  }
  int rc = 0;
  for (int it = 0; it < f->iterations && !rc; it += BATCH) {
    int m = f->iterations - it < BATCH ? f->iterations - it : BATCH;
    rc = obs_vk_run(vk, passes, 2 * m, NULL, err);
  }
  free(passes);
  return rc;
}

/* Floods on `vk`; with `validation`, a validation message fails the flood (a result the layer
 * complained about is not trusted, whatever it holds). */
static int flood_on(obs_vk *vk, int validation, obs_prox_field *f, obs_err *err) {
  flood_dev d = {0};
  int rc = dev_build(vk, f, &d, err);
  if (!rc) rc = iterate(vk, f, &d, err);
  float *out = rc ? NULL : malloc(f->count * sizeof *out);
  if (!rc && !out)
    rc = obs_err_set(err, OBS_ENOMEM,
                     "proximity field of object %zu: out of memory for the "
                     "flood (%zu voxels)",
                     f->object, f->count);
  /* Into a copy first, so a failure leaves the field as it was. */
  if (!rc) rc = obs_vk_image_download(vk, d.val, out, err);
  if (!rc) {
    char who[64];
    snprintf(who, sizeof who, "proximity field of object %zu", f->object);
    rc = obs_vk_validation_verdict(vk, validation, who, "flood", err);
  }
  if (!rc) memcpy(f->value, out, f->count * sizeof *out);
  free(out);
  dev_free(vk, &d);
  return rc;
}

int obs_prox_flood_vulkan(void *user, obs_prox_field *f, int threads, obs_err *err) {
  (void)threads;
  if (f->iterations <= 0) return 0;
  if (user) return flood_on(user, 0, f, err);
  obs_vk *vk = NULL;
  const int validation = obs_vk_validation_requested();
  int rc = obs_vk_acquire(&vk, validation, err);
  if (!rc) rc = flood_on(vk, validation, f, err);
  obs_vk_release(vk);
  return rc;
}
