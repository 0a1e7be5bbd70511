/* Reference definitions as data: filling one from a reference technique and the candidate's
 * params (what the techniques' reference hooks do), freeing it, and the response curves a
 * reference is mapped through (registry/reference.c dispatches the hooks). */
#include <jansson.h>
#include <math.h>
#include <string.h>

#include "obscura/technique.h"

void obs_reference_def_free(obs_reference_def *def) {
  if (!def) return;
  json_decref(def->params);
  memset(def, 0, sizeof *def);
}

void obs_reference_def_same(obs_reference_def *def, const obs_technique *t, const json_t *params,
                            const char *const *keys) {
  def->technique = t;
  def->response = OBS_RESPONSE_IDENTITY;
  for (const char *const *k = keys; *k; k++) {
    json_t *v = json_object_get(params, *k);
    if (v) json_object_set_new(def->params, *k, json_deep_copy(v));
  }
}

static const char *const response_names[OBS_RESPONSE_COUNT] = {"identity", "ssao_sphere",
                                                               "ssao_hemi"};

const char *obs_response_name(obs_response r) {
  return r >= 0 && r < OBS_RESPONSE_COUNT ? response_names[r] : "?";
}

int obs_response_parse(const char *name, obs_response *out) {
  for (int i = 0; name && i < OBS_RESPONSE_COUNT; i++)
    if (!strcmp(name, response_names[i])) {
      *out = (obs_response)i;
      return 0;
    }
  return -1;
}

/* The curves of docs/techniques/ssao.md: the fraction of ssao's offset points that pass the depth
 * test, as a function of the obscurance W of a sqrt-falloff reference. */
float obs_response_map(obs_response r, float w) {
  switch (r) {
    case OBS_RESPONSE_SSAO_SPHERE: return w * w / 4.0f + w / 2.0f;
    case OBS_RESPONSE_SSAO_HEMI: {
      float v = w * w + w;
      return v < 1.0f ? v : 1.0f;
    }
    default: return w;
  }
}

static float response_slope(obs_response r, float w) {
  switch (r) {
    case OBS_RESPONSE_SSAO_SPHERE: return w / 2.0f + 0.5f;
    case OBS_RESPONSE_SSAO_HEMI: return w * w + w < 1.0f ? 2.0f * w + 1.0f : 0.0f;
    default: return 1.0f;
  }
}

int obs_response_apply(obs_response r, obs_image *img, obs_err *err) {
  if (r == OBS_RESPONSE_IDENTITY) return 0;
  float *ao = obs_image_channel(img, "ao"), *se = obs_image_channel(img, "ao_stderr");
  if (!ao) return obs_err_set(err, OBS_ENOTFOUND, "reference image has no channel \"ao\"");
  size_t n = (size_t)img->width * (size_t)img->height;
  for (size_t i = 0; i < n; i++) {
    if (se) se[i] *= fabsf(response_slope(r, ao[i]));
    ao[i] = obs_response_map(r, ao[i]);
  }
  return 0;
}
