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

#endif
