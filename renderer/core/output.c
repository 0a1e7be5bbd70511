/* Declared outputs of a technique: their EXR channel names, their files and the primary one. */
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

const obs_output *obs_technique_primary(const obs_technique *t) {
  for (const obs_output *o = t ? t->outputs : NULL; o && o->name; o++)
    if (o->flags & OBS_OUTPUT_PRIMARY) return o;
  return NULL;
}

const obs_output *obs_technique_output(const obs_technique *t, const char *name) {
  for (const obs_output *o = t && name ? t->outputs : NULL; o && o->name; o++)
    if (!strcmp(o->name, name)) return o;
  return NULL;
}

void obs_technique_exr_name(const obs_technique *t, char *buf, size_t n) {
  const obs_output *p = obs_technique_primary(t);
  snprintf(buf, n, "%s.exr", p ? p->name : "image");
}

void obs_output_patch_file(const obs_output *o, char *buf, size_t n) {
  snprintf(buf, n, "%s.patches", o->name);
}

/* Adds `name` to `names` unless it is there already. */
static void add_file(char names[][OBS_OUTPUT_FILE_MAX], size_t max, size_t *n, const char *name) {
  for (size_t i = 0; i < *n; i++)
    if (!strcmp(names[i], name)) return;
  if (*n >= max) return;
  size_t len = strnlen(name, OBS_OUTPUT_FILE_MAX - 1);
  memcpy(names[*n], name, len);
  names[(*n)++][len] = '\0';
}

size_t obs_technique_files(const obs_technique *t, char names[][OBS_OUTPUT_FILE_MAX], size_t max) {
  size_t n = 0;
  char buf[OBS_OUTPUT_FILE_MAX];
  obs_technique_exr_name(t, buf, sizeof buf);
  add_file(names, max, &n, buf);
  for (const obs_output *o = t->outputs; o && o->name; o++) {
    if (o->png) add_file(names, max, &n, o->png);
    if (o->kind == OBS_OUTPUT_PATCH) {
      obs_output_patch_file(o, buf, sizeof buf);
      add_file(names, max, &n, buf);
    }
  }
  add_file(names, max, &n, "summary.json");
  return n;
}

size_t obs_output_file_names(char names[][OBS_OUTPUT_FILE_MAX], size_t max) {
  size_t n = 0;
  char one[16][OBS_OUTPUT_FILE_MAX];
  for (size_t i = 0; i < obs_technique_count(); i++) {
    size_t k = obs_technique_files(obs_technique_at(i), one, 16);
    for (size_t j = 0; j < k; j++) add_file(names, max, &n, one[j]);
  }
  return n;
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
