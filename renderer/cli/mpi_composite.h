/* Sort-last compositing of a data-parallel render (docs/mpi.md, "Data-parallel"): the images of
 * the ranks' bricks, merged per pixel front to back by depth into what one process renders. */
#ifndef OBSCURA_CLI_MPI_COMPOSITE_H
#define OBSCURA_CLI_MPI_COMPOSITE_H

#include "obscura/obscura.h"

/* Composites parts[0..nparts) (same size and channels, in rank order) into `out` (same size and
 * channels too; may be parts[0]). Per pixel the parts that cover it (alpha > 0) are sorted by
 * their `depth.Z` (ties: the lower rank first). When the nearest covers the pixel fully its
 * channels are copied bit for bit; otherwise they are merged with the "over" operator, as if
 * each part's covered samples were independent of the others': transmittance T starts at 1 and
 * each part, nearest first, adds T times its premultiplied values and multiplies T by (1 -
 * alpha). Channels by name: `alpha` is 1 - T; `ao` reads 1 where nothing is hit, so its
 * premultiplied value is ao - (1 - alpha) and the T left over adds 1; `depth.Z` and the unit
 * vectors (`normal.XYZ`, `bent_normal.XYZ`, renormalised) are averaged with weights T alpha;
 * every other channel is premultiplied by alpha as the renderer writes it (black where nothing is
 * hit). An uncovered pixel is parts[0]'s. OBS_EINVAL when the parts do not match. */
int cli_composite_depth(obs_image *out, const obs_image *const *parts, int nparts, obs_err *err);

#endif
