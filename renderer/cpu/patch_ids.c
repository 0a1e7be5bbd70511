/* The patch seen by each pixel's primary ray, from the ray tracer's geometry and primitive ids. */
#include "patch_ids.h"

#include <math.h>
#include <stdlib.h>

#include "camera.h"

/* Meshes are attached with geomID = mesh index, so a mesh's first patch is the count of the
 * triangles before it. */
static int64_t triangle_patch(const void *user, const obs_rt *rt, const obs_hit *hit) {
  (void)rt;
  return ((const int64_t *)user)[hit->geom] + hit->prim;
}

void obs_patch_ids(const obs_rt *rt, const obs_scene *scene, int32_t *ids) {
  size_t nm = rt->geo.nmeshes;
  int64_t *first = calloc(nm ? nm : 1, sizeof *first);
  for (size_t m = 1; first && m < nm; m++)
    first[m] = first[m - 1] + (int64_t)rt->geo.meshes[m - 1].ntris;
  if (first) obs_patch_ids_map(rt, scene, triangle_patch, first, ids);
  else
    for (size_t i = 0; i < (size_t)scene->width * (size_t)scene->height; i++) ids[i] = -1;
  free(first);
}

void obs_patch_ids_map(const obs_rt *rt, const obs_scene *scene, obs_patch_map_fn map,
                       const void *user, int32_t *ids) {
  size_t nm = rt->geo.nmeshes;
  obs_camera_rig rig;
  obs_camera_setup(&scene->camera, scene->width, scene->height, &rig);
  for (int y = 0; y < scene->height; y++)
    for (int x = 0; x < scene->width; x++) {
      double org[3], dir[3];
      obs_hit hit;
      int32_t id = -1;
      obs_camera_ray(&rig, x + 0.5, y + 0.5, org, dir);
      if (obs_rt_intersect(rt, org, dir, INFINITY, &hit) && hit.geom < nm) {
        int64_t p = map(user, rt, &hit);
        id = p >= 0 && p <= INT32_MAX ? (int32_t)p : -1;
      }
      ids[(size_t)y * (size_t)scene->width + (size_t)x] = id;
    }
}

int obs_patch_show(const obs_rt *rt, const obs_scene *scene, const obs_patches *p,
                   obs_image *out, const char *const *channels, obs_err *err) {
  if (out->width != scene->width || out->height != scene->height)
    return obs_err_set(err, OBS_EINVAL, "patches: image is %dx%d, the scene's %dx%d", out->width,
                       out->height, scene->width, scene->height);
  int32_t *ids = malloc((size_t)scene->width * (size_t)scene->height * sizeof *ids);
  if (!ids) return obs_err_set(err, OBS_ENOMEM, "patches: out of memory for pixel ids");
  obs_patch_ids(rt, scene, ids);
  int rc = obs_patches_render(p, ids, out, channels, err);
  free(ids);
  return rc;
}
