/* Volume files into obs_volume: NRRD (teem), raw bricks and VolPack .den files (volume_io.h). */
#include "volume_io.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <teem/nrrd.h>

/* data[0..n) -> [0, 1] by (x - lo) / (hi - lo), clamped; a flat range maps everything to 0. */
static void normalise(float *data, size_t n, double lo, double hi) {
  double w = hi - lo;
  for (size_t i = 0; i < n; i++) {
    double x = w > 0 ? (data[i] - lo) / w : 0.0;
    data[i] = (float)(x < 0 ? 0 : x > 1 ? 1 : isnan(x) ? 0 : x);
  }
}

static void data_range(const float *data, size_t n, double *lo, double *hi) {
  *lo = INFINITY, *hi = -INFINITY;
  for (size_t i = 0; i < n; i++)
    if (isfinite(data[i])) *lo = fmin(*lo, data[i]), *hi = fmax(*hi, data[i]);
  if (!(*lo <= *hi)) *lo = 0, *hi = 1;
}

/* The file's bytes (at most `max`), into a new buffer. */
static int slurp(const char *path, size_t max, unsigned char **out, size_t *len, obs_err *err) {
  FILE *f = fopen(path, "rb");
  if (!f) return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(errno));
  int rc = 0;
  long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  if (size < 0 || fseek(f, 0, SEEK_SET))
    rc = obs_err_set(err, OBS_EIO, "%s: cannot read its size", path);
  else if ((size_t)size > max)
    rc = obs_err_set(err, OBS_EINVAL, "%s: %ld bytes, more than the %zu expected", path, size,
                     max - 1);
  else if (!(*out = malloc(size ? (size_t)size : 1)))
    rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  else if (fread(*out, 1, (size_t)size, f) != (size_t)size) {
    free(*out);
    *out = NULL;
    rc = obs_err_set(err, OBS_EIO, "%s: read failed", path);
  }
  *len = (size_t)size;
  fclose(f);
  return rc;
}

static double spacing_of(const obs_volume_source *s, int a, double file) {
  if (s->spacing[a] > 0) return s->spacing[a];
  return file > 0 && isfinite(file) ? file : 1.0;
}

static int read_raw(const obs_volume_source *s, obs_volume *v, obs_err *err) {
  static const size_t bytes[] = {1, 2, 4};
  if ((int)s->type < 0 || s->type > OBS_VOLUME_FLOAT32)
    return obs_err_set(err, OBS_EINVAL, "%s: unknown raw sample type", s->path);
  double sp[3] = {spacing_of(s, 0, 0), spacing_of(s, 1, 0), spacing_of(s, 2, 0)};
  int rc = obs_volume_init(v, s->dims, sp, err);
  if (rc) return rc;
  size_t n = (size_t)s->dims[0] * (size_t)s->dims[1] * (size_t)s->dims[2], len = 0;
  size_t want = n * bytes[s->type];
  unsigned char *b = NULL;
  if ((rc = slurp(s->path, want + 1, &b, &len, err))) {
    obs_volume_free(v);
    return rc;
  }
  if (len != want) {
    free(b);
    obs_volume_free(v);
    return obs_err_set(err, OBS_EINVAL,
                       "%s: %zu bytes, but dims %d x %d x %d of %zu-byte samples "
                       "need %zu",
                       s->path, len, s->dims[0], s->dims[1], s->dims[2], bytes[s->type], want);
  }
  for (size_t i = 0; i < n; i++) {
    const unsigned char *p = b + i * bytes[s->type];
    if (s->type == OBS_VOLUME_UINT8) {
      v->data[i] = p[0];
    } else if (s->type == OBS_VOLUME_UINT16) {
      v->data[i] = (float)(p[0] | p[1] << 8);
    } else {
      uint32_t u =
          (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
      memcpy(&v->data[i], &u, 4);
    }
  }
  free(b);
  double lo = 0, hi = s->type == OBS_VOLUME_UINT8 ? 255 : 65535;
  if (s->range[0] < s->range[1])
    lo = s->range[0], hi = s->range[1];
  else if (s->type == OBS_VOLUME_FLOAT32)
    data_range(v->data, n, &lo, &hi);
  normalise(v->data, n, lo, hi);
  return 0;
}

/* VolPack's .den: a 62-byte header of 29 16-bit fields (version 1, then the original, extracted
 * and map boxes, map_len at fields 25..27, warps) and the 32-bit sample count, in the byte order
 * of the machine that wrote it (the version field tells), then one byte per sample, x fastest. */
static int read_den(const obs_volume_source *s, obs_volume *v, obs_err *err) {
  unsigned char *b = NULL;
  size_t len = 0;
  int rc = slurp(s->path, ((size_t)1 << 31) + 63, &b, &len, err);
  if (rc) return rc;
  int big = len >= 62 && b[0] == 0 && b[1] == 1, little = len >= 62 && b[0] == 1 && b[1] == 0;
  if (!big && !little) {
    free(b);
    return obs_err_set(err, OBS_EINVAL, "%s: not a .den density file (no version 1 header)",
                       s->path);
  }
  int dims[3];
  for (int a = 0; a < 3; a++) {
    const unsigned char *f = b + 2 * (25 + a);
    dims[a] = big ? f[0] << 8 | f[1] : f[1] << 8 | f[0];
  }
  const unsigned char *c = b + 58;
  uint32_t count = big ? (uint32_t)c[0] << 24 | (uint32_t)c[1] << 16 | (uint32_t)c[2] << 8 | c[3]
                       : (uint32_t)c[3] << 24 | (uint32_t)c[2] << 16 | (uint32_t)c[1] << 8 | c[0];
  size_t n = (size_t)dims[0] * (size_t)dims[1] * (size_t)dims[2];
  if (n != count || len != 62 + n) {
    free(b);
    return obs_err_set(err, OBS_EINVAL,
                       "%s: the header's %d x %d x %d samples (count %u) do not "
                       "match the file's %zu data bytes",
                       s->path, dims[0], dims[1], dims[2], count, len - 62);
  }
  double sp[3] = {spacing_of(s, 0, 0), spacing_of(s, 1, 0), spacing_of(s, 2, 0)};
  if (!(rc = obs_volume_init(v, dims, sp, err))) {
    for (size_t i = 0; i < n; i++) v->data[i] = b[62 + i];
    double lo = 0, hi = 255;
    if (s->range[0] < s->range[1]) lo = s->range[0], hi = s->range[1];
    normalise(v->data, n, lo, hi);
  }
  free(b);
  return rc;
}

/* The range of teem type t's values, for normalisation; 0 for floating-point types. */
static int nrrd_type_range(int t, double *lo, double *hi) {
  switch (t) {
    case nrrdTypeChar:
      *lo = -128, *hi = 127;
      return 1;
    case nrrdTypeUChar:
      *lo = 0, *hi = 255;
      return 1;
    case nrrdTypeShort:
      *lo = -32768, *hi = 32767;
      return 1;
    case nrrdTypeUShort:
      *lo = 0, *hi = 65535;
      return 1;
    case nrrdTypeInt:
      *lo = -2147483648.0, *hi = 2147483647.0;
      return 1;
    case nrrdTypeUInt:
      *lo = 0, *hi = 4294967295.0;
      return 1;
    default:
      return 0;
  }
}

static int nrrd_fail(const char *path, const char *what, obs_err *err) {
  char *msg = biffGetDone(NRRD);
  int rc = obs_err_set(err, OBS_EINVAL, "%s: %s: %s", path, what, msg ? msg : "?");
  free(msg);
  return rc;
}

/* The header alone first: its sizes are checked before teem allocates for them, and a detached
 * header (whose data file could lie anywhere) is refused. */
static int nrrd_header_ok(const obs_volume_source *s, obs_err *err) {
  Nrrd *h = nrrdNew();
  NrrdIoState *nio = nrrdIoStateNew();
  int rc = 0;
  if (!h || !nio) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory", s->path);
  } else {
    nio->skipData = 1;
    if (nrrdLoad(h, s->path, nio)) {
      rc = nrrd_fail(s->path, "cannot read as NRRD", err);
    } else if (nio->dataFNArr && nio->dataFNArr->len) {
      rc = obs_err_set(err, OBS_EINVAL,
                       "%s: detached NRRD headers are not read (put the data in the .nrrd file)",
                       s->path);
    } else if (h->dim == 3) {
      double count = 1;
      for (int a = 0; a < 3; a++) count *= (double)h->axis[a].size;
      if (count > (double)OBS_VOLUME_MAX_VOXELS)
        rc = obs_err_set(err, OBS_EINVAL, "%s: %.0f samples, more than %lld", s->path, count,
                         (long long)OBS_VOLUME_MAX_VOXELS);
    }
  }
  if (nio) nrrdIoStateNix(nio);
  if (h) nrrdNix(h);
  return rc;
}

static int read_nrrd(const obs_volume_source *s, obs_volume *v, obs_err *err) {
  int rc = nrrd_header_ok(s, err);
  if (rc) return rc;
  Nrrd *in = nrrdNew(), *f = nrrdNew();
  if (!in || !f)
    rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory", s->path);
  else if (nrrdLoad(in, s->path, NULL))
    rc = nrrd_fail(s->path, "cannot read as NRRD", err);
  else if (in->dim != 3)
    rc = obs_err_set(err, OBS_EINVAL, "%s: a volume has 3 axes (this NRRD has %u)", s->path,
                     in->dim);
  else if (nrrdConvert(f, in, nrrdTypeFloat))
    rc = nrrd_fail(s->path, "cannot convert its samples to float", err);
  int dims[3];
  double sp[3];
  for (int a = 0; !rc && a < 3; a++) {
    if (in->axis[a].size > (size_t)1 << 30)
      rc =
          obs_err_set(err, OBS_EINVAL, "%s: axis %d has %zu samples", s->path, a, in->axis[a].size);
    dims[a] = (int)in->axis[a].size;
    sp[a] = spacing_of(s, a, in->axis[a].spacing);
  }
  if (!rc) rc = obs_volume_init(v, dims, sp, err);
  if (!rc) {
    size_t n = (size_t)dims[0] * (size_t)dims[1] * (size_t)dims[2];
    memcpy(v->data, f->data, n * sizeof(float));
    double lo, hi;
    if (s->range[0] < s->range[1])
      lo = s->range[0], hi = s->range[1];
    else if (!nrrd_type_range(in->type, &lo, &hi))
      data_range(v->data, n, &lo, &hi);
    normalise(v->data, n, lo, hi);
  }
  nrrdNuke(in);
  nrrdNuke(f);
  return rc;
}

int obs_volume_read(const obs_volume_source *s, obs_volume *v, obs_err *err) {
  memset(v, 0, sizeof *v);
  switch (s->format) {
    case OBS_VOLUME_FILE_RAW:
      return read_raw(s, v, err);
    case OBS_VOLUME_FILE_DEN:
      return read_den(s, v, err);
    case OBS_VOLUME_FILE_NRRD:
      return read_nrrd(s, v, err);
    default:
      return obs_err_set(err, OBS_EINVAL, "%s: unknown volume format", s->path);
  }
}

/* The dims and spacing of the .den at s->path from its 62-byte header and its size. */
static int probe_den(const obs_volume_source *s, int dims[3], double sp[3], obs_err *err) {
  FILE *f = fopen(s->path, "rb");
  if (!f) return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", s->path, strerror(errno));
  unsigned char b[62];
  size_t got = fread(b, 1, sizeof b, f);
  long size = fseek(f, 0, SEEK_END) == 0 ? ftell(f) : -1;
  fclose(f);
  int big = got == 62 && b[0] == 0 && b[1] == 1, little = got == 62 && b[0] == 1 && b[1] == 0;
  if (!big && !little)
    return obs_err_set(err, OBS_EINVAL, "%s: not a .den density file (no version 1 header)",
                       s->path);
  for (int a = 0; a < 3; a++) {
    const unsigned char *x = b + 2 * (25 + a);
    dims[a] = big ? x[0] << 8 | x[1] : x[1] << 8 | x[0];
    sp[a] = spacing_of(s, a, 0);
  }
  double n = (double)dims[0] * dims[1] * dims[2];
  if (!(n >= 1) || size != 62 + (long)n)
    return obs_err_set(err, OBS_EINVAL,
                       "%s: the header's %d x %d x %d samples do not match the file's %ld data "
                       "bytes",
                       s->path, dims[0], dims[1], dims[2], size - 62);
  return 0;
}

static int probe_nrrd(const obs_volume_source *s, int dims[3], double sp[3], obs_err *err) {
  int rc = nrrd_header_ok(s, err);
  if (rc) return rc;
  Nrrd *h = nrrdNew();
  NrrdIoState *nio = nrrdIoStateNew();
  if (!h || !nio) {
    rc = obs_err_set(err, OBS_ENOMEM, "%s: out of memory", s->path);
  } else {
    nio->skipData = 1;
    if (nrrdLoad(h, s->path, nio))
      rc = nrrd_fail(s->path, "cannot read as NRRD", err);
    else if (h->dim != 3)
      rc = obs_err_set(err, OBS_EINVAL, "%s: a volume has 3 axes (this NRRD has %u)", s->path,
                       h->dim);
    for (int a = 0; !rc && a < 3; a++) {
      if (h->axis[a].size > (size_t)1 << 30)
        rc = obs_err_set(err, OBS_EINVAL, "%s: axis %d has %zu samples", s->path, a,
                         h->axis[a].size);
      dims[a] = (int)h->axis[a].size;
      sp[a] = spacing_of(s, a, h->axis[a].spacing);
    }
  }
  if (nio) nrrdIoStateNix(nio);
  if (h) nrrdNix(h);
  return rc;
}

int obs_volume_probe(const obs_volume_source *s, int dims[3], double spacing[3], obs_err *err) {
  switch (s->format) {
    case OBS_VOLUME_FILE_RAW: {
      static const size_t bytes[] = {1, 2, 4};
      if ((int)s->type < 0 || s->type > OBS_VOLUME_FLOAT32)
        return obs_err_set(err, OBS_EINVAL, "%s: unknown raw sample type", s->path);
      struct stat st;
      if (stat(s->path, &st))
        return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", s->path, strerror(errno));
      double want = (double)s->dims[0] * s->dims[1] * s->dims[2] * (double)bytes[s->type];
      if ((double)st.st_size != want)
        return obs_err_set(err, OBS_EINVAL,
                           "%s: %lld bytes, but dims %d x %d x %d of %zu-byte samples need %.0f",
                           s->path, (long long)st.st_size, s->dims[0], s->dims[1], s->dims[2],
                           bytes[s->type], want);
      for (int a = 0; a < 3; a++) dims[a] = s->dims[a], spacing[a] = spacing_of(s, a, 0);
      return 0;
    }
    case OBS_VOLUME_FILE_DEN:
      return probe_den(s, dims, spacing, err);
    case OBS_VOLUME_FILE_NRRD:
      return probe_nrrd(s, dims, spacing, err);
    default:
      return obs_err_set(err, OBS_EINVAL, "%s: unknown volume format", s->path);
  }
}
