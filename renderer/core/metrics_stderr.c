/* Calibration of reported standard errors against a reference made with many more samples: the
 * figures of docs/accuracy.md's stderr table, its bench (bench/bench_stderr.c) and the tests that
 * hold every Monte-Carlo technique to them. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "obscura/metrics.h"

typedef struct calib_acc {
  double s2, d2;
  int64_t count, within, zero, bad;
} calib_acc;

static void calib_add(calib_acc *c, double v, double se, double ref) {
  if (!isfinite(v) || !isfinite(se) || !isfinite(ref)) {
    c->bad++;
    return;
  }
  double d = v - ref;
  c->count++;
  c->s2 += se * se;
  c->d2 += d * d;
  c->within += fabs(d) <= 3.0 * se;
  c->zero += se == 0.0 && d != 0.0;
}

static void calib_finish(const calib_acc *c, obs_stderr_calib *out) {
  memset(out, 0, sizeof *out);
  out->values = c->count;
  out->nonfinite = c->bad;
  out->ratio = 1.0;
  if (!c->count) return;
  double n = (double)c->count;
  out->rms_stderr = sqrt(c->s2 / n);
  out->rmse = sqrt(c->d2 / n);
  out->ratio = out->rmse > 0 ? out->rms_stderr / out->rmse : out->rms_stderr > 0 ? INFINITY : 1.0;
  out->within3 = (double)c->within / n;
  out->zero_with_error = (double)c->zero / n;
}

/* The planes of output `name`: "<name>" alone, or "<name>.R/G/B"; returns how many (0: none). */
static int planes_of(const obs_image *img, const char *name, const float *p[3]) {
  if ((p[0] = obs_image_channel(img, name))) return 1;
  static const char *const rgb[3] = {"R", "G", "B"};
  for (int k = 0; k < 3; k++) {
    char ch[OBS_CHANNEL_NAME_MAX + 8];
    snprintf(ch, sizeof ch, "%s.%s", name, rgb[k]);
    if (!(p[k] = obs_image_channel(img, ch))) return 0;
  }
  return 3;
}

int obs_metrics_stderr_calib(const obs_image *candidate, const obs_image *reference,
                             const char *name, const char *stderr_name, const char *mask,
                             obs_stderr_calib *out, obs_err *err) {
  const float *v[3], *se[3], *ref[3], *m = NULL;
  int nv = planes_of(candidate, name, v), ns = planes_of(candidate, stderr_name, se);
  int nr = planes_of(reference, name, ref);
  if (!nv || ns != nv || nr != nv)
    return obs_err_set(err, OBS_ENOTFOUND,
                       "metrics: stderr calibration needs \"%s\" and \"%s\" of one kind in the "
                       "candidate and \"%s\" in the reference",
                       name, stderr_name, name);
  if (candidate->width != reference->width || candidate->height != reference->height)
    return obs_err_set(err, OBS_EINVAL, "metrics: stderr calibration of images of different sizes");
  if (mask && !(m = obs_image_channel(reference, mask)))
    return obs_err_set(err, OBS_ENOTFOUND, "metrics: reference image has no channel \"%s\"", mask);
  size_t n = (size_t)candidate->width * (size_t)candidate->height;
  calib_acc c = {0};
  for (int k = 0; k < nv; k++)
    for (size_t i = 0; i < n; i++)
      if (!m || m[i] > 0.0f) calib_add(&c, v[k][i], se[k][i], ref[k][i]);
  calib_finish(&c, out);
  return 0;
}

int obs_metrics_patch_stderr_calib(const obs_patches *candidate, const obs_patches *se,
                                   const obs_patches *reference, obs_stderr_calib *out,
                                   obs_err *err) {
  int fc = candidate->frames > 1 ? candidate->frames : 1;
  int fs = se->frames > 1 ? se->frames : 1, fr = reference->frames > 1 ? reference->frames : 1;
  if (candidate->count != reference->count || candidate->count != se->count || fc != fr ||
      fc != fs || candidate->components != reference->components ||
      (se->components != 1 && se->components != candidate->components))
    return obs_err_set(err, OBS_EINVAL,
                       "metrics: stderr calibration of \"%s\" needs patches of one count, frames "
                       "and components in the candidate, its errors and the reference",
                       candidate->name);
  const float *area = reference->area ? reference->area : candidate->area;
  const size_t comps = (size_t)candidate->components, sc = (size_t)se->components;
  const size_t count = (size_t)candidate->count;
  calib_acc c = {0};
  int64_t unsampled = 0;
  for (size_t f = 0; f < (size_t)fc; f++)
    for (size_t i = 0; i < count; i++) {
      if (area && !(area[i] > 0)) continue;
      size_t at = f * count + i;
      if (se->values[at * sc] >= 1.0f) { /* obscurance_map: no sample reached the patch */
        unsampled++;
        continue;
      }
      for (size_t k = 0; k < comps; k++)
        calib_add(&c, candidate->values[at * comps + k], se->values[at * sc + (sc == 1 ? 0 : k)],
                  reference->values[at * comps + k]);
    }
  calib_finish(&c, out);
  out->unsampled = unsampled;
  return 0;
}
