/* proximity_ao's bound on accessibility over several fields (docs/techniques/proximity_ao.md,
 * "Combination"), checked on one backend by unit.test_proximity and vulkan.test_proximity_vk. */
#ifndef OBS_PROX_BOUND_CASES_H
#define OBS_PROX_BOUND_CASES_H

#include "obscura/obscura.h"

/* A box and a ball on a ground, close enough that ground points lie in one, two and three fields,
 * rendered with scale_before 1e6 (every field that reads anything saturates at scale_after s) for
 * both combinations and s 0.8 and 0.3: every pixel in k fields (the `fields` output) has
 * accessibility >= max(0, 1 - k s) (additive) or (1 - s)^k (multiplicative), and for k = 2 and 3
 * the least such pixel equals it. Prints "FAIL ..." lines; returns their number. */
int obs_prox_bound_cases(obs_backend backend);

#endif
