/* The scene's volumes and environment as device textures, for the volume techniques on Vulkan:
 * every volume's samples packed into one 3D R32_SFLOAT atlas sampled trilinearly by the hardware,
 * every volume's macrocell maxima into a second atlas read texel by texel, and the environment's
 * cube map as a 2D array image of its six faces. Internal to the Vulkan backend. */
#ifndef OBS_VOLUME_TEXTURES_VK_H
#define OBS_VOLUME_TEXTURES_VK_H

#include "environment.h"
#include "vk.h"
#include "volume_scene.h"

/* Places boxes of dims[k] in one 3D texture of sides at most `max`: stacked along z, a new column
 * along x when the stack would pass `max` (each column as wide as its widest box). at[k] receives
 * each box's corner, total the texture's size. Returns the index of a box that does not fit, or
 * -1. (Also packs proximity_ao's fields.) */
long obs_vk_atlas_pack(const int (*dims)[3], size_t n, int max, int (*at)[3], int total[3]);

/* Where volume k lives: its samples at voxel offset `at[k]` of `data` (texel (i, j, l) of the
 * volume is texel at + (i, j, l)), its macrocells at `cell_at[k]` of `cells`. */
typedef struct obs_vk_volume_atlas {
  obs_vk_texture *data, *cells;
  int dims[3], cell_dims[3]; /* the atlases' sizes in texels */
  int (*at)[3], (*cell_at)[3];
  size_t n;
  /* Whether `data` filters linearly in hardware; where the device cannot, it is sampled nearest
   * and the shader interpolates eight fetches itself (the same trilinear formula). */
  int linear;
} obs_vk_volume_atlas;

/* Packs and uploads every volume of `vs` (at least one). Volumes are stacked along z, in columns
 * along x when a stack reaches the device's 3D size limit. OBS_EUNSUPPORTED naming the volume
 * when one side of a volume, or the packed atlas, is past that limit; OBS_ENOMEM past what one
 * image may hold. On failure `out` is left empty. */
int obs_vk_volume_atlas_build(obs_vk *vk, const obs_scene_volumes *vs, obs_vk_volume_atlas *out,
                              obs_err *err);
void obs_vk_volume_atlas_free(obs_vk *vk, obs_vk_volume_atlas *a);

/* The cube map `env` as a res x res x 6 RGBA 2D array texture (layer f = face f of environment.h;
 * alpha 0), filtered linearly where the device can (*linear says which); with env NULL, a zero
 * 1 x 1 x 6 texture that a shader never reads but a descriptor needs. */
int obs_vk_env_texture(obs_vk *vk, const obs_env *env, obs_vk_texture **out, int *linear,
                       obs_err *err);

#endif
