/* bench_screen_space's measuring of one render: loading a scene with the technique replaced, one
 * timed obs_render split into the screen-space stage columns, medians over runs, and the CPU time
 * other processes used meanwhile. */
#include "screen_timing.h"

#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "bench_args.h"

double screen_median(const double *v, int n) {
  double s[MAX_REPEATS];
  memcpy(s, v, (size_t)n * sizeof *s);
  return bench_median(s, n);
}

/* ---- loading and timing one render ------------------------------------------------------- */

/* Loads `path` with the image size and the whole technique object replaced. */
int screen_load_scene(const char *path, int w, int h, const char *tech, const char *backend,
                      const char *params, obs_scene *sc) {
  char wb[16], hb[16], tb[1024];
  snprintf(wb, sizeof wb, "%d", w);
  snprintf(hb, sizeof hb, "%d", h);
  snprintf(tb, sizeof tb, "{\"name\":\"%s\",\"backend\":\"%s\",\"params\":%s}", tech, backend,
           params);
  obs_override ov[3] = {{"/image/width", wb}, {"/image/height", hb}, {"/technique", tb}};
  obs_err err = OBS_ERR_INIT;
  int rc = obs_scene_load_file(sc, path, ov, 3, &err);
  if (rc) fprintf(stderr, "bench_screen_space: %s: %s\n", path, obs_err_message(&err));
  obs_err_free(&err);
  return rc;
}

const char *const screen_stage_keys[ST_COUNT] = {"gbuffer", "downsample", "ao",
                                                 "upsample", "blur", "readback"};
const char *const screen_stage_heads[ST_COUNT] = {"gbuffer", "down", "ao", "up", "blur", "readbk"};

/* One obs_render, timed. With `keep` the result is handed to the caller, else freed. */
int screen_timed_render(const obs_scene *sc, int threads, timing *t, obs_result *keep) {
  obs_render_opts opts = {.threads = threads};
  obs_result res;
  obs_err err = OBS_ERR_INIT;
  double t0 = obs_now_ms();
  int rc = obs_render(sc, &opts, &res, &err);
  double t1 = obs_now_ms();
  if (rc) {
    fprintf(stderr, "bench_screen_space: render (%s, %s): %s\n", sc->technique->name,
            obs_backend_name(sc->backend), obs_err_message(&err));
    obs_err_free(&err);
    return rc;
  }
  memset(t, 0, sizeof *t);
  t->wall = t1 - t0;
  t->build = res.timings.build_ms;
  for (int i = 0; i < res.nstages; i++) {
    int k = 0;
    /* ss_radiosity's gather is its AO pass; its direct pass has a column of its own. */
    const char *name = strcmp(res.stage_names[i], "gather") ? res.stage_names[i] : "ao";
    if (!strcmp(name, "bvh") || !strcmp(name, "direct")) {
      t->direct += res.stage_ms[i];
      t->total += res.stage_ms[i];
      continue;
    }
    while (k < ST_COUNT && strcmp(screen_stage_keys[k], name)) k++;
    /* obs_render's accounting stages (the rest of the total around the passes: the G-buffer's
     * geometry, the device, allocations) have no column and stay out of the passes' total. */
    static const char *const rest = " prepare device geometry other ";
    char key[40];
    snprintf(key, sizeof key, " %s ", res.stage_names[i]);
    if (k == ST_COUNT && strstr(rest, key)) continue;
    if (k == ST_COUNT) {
      fprintf(stderr, "bench_screen_space: unknown stage \"%s\" (counted in the total only)\n",
              res.stage_names[i]);
    } else {
      t->stage[k] += res.stage_ms[i];
      t->has[k] = 1;
    }
    t->total += res.stage_ms[i];
  }
  if (keep)
    *keep = res;
  else
    obs_result_free(&res);
  return 0;
}

/* Medians over runs, field by field (the total is the median of the per-run sums). */
void screen_summarise(const timing *runs, int n, timing *s) {
  double v[MAX_REPEATS];
  memset(s, 0, sizeof *s);
  for (int k = 0; k < ST_COUNT; k++) {
    for (int i = 0; i < n; i++) v[i] = runs[i].stage[k];
    s->stage[k] = screen_median(v, n);
    s->has[k] = runs[0].has[k];
  }
  for (int i = 0; i < n; i++) v[i] = runs[i].total;
  s->total = screen_median(v, n);
  s->total_min = s->total_max = v[0];
  for (int i = 1; i < n; i++) {
    if (v[i] < s->total_min) s->total_min = v[i];
    if (v[i] > s->total_max) s->total_max = v[i];
  }
  for (int i = 0; i < n; i++) v[i] = runs[i].wall;
  s->wall = screen_median(v, n);
  for (int i = 0; i < n; i++) v[i] = runs[i].build;
  s->build = screen_median(v, n);
  for (int i = 0; i < n; i++) v[i] = runs[i].direct;
  s->direct = screen_median(v, n);
}

/* ---- other load on the machine ---------------------------------------------------------- */

load_mark screen_load_now(void) {
  load_mark m = {0, 0, 0, 0};
  FILE *f = fopen("/proc/stat", "r");
  unsigned long long v[8] = {0};
  if (f) {
    m.ok = fscanf(f, "cpu %llu %llu %llu %llu %llu %llu %llu %llu", &v[0], &v[1], &v[2], &v[3],
                  &v[4], &v[5], &v[6], &v[7]) == 8;
    fclose(f);
  }
  double tick = (double)sysconf(_SC_CLK_TCK);
  if (!(tick > 0)) m.ok = 0;
  if (m.ok) {
    m.busy = (double)(v[0] + v[1] + v[2] + v[5] + v[6] + v[7]) / tick;
    m.total = m.busy + (double)(v[3] + v[4]) / tick;
  }
  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru) == 0)
    m.self = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
             (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
  else
    m.ok = 0;
  return m;
}

/* Percentage of all CPUs' time that other processes used between a and b (-1 if unknown). */
double screen_load_other(load_mark a, load_mark b) {
  if (!a.ok || !b.ok || !(b.total > a.total)) return -1;
  double other = (b.busy - a.busy) - (b.self - a.self);
  return other < 0 ? 0 : 100.0 * other / (b.total - a.total);
}
