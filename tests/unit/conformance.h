/* The conformance suite over the registry, shared by tests/unit/test_conformance.c (CPU) and
 * tests/vulkan/test_conformance_vk.c: every registered technique x backend goes through the same
 * checks, so a technique is covered by registering it. */
#ifndef OBS_TEST_CONFORMANCE_H
#define OBS_TEST_CONFORMANCE_H

#include "obscura/obscura.h"

/* The checks, each run over every technique that has `backend` (others are skipped). Each prints
 * one line per failure and returns the number of failures; `ran` (may be NULL) receives how many
 * technique x backend pairs were checked. */

/* Defaults on a small scene: every channel finite and the primary output in the range its kind
 * allows. */
int obs_conformance_defaults(obs_backend backend, int *ran);
/* Every parameter at both ends of its declared range (and every choice of an enum, both values of
 * a flag), the others at their defaults but for the technique's other cost drivers, held small
 * (conformance.c, end_companions): the render succeeds, finite and in range. The sanitizer
 * builds leave the two costliest ends to the release build (conformance.c, release_only_end). */
int obs_conformance_param_ends(obs_backend backend, int *ran);
/* The same bits for 1, 2 and 3 threads. */
int obs_conformance_threads(obs_backend backend, int *ran);
/* The scene and every length parameter scaled by 1e-4 and by 1e4: the primary output equals the
 * scale-1 render within the tolerance the backend declares (obs_range.tol). */
int obs_conformance_scales(obs_backend backend, int *ran);
/* A room whose wall triangles have normal components that cancel to exactly 0 (dx dy - dy dx),
 * rendered at scale 1 and at 24 factors spread over the backend's guaranteed size range (both
 * ends included), every other one translated: each equals the scale-1 render within the declared
 * tolerance (obs_range.tol) and carries no range warning. Prints how many factors give scale 1's
 * bits. */
int obs_conformance_cancellation(obs_backend backend, int *ran);
/* Scenes the technique cannot handle (a backend it lacks, a need of its descriptor unmet) give a
 * clean error that names the problem, and nothing is left allocated. */
int obs_conformance_refusals(obs_backend backend, int *ran);

#endif
