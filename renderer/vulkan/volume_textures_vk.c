/* The scene's volumes and environment as device textures (volume_textures_vk.h): the atlas
 * packing, the uploads and the environment's faces. */
#include "volume_textures_vk.h"

#include <stdlib.h>
#include <string.h>

long obs_vk_atlas_pack(const int (*dims)[3], size_t n, int max, int (*at)[3], int total[3]) {
  int x = 0, width = 0, z = 0;
  total[0] = total[1] = total[2] = 1;
  for (size_t k = 0; k < n; k++) {
    const int *d = dims[k];
    if (d[0] > max || d[1] > max || d[2] > max) return (long)k;
    if (z + d[2] > max) { /* a new column */
      x += width;
      width = 0;
      z = 0;
    }
    if (d[0] > max - x) return (long)k;
    at[k][0] = x, at[k][1] = 0, at[k][2] = z;
    z += d[2];
    if (d[0] > width) width = d[0];
    if (x + width > total[0]) total[0] = x + width;
    if (d[1] > total[1]) total[1] = d[1];
    if (z > total[2]) total[2] = z;
  }
  return -1;
}

/* Packs one atlas (`cells` chooses the macrocell grids or the samples) into a new texture and
 * uploads every volume's part. */
static int build_one(obs_vk *vk, const obs_scene_volumes *vs, int cells, obs_vk_volume_atlas *a,
                     obs_err *err) {
  int(*dims)[3] = calloc(vs->n, sizeof *dims);
  if (!dims) return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for the volume atlas");
  for (size_t k = 0; k < vs->n; k++)
    memcpy(dims[k], cells ? vs->v[k].cells.n : vs->v[k].v.n, sizeof dims[k]);
  int max = obs_vk_texture_max_side(vk, OBS_VK_TEXTURE_3D);
  int(*at)[3] = cells ? a->cell_at : a->at;
  int *total = cells ? a->cell_dims : a->dims;
  long bad = obs_vk_atlas_pack((const int(*)[3])dims, vs->n, max, at, total);
  int rc = 0;
  if (bad >= 0) {
    const int *d = dims[bad];
    rc = obs_err_set(err, OBS_EUNSUPPORTED,
                     "vulkan: /objects/%zu: a volume of %dx%dx%d %s does not fit, with the "
                     "volumes before it, in one 3D texture of sides at most %d on \"%s\"",
                     vs->v[bad].object, d[0], d[1], d[2], cells ? "macrocells" : "samples", max,
                     obs_vk_device_name(vk));
    goto done;
  }
  obs_vk_texture_desc desc = {OBS_VK_TEXTURE_3D, total[0], total[1],
                              total[2],          1,        cells ? 0 : a->linear};
  obs_vk_texture **t = cells ? &a->cells : &a->data;
  if ((rc = obs_vk_texture_create(vk, &desc, t, err))) goto done;
  for (size_t k = 0; k < vs->n && !rc; k++)
    rc = obs_vk_texture_upload(vk, *t, at[k], dims[k], cells ? vs->v[k].cells.max : vs->v[k].v.data,
                               err);
done:
  free(dims);
  return rc;
}

int obs_vk_volume_atlas_build(obs_vk *vk, const obs_scene_volumes *vs, obs_vk_volume_atlas *out,
                              obs_err *err) {
  memset(out, 0, sizeof *out);
  if (!vs || !vs->n) return obs_err_set(err, OBS_EINVAL, "vulkan: volume atlas: no volumes");
  out->n = vs->n;
  out->at = calloc(vs->n, sizeof *out->at);
  out->cell_at = calloc(vs->n, sizeof *out->cell_at);
  if (!out->at || !out->cell_at) {
    obs_vk_volume_atlas_free(vk, out);
    return obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for the volume atlas");
  }
  out->linear = obs_vk_texture_filterable(vk, 1);
  int rc = build_one(vk, vs, 0, out, err);
  if (!rc) rc = build_one(vk, vs, 1, out, err);
  if (rc) obs_vk_volume_atlas_free(vk, out);
  return rc;
}

void obs_vk_volume_atlas_free(obs_vk *vk, obs_vk_volume_atlas *a) {
  if (!a) return;
  obs_vk_texture_free(vk, a->data);
  obs_vk_texture_free(vk, a->cells);
  free(a->at);
  free(a->cell_at);
  memset(a, 0, sizeof *a);
}

int obs_vk_env_texture(obs_vk *vk, const obs_env *env, obs_vk_texture **out, int *linear,
                       obs_err *err) {
  *out = NULL;
  *linear = env && obs_vk_texture_filterable(vk, 4);
  int res = env ? env->res : 1;
  obs_vk_texture_desc desc = {OBS_VK_TEXTURE_2D_ARRAY, res, res, OBS_ENV_FACE_COUNT, 4, *linear};
  int rc = obs_vk_texture_create(vk, &desc, out, err);
  if (rc || !env) return rc;
  /* One face at a time: RGB to RGBA (there is no 3-channel float image to sample). */
  size_t texels = (size_t)res * (size_t)res;
  float *rgba = malloc(texels * 4 * sizeof *rgba);
  if (!rgba) rc = obs_err_set(err, OBS_ENOMEM, "vulkan: out of memory for the environment");
  for (int f = 0; f < OBS_ENV_FACE_COUNT && !rc; f++) {
    const float *src = obs_env_texel(env, f, 0, 0);
    for (size_t i = 0; i < texels; i++) {
      memcpy(rgba + 4 * i, src + 3 * i, 3 * sizeof *rgba);
      rgba[4 * i + 3] = 0;
    }
    const int at[3] = {0, 0, f}, size[3] = {res, res, 1};
    rc = obs_vk_texture_upload(vk, *out, at, size, rgba, err);
  }
  free(rgba);
  if (rc) {
    obs_vk_texture_free(vk, *out);
    *out = NULL;
  }
  return rc;
}
