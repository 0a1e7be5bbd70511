/* The statistical check every Monte-Carlo technique's standard error is held to (docs/accuracy.md,
 * "Standard errors"): a render at N samples against a reference at OBS_TEST_STDERR_FACTOR x N
 * with another seed, through obs_metrics_stderr_calib. Shared by the CPU and Vulkan tests. */
#ifndef OBS_STDERR_CHECK_H
#define OBS_STDERR_CHECK_H

#include "stderr_run.h"

#define OBS_TEST_STDERR_FACTOR 64

/* Renders the case at n samples and its reference, prints the figures and returns them. */
obs_stderr_calib obs_test_stderr_calib(const obs_stderr_case *c, long n);

/* Asserts the case's calibration at n samples: RMS stderr / RMSE within [0.67, 1.5], no value
 * with a zero stderr and a non-zero error, and from 16 samples at least 97 % within 3 stderr. */
void obs_test_stderr_check(const obs_stderr_case *c, long n);

#endif
