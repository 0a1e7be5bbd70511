/* What sss_single's Vulkan run takes from the host, without the ray tracer's headers: the BVH,
 * the media and lights (sss_job.h) with each light's map projection as a camera rig the device
 * rasterises the light-view maps from, and the hits of each pixel sample's camera ray, packed as
 * the device reads them (layout.h). Built in sss_maps.c. */
#ifndef OBS_SSS_HOST_H
#define OBS_SSS_HOST_H

#include <stddef.h>

#include "camera.h"
#include "geometry.h"
#include "obscura/technique.h"

typedef struct obs_sss_host obs_sss_host;

/* Builds the BVH (stage "bvh"), the job and the maps' projections for ctx's scene and bound
 * parameters. */
int obs_sss_host_open(obs_render_ctx *ctx, obs_sss_host **out, obs_err *err);
void obs_sss_host_close(obs_sss_host *h);
int obs_sss_host_nlights(const obs_sss_host *h);
int obs_sss_host_nobjects(const obs_sss_host *h);
/* The geometry the BVH holds, in the ray tracer's frame (positions relative to its origin). */
const obs_geometry *obs_sss_host_geometry(const obs_sss_host *h);
/* Light i's map projection as a map_size^2 camera (world space; orthographic for a directional
 * light, perspective from a point light) whose pixel (x, y) is the maps' texel (x, y). */
void obs_sss_host_light_rig(const obs_sss_host *h, int i, obs_camera_rig *rig);
/* The parameter buffer: OBS_SSS_OBJ_ROWS vec4 rows per object, then OBS_SSS_LIGHT_ROWS per
 * light; *rows receives their number. */
const float *obs_sss_host_table(const obs_sss_host *h, size_t *rows);
/* Pixel sample s's camera hits into three width x height RGBA images: position in the ray
 * tracer's frame and the object seen (-1: none, or an object without a medium), the shading
 * normal, the unit ray direction; alpha[] counts the hits. Returns the rays traced. */
size_t obs_sss_host_hits(const obs_sss_host *h, int s, float *pos, float *nrm, float *dir,
                         float *alpha);

#endif
