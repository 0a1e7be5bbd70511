/* Per-patch values (one value or RGB triple per triangle of the scene) and their file format.
 *
 * A patch is a triangle, numbered in the order the scene's geometry emits them: objects in scene
 * order, each object's triangles in its mesh's order (analytic spheres have no patches); a
 * technique that splits triangles into smaller patches numbers their sub-triangles
 * within each triangle (renderer/techniques/obscurance_map/patch_mesh.h). The
 * file "<name>.patches" is one line of JSON, padded with spaces to a multiple of 16 bytes
 * including its '\n', followed by little-endian float32 data: `count` x `components` values
 * (patch-major), then, when the header says "area": true, `count` triangle areas in scene units
 * squared. A scene with moving objects has "frames": F in the header (absent: 1) and F such blocks
 * of values, frame after frame, before the areas (the patches are those of frame 0 moved along:
 * their areas hold in every frame). The header:
 *   {"format":"obscura-patches","version":1,"name":"ao","count":N,"components":1,
 *    "channels":["ao"],"area":true,"dtype":"<f4"}
 * so numpy loads it as: f = open(p, "rb"); h = json.loads(f.readline());
 *   d = np.fromfile(f, "<f4"); v = d[:F*N*C].reshape(F, N, C); a = d[F*N*C:]. */
#ifndef OBSCURA_PATCHES_H
#define OBSCURA_PATCHES_H

#include <stdint.h>
#include "obscura/error.h"
#include "obscura/image.h"
#include "obscura/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OBS_PATCHES_MAX_COMPONENTS 3

/* Values of one per-patch output. Owns `values` and `area`. */
typedef struct obs_patches {
  char name[OBS_CHANNEL_NAME_MAX];
  int64_t count;
  int components;  /* 1 (scalar) or 3 (RGB) */
  int frames;      /* >= 1: frames of a scene with moving objects */
  float *values;   /* frames * count * components, frame-major, then patch-major */
  float *area;     /* count triangle areas, or NULL */
} obs_patches;

/* Allocates zeroed values (and areas when with_area). */
int obs_patches_init(obs_patches *p, const char *name, int64_t count, int components,
                     int with_area, obs_err *err);
/* The same for `frames` frames (1 to OBS_PATCHES_MAX_FRAMES). */
int obs_patches_init_frames(obs_patches *p, const char *name, int frames, int64_t count,
                            int components, int with_area, obs_err *err);
#define OBS_PATCHES_MAX_FRAMES 1025
void obs_patches_free(obs_patches *p);
/* The number of values of `p`: frames x count x components. */
static inline size_t obs_patches_values(const obs_patches *p) {
  return (size_t)(p->frames > 1 ? p->frames : 1) * (size_t)p->count * (size_t)p->components;
}
/* Writes `p` to `path` (format above); reads it back (`p` initialised by the call). */
int obs_patches_write(const obs_patches *p, const char *path, obs_err *err);
int obs_patches_read(obs_patches *p, const char *path, obs_err *err);
/* The number of patches of `scene` (its triangles after tessellation) and, with `area` non-NULL,
 * a new array of their areas (free() it). */
int obs_patches_scene(const obs_scene *scene, int64_t *count, float **area, obs_err *err);
/* Fills `out`'s planes `channels` (p->components of them) per pixel with the value, in the last
 * frame, of the patch `ids[pixel]` sees (width x height ids, row 0 on top; negative or out-of-range ids give 0). */
int obs_patches_render(const obs_patches *p, const int32_t *ids, obs_image *out,
                       const char *const *channels, obs_err *err);

#ifdef __cplusplus
}
#endif
#endif
