/* What both backends of isosurface_mesh do with an extracted mesh: carry it from the volume's
 * data space to the render's frame, and record it in the result's `built`. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "isosurface_mesh.h"

/* The field's gradient at data point p by central differences half a voxel apart, turned to
 * point down the field (out of the region above the isovalue) and carried to world space. */
static void vertex_normal(const obs_scene_volume *sv, const double p[3], float out[3]) {
  double g[3], n[3];
  for (int a = 0; a < 3; a++) {
    double q0[3] = {p[0], p[1], p[2]}, q1[3] = {p[0], p[1], p[2]}, h = 0.5 * sv->v.spacing[a];
    q0[a] -= h;
    q1[a] += h;
    g[a] = ((double)obs_volume_sample(&sv->v, q0) - (double)obs_volume_sample(&sv->v, q1)) / (2 * h);
  }
  for (int i = 0; i < 3; i++) n[i] = sv->normal[i][0] * g[0] + sv->normal[i][1] * g[1] + sv->normal[i][2] * g[2];
  double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int i = 0; i < 3; i++) out[i] = len > 0 ? (float)(n[i] / len) : 0.0f;
}

/* Volume sv's mesh in the frame at `origin`: data space through to_world in double, with the
 * field's gradient as each vertex's shading normal (Embree interpolates it across the face, so a
 * ray on a shared edge sees the same normal from either triangle). */
int obs_iso_mesh_world(const obs_scene_volume *sv, const obs_iso_mesh *im, const double origin[3],
                       double unit, int normals, obs_mesh *m) {
  memset(m, 0, sizeof *m);
  m->pos = malloc((im->nverts ? im->nverts : 1) * 3 * sizeof(float));
  m->idx = malloc((im->ntris ? im->ntris : 1) * 3 * sizeof(uint32_t));
  m->nrm = normals ? malloc((im->nverts ? im->nverts : 1) * 3 * sizeof(float)) : NULL;
  if (!m->pos || !m->idx || (normals && !m->nrm)) return OBS_ENOMEM;
  for (size_t i = 0; i < im->nverts; i++) {
    double w[3];
    obs_affine_point(sv->to_world, im->pos + 3 * i, w);
    for (int k = 0; k < 3; k++) m->pos[3 * i + k] = (float)((w[k] - origin[k]) / unit);
    if (normals) vertex_normal(sv, im->pos + 3 * i, m->nrm + 3 * i);
  }
  if (im->ntris) memcpy(m->idx, im->idx, im->ntris * 3 * sizeof(uint32_t));
  m->nverts = im->nverts;
  m->ntris = im->ntris;
  m->object = sv->object;
  return 0;
}

void obs_iso_mesh_record(obs_render_ctx *ctx, const obs_scene_volume *sv, const obs_iso_mesh *im,
                         double ms) {
  size_t bytes = im->nverts * 3 * sizeof(float) + im->ntris * 3 * sizeof(uint32_t);
  json_array_append_new(ctx->built,
                        json_pack("{s:s, s:I, s:I, s:I, s:I, s:[i,i,i], s:f}", "name",
                                  "isosurface_mesh", "object", (json_int_t)sv->object, "bytes",
                                  (json_int_t)bytes, "triangles", (json_int_t)im->ntris,
                                  "vertices", (json_int_t)im->nverts, "cells", im->lat.c[0],
                                  im->lat.c[1], im->lat.c[2], "extract_ms", ms));
}
