/* The CPU backend's G-buffer producers (gbuffer_raster.c, gbuffer_raycast.c): private to the CPU
 * layer and its tests; the rest of the renderer reaches them through the backend's operations
 * table (obs_backend_ops.gbuffer). */
#ifndef OBS_GBUFFER_CPU_H
#define OBS_GBUFFER_CPU_H

#include <stddef.h>

#include "gbuffer.h"

/* The CPU backend's G-buffer, made one of two ways that give the same buffers
 * (renderer/cpu/gbuffer_raster.c): rasterised (no BVH; cost grows with the triangles and the
 * pixels of their boxes) or one Embree ray through each pixel centre (a BVH build first).
 * obs_gbuffer_method picks one from the raster's pixel tests (the area of every primitive's box on
 * the image) and the image's pixels: the cost rule, unless OBSCURA_GBUFFER=raster|raycast forces
 * one ("auto" or unset: the rule). build_ms receives the geometry build plus any BVH build,
 * render_ms the rest (the raster's set-up included). */
enum { OBS_GBUFFER_RASTER = 0, OBS_GBUFFER_RAYCAST = 1 };
int obs_gbuffer_method(double tests, size_t pixels);
/* The raster's pixel tests on `scene` (for benchmarks and tests of the rule). */
int obs_gbuffer_raster_tests(const obs_scene *scene, int threads, double *tests, obs_err *err);
int obs_gbuffer_cpu(const obs_scene *scene, obs_gbuffer *g, int threads, double *build_ms,
                    double *render_ms, obs_err *err);
/* Each way by itself, whatever the rule says. */
int obs_gbuffer_raycast(const obs_scene *scene, obs_gbuffer *g, int threads, double *build_ms,
                        double *render_ms, obs_err *err);
int obs_gbuffer_raster(const obs_scene *scene, obs_gbuffer *g, int threads, double *build_ms,
                       double *render_ms, obs_err *err);
/* The raster through its plain per-pixel loops, one pixel and one test after another: slow, the
 * reference that the fast loops must match bit for bit (tests). */
int obs_gbuffer_raster_reference(const obs_scene *scene, obs_gbuffer *g, int threads,
                                 obs_err *err);
/* The same over geometry built at the camera (obs_geometry_build_at with the camera's position).
 * The ray cast takes `geo` over (and frees it); `bvh_ms` is its BVH build alone. */
int obs_gbuffer_raycast_geo(const obs_scene *scene, obs_geometry *geo, obs_gbuffer *g, int threads,
                            double *bvh_ms, double *render_ms, obs_err *err);
int obs_gbuffer_raster_geo(const obs_scene *scene, const obs_geometry *geo, obs_gbuffer *g,
                           int threads, double *render_ms, obs_err *err);

#endif
