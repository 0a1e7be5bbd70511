/* The metrics of one comparison candidate on the primary output its technique declares (or the
 * output an alternative reference compares), of any kind, by obs_metrics_compare_all: scalar
 * outputs as they are, RGB outputs with their RGB figures and on their luminance, depth on its ".Z"
 * channel, per-patch outputs on their rendered channel plus the area-weighted RMSE over the
 * patches against a per-patch reference. */
#include <errno.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "compare_internal.h"
#include "obscura/metric_table.h"
#include "obscurad.h"

/* The technique whose result lies in `dir`, from its summary.json; rt_ao for a result written
 * before summaries named anything else (every such result is an AO one). */
static const obs_technique *result_technique(const char *dir) {
  char path[4300];
  snprintf(path, sizeof path, "%s/summary.json", dir);
  json_t *sum = json_load_file(path, 0, NULL);
  const obs_technique *t = obs_technique_find(json_string_value(json_object_get(sum, "technique")));
  json_decref(sum);
  return t ? t : obs_technique_find("rt_ao");
}

static int read_exr(const char *dir, const obs_technique *t, obs_image *img, obs_err *err) {
  char name[OBS_OUTPUT_FILE_MAX], path[4300];
  obs_technique_exr_name(t, name, sizeof name);
  snprintf(path, sizeof path, "%s/%s", dir, name);
  return obs_image_read_exr(img, path, err);
}

/* Replaces `img` by its luminance image for RGB output `o` of `t`. */
static int to_luminance(const obs_technique *t, const obs_output *o, obs_image *img,
                        obs_err *err) {
  const char *se = obs_technique_stderr_name(t, o->name);
  obs_image y;
  int rc = obs_metrics_luminance_image(img, o->name, se, &y, err);
  if (rc) return rc;
  obs_image_free(img);
  *img = y;
  return 0;
}

static int patch_rmse(const char *dir, const char *rdir, const obs_output *o, double *rmse,
                      obs_err *err) {
  char name[OBS_OUTPUT_FILE_MAX], path[4300];
  obs_output_patch_file(o, name, sizeof name);
  obs_patches c, r;
  snprintf(path, sizeof path, "%s/%s", dir, name);
  int rc = obs_patches_read(&c, path, err);
  if (rc) return rc;
  snprintf(path, sizeof path, "%s/%s", rdir, name);
  rc = obs_patches_read(&r, path, err);
  if (!rc) rc = obs_metrics_patch_rmse(&c, &r, rmse, err);
  obs_patches_free(&c);
  obs_patches_free(&r);
  return rc;
}

/* Moves staged file `stage` to `final` (removing the stage when that fails). */
static int put_in_place(int rc, const char *stage, const char *final, obs_err *err) {
  if (!rc && rename(stage, final))
    rc = obs_err_set(err, OBS_EIO, "%s: cannot rename into place: %s", final, strerror(errno));
  if (rc) unlink(stage);
  return rc;
}

/* Writes `dir`/reference_mapped.png: the reference's output `o` after the candidate's response
 * mapping, as the candidate's own PNG shows it (linear grey), so the dashboard's slider shows what
 * the metrics compared; and reference_mapped.exr, the same values as floats under the candidate's
 * channel names (with the reference's noise and coverage), so the viewer's A - B at a pixel is the
 * error the metrics summed. Staged and renamed like the error images. */
static int write_mapped_reference(const obs_image *ref, const obs_output *o, const char *dir,
                                  obs_err *err) {
  char stage[4300], final[4300];
  snprintf(stage, sizeof stage, "%s/.%s.new", dir, SRV_MAPPED_REFERENCE_PNG);
  snprintf(final, sizeof final, "%s/%s", dir, SRV_MAPPED_REFERENCE_PNG);
  const char *ch[1] = {o->name};
  int rc = put_in_place(obs_image_write_png(ref, ch, 1, 0, stage, err), stage, final, err);
  if (rc) return rc;
  char se[OBS_CHANNEL_NAME_MAX + 8];
  snprintf(se, sizeof se, "%s_stderr", o->name);
  const char *want[3] = {o->name, se, "alpha"};
  const char *names[3];
  int n = 0;
  for (int i = 0; i < 3; i++)
    if (obs_image_channel(ref, want[i])) names[n++] = want[i];
  obs_image out;
  memset(&out, 0, sizeof out);
  rc = obs_image_init(&out, ref->width, ref->height, n, names, err);
  size_t px = (size_t)ref->width * (size_t)ref->height;
  for (int i = 0; !rc && i < n; i++)
    memcpy(obs_image_channel(&out, names[i]), obs_image_channel(ref, names[i]),
           px * sizeof(float));
  snprintf(stage, sizeof stage, "%s/.%s.new", dir, SRV_MAPPED_REFERENCE_EXR);
  snprintf(final, sizeof final, "%s/%s", dir, SRV_MAPPED_REFERENCE_EXR);
  if (!rc) rc = put_in_place(obs_image_write_exr(&out, stage, err), stage, final, err);
  obs_image_free(&out);
  return rc;
}

int srv_compare_primary(const char *dir, const char *rdir, obs_response resp,
                        obs_metric_values *m, json_t *extra, obs_image *eimg, obs_image *flip,
                        obs_err *err) {
  const obs_technique *t = result_technique(dir), *rt = result_technique(rdir);
  /* The candidate's primary output, or the one an alternative reference compares. */
  const obs_output *o = obs_technique_compared_output(t, rt);
  if (!o) return obs_err_set(err, OBS_EINVAL, "technique %s declares no primary output", t->name);
  obs_image cand, ref;
  memset(&cand, 0, sizeof cand);
  memset(&ref, 0, sizeof ref);
  char channel[OBS_CHANNEL_NAME_MAX + 4];
  snprintf(channel, sizeof channel, o->kind == OBS_OUTPUT_DEPTH ? "%s.Z" : "%s", o->name);
  int rc = read_exr(dir, t, &cand, err);
  if (!rc) rc = read_exr(rdir, rt, &ref, err);
  const obs_output *ro = obs_technique_primary(rt);
  /* A scalar reference of another kind of output (rt_ao's ao for obscurance's W, in RGB with
   * equal channels, or obscurance_map's per-patch W shown per pixel) is compared with that
   * output's per-pixel luminance or channel. */
  int scalar_ref = !rc && ro && ro->kind == OBS_OUTPUT_SCALAR && o->kind != OBS_OUTPUT_SCALAR;
  int renamed = !rc && ro && (ro->kind == o->kind || scalar_ref) && strcmp(ro->name, o->name);
  if (renamed) {
    obs_image_rename_output(&ref, ro->name, o->name);
    /* The reference's noise follows it under the name the metrics look for, "<output>_stderr"
     * (which is the candidate's own stderr output's name where it has one). */
    const char *rs = obs_technique_stderr_name(rt, ro->name);
    char cs[OBS_CHANNEL_NAME_MAX];
    snprintf(cs, sizeof cs, "%s_stderr", o->name);
    if (rs) obs_image_rename_output(&ref, rs, cs);
  }
  /* Response curves map AO; an identity mapping leaves any output as it is. */
  if (!rc && resp != OBS_RESPONSE_IDENTITY) rc = obs_response_apply(resp, &ref, err);
  if (!rc && resp != OBS_RESPONSE_IDENTITY && o->kind == OBS_OUTPUT_SCALAR &&
      o->show == OBS_SHOW_GREY)
    rc = write_mapped_reference(&ref, o, dir, err);
  if (!rc && o->kind == OBS_OUTPUT_VECTOR)
    rc = obs_err_set(err, OBS_EUNSUPPORTED, "no metrics for the vector output \"%s\"", o->name);
  float *ra = obs_image_channel(&ref, "alpha");
  const char *mask = ra ? "alpha" : NULL;
  /* Against another technique's output, only pixels both cover count: obscurance_map has no
   * patch on an analytic sphere (alpha 0) where rt_ao sees one. */
  const float *ca = scalar_ref ? obs_image_channel(&cand, "alpha") : NULL;
  if (ra && ca && cand.width == ref.width && cand.height == ref.height)
    for (size_t i = 0; i < (size_t)ref.width * (size_t)ref.height; i++) ra[i] *= ca[i];
  if (!rc && o->kind == OBS_OUTPUT_RGB && scalar_ref) rc = to_luminance(t, o, &cand, err);
  /* Every metric of the table that applies: an RGB output's RGB figures and HDR-FLIP, and the
   * scalar ones on its luminance (the reference's noise from its standard error's). */
  obs_metric_opts mo = {.channel = channel, .mask = mask, .flip_map = flip};
  if (!rc) rc = obs_metrics_compare_all(&cand, &ref, &mo, m, err);
  if (!rc && o->kind == OBS_OUTPUT_RGB && !scalar_ref) {
    rc = to_luminance(t, o, &cand, err);
    if (!rc) rc = to_luminance(renamed ? t : rt, o, &ref, err);
  }
  if (!rc) rc = obs_metrics_error_image(&cand, &ref, channel, mask, eimg, err);
  double prmse;
  if (!rc && o->kind == OBS_OUTPUT_PATCH && ro && ro->kind == OBS_OUTPUT_PATCH &&
      !(rc = patch_rmse(dir, rdir, o, &prmse, err))) {
    m->v[OBS_METRIC_PATCH_RMSE] = prmse;
    m->has[OBS_METRIC_PATCH_RMSE] = 1;
  }
  if (!rc && strcmp(o->name, "ao")) json_object_set_new(extra, "output", json_string(o->name));
  obs_image_free(&cand);
  obs_image_free(&ref);
  return rc;
}

int srv_compare_output(const char *dir, const char *rdir, const char *output, json_t *metrics,
                       obs_err *err) {
  const obs_technique *t = result_technique(dir), *rt = result_technique(rdir);
  const obs_output_pair *q = t->compared_outputs;
  while (q && q->output && strcmp(q->output, output)) q++;
  const obs_output *o = obs_technique_output(t, output);
  const obs_output *ro = q && q->output ? obs_technique_output(rt, q->reference_output) : NULL;
  if (!o || !ro)
    return obs_err_set(err, OBS_EINVAL, "%s does not compare its output \"%s\" with %s's",
                       t->name, output, rt->name);
  obs_image cand, ref;
  memset(&cand, 0, sizeof cand);
  memset(&ref, 0, sizeof ref);
  int rc = read_exr(dir, t, &cand, err);
  if (!rc) rc = read_exr(rdir, rt, &ref, err);
  if (!rc && strcmp(ro->name, o->name)) obs_image_rename_output(&ref, ro->name, o->name);
  obs_metric_opts opts = {.channel = o->name,
                          .mask = obs_image_channel(&ref, "alpha") ? "alpha" : NULL};
  obs_metric_values v;
  if (!rc) rc = obs_metrics_compare_all(&cand, &ref, &opts, &v, err);
  if (!rc) rc = obs_metric_values_json(&v, metrics);
  if (!rc) {
    json_object_set_new(metrics, "output", json_string(o->name));
    json_object_set_new(metrics, "reference_output", json_string(ro->name));
  }
  obs_image_free(&cand);
  obs_image_free(&ref);
  return rc;
}
