/* Previews of running jobs: the per-pixel driver's finished tiles (obs_tile_watch), copied out of
 * the render's image by the maintenance thread at most every SRV_PREVIEW_MS, written as an EXR
 * under a staging name and renamed (a reader never sees half a file), served at
 * GET /api/v1/jobs/{id}/preview.exr while the job runs and removed when it ends. The render's
 * threads only lock a mutex and append the tile's rectangle; the copy, the encoding and the
 * write happen on the maintenance thread, outside the render's timed stages. */
#include <errno.h>
#include <fcntl.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

struct srv_preview {
  int64_t job;
  const srv_app *app;
  obs_tile_watch watch;
  pthread_mutex_t mu;       /* img and the queue: taken by the render's threads once per tile */
  pthread_mutex_t read_mu;  /* held while tiles are copied out of img; end() waits for it */
  const obs_image *img;     /* the driver's image between its first tile and end() */
  obs_region *queue;        /* tiles finished since the last copy */
  int nqueue, cap;
  /* The channels a preview holds: the primary output's and alpha (the others would multiply
   * the bytes written for an image nobody looks at in full until the job ends). */
  char want[OBS_OUTPUT_MAX_CHANNELS + 1][OBS_CHANNEL_NAME_MAX];
  int nwant;
  /* The maintenance thread's own (under io_mu). */
  obs_image copy;
  int from[OBS_OUTPUT_MAX_CHANNELS + 1]; /* copy's channel k is the image's from[k] */
  double last_ms, wait_ms;              /* the last write, and the pause before the next */
  int dirty;
  struct srv_preview *next;
};

/* Registered previews: begin() prepends under list_mu; finish() unlinks under io_mu and list_mu,
 * so a tick holding io_mu may walk the list from a head read under list_mu. */
static pthread_mutex_t list_mu = PTHREAD_MUTEX_INITIALIZER;
static pthread_mutex_t io_mu = PTHREAD_MUTEX_INITIALIZER;
static srv_preview *list;

static void preview_path(const srv_app *app, int64_t id, const char *tail, char *buf, size_t n) {
  /* The .tmp-<id>- prefix: removed with the job's files and by the start-up sweep. */
  snprintf(buf, n, "%s/.tmp-%lld-preview%s", app->results_dir, (long long)id, tail);
}

static void on_tile(void *user, const obs_image *img, const obs_region *t) {
  srv_preview *p = user;
  pthread_mutex_lock(&p->mu);
  p->img = img;
  if (p->nqueue == p->cap) {
    int cap = p->cap ? 2 * p->cap : 256;
    obs_region *q = realloc(p->queue, (size_t)cap * sizeof *q);
    if (q) p->queue = q, p->cap = cap;
  }
  /* Out of memory: the tile is left out of the preview, never out of the render. */
  if (p->nqueue < p->cap) p->queue[p->nqueue++] = *t;
  pthread_mutex_unlock(&p->mu);
}

static void on_end(void *user, const obs_image *img) {
  srv_preview *p = user;
  (void)img;
  pthread_mutex_lock(&p->read_mu);
  pthread_mutex_lock(&p->mu);
  p->img = NULL;
  p->nqueue = 0;
  pthread_mutex_unlock(&p->mu);
  pthread_mutex_unlock(&p->read_mu);
}

srv_preview *srv_preview_begin(const srv_app *app, int64_t job, const char *technique) {
  const obs_technique *t = obs_technique_find(technique);
  const obs_output *prim = t ? obs_technique_primary(t) : NULL;
  srv_preview *p = prim ? calloc(1, sizeof *p) : NULL;
  if (!p) return NULL;
  p->nwant = obs_output_channels(prim, p->want);
  snprintf(p->want[p->nwant++], OBS_CHANNEL_NAME_MAX, "alpha");
  p->wait_ms = SRV_PREVIEW_MS;
  p->job = job;
  p->app = app;
  p->watch = (obs_tile_watch){on_tile, on_end, p};
  pthread_mutex_init(&p->mu, NULL);
  pthread_mutex_init(&p->read_mu, NULL);
  pthread_mutex_lock(&list_mu);
  p->next = list;
  list = p;
  pthread_mutex_unlock(&list_mu);
  return p;
}

const obs_tile_watch *srv_preview_watch(const srv_preview *p) { return p ? &p->watch : NULL; }

void srv_preview_finish(srv_preview *p) {
  if (!p) return;
  pthread_mutex_lock(&io_mu);
  pthread_mutex_lock(&list_mu);
  for (srv_preview **q = &list; *q; q = &(*q)->next)
    if (*q == p) {
      *q = p->next;
      break;
    }
  pthread_mutex_unlock(&list_mu);
  char path[4400];
  preview_path(p->app, p->job, ".exr", path, sizeof path);
  unlink(path);
  pthread_mutex_unlock(&io_mu);
  obs_image_free(&p->copy);
  free(p->queue);
  pthread_mutex_destroy(&p->mu);
  pthread_mutex_destroy(&p->read_mu);
  free(p);
}

/* Copies the tiles finished since the last call into p->copy. Returns 1 when any were. */
static int copy_tiles(srv_preview *p) {
  pthread_mutex_lock(&p->read_mu);
  pthread_mutex_lock(&p->mu);
  const obs_image *img = p->img;
  obs_region *q = p->queue;
  int n = p->nqueue;
  p->queue = NULL;
  p->nqueue = p->cap = 0;
  pthread_mutex_unlock(&p->mu);
  int copied = 0;
  obs_image *c = &p->copy;
  if (img && n && (c->width != img->width || c->height != img->height || !c->data)) {
    const char *names[OBS_OUTPUT_MAX_CHANNELS + 1];
    int k = 0;
    for (int w = 0; w < p->nwant; w++)
      for (int i = 0; i < img->nchannels; i++)
        if (!strcmp(img->names[i], p->want[w])) names[k] = p->want[w], p->from[k++] = i;
    obs_err err = OBS_ERR_INIT;
    obs_image_free(c);
    if (!k || obs_image_init(c, img->width, img->height, k, names, &err)) n = 0;
    obs_err_free(&err);
  }
  /* The tiles' pixels are final: the render's threads write other tiles meanwhile. */
  const size_t plane = img ? (size_t)img->width * (size_t)img->height : 0;
  for (int i = 0; img && i < n; i++) {
    const obs_region *t = &q[i];
    for (int k = 0; k < c->nchannels; k++)
      for (int y = t->y0; y < t->y1; y++) {
        size_t at = (size_t)y * (size_t)img->width + (size_t)t->x0;
        memcpy(c->data + (size_t)k * plane + at, img->data + (size_t)p->from[k] * plane + at,
               (size_t)(t->x1 - t->x0) * sizeof *c->data);
      }
    copied = 1;
  }
  pthread_mutex_unlock(&p->read_mu);
  free(q);
  return copied;
}

/* Writes p->copy under the staging name and renames it into place. */
static void write_preview(srv_preview *p) {
  char stage[4400], path[4400];
  preview_path(p->app, p->job, ".part", stage, sizeof stage);
  preview_path(p->app, p->job, ".exr", path, sizeof path);
  obs_err err = OBS_ERR_INIT;
  if (obs_image_write_exr(&p->copy, stage, &err) || rename(stage, path)) {
    srv_log("job %lld: preview not written: %s", (long long)p->job,
            err.count ? obs_err_message(&err) : strerror(errno));
    unlink(stage);
  } else {
    p->dirty = 0;
  }
  obs_err_free(&err);
}

void srv_preview_tick(void) {
  pthread_mutex_lock(&io_mu);
  pthread_mutex_lock(&list_mu);
  srv_preview *p = list;
  pthread_mutex_unlock(&list_mu);
  double now = obs_now_ms();
  for (; p; p = p->next) {
    if (now - p->last_ms < p->wait_ms) continue;
    if (copy_tiles(p)) p->dirty = 1;
    if (p->dirty) {
      write_preview(p);
      p->last_ms = now;
      /* A large image's write waits four times its own duration: the previews take at most a
       * fifth of this thread's time, whatever the size. */
      double took = obs_now_ms() - now;
      p->wait_ms = took * 4 > SRV_PREVIEW_MS ? took * 4 : SRV_PREVIEW_MS;
    }
  }
  pthread_mutex_unlock(&io_mu);
}

int srv_preview_serve(srv_req *r, int64_t id) {
  srv_job j;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_get_job(r->app->db, id, &j, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no job %lld", (long long)id);
  }
  if (rc) return srv_respond_unavailable(r, &err);
  srv_state st = j.state;
  char final[80] = "";
  /* A finished job's preview is its image: the EXR output (the error image is a comparison's). */
  for (int i = 0; st == SRV_SUCCEEDED && i < j.noutputs; i++) {
    const char *name = j.outputs[i].name;
    size_t n = strlen(name);
    if (n > 4 && !strcmp(name + n - 4, ".exr") && strcmp(name, "error.exr") && !final[0])
      snprintf(final, sizeof final, "/api/v1/jobs/%lld/outputs/%s", (long long)id, name);
  }
  srv_job_free(&j);
  if (final[0]) {
    struct MHD_Response *resp = MHD_create_response_from_buffer(0, "", MHD_RESPMEM_PERSISTENT);
    MHD_add_response_header(resp, "Location", final);
    MHD_add_response_header(resp, "Cache-Control", "no-store");
    return srv_respond(r, MHD_HTTP_SEE_OTHER, resp);
  }
  if (st != SRV_RUNNING)
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL,
                             "job %lld is %s: a preview exists only while a job runs, and a "
                             "finished job's is its EXR output",
                             (long long)id, srv_state_name(st));
  char path[4400];
  preview_path(r->app, id, ".exr", path, sizeof path);
  int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  struct stat sb;
  if (fd < 0 || fstat(fd, &sb) || !S_ISREG(sb.st_mode)) {
    if (fd >= 0) close(fd);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL,
                             "job %lld is running and has no preview yet: the first is written "
                             "about %d ms after its first tile; techniques that render in passes, "
                             "comparison jobs and Open MPI jobs have none",
                             (long long)id, SRV_PREVIEW_MS);
  }
  struct MHD_Response *resp = MHD_create_response_from_fd64((uint64_t)sb.st_size, fd);
  if (!resp) {
    close(fd);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "cannot serve the preview");
  }
  MHD_add_response_header(resp, "Content-Type", "image/x-exr");
  MHD_add_response_header(resp, "Cache-Control", "no-store");
  return srv_respond(r, MHD_HTTP_OK, resp);
}
