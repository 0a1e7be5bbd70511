/* What the CPU backend builds for a technique's `needs` before its run: the Embree BVH for
 * OBS_NEED_BVH, in the frame the technique asks for, handed to the run as ctx->rt. The screen-space
 * drivers build their own G-buffer (renderer/cpu/screen.c). */
#include <jansson.h>
#include <stdlib.h>

#include "driver.h"
#include "obscura/render.h"
#include "raytrace.h"

static int cpu_build(obs_render_ctx *ctx, unsigned needs, void **state, obs_err *err) {
  *state = NULL;
  if (!(needs & OBS_NEED_BVH)) return 0;
  obs_rt *rt = calloc(1, sizeof *rt);
  if (!rt) return obs_err_set(err, OBS_ENOMEM, "%s: BVH: out of memory", ctx->scene->name);
  int frame = needs & OBS_NEED_BVH_FRAME_GEOMETRY ? OBS_RT_FRAME_GEOMETRY : OBS_RT_FRAME_CAMERA;
  double t0 = obs_now_ms();
  int rc = obs_rt_build_ex(ctx->scene, rt, ctx->threads, frame, err);
  if (rc) {
    free(rt);
    return rc;
  }
  obs_driver_stage_add(ctx, "bvh", obs_now_ms() - t0);
  size_t tris = 0;
  for (size_t i = 0; i < rt->geo.nmeshes; i++) tris += rt->geo.meshes[i].ntris;
  /* Embree's memory once built (BVH and its copies of the vertices and indices) and at the
   * build's peak; our own geometry arrays are not in it. */
  json_array_append_new(ctx->built,
                        json_pack("{s:s, s:I, s:I, s:I, s:I}", "name", "bvh", "triangles",
                                  (json_int_t)tris, "spheres", (json_int_t)rt->geo.nspheres,
                                  "bytes", (json_int_t)atomic_load(&rt->embree_bytes),
                                  "peak_bytes", (json_int_t)atomic_load(&rt->embree_peak)));
  ctx->rt = rt;
  *state = rt;
  return 0;
}

static void cpu_release(void *state) {
  if (!state) return;
  obs_rt_free(state);
  free(state);
}

const obs_needs_builder obs_cpu_needs_builder = {cpu_build, cpu_release};
