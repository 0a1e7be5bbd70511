/* bench_screen_space's measuring of one render (screen_timing.c): the scene load, the timed render
 * with its stages in table columns, the medians, and other processes' load. */
#ifndef OBS_BENCH_SCREEN_TIMING_H
#define OBS_BENCH_SCREEN_TIMING_H

#include "obscura/obscura.h"

#define MAX_REPEATS 64

/* The stages screen-space techniques report, in table order. */
enum { ST_GBUFFER, ST_DOWN, ST_AO, ST_UP, ST_BLUR, ST_READBACK, ST_COUNT };
extern const char *const screen_stage_keys[ST_COUNT];
extern const char *const screen_stage_heads[ST_COUNT];

typedef struct timing {
  double build, stage[ST_COUNT], total, wall;
  double direct; /* ss_radiosity's direct pass (stages bvh and direct), included in total */
  double total_min, total_max; /* summaries only: range of the per-run totals */
  int has[ST_COUNT];
} timing;

/* CPU time used by other processes while we measure, from /proc/stat (all CPUs) minus our own
 * (getrusage counts every thread of this process, lavapipe's included). */
typedef struct load_mark {
  double busy, total, self; /* seconds */
  int ok;
} load_mark;

/* The median of v[0..n), n <= MAX_REPEATS (v is left as it is). */
double screen_median(const double *v, int n);
/* Loads `path` with the image size and the whole technique object replaced; says why on stderr. */
int screen_load_scene(const char *path, int w, int h, const char *tech, const char *backend,
                      const char *params, obs_scene *sc);
/* One obs_render, timed. With `keep` the result is handed to the caller, else freed. */
int screen_timed_render(const obs_scene *sc, int threads, timing *t, obs_result *keep);
/* Medians over runs, field by field (the total is the median of the per-run sums). */
void screen_summarise(const timing *runs, int n, timing *s);
/* A mark of this process's and the machine's CPU time (/proc/stat, getrusage). */
load_mark screen_load_now(void);
/* Percentage of all CPUs' time that other processes used between a and b (-1 if unknown). */
double screen_load_other(load_mark a, load_mark b);

#endif
