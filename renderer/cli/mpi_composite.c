/* Sort-last compositing of the bricks of a data-parallel render (mpi_composite.h). */
#include "mpi_composite.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { KIND_OVER, KIND_ALPHA, KIND_DEPTH, KIND_VECTOR };

/* How channel `name` merges, from the technique's outputs: its kind, and for KIND_OVER its
 * background; -1 for a channel no output has. A vector output's group is the three channels
 * from its X (the writer puts X, Y, Z in a row). */
static int kind_of(const obs_technique *t, const char *name, double *bg) {
  *bg = 0;
  for (const obs_output *o = t->outputs; o && o->name; o++) {
    char names[OBS_OUTPUT_MAX_CHANNELS][OBS_CHANNEL_NAME_MAX];
    int n = obs_output_channels(o, names);
    for (int c = 0; c < n; c++) {
      if (strcmp(names[c], name)) continue;
      if (!strcmp(o->name, "alpha")) return KIND_ALPHA;
      if (o->kind == OBS_OUTPUT_DEPTH) return KIND_DEPTH;
      if (o->kind == OBS_OUTPUT_VECTOR) return KIND_VECTOR;
      *bg = o->background;
      return KIND_OVER;
    }
  }
  return -1;
}

typedef struct frag {
  int part;
  float depth, alpha;
} frag;

/* The covering parts of pixel `at`, nearest first (insertion sort: a few ranks). */
static int fragments(const obs_image *const *parts, int nparts, int ca, int cd, size_t at,
                     frag *f) {
  size_t plane = (size_t)parts[0]->width * (size_t)parts[0]->height;
  int n = 0;
  for (int p = 0; p < nparts; p++) {
    float a = parts[p]->data[(size_t)ca * plane + at];
    if (!(a > 0)) continue;
    frag x = {p, parts[p]->data[(size_t)cd * plane + at], a};
    int i = n++;
    while (i > 0 && f[i - 1].depth > x.depth) {
      f[i] = f[i - 1];
      i--;
    }
    f[i] = x;
  }
  return n;
}

/* The "over" merge of n > 1 fragments, or one that covers part of the pixel. */
static void merge(const obs_image *const *parts, const frag *f, int n, const int *kind,
                  const double *bg, size_t at, double *acc, int nch) {
  size_t plane = (size_t)parts[0]->width * (size_t)parts[0]->height;
  double t = 1, wsum = 0;
  memset(acc, 0, (size_t)nch * sizeof *acc);
  for (int i = 0; i < n && t > 0; i++) {
    const float *d = parts[f[i].part]->data + at;
    double a = f[i].alpha, w = t * a;
    for (int c = 0; c < nch; c++) {
      double v = d[(size_t)c * plane];
      if (kind[c] == KIND_OVER) acc[c] += t * (v - (1 - a) * bg[c]);
      if (kind[c] == KIND_DEPTH || kind[c] == KIND_VECTOR) acc[c] += w * v;
    }
    wsum += w;
    t *= 1 - a;
  }
  for (int c = 0; c < nch; c++) {
    if (kind[c] == KIND_OVER) acc[c] += t * bg[c];
    if (kind[c] == KIND_ALPHA) acc[c] = 1 - t;
    if (kind[c] == KIND_DEPTH && wsum > 0) acc[c] /= wsum;
    if (kind[c] == KIND_VECTOR && c + 2 < nch && kind[c + 1] == KIND_VECTOR &&
        kind[c + 2] == KIND_VECTOR &&
        !strcmp(parts[0]->names[c] + strlen(parts[0]->names[c]) - 2, ".X")) {
      double l = sqrt(acc[c] * acc[c] + acc[c + 1] * acc[c + 1] + acc[c + 2] * acc[c + 2]);
      if (l > 0 && isfinite(l))
        for (int k = 0; k < 3; k++) acc[c + k] /= l;
    }
  }
}

/* Each channel's kind and background (kind_of), the alpha and depth channels, and whether every
 * part matches `out`. */
static int check_parts(const obs_image *out, const obs_image *const *parts, int nparts,
                       const obs_technique *t, int *kind, double *bg, int *ca, int *cd,
                       obs_err *err) {
  *ca = *cd = -1;
  for (int c = 0; c < out->nchannels; c++) {
    kind[c] = kind_of(t, out->names[c], &bg[c]);
    if (kind[c] < 0)
      return obs_err_set(err, OBS_EINVAL, "composite: channel %s is none of %s's outputs",
                         out->names[c], t->name);
    if (kind[c] == KIND_ALPHA) *ca = c;
    if (kind[c] == KIND_DEPTH) *cd = c;
  }
  if (*ca < 0 || *cd < 0)
    return obs_err_set(err, OBS_EINVAL,
                       "composite: %s's image has no alpha or depth channel to composite by",
                       t->name);
  for (int p = 0; p < nparts; p++) {
    const obs_image *im = parts[p];
    int same =
        im->width == out->width && im->height == out->height && im->nchannels == out->nchannels;
    for (int c = 0; same && c < out->nchannels; c++) same = !strcmp(im->names[c], out->names[c]);
    if (!same)
      return obs_err_set(err, OBS_EINVAL,
                         "composite: rank %d's image (%dx%d, %d channels) is not rank 0's", p,
                         im->width, im->height, im->nchannels);
  }
  return 0;
}

int cli_composite_depth(obs_image *out, const obs_image *const *parts, int nparts,
                        const obs_technique *t, obs_err *err) {
  int ca, cd, nch = out->nchannels, kind[OBS_IMAGE_MAX_CHANNELS];
  double bg[OBS_IMAGE_MAX_CHANNELS];
  int rc = check_parts(out, parts, nparts, t, kind, bg, &ca, &cd, err);
  if (rc) return rc;
  size_t plane = (size_t)out->width * (size_t)out->height;
  frag *f = malloc((size_t)nparts * sizeof *f);
  double *acc = malloc((size_t)nch * sizeof *acc);
  if (!f || !acc) {
    free(f);
    free(acc);
    return obs_err_set(err, OBS_ENOMEM, "composite: out of memory");
  }
  for (size_t at = 0; at < plane; at++) {
    int n = fragments(parts, nparts, ca, cd, at, f);
    /* Nothing covers it: every rank wrote the same background; one covering fully: its bits. */
    const obs_image *src = n == 0 ? parts[0] : f[0].alpha >= 1 ? parts[f[0].part] : NULL;
    if (src) {
      if (src != out)
        for (int c = 0; c < nch; c++)
          out->data[(size_t)c * plane + at] = src->data[(size_t)c * plane + at];
      continue;
    }
    merge(parts, f, n, kind, bg, at, acc, nch);
    for (int c = 0; c < nch; c++) out->data[(size_t)c * plane + at] = (float)acc[c];
  }
  free(f);
  free(acc);
  return 0;
}
