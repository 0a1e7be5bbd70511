/* Per-patch values: the ".patches" file (JSON header line + little-endian float32 data), the
 * scene's patch count and areas, and the per-pixel rendering of the values. */
#include "obscura/patches.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "geometry.h"

#define PATCHES_FORMAT "obscura-patches"
#define PATCHES_MAX_HEADER 4096

int obs_patches_init(obs_patches *p, const char *name, int64_t count, int components, int with_area,
                     obs_err *err) {
  return obs_patches_init_frames(p, name, 1, count, components, with_area, err);
}

int obs_patches_init_frames(obs_patches *p, const char *name, int frames, int64_t count,
                            int components, int with_area, obs_err *err) {
  memset(p, 0, sizeof p[0]);
  if (!name || strlen(name) >= sizeof p->name || count < 0 || components < 1 ||
      components > OBS_PATCHES_MAX_COMPONENTS || frames < 1 || frames > OBS_PATCHES_MAX_FRAMES)
    return obs_err_set(err, OBS_EINVAL, "patches: bad name, count, components or frames");
  /* A header may say anything: the values must be countable in memory. */
  if ((double)count * components * frames > (double)(SIZE_MAX / sizeof(float) / 2))
    return obs_err_set(err, OBS_EINVAL, "patches: %lld x %d x %d values do not fit in memory",
                       (long long)count, components, frames);
  snprintf(p->name, sizeof p->name, "%s", name);
  p->count = count;
  p->components = components;
  p->frames = frames;
  size_t n = count ? (size_t)count : 1;
  p->values = calloc(n * (size_t)components * (size_t)frames, sizeof(float));
  if (with_area) p->area = calloc(n, sizeof(float));
  if (!p->values || (with_area && !p->area)) {
    obs_patches_free(p);
    return obs_err_set(err, OBS_ENOMEM, "patches: out of memory for %lld patches",
                       (long long)count);
  }
  return 0;
}

void obs_patches_free(obs_patches *p) {
  if (!p) return;
  free(p->values);
  free(p->area);
  memset(p, 0, sizeof p[0]);
}

/* float32 little-endian regardless of the host. */
static void put_f32(unsigned char *b, float f) {
  uint32_t u;
  memcpy(&u, &f, 4);
  for (int i = 0; i < 4; i++) b[i] = (unsigned char)(u >> (8 * i));
}

static float get_f32(const unsigned char *b) {
  uint32_t u = 0;
  for (int i = 0; i < 4; i++) u |= (uint32_t)b[i] << (8 * i);
  float f;
  memcpy(&f, &u, 4);
  return f;
}

static int write_floats(FILE *fp, const float *v, size_t n) {
  unsigned char buf[4096];
  for (size_t i = 0; i < n;) {
    size_t k = 0;
    for (; k < sizeof buf / 4 && i < n; k++, i++) put_f32(buf + 4 * k, v[i]);
    if (fwrite(buf, 4, k, fp) != k) return -1;
  }
  return 0;
}

static int read_floats(FILE *fp, float *v, size_t n) {
  unsigned char buf[4096];
  for (size_t i = 0; i < n;) {
    size_t want = n - i < sizeof buf / 4 ? n - i : sizeof buf / 4;
    if (fread(buf, 4, want, fp) != want) return -1;
    for (size_t k = 0; k < want; k++) v[i++] = get_f32(buf + 4 * k);
  }
  return 0;
}

static char *header_text(const obs_patches *p) {
  static const char *const rgb[3] = {"R", "G", "B"};
  json_t *ch = json_array();
  for (int c = 0; c < p->components; c++) {
    char n[OBS_CHANNEL_NAME_MAX + 4];
    if (p->components == 1)
      snprintf(n, sizeof n, "%s", p->name);
    else
      snprintf(n, sizeof n, "%s.%s", p->name, rgb[c % 3]);
    json_array_append_new(ch, json_string(n));
  }
  json_t *h = json_pack("{s:s, s:i, s:s, s:I, s:i, s:o, s:b, s:s}", "format", PATCHES_FORMAT,
                        "version", 1, "name", p->name, "count", (json_int_t)p->count, "components",
                        p->components, "channels", ch, "area", p->area != NULL, "dtype", "<f4");
  if (p->frames > 1) json_object_set_new(h, "frames", json_integer(p->frames));
  char *s = json_dumps(h, JSON_COMPACT | JSON_PRESERVE_ORDER);
  json_decref(h);
  return s;
}

int obs_patches_write(const obs_patches *p, const char *path, obs_err *err) {
  if (!p || !p->values || !path) return obs_err_set(err, OBS_EINVAL, "patches: nothing to write");
  char *h = header_text(p);
  if (!h) return obs_err_set(err, OBS_ENOMEM, "patches: out of memory");
  FILE *fp = fopen(path, "wb");
  if (!fp) {
    free(h);
    return obs_err_set(err, OBS_EIO, "%s: cannot create: %s", path, strerror(errno));
  }
  /* Padding keeps the floats 16-byte aligned for a reader that maps the file. */
  size_t len = strlen(h), pad = (16 - (len + 1) % 16) % 16;
  int bad = fputs(h, fp) < 0;
  for (size_t i = 0; i < pad && !bad; i++) bad = fputc(' ', fp) == EOF;
  bad = bad || fputc('\n', fp) == EOF;
  bad = bad || write_floats(fp, p->values, obs_patches_values(p));
  if (p->area) bad = bad || write_floats(fp, p->area, (size_t)p->count);
  bad = fclose(fp) || bad;
  free(h);
  if (bad) {
    remove(path);
    return obs_err_set(err, OBS_EIO, "%s: write failed", path);
  }
  return 0;
}

int obs_patches_read(obs_patches *p, const char *path, obs_err *err) {
  memset(p, 0, sizeof p[0]);
  FILE *fp = fopen(path, "rb");
  if (!fp) return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(errno));
  char line[PATCHES_MAX_HEADER];
  int rc = 0;
  json_t *h = NULL;
  if (!fgets(line, sizeof line, fp) || !strchr(line, '\n') ||
      !(h = json_loads(line, JSON_DISABLE_EOF_CHECK, NULL)))
    rc = obs_err_set(err, OBS_EINVAL, "%s: no JSON header line", path);
  const char *fmt = json_string_value(json_object_get(h, "format"));
  const char *name = json_string_value(json_object_get(h, "name"));
  json_t *count = json_object_get(h, "count"), *comp = json_object_get(h, "components");
  json_t *frames = json_object_get(h, "frames");
  if (!rc && (!fmt || strcmp(fmt, PATCHES_FORMAT) || !name || !json_is_integer(count) ||
              !json_is_integer(comp) || (frames && !json_is_integer(frames)) ||
              json_integer_value(json_object_get(h, "version")) != 1))
    rc = obs_err_set(err, OBS_EINVAL, "%s: not an obscura-patches version 1 header", path);
  json_int_t nf = frames ? json_integer_value(frames) : 1;
  if (!rc && (nf < 1 || nf > OBS_PATCHES_MAX_FRAMES))
    rc = obs_err_set(err, OBS_EINVAL, "%s: frames must be 1 to %d (got %lld)", path,
                     OBS_PATCHES_MAX_FRAMES, (long long)nf);
  if (!rc)
    rc = obs_patches_init_frames(p, name, (int)nf, json_integer_value(count),
                                 (int)json_integer_value(comp),
                                 json_is_true(json_object_get(h, "area")), err);
  if (!rc && (read_floats(fp, p->values, obs_patches_values(p)) ||
              (p->area && read_floats(fp, p->area, (size_t)p->count)) || fgetc(fp) != EOF))
    rc = obs_err_set(err, OBS_EINVAL, "%s: data does not match the header's size", path);
  if (rc) obs_patches_free(p);
  json_decref(h);
  fclose(fp);
  return rc;
}

int obs_patches_scene(const obs_scene *scene, int64_t *count, float **area, obs_err *err) {
  obs_geometry geo;
  int rc = obs_geometry_build(scene, &geo, err);
  if (rc) return rc;
  *count = (int64_t)geo.ntris;
  if (area) {
    *area = malloc((geo.ntris ? geo.ntris : 1) * sizeof(float));
    if (!*area) rc = obs_err_set(err, OBS_ENOMEM, "patches: out of memory for areas");
    size_t k = 0;
    for (size_t m = 0; !rc && m < geo.nmeshes; m++) {
      const obs_mesh *me = &geo.meshes[m];
      for (size_t t = 0; t < me->ntris; t++)
        (*area)[k++] = (float)obs_geometry_mesh_tri_area(me, t);
    }
  }
  obs_geometry_free(&geo);
  return rc;
}

int obs_patches_render(const obs_patches *p, const int32_t *ids, obs_image *out,
                       const char *const *channels, obs_err *err) {
  float *plane[OBS_PATCHES_MAX_COMPONENTS];
  for (int c = 0; c < p->components; c++)
    if (!(plane[c] = obs_image_channel(out, channels[c])))
      return obs_err_set(err, OBS_ENOTFOUND, "patches: image has no channel \"%s\"", channels[c]);
  size_t n = (size_t)out->width * (size_t)out->height;
  const float *last = p->values + obs_patches_values(p) - (size_t)p->count * (size_t)p->components;
  for (size_t i = 0; i < n; i++) {
    int32_t id = ids[i];
    const float *v = id >= 0 && id < p->count ? last + (size_t)id * (size_t)p->components : NULL;
    for (int c = 0; c < p->components; c++) plane[c][i] = v ? v[c] : 0.0f;
  }
  return 0;
}
