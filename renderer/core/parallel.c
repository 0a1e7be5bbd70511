/* Dynamic tile scheduling on pthreads; results never depend on which thread ran a tile. */
#include "parallel.h"

#include <pthread.h>
#include <stdlib.h>

#include "obscura/error.h"

typedef struct pool {
  int width, height, tiles_x, ntiles, threads;
  obs_tile_fn fn;
  void *user;
  const atomic_int *cancel;
  void (*progress)(void *, double);
  void *progress_user;
  obs_tile_next_fn source; /* NULL: the grid of width x height below, counted by `next` */
  void *source_user;
  atomic_int next, done, status;
  pthread_mutex_t progress_lock;
} pool;

typedef struct worker {
  pool *p;
  int index;
} worker;

/* The next tile: from the caller's source, else the next of the grid. 1, 0 or a negative code. */
static int take_tile(pool *p, int *x0, int *y0, int *x1, int *y1) {
  if (p->source) return p->source(p->source_user, x0, y0, x1, y1);
  int t = atomic_fetch_add(&p->next, 1);
  if (t >= p->ntiles) return 0;
  *x0 = (t % p->tiles_x) * OBS_TILE, *y0 = (t / p->tiles_x) * OBS_TILE;
  *x1 = *x0 + OBS_TILE < p->width ? *x0 + OBS_TILE : p->width;
  *y1 = *y0 + OBS_TILE < p->height ? *y0 + OBS_TILE : p->height;
  return 1;
}

static void fail(pool *p, int rc) {
  int expected = 0;
  atomic_compare_exchange_strong(&p->status, &expected, rc);
}

static void *run_worker(void *arg) {
  worker *w = arg;
  pool *p = w->p;
  for (;;) {
    if (atomic_load(&p->status)) break;
    if (p->cancel && atomic_load(p->cancel)) {
      fail(p, OBS_ECANCELED);
      break;
    }
    int x0, y0, x1, y1;
    int rc = take_tile(p, &x0, &y0, &x1, &y1);
    if (rc == 0) break;
    if (rc == 1) rc = p->fn(p->user, w->index, x0, y0, x1, y1);
    if (rc) {
      fail(p, rc);
      break;
    }
    if (p->progress) {
      /* Serialised so callers need no locking of their own, and counted under the lock so the
       * fractions they receive never go back. */
      pthread_mutex_lock(&p->progress_lock);
      int d = atomic_fetch_add(&p->done, 1) + 1;
      p->progress(p->progress_user, (double)d / p->ntiles);
      pthread_mutex_unlock(&p->progress_lock);
    } else {
      atomic_fetch_add(&p->done, 1);
    }
  }
  return NULL;
}

/* Runs the pool's loop on p->threads threads, the caller's thread being one of them. */
static int run_pool(pool *p) {
  atomic_init(&p->next, 0);
  atomic_init(&p->done, 0);
  atomic_init(&p->status, 0);
  pthread_mutex_init(&p->progress_lock, NULL);
  worker *ws = calloc((size_t)p->threads, sizeof *ws);
  pthread_t *tids = calloc((size_t)p->threads, sizeof *tids);
  if (!ws || !tids) {
    free(ws);
    free(tids);
    pthread_mutex_destroy(&p->progress_lock);
    return OBS_ENOMEM;
  }
  int started = 1;
  for (int i = 0; i < p->threads; i++) {
    ws[i].p = p;
    ws[i].index = i;
  }
  for (int i = 1; i < p->threads; i++) {
    if (pthread_create(&tids[i], NULL, run_worker, &ws[i])) break;
    started++;
  }
  run_worker(&ws[0]);
  for (int i = 1; i < started; i++) pthread_join(tids[i], NULL);
  free(ws);
  free(tids);
  pthread_mutex_destroy(&p->progress_lock);
  return atomic_load(&p->status);
}

static int clamp_threads(int threads) { return threads < 1 ? 1 : threads > 256 ? 256 : threads; }

int obs_parallel_tiles(int width, int height, int threads, obs_tile_fn fn, void *user,
                       const atomic_int *cancel, void (*progress)(void *, double),
                       void *progress_user) {
  pool p = {0};
  p.width = width;
  p.height = height;
  p.tiles_x = (width + OBS_TILE - 1) / OBS_TILE;
  p.ntiles = p.tiles_x * ((height + OBS_TILE - 1) / OBS_TILE);
  p.threads = clamp_threads(threads);
  if (p.threads > p.ntiles) p.threads = p.ntiles > 0 ? p.ntiles : 1;
  p.fn = fn;
  p.user = user;
  p.cancel = cancel;
  p.progress = progress;
  p.progress_user = progress_user;
  return run_pool(&p);
}

int obs_parallel_tiles_from(obs_tile_next_fn next, void *next_user, int threads, obs_tile_fn fn,
                            void *user, const atomic_int *cancel) {
  pool p = {0};
  p.threads = clamp_threads(threads);
  p.fn = fn;
  p.user = user;
  p.cancel = cancel;
  p.source = next;
  p.source_user = next_user;
  return run_pool(&p);
}

void obs_progress_part_report(void *part, double fraction) {
  const obs_progress_part *p = part;
  p->fn(p->user, p->base + p->share * fraction);
}
