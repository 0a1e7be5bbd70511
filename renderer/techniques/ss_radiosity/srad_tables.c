/* ss_radiosity's backend-neutral pieces: the sample tables and push block both backends read, and
 * the export of the passes' results into the output channels, shared so the twins cannot drift. */
#include <math.h>
#include <string.h>

#include "camera.h"
#include "sampling.h"
#include "ss_radiosity.h"

const char *const obs_ss_radiosity_extra_names[OBS_SRAD_EXTRA] = {
    "final.R",  "final.G",  "final.B",  "bounce.R", "bounce.G",
    "bounce.B", "direct.R", "direct.G", "direct.B"};

/* A uniform direction from hash h: rejection from the cube [-1,1)^3 into the unit ball, a vector
 * too short to normalise safely redrawn. Returns the point's squared length (the direction is
 * v / sqrt of it). */
static float ball_point(uint32_t h, float v[3]) {
  for (uint32_t attempt = 0;; attempt++) {
    float l2 = 0.0f;
    for (uint32_t c = 0; c < 3; c++) {
      v[c] = 2.0f * obs_u32_to_unit(obs_hash_combine(h, 3 * attempt + c)) - 1.0f;
      l2 += v[c] * v[c];
    }
    if (l2 > 1e-4f && l2 <= 1.0f) return l2;
  }
}

void obs_ss_radiosity_tables_make(const obs_ss_radiosity_params *p, obs_ss_radiosity_tables *t) {
  memset(t, 0, sizeof *t);
  /* Points in the unit ball: a uniform direction times a length whose cube is stratified,
   * (k + 1/2) / N, so the points fill the ball evenly in volume. The seed moves the directions;
   * sample k keeps its stratum. */
  const uint32_t n = (uint32_t)p->samples;
  for (uint32_t k = 0; k < n; k++) {
    float v[3], l2 = ball_point(obs_hash_combine(p->seed ^ 0x5ad10517U, k), v);
    float len = cbrtf(((float)k + 0.5f) / (float)n) / sqrtf(l2);
    for (int c = 0; c < 3; c++) t->offsets[k][c] = v[c] * len;
  }
  /* The 4x4 rotation tile: unit reflection normals (reflect() needs a unit plane normal). */
  for (uint32_t j = 0; j < 16; j++) {
    float v[3], inv = 1.0f / sqrtf(ball_point(obs_hash_combine(p->seed, j), v));
    for (int c = 0; c < 3; c++) t->rotation[j][c] = v[c] * inv;
  }
  for (int c = 1; c <= 16; c++) t->inv_count[c] = 1.0f / (float)c;
}

int obs_ss_radiosity_probes_make(const obs_scene *sc, float *out) {
  obs_camera_rig rig;
  obs_camera_setup(&sc->camera, sc->width, sc->height, &rig);
  int n = sc->nprobes < OBS_SRAD_MAX_PROBES ? (int)sc->nprobes : OBS_SRAD_MAX_PROBES;
  for (int i = 0; i < n; i++) {
    const obs_probe *pr = &sc->probes[i];
    const double d[3] = {pr->position.x - rig.origin[0], pr->position.y - rig.origin[1],
                         pr->position.z - rig.origin[2]};
    const double *axes[3] = {rig.right, rig.up, rig.forward};
    for (int k = 0; k < 3; k++)
      out[4 * i + k] = (float)(d[0] * axes[k][0] + d[1] * axes[k][1] + d[2] * axes[k][2]);
    out[4 * i + 3] = (float)(3.14159265358979323846 * pr->radius * pr->radius);
  }
  return n;
}

void obs_ss_radiosity_push_make(const obs_ss_radiosity_params *p, int w, int h, int ortho,
                                float half_w, float half_h, obs_srad_gather_push *out) {
  memset(out, 0, sizeof *out);
  out->width = w;
  out->height = h;
  out->samples = p->samples;
  out->flags = (ortho ? OBS_SRAD_ORTHO : 0) | (p->exclude_self ? OBS_SRAD_EXCLUDE_SELF : 0) |
               (p->probe_add ? OBS_SRAD_PROBES_ADD : 0);
  out->half_w = half_w;
  out->half_h = half_h;
  out->kernel_size = p->kernel_size;
  out->directivity = p->directivity;
  out->spread = 1.0f - p->directivity;
  out->attenuation = p->attenuation;
  out->inv_bias = 1.0f / p->bias;
  out->inv_samples = 1.0f / (float)p->samples;
  out->scale = p->strength * out->inv_samples;
}

void obs_ss_radiosity_export(const obs_gbuffer *g, const float *direct, const float *raw,
                             const float *res, float *ao, float *ao_raw, float *extra) {
  const size_t n = (size_t)g->width * (size_t)g->height;
  for (size_t i = 0; i < n; i++) {
    const int cov = g->depth[i] > 0.0f;
    ao[i] = cov ? res[4 * i + 3] : 1.0f;
    ao_raw[i] = cov ? raw[4 * i + 3] : 1.0f;
    for (int c = 0; c < 3; c++) {
      float b = cov ? res[4 * i + (size_t)c] : 0.0f, d = direct[4 * i + (size_t)c];
      extra[(size_t)(OBS_SRAD_FINAL + c) * n + i] = d + b;
      extra[(size_t)(OBS_SRAD_BOUNCE + c) * n + i] = b;
      extra[(size_t)(OBS_SRAD_DIRECT + c) * n + i] = d;
    }
  }
}
