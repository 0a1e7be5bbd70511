/* Declared outputs: their EXR channel names, kind and display names, patch file names and content
 * types (a descriptor's files and primary output: renderer/registry/descriptor.c). */
#include <stdio.h>
#include <string.h>

#include "obscura/technique.h"

int obs_output_channels(const obs_output *o, char names[][OBS_CHANNEL_NAME_MAX]) {
  static const char *const xyz[3] = {"X", "Y", "Z"}, *const rgb[3] = {"R", "G", "B"};
  switch (o->kind) {
  case OBS_OUTPUT_SCALAR:
  case OBS_OUTPUT_PATCH:
    snprintf(names[0], OBS_CHANNEL_NAME_MAX, "%s", o->name);
    return 1;
  case OBS_OUTPUT_DEPTH:
    snprintf(names[0], OBS_CHANNEL_NAME_MAX, "%s.Z", o->name);
    return 1;
  case OBS_OUTPUT_VECTOR:
  case OBS_OUTPUT_RGB:
    for (int c = 0; c < 3; c++)
      snprintf(names[c], OBS_CHANNEL_NAME_MAX, "%s.%s", o->name,
               o->kind == OBS_OUTPUT_RGB ? rgb[c] : xyz[c]);
    return 3;
  default:
    return 0;
  }
}

const char *obs_output_kind_name(obs_output_kind k) {
  static const char *const n[OBS_OUTPUT_KIND_COUNT] = {"scalar", "vector", "rgb",
                                                      "depth",  "patch",  "voxel"};
  return (unsigned)k < OBS_OUTPUT_KIND_COUNT ? n[k] : "unknown";
}

const char *obs_output_show_name(obs_output_show s) {
  static const char *const n[OBS_SHOW_COUNT] = {"none",   "grey",  "false_colour",
                                               "normal", "depth", "tonemap"};
  return (unsigned)s < OBS_SHOW_COUNT ? n[s] : "unknown";
}

void obs_output_patch_file(const obs_output *o, char *buf, size_t n) {
  snprintf(buf, n, "%s.patches", o->name);
}

const char *obs_output_content_type(const char *file) {
  const char *dot = file ? strrchr(file, '.') : NULL;
  if (!dot) return NULL;
  if (!strcmp(dot, ".exr")) return "image/x-exr";
  if (!strcmp(dot, ".png")) return "image/png";
  if (!strcmp(dot, ".json")) return "application/json";
  if (!strcmp(dot, ".patches")) return "application/octet-stream";
  return NULL;
}
