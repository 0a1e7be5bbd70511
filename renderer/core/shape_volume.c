/* The volume shape kind (shapes.h): how a scene document states a scalar volume (a file of one
 * of volume_io.h's formats, or a procedural one of volume.h), checked at validation from the
 * file's header alone, and the box it fills in object space. */
#include <jansson.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "isosurface.h"
#include "shapes.h"
#include "volume.h"
#include "volume_io.h"

static const char *const formats[] = {"nrrd", "raw", "den", NULL}; /* obs_volume_file order */
static const char *const data_types[] = {"uint8", "uint16", "float32", NULL};
#define DIM_MAX 65536

/* dims: three integers of 1..DIM_MAX whose product is at most OBS_VOLUME_MAX_VOXELS. */
static int parse_dims(obs_jpath *p, const json_t *js, int dims[3]) {
  json_t *a = obs_json_get_array(p, js, "dims", 1, NULL);
  if (!a) return 0;
  size_t m = obs_jpath_push_key(p, "dims");
  int ok = json_array_size(a) == 3;
  double count = 1;
  for (size_t i = 0; ok && i < 3; i++) {
    long long v = 0;
    ok = obs_json_as_int(json_array_get(a, i), &v) && v >= 1 && v <= DIM_MAX;
    dims[i] = (int)v;
    count *= (double)v;
  }
  if (!ok)
    obs_jpath_fail(p, "must be 3 integers of 1 to %d (got %s)", DIM_MAX, obs_json_brief(a));
  else if (count > (double)OBS_VOLUME_MAX_VOXELS)
    obs_jpath_fail(p, "must hold at most %lld samples (got %.0f)", (long long)OBS_VOLUME_MAX_VOXELS,
                   count);
  obs_jpath_pop(p, m);
  return ok && count <= (double)OBS_VOLUME_MAX_VOXELS;
}

static void parse_range(obs_jpath *p, const json_t *js, double range[2]) {
  int absent = 0;
  json_t *a = obs_json_get_array(p, js, "range", 0, &absent);
  if (!a) return;
  size_t m = obs_jpath_push_key(p, "range");
  json_t *lo = json_array_get(a, 0), *hi = json_array_get(a, 1);
  if (json_array_size(a) != 2 || !obs_json_is_number(lo) || !obs_json_is_number(hi) ||
      !(obs_json_number(lo) < obs_json_number(hi)) ||
      !isfinite(obs_json_number(hi) - obs_json_number(lo))) {
    obs_jpath_fail(p, "must be [low, high] with low < high, both finite (got %s)",
                   obs_json_brief(a));
  } else {
    range[0] = obs_json_number(lo);
    range[1] = obs_json_number(hi);
  }
  obs_jpath_pop(p, m);
}

/* colormap: [[value, r, g, b], ...] by strictly rising value in [0, 1], colours >= 0. */
static void parse_colormap(obs_jpath *p, const json_t *js, obs_shape *s) {
  int absent = 0;
  json_t *a = obs_json_get_array(p, js, "colormap", 0, &absent);
  if (!a) return;
  size_t m = obs_jpath_push_key(p, "colormap");
  size_t n = json_array_size(a);
  if (n < 1 || n > 256) {
    obs_jpath_fail(p, "must list 1 to 256 points [value, r, g, b] (got %zu)", n);
  } else if ((s->volume.colormap = malloc(n * 4 * sizeof(double)))) {
    s->volume.ncolormap = n;
    for (size_t i = 0; i < n; i++) {
      json_t *e = json_array_get(a, i);
      double *c = s->volume.colormap + 4 * i;
      int ok = json_array_size(e) == 4;
      for (size_t k = 0; ok && k < 4; k++) {
        json_t *x = json_array_get(e, k);
        ok = obs_json_is_number(x) && obs_json_number(x) >= 0 && obs_json_number(x) <= 1e30;
        c[k] = ok ? obs_json_number(x) : 0;
      }
      ok = ok && c[0] <= 1 && (i == 0 || c[0] > c[-4]);
      if (!ok) {
        size_t mi = obs_jpath_push_index(p, i);
        obs_jpath_fail(p,
                       "must be [value, r, g, b]: value in [0, 1] above the previous point's, "
                       "colours >= 0 (got %s)",
                       obs_json_brief(e));
        obs_jpath_pop(p, mi);
      }
    }
  }
  obs_jpath_pop(p, m);
}

/* The format named by `format`, else by the file's extension; -1 after reporting. */
static int file_format(obs_jpath *p, const json_t *js) {
  const char *f = NULL;
  if (obs_json_get_string(p, js, "format", 0, formats, &f) < 0) return -1;
  if (f) {
    for (int i = 0; formats[i]; i++)
      if (!strcmp(f, formats[i])) return i;
  }
  const char *file = json_string_value(json_object_get(js, "file"));
  const char *ext = file ? strrchr(file, '.') : NULL;
  if (ext && !strcasecmp(ext, ".nrrd")) return OBS_VOLUME_FILE_NRRD;
  if (ext && !strcasecmp(ext, ".raw")) return OBS_VOLUME_FILE_RAW;
  if (ext && !strcasecmp(ext, ".den")) return OBS_VOLUME_FILE_DEN;
  size_t m = obs_jpath_push_key(p, "format");
  obs_jpath_fail(p, "is needed when the file's extension is not .nrrd, .raw or .den (got %s)",
                 obs_json_brief(json_object_get(js, "file")));
  obs_jpath_pop(p, m);
  return -1;
}

/* A file volume: format, path, and for raw its dims and type; the header gives the rest. */
static int parse_file(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s,
                      double spacing[3]) {
  int fmt = file_format(p, js);
  static const char *const exts[] = {".nrrd", ".raw", ".den", ".vol", ".bin", ".dat", NULL};
  char real_base[PATH_MAX], real_file[PATH_MAX];
  int resolved =
      obs_shape_resolve_file(p, js, "file", base_dir, exts,
                             "a .nrrd, .raw, .den, .vol, .bin or .dat", real_file, real_base);
  obs_volume_source src = {.format = (obs_volume_file)(fmt < 0 ? 0 : fmt), .path = real_file};
  memcpy(src.spacing, s->volume.spacing, sizeof src.spacing);
  if (fmt == OBS_VOLUME_FILE_RAW) {
    const char *t = NULL;
    int ok = parse_dims(p, js, src.dims);
    ok &= obs_json_get_string(p, js, "data_type", 1, data_types, &t) == 0 && t;
    for (int i = 0; ok && data_types[i]; i++)
      if (!strcmp(t, data_types[i])) src.type = (obs_volume_type)i;
    s->volume.data_type = (int)src.type;
    if (!ok) return 0;
  } else {
    static const char *const raw_only[] = {"dims", "data_type", NULL};
    for (int i = 0; raw_only[i]; i++) {
      if (!json_object_get(js, raw_only[i])) continue;
      size_t m = obs_jpath_push_key(p, raw_only[i]);
      obs_jpath_fail(p, "is for raw files only; this file's header says it");
      obs_jpath_pop(p, m);
    }
  }
  if (fmt < 0 || !resolved) return 0;
  s->volume.format = fmt;
  size_t m = obs_jpath_push_key(p, "file");
  obs_err e = OBS_ERR_INIT;
  int rc = obs_volume_probe(&src, s->volume.dims, spacing, &e);
  if (rc) {
    obs_jpath_fail(p, "%s", obs_err_message(&e));
  } else if ((double)s->volume.dims[0] * s->volume.dims[1] * s->volume.dims[2] >
             (double)OBS_VOLUME_MAX_VOXELS) {
    obs_jpath_fail(p, "holds more than %lld samples", (long long)OBS_VOLUME_MAX_VOXELS);
    rc = OBS_EINVAL;
  } else if ((s->volume.path = strdup(real_file)) == NULL) {
    rc = obs_err_set(p->err, OBS_ENOMEM, "%s: out of memory", p->doc);
  }
  obs_err_free(&e);
  obs_jpath_pop(p, m);
  return rc == 0;
}

static void parse_procedural(obs_jpath *p, const json_t *js, obs_shape *s, double spacing[3]) {
  const char *kind = NULL;
  obs_json_get_string(p, js, "procedural", 1, obs_volume_procedural_names, &kind);
  for (int i = 0; kind && obs_volume_procedural_names[i]; i++)
    if (!strcmp(kind, obs_volume_procedural_names[i])) s->volume.procedural = i;
  long long seed = 1;
  obs_json_get_int(p, js, "seed", 0, 0, 4294967295LL, &seed);
  s->volume.seed = (unsigned)seed;
  int ok = parse_dims(p, js, s->volume.dims);
  static const char *const file_only[] = {"format", "data_type", "range", NULL};
  for (int i = 0; file_only[i]; i++) {
    if (!json_object_get(js, file_only[i])) continue;
    size_t m = obs_jpath_push_key(p, file_only[i]);
    obs_jpath_fail(p, "is for volume files only (this one is procedural)");
    obs_jpath_pop(p, m);
  }
  /* Procedural volumes sample [-1, 1]^3: a cube unless a spacing says otherwise. */
  for (int a = 0; ok && a < 3; a++)
    spacing[a] = s->volume.spacing[a] > 0 ? s->volume.spacing[a] : 2.0 / s->volume.dims[a];
}

void obs_shape_volume_parse(obs_jpath *p, const json_t *js, const char *base_dir, obs_shape *s) {
  memset(&s->volume, 0, sizeof s->volume);
  s->volume.procedural = -1;
  s->volume.isovalue = 0.5;
  if (json_object_get(js, "spacing")) {
    double sp[3] = {1, 1, 1};
    if (obs_json_get_vec3(p, js, "spacing", 1, 1e-30, 1e30, sp) == 0)
      memcpy(s->volume.spacing, sp, sizeof sp);
  }
  obs_json_get_number(p, js, "isovalue", 0, 0, 1, 0, 0, &s->volume.isovalue);
  long long cells = 0;
  obs_json_get_int(p, js, "mesh_cells", 0, 1, OBS_ISO_CELLS_MAX, &cells);
  s->volume.mesh_cells = (int)cells;
  parse_range(p, js, s->volume.range);
  parse_colormap(p, js, s);
  int has_file = json_object_get(js, "file") != NULL;
  int has_proc = json_object_get(js, "procedural") != NULL;
  double spacing[3] = {0, 0, 0};
  if (has_file == has_proc) {
    obs_jpath_fail(p, "a volume names either a \"file\" or a \"procedural\" kind (got %s)",
                   has_file ? "both" : "neither");
    return;
  }
  if (has_file)
    parse_file(p, js, base_dir, s, spacing);
  else
    parse_procedural(p, js, s, spacing);
  double side[3], longest = 0;
  for (int a = 0; a < 3; a++) {
    side[a] = s->volume.dims[a] * spacing[a];
    if (side[a] > longest) longest = side[a];
  }
  if (!(longest > 0) || !isfinite(longest)) return; /* reported above */
  for (int a = 0; a < 3; a++) s->volume.extent[a] = side[a] / longest;
}

int obs_shape_volume_points(const obs_shape *s, double pts[8][3], double *radius) {
  *radius = 0;
  for (int i = 0; i < 8; i++)
    for (int k = 0; k < 3; k++) pts[i][k] = ((i >> k) & 1 ? 0.5 : -0.5) * s->volume.extent[k];
  return 8;
}
