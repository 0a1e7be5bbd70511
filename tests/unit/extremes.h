/* The guaranteed-range conformance check shared by tests/unit/test_extremes.c (CPU) and
 * tests/vulkan/test_extremes_vk.c: every registered technique with `backend`, at both ends of its
 * declared range (obs_range), against the same view at scale 1. */
#ifndef OBS_TEST_EXTREMES_H
#define OBS_TEST_EXTREMES_H

#include "obscura/obscura.h"

/* Renders every case for every technique that runs on `backend` and prints one line per failed
 * check; returns the number of failures (0: all held). Techniques without `backend` are skipped;
 * `ran` (may be NULL) receives how many technique x backend pairs were checked. */
int obs_extremes_check_backend(obs_backend backend, int *ran);
/* Renders just outside each end of each declared range and checks that every such render
 * carries a warning naming the quantity (and that the render still succeeds or fails cleanly);
 * returns the number of failures. */
int obs_extremes_check_warnings(obs_backend backend);

/* The pieces of the check that other scale checks share (tests/unit/conformance.c): */
/* Cheap settings for the techniques the repository has ("" for others: their defaults). */
const char *obs_extremes_fast_params(const char *technique);
/* `base` (scale 1) against `scaled` (scale s) within `tol` over base's covered pixels: coverage
 * equal, the primary output's mean and share of per-pixel differences, normals, depth / s. One
 * "FAIL" line per check that fails; returns how many failed. OBS_EXTREMES_VERBOSE=1 prints the
 * deviations of every comparison; `dev` (may be NULL) receives the primary output's. */
typedef struct obs_extremes_dev {
  double mean;  /* of the primary output's |d| over the covered pixels */
  double worst; /* its largest */
  double share; /* of the covered pixels with |d| > tol->ao_pixel */
} obs_extremes_dev;
int obs_extremes_compare(const char *what, const obs_technique *t, const obs_image *base,
                         const obs_image *scaled, double s, const obs_tolerance *tol,
                         obs_extremes_dev *dev);
/* No range warning on `res`. A length far off the scene's size (OBS_LENGTH_TINY,
 * OBS_LENGTH_HUGE) still warns that the image is likely white or saturated, and a screen-space
 * radius under a pixel (obs_screen_rule) that it sees no geometry: that is about what was asked
 * for, not about precision, and the ends of a length's range are such lengths. A radius under the
 * depth precision is about precision, and must not happen inside the range. Returns 1 (after a
 * "FAIL" line per warning) when there is one. */
int obs_extremes_no_warnings(const char *what, const obs_result *res);

#endif
