/* Which backend builds what ahead of a technique's run (core/driver.h's obs_needs_builder): the
 * registry knows the backends, core does not. */
#include "driver.h"
#include "techniques.h"

const obs_needs_builder *obs_backend_needs_builder(obs_backend backend) {
  return backend == OBS_BACKEND_CPU ? &obs_cpu_needs_builder : NULL;
}
