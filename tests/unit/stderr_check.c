/* The statistical check of reported standard errors (stderr_check.h). */
#include "stderr_check.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "testutil.h"

/* c->params with $N, $L, $G and $S replaced. */
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

static void render(const obs_stderr_case *c, long n, unsigned seed, obs_result *res) {
  char params[512], size[16], name[64], backend[32];
  expand(c->params, n, seed, params, sizeof params);
  snprintf(size, sizeof size, "%d", c->size);
  snprintf(name, sizeof name, "\"%s\"", c->technique);
  snprintf(backend, sizeof backend, "\"%s\"", c->backend);
  const obs_override ov[] = {{"/image/width", size},      {"/image/height", size},
                             {"/image/spp", "1"},         {"/technique/name", name},
                             {"/technique/backend", backend}, {"/technique/params", params}};
  obs_scene sc;
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(&sc, obs_test_src(c->scene), ov, sizeof ov / sizeof ov[0], &err);
  obs_render_opts opts = {.threads = 2};
  if (!rc) rc = obs_render(&sc, &opts, res, &err);
  if (rc) printf("%s: %s\n", c->label, obs_err_message(&err));
  assert_int_equal(rc, 0);
  obs_scene_free(&sc);
  obs_err_free(&err);
}

static const obs_patches *patches_named(const obs_result *r, const char *name) {
  for (int i = 0; i < r->npatches; i++)
    if (!strcmp(r->patches[i].name, name)) return &r->patches[i];
  return NULL;
}

obs_stderr_calib obs_test_stderr_calib(const obs_stderr_case *c, long n) {
  obs_result cand, ref;
  render(c, n, 1, &cand);
  render(c, n * OBS_TEST_STDERR_FACTOR, 1000003, &ref);
  obs_stderr_calib k;
  obs_err err = OBS_ERR_INIT;
  int rc;
  if (c->patch) {
    const obs_patches *v = patches_named(&cand, c->value), *s = patches_named(&cand, c->se);
    const obs_patches *r = patches_named(&ref, c->value);
    assert_non_null(v);
    assert_non_null(s);
    assert_non_null(r);
    rc = obs_metrics_patch_stderr_calib(v, s, r, &k, &err);
  } else {
    rc = obs_metrics_stderr_calib(&cand.image, &ref.image, c->value, c->se, "alpha", &k, &err);
  }
  if (rc) printf("%s: %s\n", c->label, obs_err_message(&err));
  assert_int_equal(rc, 0);
  printf("%s at %ld: RMS stderr / RMSE %.3f (RMSE %.4g), %.2f %% within 3 sigma, %.2f %% zero with "
         "an error, over %lld values\n",
         c->label, n, k.ratio, k.rmse, 100 * k.within3, 100 * k.zero_with_error,
         (long long)k.values);
  obs_err_free(&err);
  obs_result_free(&cand);
  obs_result_free(&ref);
  return k;
}

void obs_test_stderr_check(const obs_stderr_case *c, long n) {
  obs_test_numeric_only(); /* a statistical check: renders at 64 n samples */
  obs_stderr_calib k = obs_test_stderr_calib(c, n);
  assert_true(k.values >= 100);
  assert_int_equal(k.nonfinite, 0);
  assert_true(k.ratio >= 0.67 && k.ratio <= 1.5);
  assert_true(k.zero_with_error == 0.0);
  if (n >= 16) assert_true(k.within3 >= 0.97);
}
