/* Image-parallel `obscura render` under mpirun (docs/mpi.md). Every rank loads the scene and
 * builds its BVH itself; rank 0 keeps the queue of 16x16 tiles, which its own render threads take
 * from directly and the other ranks on request, answered by a communication thread on rank 0 (as
 * OSPRay's MPI offload device hands out tiles). The others send each finished tile's pixels to
 * rank 0, which pastes them into its image and writes the outputs as one process would. A pixel's
 * bits depend only on (pixel, sample, seed), never on the rank or thread that shaded it. */
#define _GNU_SOURCE /* sched_getaffinity, CPU_COUNT */
#include "mpi_render.h"
#include "mpi_composite.h"

#include <mpi.h>
#include <pthread.h>
#include <sched.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* Small enough that 2-3 ranks share even the tests' 48x32 images, big enough (a few ms of rt_ao
 * each) that a request per tile costs little; the next request is sent while a tile renders. */
#define TILE 16
/* Waits poll with growing naps instead of blocking in MPI: Open MPI's blocking calls spin a core,
 * which a rank's own render threads (or, oversubscribed, another rank) need. */
#define NAP_MIN_US 10
#define NAP_MAX_US 500

enum { TAG_REQUEST = 1, TAG_GRANT, TAG_TILE, TAG_BYE, TAG_BRICK };
enum { BYE_TILED = 0, BYE_IDLE = 1 };
/* A grant's answer besides a tile index: -1, the queue is empty; GRANT_LATER, a request made
 * ahead was declined because few tiles are left (ask again when one is needed). */
enum { GRANT_NONE = -1, GRANT_LATER = -2 };

struct cli_mpi {
  int rank, size;
};

/* Which rank this process is, for messages from any thread (one MPI job per process). */
static int g_rank = -1;

/* A tile's pixels as a worker sends them: this header, then nch planes of the tile's pixels in
 * row order (channel order of the image). */
typedef struct tile_head {
  int32_t index, nch;
} tile_head;

/* What a worker says when its render is over. */
typedef struct bye_msg {
  int32_t state, pad;
  uint64_t rays;
} bye_msg;

/* The tiles of a width x height image, numbered row by row. */
typedef struct grid {
  int width, height, tiles_x, ntiles;
} grid;

static grid grid_of(int width, int height) {
  grid g = {width, height, (width + TILE - 1) / TILE, 0};
  g.ntiles = g.tiles_x * ((height + TILE - 1) / TILE);
  return g;
}

static obs_region grid_tile(const grid *g, int t) {
  obs_region r = {(t % g->tiles_x) * TILE, (t / g->tiles_x) * TILE, 0, 0};
  r.x1 = r.x0 + TILE < g->width ? r.x0 + TILE : g->width;
  r.y1 = r.y0 + TILE < g->height ? r.y0 + TILE : g->height;
  return r;
}

static int grid_index(const grid *g, const obs_region *r) {
  return r->y0 / TILE * g->tiles_x + r->x0 / TILE;
}

static size_t region_pixels(const obs_region *r) {
  return (size_t)(r->x1 - r->x0) * (size_t)(r->y1 - r->y0);
}

static int env_int(const char *name, int fallback) {
  const char *v = getenv(name);
  if (!v || !*v) return fallback;
  char *end;
  long n = strtol(v, &end, 10);
  return *end || n < 0 || n > 1 << 24 ? fallback : (int)n;
}

int cli_mpi_env_size(void) { return env_int("OMPI_COMM_WORLD_SIZE", 1); }
int cli_mpi_env_rank(void) { return env_int("OMPI_COMM_WORLD_RANK", 0); }
int cli_mpi_rank(const cli_mpi *m) { return m->rank; }

int cli_mpi_threads(void) {
  cpu_set_t set;
  if (sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0) return CPU_COUNT(&set);
  return obs_cpu_count();
}

int cli_mpi_tty(void) {
  char link[64], target[256];
  snprintf(link, sizeof link, "/proc/%ld/fd/2", (long)getppid());
  ssize_t n = readlink(link, target, sizeof target - 1);
  if (n <= 0) return 0;
  target[n] = '\0';
  return !strncmp(target, "/dev/pts/", 9) || !strncmp(target, "/dev/tty", 8);
}

static void nap(int *us) {
  struct timespec ts = {0, (long)*us * 1000};
  nanosleep(&ts, NULL);
  *us = *us * 2 > NAP_MAX_US ? NAP_MAX_US : *us * 2;
}

/* The job cannot go on: say why, then end every rank (mpirun exits non-zero and names this
 * one), since the others may be waiting for tiles or answers from this rank. */
static _Noreturn void fail_job(int code, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static _Noreturn void fail_job(int code, const char *fmt, ...) {
  char msg[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  fprintf(stderr, "obscura: rank %d: %s\n", g_rank, msg);
  fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, code);
  abort(); /* MPI_Abort does not return; this keeps the promise if it did */
}

/* MPI_COMM_WORLD returns errors (MPI_ERRORS_RETURN) so that the message names the call. */
static void mpi_check(int rc, const char *call) {
  if (rc == MPI_SUCCESS) return;
  char msg[MPI_MAX_ERROR_STRING];
  int len = 0;
  if (MPI_Error_string(rc, msg, &len) != MPI_SUCCESS) snprintf(msg, sizeof msg, "error %d", rc);
  fail_job(EXIT_FAILURE, "%s failed: %s", call, msg);
}

static void wait_request(MPI_Request *req, const char *call) {
  int us = NAP_MIN_US, flag = 0;
  for (;;) {
    mpi_check(MPI_Test(req, &flag, MPI_STATUS_IGNORE), call);
    if (flag) return;
    nap(&us);
  }
}

/* Test hook (tests/cli/mpi.sh): OBSCURA_MPI_TEST_ABORT_RANK=R makes rank R abort() after its first
 * finished tile, as a crashed rank would (called after each tile, and once more when its render is
 * over, for a rank that got no tile). */
static void test_abort_hook(const char *when) {
  if (env_int("OBSCURA_MPI_TEST_ABORT_RANK", -1) != g_rank) return;
  fprintf(stderr, "obscura: rank %d: aborting %s (test hook OBSCURA_MPI_TEST_ABORT_RANK)\n", g_rank,
          when);
  fflush(stderr);
  abort();
}

int cli_mpi_init(cli_mpi **out, obs_err *err) {
  *out = NULL;
  int provided = MPI_THREAD_SINGLE;
  if (MPI_Init_thread(NULL, NULL, MPI_THREAD_MULTIPLE, &provided) != MPI_SUCCESS)
    return obs_err_set(err, OBS_EINTERNAL, "obscura: MPI_Init_thread failed");
  cli_mpi *m = calloc(1, sizeof *m);
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  /* Calls come from several threads (rank 0's communication thread, a worker's render threads)
   * but never two at once: a worker's tile source holds its lock around them, and rank 0's main
   * thread leaves MPI to the communication thread while it runs. SERIALIZED is enough. */
  if (!m || provided < MPI_THREAD_SERIALIZED) {
    free(m);
    MPI_Finalize();
    return m ? obs_err_set(err, OBS_EUNSUPPORTED,
                           "obscura: this MPI library gives thread level %d; a split render "
                           "needs MPI_THREAD_SERIALIZED (%d) or more",
                           provided, MPI_THREAD_SERIALIZED)
             : obs_err_set(err, OBS_ENOMEM, "obscura: out of memory");
  }
  mpi_check(MPI_Comm_rank(MPI_COMM_WORLD, &m->rank), "MPI_Comm_rank");
  mpi_check(MPI_Comm_size(MPI_COMM_WORLD, &m->size), "MPI_Comm_size");
  g_rank = m->rank;
  *out = m;
  return 0;
}

void cli_mpi_finish(cli_mpi *m) {
  if (!m) return;
  MPI_Finalize();
  free(m);
}

int cli_mpi_loaded(cli_mpi *m, int code, const obs_err *err) {
  int *all = calloc((size_t)m->size, sizeof *all);
  if (!all) fail_job(EXIT_FAILURE, "out of memory");
  mpi_check(MPI_Allgather(&code, 1, MPI_INT, all, 1, MPI_INT, MPI_COMM_WORLD), "MPI_Allgather");
  int exit_code = all[0];
  for (int r = 1; r < m->size && !exit_code; r++) exit_code = all[r];
  int rank0_failed = all[0] != 0;
  free(all);
  /* Every rank reads the same files, so rank 0's problems are everyone's: said once. A worker
   * that failed where rank 0 did not (a host without the file) says why itself. */
  if (code && m->rank == 0)
    fprintf(stderr, "%s\n", obs_err_message(err));
  else if (code && !rank0_failed)
    fprintf(stderr, "obscura: rank %d: %s\n", m->rank, obs_err_message(err));
  return exit_code;
}

/* Every rank renders on rank 0's choice of backend: `auto` may choose differently on machines with
 * and without a device, and two backends' tiles must not meet in one image. */
static int agree_backend(cli_mpi *m, obs_scene *sc, obs_err *err) {
  int be = 0;
  if (m->rank == 0) {
    obs_backend b;
    be = obs_technique_pick_backend(sc->technique, sc->backend, &b, err);
    if (!be) be = (int)obs_technique_motion_backend(sc->technique, sc, b);
  }
  mpi_check(MPI_Bcast(&be, 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Bcast");
  if (be < 0) return be;
  sc->backend = (obs_backend)be;
  return 0;
}

/* ---- rank 0: the tile queue, its own tile source and the communication thread ---- */

enum { TILE_QUEUED = 0, TILE_OUT, TILE_DONE };

typedef struct master {
  cli_mpi *m;
  grid g;
  pthread_mutex_t lock; /* everything below, and the progress bar */
  int next;             /* the first tile not handed out */
  int finished;         /* tiles done on any rank */
  unsigned char *state; /* TILE_* per tile */
  int *owner;           /* the rank each tile went to */
  float **parts;        /* the pixels of the tiles other ranks rendered (tile_head's layout) */
  int *part_nch;
  uint64_t worker_rays; /* of the ranks that rendered tiles */
  int byes, idle;       /* workers done; of them, those whose run took no tiles */
  cli_progress *pr;
  obs_tile_source src;
} master;

/* The next queued tile for `rank`, or -1 when none is left. */
static int master_take(master *ms, int rank) {
  pthread_mutex_lock(&ms->lock);
  int t = ms->next < ms->g.ntiles ? ms->next++ : GRANT_NONE;
  if (t >= 0) {
    ms->state[t] = TILE_OUT;
    ms->owner[t] = rank;
  }
  pthread_mutex_unlock(&ms->lock);
  return t;
}

/* Marks tile t done (pixels stored in parts[t] when another rank rendered it) and moves the bar. */
static void master_finished(master *ms, int t, float *pixels, int nch) {
  pthread_mutex_lock(&ms->lock);
  ms->state[t] = TILE_DONE;
  ms->parts[t] = pixels;
  ms->part_nch[t] = nch;
  ms->finished++;
  if (ms->pr) cli_progress_draw(ms->pr, (double)ms->finished / ms->g.ntiles);
  pthread_mutex_unlock(&ms->lock);
}

static int master_next(void *user, obs_region *tile) {
  master *ms = user;
  int t = master_take(ms, 0);
  if (t < 0) return 0;
  *tile = grid_tile(&ms->g, t);
  return 1;
}

static int master_done(void *user, const obs_image *img, const obs_region *tile, uint64_t rays) {
  master *ms = user;
  (void)img, (void)rays; /* rank 0 renders into the image it writes; its rays are its result's */
  master_finished(ms, grid_index(&ms->g, tile), NULL, 0);
  test_abort_hook("after its first tile");
  return 0;
}

/* A worker's finished tile: checked against what was handed to it, then kept. */
static void master_take_tile(master *ms, const MPI_Status *st) {
  int bytes = 0;
  mpi_check(MPI_Get_count(st, MPI_BYTE, &bytes), "MPI_Get_count");
  unsigned char *buf = malloc(bytes > 0 ? (size_t)bytes : 1);
  if (!buf) fail_job(EXIT_FAILURE, "out of memory");
  mpi_check(
      MPI_Recv(buf, bytes, MPI_BYTE, st->MPI_SOURCE, TAG_TILE, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
      "MPI_Recv (tile pixels)");
  tile_head h = {-1, 0};
  if ((size_t)bytes >= sizeof h) memcpy(&h, buf, sizeof h);
  int t = h.index;
  int ok = t >= 0 && t < ms->g.ntiles && h.nch > 0 && h.nch <= OBS_IMAGE_MAX_CHANNELS;
  if (ok) {
    obs_region r = grid_tile(&ms->g, t);
    pthread_mutex_lock(&ms->lock);
    ok = ms->state[t] == TILE_OUT && ms->owner[t] == st->MPI_SOURCE;
    pthread_mutex_unlock(&ms->lock);
    ok = ok && (size_t)bytes == sizeof h + (size_t)h.nch * region_pixels(&r) * sizeof(float);
  }
  if (!ok)
    fail_job(EXIT_FAILURE,
             "rank %d sent tile %d (%d bytes), which is not a tile it was "
             "given or not its size",
             st->MPI_SOURCE, t, bytes);
  float *pixels = malloc((size_t)bytes - sizeof h);
  if (!pixels) fail_job(EXIT_FAILURE, "out of memory");
  memcpy(pixels, buf + sizeof h, (size_t)bytes - sizeof h);
  free(buf);
  master_finished(ms, t, pixels, h.nch);
}

static void master_handle(master *ms, const MPI_Status *st) {
  int src = st->MPI_SOURCE;
  if (st->MPI_TAG == TAG_REQUEST) {
    int32_t held = 0; /* the worker's requests out before this one: tiles it will have first */
    mpi_check(MPI_Recv(&held, 1, MPI_INT32_T, src, TAG_REQUEST, MPI_COMM_WORLD,
                       MPI_STATUS_IGNORE),
              "MPI_Recv (tile request)");
    /* Near the end a tile parked in a worker's queue may leave another rank idle: requests made
     * ahead get no tile once fewer than 4 per rank are left. */
    pthread_mutex_lock(&ms->lock);
    int few = ms->g.ntiles - ms->next < 4 * ms->m->size;
    pthread_mutex_unlock(&ms->lock);
    int t = held > 0 && few ? GRANT_LATER : master_take(ms, src);
    mpi_check(MPI_Send(&t, 1, MPI_INT, src, TAG_GRANT, MPI_COMM_WORLD), "MPI_Send (tile grant)");
  } else if (st->MPI_TAG == TAG_TILE) {
    master_take_tile(ms, st);
  } else if (st->MPI_TAG == TAG_BYE) {
    bye_msg b;
    mpi_check(
        MPI_Recv(&b, (int)sizeof b, MPI_BYTE, src, TAG_BYE, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
        "MPI_Recv (end of render)");
    ms->byes++;
    if (b.state == BYE_IDLE)
      ms->idle++;
    else
      ms->worker_rays += b.rays;
  } else {
    fail_job(EXIT_FAILURE, "rank %d sent a message with unknown tag %d", src, st->MPI_TAG);
  }
}

/* The communication thread: answers every worker until each has said its render is over. */
static void *master_serve(void *arg) {
  master *ms = arg;
  int us = NAP_MIN_US;
  while (ms->byes < ms->m->size - 1) {
    int flag = 0;
    MPI_Status st;
    mpi_check(MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st), "MPI_Iprobe");
    if (!flag) {
      nap(&us);
      continue;
    }
    us = NAP_MIN_US;
    master_handle(ms, &st);
  }
  return NULL;
}

static void master_free(master *ms) {
  for (int t = 0; ms->parts && t < ms->g.ntiles; t++) free(ms->parts[t]);
  free(ms->parts);
  free(ms->part_nch);
  free(ms->state);
  free(ms->owner);
  pthread_mutex_destroy(&ms->lock);
}

static void master_init(master *ms, cli_mpi *m, const obs_scene *sc, cli_progress *pr) {
  memset(ms, 0, sizeof *ms);
  ms->m = m;
  ms->g = grid_of(sc->width, sc->height);
  size_t n = (size_t)ms->g.ntiles;
  ms->state = calloc(n, sizeof *ms->state);
  ms->owner = calloc(n, sizeof *ms->owner);
  ms->parts = calloc(n, sizeof *ms->parts);
  ms->part_nch = calloc(n, sizeof *ms->part_nch);
  pthread_mutex_init(&ms->lock, NULL);
  if (!ms->state || !ms->owner || !ms->parts || !ms->part_nch)
    fail_job(EXIT_FAILURE, "out of memory");
  ms->pr = pr && (pr->tty || pr->fd > 0) ? pr : NULL;
  ms->src = (obs_tile_source){master_next, master_done, ms};
}

/* Pastes the other ranks' tiles into rank 0's image, which holds rank 0's own already. */
static void master_assemble(master *ms, obs_image *img) {
  const size_t plane = (size_t)img->width * (size_t)img->height;
  for (int t = 0; t < ms->g.ntiles; t++) {
    if (ms->state[t] != TILE_DONE)
      fail_job(EXIT_FAILURE, "tile %d of %d never came back from rank %d", t, ms->g.ntiles,
               ms->owner[t]);
    if (!ms->parts[t]) continue;
    if (ms->part_nch[t] != img->nchannels)
      fail_job(EXIT_FAILURE, "rank %d rendered %d channels, rank 0 %d", ms->owner[t],
               ms->part_nch[t], img->nchannels);
    obs_region r = grid_tile(&ms->g, t);
    const float *src = ms->parts[t];
    for (int c = 0; c < img->nchannels; c++)
      for (int y = r.y0; y < r.y1; y++) {
        size_t n = (size_t)(r.x1 - r.x0);
        memcpy(img->data + (size_t)c * plane + (size_t)y * (size_t)img->width + (size_t)r.x0, src,
               n * sizeof *src);
        src += n;
      }
  }
}

static int master_render(cli_mpi *m, obs_scene *sc, const obs_render_opts *opts, cli_progress *pr,
                         obs_result *res, obs_err *err) {
  master ms;
  master_init(&ms, m, sc, pr);
  obs_render_opts o = *opts;
  o.tiles = &ms.src;
  pthread_t tid;
  if (pthread_create(&tid, NULL, master_serve, &ms))
    fail_job(EXIT_FAILURE, "cannot start the communication thread");
  int rc = obs_render(sc, &o, res, err);
  test_abort_hook("at the end of its render, which got no tile");
  if (rc) fail_job(rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE, "%s", obs_err_message(err));
  /* The render is not over until the last worker's tile is in. */
  double t0 = obs_now_ms();
  pthread_join(tid, NULL);
  double wait_ms = obs_now_ms() - t0;
  res->timings.render_ms += wait_ms;
  res->timings.total_ms += wait_ms;
  obs_result_stage_add(res, "wait", wait_ms);
  res->ranks = m->size;
  if (res->tiled) {
    master_assemble(&ms, &res->image);
    res->rays += ms.worker_rays;
    /* Right bytes still (rank 0 rendered what they left), but not the split asked for. */
    if (ms.idle && res->nwarnings < OBS_MAX_WARNINGS)
      snprintf(res->warnings[res->nwarnings++], OBS_WARNING_LEN,
               "%d of the %d other ranks judged the run not per pixel and rendered no tile: "
               "rank 0 rendered their share",
               ms.idle, m->size - 1);
  } else if (res->nwarnings < OBS_MAX_WARNINGS) {
    char others[32] = "rank";
    if (m->size > 2) snprintf(others, sizeof others, "%d ranks", m->size - 1);
    snprintf(res->warnings[res->nwarnings++], OBS_WARNING_LEN,
             "technique \"%s\" on the %s backend does not render per pixel, so the render was "
             "not split: rank 0 rendered it alone and the other %s idled",
             res->technique->name, obs_backend_name(res->backend), others);
  }
  master_free(&ms);
  return 0;
}

/* ---- the other ranks: a tile source that asks rank 0 ---- */

typedef struct pending_send {
  MPI_Request req;
  void *buf;
} pending_send;

/* Most tile requests a worker keeps out while it renders one tile. */
#define MAX_AHEAD 4
#define RING (MAX_AHEAD + 1)

typedef struct worker {
  grid g;
  pthread_mutex_t lock; /* every MPI call of the render, and everything below */
  /* Requests out, answered in the order sent (MPI keeps the order of two ranks' messages): a
   * ring of `asking` from `head`. Rank 0's communication thread shares a core with rank 0's
   * render thread and may answer late; a few tiles asked ahead keep this rank busy meanwhile. */
  MPI_Request grant_req[RING];
  int grant[RING]; /* the tiles rank 0 answered with; -1: none left */
  int head, asking, ahead;
  int exhausted;       /* rank 0 has no more tiles */
  pending_send *sends; /* tiles on their way to rank 0; their buffers are ours until sent */
  int nsends, cap;
  /* Raised by worker_progress: this rank's run does not render per pixel. */
  atomic_int cancel;
  obs_tile_source src;
} worker;

static void worker_ask(worker *w) {
  int i = (w->head + w->asking) % RING;
  mpi_check(MPI_Irecv(&w->grant[i], 1, MPI_INT, 0, TAG_GRANT, MPI_COMM_WORLD, &w->grant_req[i]),
            "MPI_Irecv (tile grant)");
  int32_t held = w->asking;
  mpi_check(MPI_Send(&held, 1, MPI_INT32_T, 0, TAG_REQUEST, MPI_COMM_WORLD),
            "MPI_Send (tile request)");
  w->asking++;
}

/* The answer to the oldest request out. */
static int worker_answer(worker *w) {
  wait_request(&w->grant_req[w->head], "MPI_Irecv (tile grant)");
  int t = w->grant[w->head];
  w->head = (w->head + 1) % RING;
  w->asking--;
  return t;
}

/* Frees the buffers of the tiles rank 0 has received. Under w->lock. */
static void worker_reap(worker *w) {
  for (int i = 0; i < w->nsends;) {
    int flag = 0;
    mpi_check(MPI_Test(&w->sends[i].req, &flag, MPI_STATUS_IGNORE), "MPI_Test (tile pixels)");
    if (!flag) {
      i++;
      continue;
    }
    free(w->sends[i].buf);
    w->sends[i] = w->sends[--w->nsends];
  }
}

static int worker_next(void *user, obs_region *tile) {
  worker *w = user;
  pthread_mutex_lock(&w->lock);
  int t = -1;
  if (!w->exhausted) {
    /* `ahead` more stay out while this tile renders, so their answers are here when needed. A
     * request made ahead that rank 0 declined (the last tiles go one at a time) ends asking
     * ahead; the tile is asked for again. */
    for (;;) {
      while (w->asking <= w->ahead) worker_ask(w);
      t = worker_answer(w);
      if (t != GRANT_LATER) break;
      w->ahead = 0;
    }
    if (t < 0) {
      /* The queue is empty for good: the requests still out are answered -1 too. */
      w->exhausted = 1;
      while (w->asking) worker_answer(w);
    }
  }
  worker_reap(w);
  pthread_mutex_unlock(&w->lock);
  if (t < 0) return 0;
  if (t >= w->g.ntiles) fail_job(EXIT_FAILURE, "rank 0 gave tile %d of %d", t, w->g.ntiles);
  *tile = grid_tile(&w->g, t);
  return 1;
}

static int worker_done(void *user, const obs_image *img, const obs_region *r, uint64_t rays) {
  worker *w = user;
  (void)rays; /* the result's total goes to rank 0 at the end */
  const size_t plane = (size_t)img->width * (size_t)img->height, row = (size_t)(r->x1 - r->x0);
  size_t bytes = sizeof(tile_head) + (size_t)img->nchannels * region_pixels(r) * sizeof(float);
  unsigned char *buf = malloc(bytes);
  if (!buf) return OBS_ENOMEM;
  tile_head h = {grid_index(&w->g, r), img->nchannels};
  memcpy(buf, &h, sizeof h);
  float *dst = (float *)(buf + sizeof h);
  for (int c = 0; c < img->nchannels; c++)
    for (int y = r->y0; y < r->y1; y++, dst += row)
      memcpy(dst, img->data + (size_t)c * plane + (size_t)y * (size_t)img->width + (size_t)r->x0,
             row * sizeof *dst);
  pthread_mutex_lock(&w->lock);
  if (w->nsends == w->cap) {
    int cap = w->cap ? w->cap * 2 : 8;
    pending_send *s = realloc(w->sends, (size_t)cap * sizeof *s);
    if (!s) fail_job(EXIT_FAILURE, "out of memory");
    w->sends = s, w->cap = cap;
  }
  pending_send *p = &w->sends[w->nsends++];
  p->buf = buf;
  mpi_check(MPI_Isend(buf, (int)bytes, MPI_BYTE, 0, TAG_TILE, MPI_COMM_WORLD, &p->req),
            "MPI_Isend (tile pixels)");
  worker_reap(w);
  pthread_mutex_unlock(&w->lock);
  test_abort_hook("after its first tile");
  return 0;
}

/* The per-pixel driver reports no progress while it takes tiles from a source, so a run that
 * reports progress does not render per pixel: rank 0 renders it alone, and this rank stops its
 * own copy at the run's next cancellation point instead of taking cores from rank 0. */
static void worker_progress(void *user, double fraction) {
  worker *w = user;
  (void)fraction;
  atomic_store(&w->cancel, 1);
}

static int worker_render(obs_scene *sc, int size, const obs_render_opts *opts, obs_err *err) {
  worker w;
  memset(&w, 0, sizeof w);
  w.g = grid_of(sc->width, sc->height);
  /* Asking ahead holds tiles back from the other ranks: only when there are plenty. */
  w.ahead = w.g.ntiles / (8 * size);
  w.ahead = w.ahead < 1 ? 1 : w.ahead > MAX_AHEAD ? MAX_AHEAD : w.ahead;
  pthread_mutex_init(&w.lock, NULL);
  atomic_init(&w.cancel, 0);
  w.src = (obs_tile_source){worker_next, worker_done, &w};
  obs_render_opts o = *opts;
  o.tiles = &w.src;
  o.progress = worker_progress;
  o.progress_user = &w;
  o.cancel = &w.cancel;
  obs_result res;
  int rc = obs_render(sc, &o, &res, err);
  test_abort_hook("at the end of its render, which got no tile");
  int idle = (rc == 0 && !res.tiled) || (rc == OBS_ECANCELED && atomic_load(&w.cancel));
  if (rc && !idle)
    fail_job(rc == OBS_EINVAL ? EXIT_BAD_INPUT : EXIT_FAILURE, "%s", obs_err_message(err));
  obs_err_clear(err);
  /* Every tile's pixels reach rank 0 before the goodbye (messages between two ranks keep their
   * order), and no request may be left unanswered. */
  int us = NAP_MIN_US;
  for (;;) {
    worker_reap(&w);
    if (!w.nsends) break;
    nap(&us);
  }
  if (w.asking) fail_job(EXIT_FAILURE, "the render ended with a tile request still out");
  bye_msg b = {idle ? BYE_IDLE : BYE_TILED, 0, idle ? 0 : res.rays};
  mpi_check(MPI_Send(&b, (int)sizeof b, MPI_BYTE, 0, TAG_BYE, MPI_COMM_WORLD),
            "MPI_Send (end of render)");
  obs_result_free(&res);
  free(w.sends);
  pthread_mutex_destroy(&w.lock);
  return 0;
}

/* ---- data-parallel: each rank renders its brick of the volumes, rank 0 composites ---- */

/* What a rank sends rank 0 after its brick's render: this header, then its image's channel
 * planes, one message each. */
typedef struct brick_head {
  int32_t width, height, nch, pad;
  uint64_t rays;
} brick_head;

/* A worker's image, sent to rank 0 (waits with naps, not spinning, as every wait here). */
static void brick_send(const obs_result *r) {
  const obs_image *im = &r->image;
  brick_head h = {im->width, im->height, im->nchannels, 0, r->rays};
  size_t plane = (size_t)im->width * (size_t)im->height;
  MPI_Request req;
  mpi_check(MPI_Isend(&h, (int)sizeof h, MPI_BYTE, 0, TAG_BRICK, MPI_COMM_WORLD, &req),
            "MPI_Isend (brick header)");
  wait_request(&req, "MPI_Isend (brick header)");
  for (int c = 0; c < im->nchannels; c++) {
    mpi_check(MPI_Isend(im->data + (size_t)c * plane, (int)plane, MPI_FLOAT, 0, TAG_BRICK,
                        MPI_COMM_WORLD, &req),
              "MPI_Isend (brick pixels)");
    wait_request(&req, "MPI_Isend (brick pixels)");
  }
}

/* Rank `src`'s image into `im` (rank 0's names), its rays added to *rays. */
static void brick_recv(int src, const obs_image *mine, obs_image *im, uint64_t *rays) {
  brick_head h;
  MPI_Request req;
  mpi_check(MPI_Irecv(&h, (int)sizeof h, MPI_BYTE, src, TAG_BRICK, MPI_COMM_WORLD, &req),
            "MPI_Irecv (brick header)");
  wait_request(&req, "MPI_Irecv (brick header)");
  if (h.width != mine->width || h.height != mine->height || h.nch != mine->nchannels)
    fail_job(EXIT_FAILURE, "rank %d rendered a %dx%d image of %d channels, rank 0 %dx%d of %d",
             src, h.width, h.height, h.nch, mine->width, mine->height, mine->nchannels);
  *im = *mine;
  size_t plane = (size_t)h.width * (size_t)h.height;
  if (!(im->data = malloc((size_t)h.nch * plane * sizeof *im->data)))
    fail_job(EXIT_FAILURE, "out of memory");
  for (int c = 0; c < h.nch; c++) {
    mpi_check(MPI_Irecv(im->data + (size_t)c * plane, (int)plane, MPI_FLOAT, src, TAG_BRICK,
                        MPI_COMM_WORLD, &req),
              "MPI_Irecv (brick pixels)");
    wait_request(&req, "MPI_Irecv (brick pixels)");
  }
  *rays += h.rays;
}

/* Collective: whether every rank's brick rendered. A rank that failed where rank 0 did not says
 * why itself; rank 0 returns the first failure's code (its own message in `err`). */
static int bricks_rendered(cli_mpi *m, int rc, obs_err *err) {
  int *all = calloc((size_t)m->size, sizeof *all);
  if (!all) fail_job(EXIT_FAILURE, "out of memory");
  /* Not MPI_Allgather: a rank done early would spin in it on a core a slower rank renders on. */
  MPI_Request req;
  mpi_check(MPI_Iallgather(&rc, 1, MPI_INT, all, 1, MPI_INT, MPI_COMM_WORLD, &req),
            "MPI_Iallgather");
  wait_request(&req, "MPI_Iallgather");
  int first = 0, rank0 = all[0];
  for (int r = 0; r < m->size && !first; r++) first = all[r];
  free(all);
  if (rc && m->rank > 0 && !rank0)
    fprintf(stderr, "obscura: rank %d: %s\n", m->rank, obs_err_message(err));
  if (first && m->rank == 0 && !rank0)
    obs_err_set(err, first, "obscura: another rank could not render its brick (it said why)");
  return first;
}

static int data_render(cli_mpi *m, obs_scene *sc, const obs_render_opts *opts, obs_result *res,
                       obs_err *err) {
  obs_render_opts o = *opts;
  o.brick.index = m->rank;
  o.brick.count = m->size;
  if (m->rank > 0) o.progress = NULL;
  obs_result mine;
  int rc = obs_render(sc, &o, &mine, err);
  /* The render is not over until the last rank's image is in and composited. */
  double t0 = obs_now_ms();
  if ((rc = bricks_rendered(m, rc, err))) {
    obs_result_free(&mine);
    return rc;
  }
  if (m->rank > 0) {
    brick_send(&mine);
    obs_result_free(&mine);
    return 0;
  }
  const obs_image **parts = calloc((size_t)m->size, sizeof *parts);
  obs_image *theirs = calloc((size_t)m->size, sizeof *theirs);
  if (!parts || !theirs) fail_job(EXIT_FAILURE, "out of memory");
  parts[0] = &mine.image;
  for (int r = 1; r < m->size; r++) {
    brick_recv(r, &mine.image, &theirs[r], &mine.rays);
    parts[r] = &theirs[r];
  }
  /* The composite overwrites rank 0's image, which it reads pixel by pixel before writing. */
  rc = cli_composite_depth(&mine.image, parts, m->size, sc->technique, err);
  for (int r = 1; r < m->size; r++) free(theirs[r].data);
  free(theirs);
  free(parts);
  if (rc) fail_job(EXIT_FAILURE, "%s", obs_err_message(err));
  double wait_ms = obs_now_ms() - t0;
  mine.timings.render_ms += wait_ms;
  mine.timings.total_ms += wait_ms;
  obs_result_stage_add(&mine, "wait", wait_ms);
  mine.ranks = m->size;
  *res = mine;
  return 0;
}

int cli_mpi_render(cli_mpi *m, obs_scene *sc, const obs_render_opts *opts, cli_progress *pr,
                   obs_result *res, obs_err *err) {
  memset(res, 0, sizeof *res);
  /* Bricks render on the CPU backend only: `auto` must not pick another on some rank. */
  if (opts->brick.count > 0) sc->backend = obs_render_brick_backend(sc);
  obs_err quiet = OBS_ERR_INIT;
  int rc = agree_backend(m, sc, m->rank == 0 ? err : &quiet);
  obs_err_free(&quiet);
  if (rc) return rc;
  if (opts->brick.count > 0) return data_render(m, sc, opts, res, err);
  return m->rank == 0 ? master_render(m, sc, opts, pr, res, err)
                      : worker_render(sc, m->size, opts, err);
}
