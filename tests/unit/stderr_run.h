/* One standard-error calibration run (docs/accuracy.md, "Standard errors"): a technique and
 * sampler rendered at N samples and a reference at many more with another seed, compared through
 * obs_metrics_stderr_calib. Shared by the tests' check (stderr_check.h) and bench/bench_stderr.c;
 * no test framework here. */
#ifndef OBS_STDERR_RUN_H
#define OBS_STDERR_RUN_H

#include "obscura/obscura.h"

/* The seeds of the render under test and of its reference. */
#define OBS_STDERR_SEED 1
#define OBS_STDERR_REF_SEED 1000003

/* One technique and sampler: the scene (relative to the source tree) rendered size x size with
 * one pixel sample (0: the caller's size), `technique` on `backend`, its params from `params`
 * with $N replaced by the sample count (and $L by a quarter of it, at least 4; $G by 4096 times
 * it) and $S by the seed; `value` and `se` the outputs compared (per patch when `patch`). */
typedef struct obs_stderr_case {
  const char *label, *scene, *technique, *backend, *params, *value, *se;
  int patch, size;
} obs_stderr_case;

/* Renders c at n samples and at ref_n samples (the reference), each `size` x `size` (c->size
 * when that is not 0) on `threads` threads, and fills *k with the calibration; *ms (may be NULL)
 * receives the first render's milliseconds. Returns 0, or the failing OBS_E* code with err
 * naming the case. */
int obs_stderr_run(const obs_stderr_case *c, long n, long ref_n, int size, int threads,
                   obs_stderr_calib *k, double *ms, obs_err *err);

#endif
