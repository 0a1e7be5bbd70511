/* Tile-parallel loops over an image: 32x32 tiles handed out dynamically to worker threads. */
#ifndef OBS_PARALLEL_H
#define OBS_PARALLEL_H

#include <stdatomic.h>

#define OBS_TILE 32

/* What a hot kernel calls per pixel or sample: inlined into each instruction-set variant of the
 * kernel (simd.h's OBS_TILE_KERNELS; a call would run the portable code whatever variant called
 * it). */
#if defined(__GNUC__)
#define OBS_HOT_INLINE static inline __attribute__((always_inline))
#else
#define OBS_HOT_INLINE static inline
#endif

/* Renders pixels [x0,x1) x [y0,y1); `thread` in [0, threads). Returns 0 or a negative code,
 * which stops the loop. */
typedef int (*obs_tile_fn)(void *user, int thread, int x0, int y0, int x1, int y1);

/* Runs fn over every tile with `threads` threads (the caller's thread is one of them). Stops
 * between tiles when *cancel becomes nonzero (returns OBS_ECANCELED) or fn fails (returns its
 * code). progress (may be NULL) receives the completed fraction after each tile, never
 * decreasing. */
int obs_parallel_tiles(int width, int height, int threads, obs_tile_fn fn, void *user,
                       const atomic_int *cancel, void (*progress)(void *, double),
                       void *progress_user);

/* One loop of several that make up a render's progress: its loop's fraction f is reported to
 * `fn` as base + share f. Pass obs_progress_part_report (NULL when fn is) and the part. */
typedef struct obs_progress_part {
  void (*fn)(void *, double);
  void *user;
  double base, share;
} obs_progress_part;
void obs_progress_part_report(void *part, double fraction);

/* Gives the next tile [*x0, *x1) x [*y0, *y1): returns 1, 0 when there are no more, or a negative
 * code (which stops the loop and is returned). Called from any of the loop's threads at once. */
typedef int (*obs_tile_next_fn)(void *user, int *x0, int *y0, int *x1, int *y1);

/* As obs_parallel_tiles, over the tiles `next` hands out (any size, any order) instead of a
 * width x height grid, and without progress: only the source knows how many tiles there are. */
int obs_parallel_tiles_from(obs_tile_next_fn next, void *next_user, int threads, obs_tile_fn fn,
                            void *user, const atomic_int *cancel);

#endif
