/* The CPU screen-space driver: everything a screen-space technique shares on the CPU (the image,
 * the G-buffer built once, cancellation, progress, stage timings, the channel export), so that a
 * technique supplies its passes and nothing else. Internal to the CPU backend. */
#ifndef OBS_SCREEN_CPU_H
#define OBS_SCREEN_CPU_H

#include <stdatomic.h>

#include "gbuffer.h"
#include "obscura/technique.h"
#include "parallel.h"

/* How a technique's passes run: the render's threads, cancellation and progress. A technique's
 * pass functions also run outside a render (tests, benchmarks): then only `threads` is set. */
typedef struct obs_screen_cpu {
  int threads;
  const atomic_int *cancel;   /* may be NULL */
  obs_render_ctx *ctx;        /* may be NULL: stages go nowhere and progress is not reported */
  int passes;                 /* tile passes the technique runs, set before the first one */
  int done;                   /* tile passes finished */
} obs_screen_cpu;

/* One tile pass of the technique (obs_parallel_tiles over w x h) with the render's cancellation
 * (OBS_ECANCELED) and progress ((passes done + fraction of this one) / passes). */
int obs_screen_cpu_tiles(obs_screen_cpu *r, int w, int h, obs_tile_fn fn, void *user);
/* Records the time of one of the technique's stages (added to a stage of the same name). */
void obs_screen_cpu_stage(obs_screen_cpu *r, const char *name, double ms);

/* A screen-space technique on the CPU: its passes over the G-buffer `g`, writing the AO after and
 * before its blur (w x h planes each), with the params the run read. Returns 0 or a negative
 * code (OBS_ECANCELED without a message). */
typedef int (*obs_screen_cpu_passes_fn)(obs_screen_cpu *r, const obs_gbuffer *g,
                                        const void *params, float *ao, float *ao_raw,
                                        obs_err *err);

/* Allocates `out` (obs_screen_channel_names), builds the CPU G-buffer (timed as build, stage
 * "gbuffer"), runs the passes (timed as render with the export), exports the G-buffer channels
 * and clears the pixels outside ctx's region. On failure `out` is released. */
int obs_screen_cpu_run(obs_render_ctx *ctx, obs_screen_cpu_passes_fn passes, const void *params,
                       obs_image *out, obs_err *err);

/* The passes of a technique with extra channels (obs_screen_extra, gbuffer.h): as
 * obs_screen_cpu_passes_fn, and `extra` holds its extra channels' planes (extra->n planes of
 * w x h, in the order of the names). */
typedef int (*obs_screen_cpu_passes_ex_fn)(obs_screen_cpu *r, const obs_gbuffer *g,
                                           const void *params, float *ao, float *ao_raw,
                                           float *extra, obs_err *err);

/* obs_screen_cpu_run for a technique with extra channels. */
int obs_screen_cpu_run_ex(obs_render_ctx *ctx, obs_screen_cpu_passes_ex_fn passes,
                          const obs_screen_extra *extra, const void *params, obs_image *out,
                          obs_err *err);

#endif
