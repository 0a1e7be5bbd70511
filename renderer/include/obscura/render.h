/* Rendering a loaded scene with its technique, and the summary that goes with the images. */
#ifndef OBSCURA_RENDER_H
#define OBSCURA_RENDER_H

#include <stdatomic.h>
#include "obscura/image.h"
#include "obscura/metrics.h"
#include "obscura/scene.h"
#include "obscura/technique.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One brick of a data-parallel (sort-last) render: each volume of the scene is cut in `count`
 * slabs along its axis with the most voxels and this render reads and owns slab `index` only
 * (plus a ghost zone as wide as the technique's AO reach, unless `no_ghost`), so its memory
 * shrinks with `count`. A camera ray counts only the isosurface hits inside the owned slab;
 * compositing the `count` renders front to back by depth gives the whole image. count 0: no
 * brick, the whole volume. Techniques that need no volumes, and every backend but the CPU,
 * refuse a brick (OBS_EUNSUPPORTED); `auto` picks the CPU backend. The caller composites the
 * bricks' images (the CLI: renderer/cli/mpi_composite.h; docs/mpi.md, "Data-parallel"). */
typedef struct obs_brick {
  int index, count; /* 0 <= index < count; count 0: none */
  int no_ghost;     /* 1: keep the slab's voxels alone (shows what the ghost zone is for) */
} obs_brick;

typedef struct obs_render_opts {
  int threads;                 /* 0 = all cores */
  obs_progress_fn progress;    /* may be NULL */
  void *progress_user;
  const atomic_int *cancel;    /* may be NULL */
  obs_region region;           /* all zero: the whole image (see obs_render_ctx.region) */
  /* NULL, or the tiles of the region this render shades (obs_tile_source): a technique that
   * renders per pixel shades only those (the rest of the image stays 0) and the result says
   * `tiled`; any other renders the whole region as without a source. */
  const obs_tile_source *tiles;
  /* NULL, or who watches the per-pixel driver's finished tiles (obs_tile_watch): renders that do
   * not go through the per-pixel driver never call it. */
  const obs_tile_watch *watch;
  /* The caller's (the CLI under `mpirun ... --distribute data`): the brick this render owns. */
  obs_brick brick;
} obs_render_opts;

/* The outcome of one render. Owns `image`, `patches`, `frames` and `built`; release with
 * obs_result_free. */
typedef struct obs_result {
  const obs_technique *technique;
  obs_backend backend;         /* the backend that ran */
  obs_image image;
  obs_timings timings;         /* load_ms/write_ms are filled by the caller that did those stages */
  int nstages;                 /* finer stages reported by the technique */
  const char *stage_names[OBS_MAX_STAGES];
  double stage_ms[OBS_MAX_STAGES];
  uint64_t rays;
  int threads;
  /* 1 when the run took its tiles from obs_render_opts.tiles (the technique renders per pixel on
   * this backend), 0 when it rendered the region itself. */
  int tiled;
  /* Processes the render was split across, set by the caller that split it (the CLI under
   * mpirun); summary.json says "ranks" when it is above 1. */
  int ranks;
  obs_patches patches[OBS_MAX_PATCH_OUTPUTS]; /* per-patch outputs (obs_render_ctx.patches) */
  int npatches;
  json_t *frames;              /* per-frame figures (obs_render_ctx.frames) or NULL; owned */
  json_t *built;               /* what was built, with sizes (obs_render_ctx.built); owned */
  int nwarnings;               /* copied from the render context; see obs_render_ctx_warn */
  char warnings[OBS_MAX_WARNINGS][OBS_WARNING_LEN];
} obs_result;

int obs_render(const obs_scene *scene, const obs_render_opts *opts, obs_result *result,
               obs_err *err);
/* Whether scene sc can render bricks (obs_render_opts.brick): 0, or OBS_EUNSUPPORTED naming why
 * (its technique reads no volumes, or its backend is not the CPU); obs_render checks it, callers
 * that split a render may say it first. */
int obs_render_brick_check(const obs_scene *sc, obs_err *err);
/* The backend a brick of sc renders on: its own, auto being the CPU (the one that renders
 * bricks). */
obs_backend obs_render_brick_backend(const obs_scene *sc);
void obs_result_free(obs_result *result);

/* Writes the result's files into DIR (creating it), all from the technique's declared outputs:
 * "<primary>.exr" with every channel of the image; the PNG of each output that names one, shown
 * as the output says (obs_output_show; an output whose channels the image lacks has none); the
 * "<name>.patches" file of each per-patch output (obscura/patches.h); summary.json. Files of an
 * earlier result in DIR that this one does not have are removed. With result->threads > 1 the
 * image files are written in parallel: the EXR's chunks on result->threads - 1 threads beside the
 * caller and each PNG on a thread of its own (same bytes for any count). Times the writes into
 * result->timings.write_ms and recomputes total_ms. */
int obs_result_write(obs_result *result, const obs_scene *scene, const char *dir, obs_err *err);
/* The summary document (new reference). */
json_t *obs_result_summary_json(const obs_result *result, const obs_scene *scene);

/* For programs that render again and again in one process (obscurad, the benchmarks): keep freed
 * image planes and G-buffers (up to 32 MiB each, 256 MiB in all) in the heap for the next render
 * instead of returning them to the kernel, which would fault every page in afresh on each render
 * (about 10 ms of a 1280x720 screen-space frame). Process-wide malloc settings (glibc mallopt; a
 * no-op elsewhere): call once at start-up, before threads start; the library never calls it. */
void obs_render_keep_memory(void);

/* Number of online cores. */
int obs_cpu_count(void);
/* Monotonic clock in milliseconds. */
double obs_now_ms(void);

#ifdef __cplusplus
}
#endif
#endif
