/* What every layer records into a render: the clock, the CPU count, the stages and warnings of a
 * render's context and result, and freeing a result. */
#include <errno.h>
#if defined(__GLIBC__) || defined(__linux__)
#include <malloc.h>
#endif
#include <jansson.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "obscura/render.h"

void obs_render_keep_memory(void) {
#if defined(M_MMAP_THRESHOLD) && defined(M_TRIM_THRESHOLD)
  /* 32 MiB is glibc's ceiling for the mmap threshold: larger blocks are always mapped afresh. */
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
}

double obs_now_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

int obs_cpu_count(void) {
  long n = sysconf(_SC_NPROCESSORS_ONLN);
  return n > 0 ? (int)n : 1;
}

void obs_result_stage_add(obs_result *r, const char *name, double ms) {
  for (int i = 0; i < r->nstages; i++)
    if (!strcmp(r->stage_names[i], name)) {
      r->stage_ms[i] += ms;
      return;
    }
  if (r->nstages >= OBS_MAX_STAGES) return;
  r->stage_names[r->nstages] = name;
  r->stage_ms[r->nstages++] = ms;
}

void obs_render_ctx_stage(obs_render_ctx *ctx, const char *name, double ms) {
  if (ctx->nstages >= OBS_MAX_STAGES) return;
  ctx->stage_names[ctx->nstages] = name;
  ctx->stage_ms[ctx->nstages++] = ms;
}

void obs_render_ctx_warn(obs_render_ctx *ctx, const char *fmt, ...) {
  if (ctx->nwarnings >= OBS_MAX_WARNINGS) return;
  char *w = ctx->warnings[ctx->nwarnings];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(w, OBS_WARNING_LEN, fmt, ap);
  va_end(ap);
  for (int i = 0; i < ctx->nwarnings; i++)
    if (!strcmp(ctx->warnings[i], w)) return;
  ctx->nwarnings++;
}

void obs_result_free(obs_result *res) {
  if (!res) return;
  obs_image_free(&res->image);
  for (int i = 0; i < res->npatches && i < OBS_MAX_PATCH_OUTPUTS; i++)
    obs_patches_free(&res->patches[i]);
  json_decref(res->frames);
  json_decref(res->built);
  memset(res, 0, sizeof *res);
}
