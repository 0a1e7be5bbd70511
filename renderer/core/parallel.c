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
  atomic_int next, done, status;
  pthread_mutex_t progress_lock;
} pool;

typedef struct worker {
  pool *p;
  int index;
} worker;

static void *run_worker(void *arg) {
  worker *w = arg;
  pool *p = w->p;
  for (;;) {
    if (atomic_load(&p->status)) break;
    if (p->cancel && atomic_load(p->cancel)) {
      int expected = 0;
      atomic_compare_exchange_strong(&p->status, &expected, OBS_ECANCELED);
      break;
    }
    int t = atomic_fetch_add(&p->next, 1);
    if (t >= p->ntiles) break;
    int x0 = (t % p->tiles_x) * OBS_TILE, y0 = (t / p->tiles_x) * OBS_TILE;
    int x1 = x0 + OBS_TILE < p->width ? x0 + OBS_TILE : p->width;
    int y1 = y0 + OBS_TILE < p->height ? y0 + OBS_TILE : p->height;
    int rc = p->fn(p->user, w->index, x0, y0, x1, y1);
    if (rc) {
      int expected = 0;
      atomic_compare_exchange_strong(&p->status, &expected, rc);
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

int obs_parallel_tiles(int width, int height, int threads, obs_tile_fn fn, void *user,
                       const atomic_int *cancel, void (*progress)(void *, double),
                       void *progress_user) {
  pool p = {0};
  p.width = width;
  p.height = height;
  p.tiles_x = (width + OBS_TILE - 1) / OBS_TILE;
  p.ntiles = p.tiles_x * ((height + OBS_TILE - 1) / OBS_TILE);
  p.threads = threads < 1 ? 1 : threads > 256 ? 256 : threads;
  if (p.threads > p.ntiles) p.threads = p.ntiles > 0 ? p.ntiles : 1;
  p.fn = fn;
  p.user = user;
  p.cancel = cancel;
  p.progress = progress;
  p.progress_user = progress_user;
  atomic_init(&p.next, 0);
  atomic_init(&p.done, 0);
  atomic_init(&p.status, 0);
  pthread_mutex_init(&p.progress_lock, NULL);
  worker *ws = calloc((size_t)p.threads, sizeof *ws);
  pthread_t *tids = calloc((size_t)p.threads, sizeof *tids);
  if (!ws || !tids) {
    free(ws);
    free(tids);
    pthread_mutex_destroy(&p.progress_lock);
    return OBS_ENOMEM;
  }
  int started = 1;
  for (int i = 0; i < p.threads; i++) {
    ws[i].p = &p;
    ws[i].index = i;
  }
  for (int i = 1; i < p.threads; i++) {
    if (pthread_create(&tids[i], NULL, run_worker, &ws[i])) break;
    started++;
  }
  run_worker(&ws[0]);
  for (int i = 1; i < started; i++) pthread_join(tids[i], NULL);
  free(ws);
  free(tids);
  pthread_mutex_destroy(&p.progress_lock);
  return atomic_load(&p.status);
}
