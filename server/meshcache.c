/* The cache of imported meshes: validation and every render of a scene ask for the same files, and
 * a file that crashed or hung the importer must not cost a worker process each time it is named.
 * Keyed by file identity, bounded in bytes, least recently used out first. Lookups are linear: the
 * bound keeps entries few, and each lookup is dwarfed by the mesh copy a hit makes. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "meshimport.h"

typedef struct entry {
  struct entry *prev, *next; /* prev: more recently used */
  char *path, *root;
  dev_t dev;
  ino_t ino;
  off_t size;
  struct timespec mtim;
  obs_mesh mesh; /* when !failed */
  int failed, code;
  char *msg;
  size_t bytes;
} entry;

struct srv_meshcache {
  pthread_mutex_t mu;
  size_t max_bytes;
  entry *head, *tail;
  srv_meshcache_stats st;
};

srv_meshcache *srv_meshcache_new(size_t max_bytes) {
  srv_meshcache *c = calloc(1, sizeof *c);
  if (!c) return NULL;
  pthread_mutex_init(&c->mu, NULL);
  c->max_bytes = max_bytes;
  return c;
}

static void entry_free(entry *e) {
  free(e->path);
  free(e->root);
  free(e->msg);
  obs_geometry_mesh_free(&e->mesh);
  free(e);
}

static void unlink_entry(srv_meshcache *c, entry *e) {
  if (e->prev) e->prev->next = e->next;
  else c->head = e->next;
  if (e->next) e->next->prev = e->prev;
  else c->tail = e->prev;
  e->prev = e->next = NULL;
  c->st.entries--;
  c->st.bytes -= e->bytes;
}

static void push_front(srv_meshcache *c, entry *e) {
  e->prev = NULL;
  e->next = c->head;
  if (c->head) c->head->prev = e;
  c->head = e;
  if (!c->tail) c->tail = e;
  c->st.entries++;
  c->st.bytes += e->bytes;
}

void srv_meshcache_free(srv_meshcache *c) {
  if (!c) return;
  for (entry *e = c->head, *n; e; e = n) {
    n = e->next;
    entry_free(e);
  }
  pthread_mutex_destroy(&c->mu);
  free(c);
}

static int same(const entry *e, const srv_meshkey *k) {
  return e->dev == k->dev && e->ino == k->ino && e->size == k->size &&
         e->mtim.tv_sec == k->mtim.tv_sec && e->mtim.tv_nsec == k->mtim.tv_nsec &&
         !strcmp(e->path, k->path) && !strcmp(e->root, k->root);
}

/* The entry of the same path and root, whatever its identity (a stale one is replaced). */
static entry *find_path(srv_meshcache *c, const srv_meshkey *k) {
  for (entry *e = c->head; e; e = e->next)
    if (!strcmp(e->path, k->path) && !strcmp(e->root, k->root)) return e;
  return NULL;
}

static int mesh_copy(const obs_mesh *from, obs_mesh *to) {
  memset(to, 0, sizeof *to);
  size_t pb = from->nverts * 3 * sizeof(float), ib = from->ntris * 3 * sizeof(uint32_t);
  to->pos = malloc(pb ? pb : 1);
  to->idx = malloc(ib ? ib : 1);
  to->nrm = from->nrm ? malloc(pb ? pb : 1) : NULL;
  if (!to->pos || !to->idx || (from->nrm && !to->nrm)) {
    obs_geometry_mesh_free(to);
    return OBS_ENOMEM;
  }
  memcpy(to->pos, from->pos, pb);
  memcpy(to->idx, from->idx, ib);
  if (from->nrm) memcpy(to->nrm, from->nrm, pb);
  to->nverts = from->nverts;
  to->ntris = from->ntris;
  to->object = from->object;
  return 0;
}

int srv_meshcache_get(srv_meshcache *c, const srv_meshkey *k, obs_mesh *m, int *code, char **msg) {
  memset(m, 0, sizeof *m);
  *msg = NULL;
  pthread_mutex_lock(&c->mu);
  entry *e = find_path(c, k);
  int rc = 0;
  if (e && same(e, k)) {
    unlink_entry(c, e);
    push_front(c, e);
    if (e->failed) {
      *code = e->code;
      *msg = strdup(e->msg);
      rc = *msg ? 2 : OBS_ENOMEM;
    } else {
      rc = mesh_copy(&e->mesh, m) ? OBS_ENOMEM : 1;
    }
  }
  if (rc > 0) c->st.hits++;
  else c->st.misses++;
  pthread_mutex_unlock(&c->mu);
  return rc;
}

static void evict_to(srv_meshcache *c, size_t room) {
  while (c->tail && c->st.bytes + room > c->max_bytes) {
    entry *e = c->tail;
    unlink_entry(c, e);
    entry_free(e);
    c->st.evictions++;
  }
}

/* Takes ownership of `e` (fully built, bytes set): inserted, or freed when it cannot fit. */
static void insert(srv_meshcache *c, const srv_meshkey *k, entry *e) {
  e->path = strdup(k->path);
  e->root = strdup(k->root);
  e->dev = k->dev;
  e->ino = k->ino;
  e->size = k->size;
  e->mtim = k->mtim;
  e->bytes += sizeof *e + strlen(k->path) + strlen(k->root) + 2;
  pthread_mutex_lock(&c->mu);
  entry *old = find_path(c, k);
  if (old) {
    unlink_entry(c, old);
    entry_free(old);
  }
  if (!e->path || !e->root || e->bytes > c->max_bytes) {
    pthread_mutex_unlock(&c->mu);
    entry_free(e);
    return;
  }
  evict_to(c, e->bytes);
  push_front(c, e);
  pthread_mutex_unlock(&c->mu);
}

void srv_meshcache_put_mesh(srv_meshcache *c, const srv_meshkey *k, const obs_mesh *m) {
  size_t bytes = (m->nverts * (m->nrm ? 6 : 3)) * sizeof(float) + m->ntris * 3 * sizeof(uint32_t);
  if (bytes > c->max_bytes) return; /* not worth copying what cannot be kept */
  entry *e = calloc(1, sizeof *e);
  if (!e) return;
  if (mesh_copy(m, &e->mesh)) {
    free(e);
    return;
  }
  e->bytes = bytes;
  insert(c, k, e);
}

void srv_meshcache_put_error(srv_meshcache *c, const srv_meshkey *k, int code, const char *msg) {
  entry *e = calloc(1, sizeof *e);
  if (!e) return;
  e->failed = 1;
  e->code = code;
  e->msg = strdup(msg);
  if (!e->msg) {
    free(e);
    return;
  }
  e->bytes = strlen(msg) + 1;
  insert(c, k, e);
}

void srv_meshcache_stats_get(srv_meshcache *c, srv_meshcache_stats *s) {
  pthread_mutex_lock(&c->mu);
  *s = c->st;
  pthread_mutex_unlock(&c->mu);
}
