/* Reference definitions: the dispatcher of the techniques' reference hooks (which rt_ao settings
 * define the same AO as a candidate) and the response curves a reference is mapped through. */
#include <jansson.h>
#include <math.h>
#include <string.h>

#include "obscura/technique.h"

int obs_technique_reference(const obs_technique *t, const obs_scene *scene, const json_t *params,
                            obs_reference_facts *facts, json_t **rt_ao_params,
                            obs_response *response, obs_err *err) {
  *rt_ao_params = NULL;
  *response = OBS_RESPONSE_IDENTITY;
  if (!t || !t->reference)
    return obs_err_set(err, OBS_EUNSUPPORTED, "technique \"%s\" has no reference definition, so "
                       "it cannot be compared with rt_ao", t ? t->name : "?");
  obs_reference_facts local;
  memset(&local, 0, sizeof local);
  json_t *out = json_object();
  if (!out) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  int rc = t->reference(scene, params, facts ? facts : &local, out, response, err);
  if (rc) {
    json_decref(out);
    return rc;
  }
  *rt_ao_params = out;
  return 0;
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
  float *ao = obs_image_channel(img, "ao"), *se = obs_image_channel(img, "ao_stderr");
  if (!ao) return obs_err_set(err, OBS_ENOTFOUND, "reference image has no channel \"ao\"");
  if (r == OBS_RESPONSE_IDENTITY) return 0;
  size_t n = (size_t)img->width * (size_t)img->height;
  for (size_t i = 0; i < n; i++) {
    if (se) se[i] *= fabsf(response_slope(r, ao[i]));
    ao[i] = obs_response_map(r, ao[i]);
  }
  return 0;
}
