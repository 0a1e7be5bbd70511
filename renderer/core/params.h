/* Internal side of technique parameters (params.c): the document validation the scene loader
 * runs and the pieces the registry's generated texts share. The public API is in
 * obscura/technique.h. */
#ifndef OBS_PARAMS_H
#define OBS_PARAMS_H

#include <jansson.h>

#include "json_util.h"
#include "obscura/technique.h"

/* Validates `value` (a params object, may be NULL) against t's table, reporting every problem
 * under p's pointer, and returns a new object with defaults filled in (table order after the
 * given members), or NULL after reporting. */
json_t *obs_params_resolve(obs_jpath *p, const obs_technique *t, const json_t *value);
/* The technique's cross-field rules (t->rules) on resolved `params`, reported under
 * "/technique/params" of document `doc`. */
void obs_params_check_rules(const obs_technique *t, const json_t *params, const char *doc,
                            obs_err *err);
/* One value against its entry; reports under p's pointer. Returns 0 or OBS_EINVAL. */
int obs_param_check(obs_jpath *p, const obs_param *d, const json_t *v);
/* The declared parameter name nearest to `name` by edit distance when it is close enough to be a
 * likely typo (at most a third of its letters, between 1 and 3), else NULL. */
const char *obs_params_nearest(const obs_technique *t, const char *name);
/* The entry's default as JSON (new reference). */
json_t *obs_param_default_json(const obs_param *d);
/* The entry as a JSON Schema (new reference): type, range or choices, default, description. */
json_t *obs_param_schema(const obs_param *d);
/* The faults of one entry of a table bound into `bound_size` bytes that do not need its default
 * (a type, a description, an offset inside the struct, a range its type stores): writes why
 * into `why` and returns non-zero, or returns 0. */
int obs_param_entry_fault(const obs_param *d, size_t bound_size, char *why, size_t n);

#endif
