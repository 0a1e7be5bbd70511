/* One standard-error calibration run (stderr_run.h). */
#include "stderr_run.h"

#include <stdio.h>
#include <string.h>


/* tmpl with $N, $L (N / 4, at least 4), $G (4096 N) and $S replaced. */
static void expand(const char *tmpl, long n, unsigned seed, char *out, size_t size) {
  size_t k = 0;
  for (const char *p = tmpl; *p && k + 24 < size; p++) {
    if (*p != '$') {
      out[k++] = *p;
      continue;
    }
    long v = p[1] == 'N'   ? n
             : p[1] == 'L' ? (n / 4 > 4 ? n / 4 : 4)
             : p[1] == 'G' ? 4096 * n
                           : (long)seed;
    k += (size_t)snprintf(out + k, size - k, "%ld", v);
    p++;
  }
  out[k] = 0;
}

static int render(const obs_stderr_case *c, long n, unsigned seed, int side, int threads,
                  obs_result *res, obs_err *err) {
  char params[512], size[16], name[64], backend[32], path[1024];
  expand(c->params, n, seed, params, sizeof params);
  snprintf(size, sizeof size, "%d", side);
  snprintf(name, sizeof name, "\"%s\"", c->technique);
  snprintf(backend, sizeof backend, "\"%s\"", c->backend);
  snprintf(path, sizeof path, "%s/%s", OBS_SOURCE_DIR, c->scene);
  const obs_override ov[] = {{"/image/width", size},      {"/image/height", size},
                             {"/image/spp", "1"},         {"/technique/name", name},
                             {"/technique/backend", backend}, {"/technique/params", params}};
  obs_scene sc;
  int rc = obs_scene_load_file(&sc, path, ov, sizeof ov / sizeof ov[0], err);
  if (rc) return rc;
  obs_render_opts opts = {.threads = threads};
  rc = obs_render(&sc, &opts, res, err);
  obs_scene_free(&sc);
  return rc;
}

static const obs_patches *patches_named(const obs_result *r, const char *name) {
  for (int i = 0; i < r->npatches; i++)
    if (!strcmp(r->patches[i].name, name)) return &r->patches[i];
  return NULL;
}

int obs_stderr_run(const obs_stderr_case *c, long n, long ref_n, int size, int threads,
                   obs_stderr_calib *k, double *ms, obs_err *err) {
  obs_result cand, ref;
  memset(&cand, 0, sizeof cand);
  memset(&ref, 0, sizeof ref);
  int side = c->size ? c->size : size;
  double t0 = obs_now_ms();
  int rc = render(c, n, OBS_STDERR_SEED, side, threads, &cand, err);
  if (ms) *ms = obs_now_ms() - t0;
  if (!rc) rc = render(c, ref_n, OBS_STDERR_REF_SEED, side, threads, &ref, err);
  if (!rc && c->patch) {
    const obs_patches *v = patches_named(&cand, c->value), *s = patches_named(&cand, c->se);
    const obs_patches *r = patches_named(&ref, c->value);
    rc = v && s && r ? obs_metrics_patch_stderr_calib(v, s, r, k, err)
                     : obs_err_set(err, OBS_ENOTFOUND, "%s: no per-patch %s with %s", c->label,
                                   c->value, c->se);
  } else if (!rc) {
    rc = obs_metrics_stderr_calib(&cand.image, &ref.image, c->value, c->se, "alpha", k, err);
  }
  obs_result_free(&cand);
  obs_result_free(&ref);
  return rc;
}
