/* Sort-last compositing of a data-parallel render (docs/mpi.md, "Data-parallel"): the images of
 * the ranks' bricks, merged per pixel front to back by depth into what one process renders. */
#ifndef OBSCURA_CLI_MPI_COMPOSITE_H
#define OBSCURA_CLI_MPI_COMPOSITE_H

#include "obscura/obscura.h"

/* Composites parts[0..nparts) (same size and channels, in rank order) into `out` (same size and
 * channels too; may be parts[0]), the images of technique `t`. Per pixel the parts that cover it
 * (alpha > 0) are sorted by their depth (ties: the lower rank first). When the nearest covers the
 * pixel fully its channels are copied bit for bit; otherwise they are merged with the "over"
 * operator, as if each part's covered samples were independent of the others': transmittance T
 * starts at 1 and each part, nearest first, adds T times its covered share and multiplies T by
 * (1 - alpha). The channels follow t's outputs: `alpha` is 1 - T; a scalar or RGB output with
 * background b (obs_output.background) holds a alpha x + (1 - alpha) b, so its covered share is
 * the value less (1 - alpha) b and the T left over adds T b; depth and vector outputs (renormalised)
 * are averaged with weights T alpha. An uncovered pixel is parts[0]'s. OBS_EINVAL when the parts
 * do not match or a channel is none of t's outputs'. */
int cli_composite_depth(obs_image *out, const obs_image *const *parts, int nparts,
                        const obs_technique *t, obs_err *err);

#endif
