/* The contained mesh importer of obscurad: the pipe protocol between the daemon and its worker
 * process obscura-import, the daemon-side client that enforces time, size and sanity limits on
 * the worker's answers, and the cache of imported meshes (positive and negative). */
#ifndef SRV_MESHIMPORT_H
#define SRV_MESHIMPORT_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>
#include <time.h>

#include "geometry.h"
#include "obscura/obscura.h"

/* ---- protocol ---------------------------------------------------------------------------------
 * Little-endian host order (both ends are the same build on the same machine).
 * Request:  u32 SRV_MESH_MAGIC, u32 path_len, u32 root_len, u64 max_triangles, path, root
 * Reply:    u32 SRV_MESH_MAGIC, i32 status
 *   status 0:  u64 nverts, u64 ntris, u32 has_normals, f32 pos[3 nverts],
 *              f32 nrm[3 nverts] (if has_normals), u32 idx[3 ntris]
 *   status <0: (an OBS_E* code) u32 msg_len, msg (the import's own error, not NUL-terminated) */
#define SRV_MESH_MAGIC 0x314d424fu /* "OBM1" */
#define SRV_MESH_MAX_PATH 4096
#define SRV_MESH_MAX_MSG 4096

/* What a reply may hold: anything beyond is a protocol error, checked before allocating. */
typedef struct srv_mesh_limits {
  uint64_t max_triangles;
  uint64_t max_vertices;
} srv_mesh_limits;

enum {
  SRV_MESH_REPLY_MESH = 0,    /* *m filled */
  SRV_MESH_REPLY_ERROR = 1,   /* the worker's import failed: msg holds its message */
  SRV_MESH_REPLY_TIMEOUT = 2, /* no complete reply by the deadline */
  SRV_MESH_REPLY_EOF = 3,     /* the pipe closed (the worker died) */
  SRV_MESH_REPLY_BAD = 4      /* malformed reply: msg says what */
};

/* Reads one reply from `fd` within `timeout_ms`, checking the header against `lim` before
 * allocating and every index and coordinate after. Returns SRV_MESH_REPLY_*; on MESH, *m is owned
 * by the caller; *code gets the worker's OBS_E* code for ERROR. */
int srv_meshproto_read_reply(int fd, double timeout_ms, const srv_mesh_limits *lim, obs_mesh *m,
                             int *code, char *msg, size_t n);
/* Writes a request / reply (blocking). 0, or -1 with errno. */
int srv_meshproto_write_request(int fd, const char *path, const char *root,
                                uint64_t max_triangles);
int srv_meshproto_write_mesh(int fd, const obs_mesh *m);
int srv_meshproto_write_error(int fd, int code, const char *msg);
/* Reads a request (blocking): 0 with path and root filled (NUL-terminated, at least
 * SRV_MESH_MAX_PATH + 1 bytes each), 1 at a clean end of input, -1 when malformed. */
int srv_meshproto_read_request(int fd, char *path, char *root, uint64_t *max_triangles);

/* ---- cache ------------------------------------------------------------------------------------ */

/* A file's identity: the same path, root and inode with the same size and mtime is the same
 * content (a file rewritten within one timestamp tick at the same size would not be told apart). */
typedef struct srv_meshkey {
  const char *path, *root; /* resolved; borrowed */
  dev_t dev;
  ino_t ino;
  off_t size;
  struct timespec mtim;
} srv_meshkey;

typedef struct srv_meshcache srv_meshcache;
typedef struct srv_meshcache_stats {
  uint64_t hits, misses, entries, bytes, evictions;
} srv_meshcache_stats;

/* An LRU cache bounded to `max_bytes` (mesh arrays plus bookkeeping); 0 keeps nothing. */
srv_meshcache *srv_meshcache_new(size_t max_bytes);
void srv_meshcache_free(srv_meshcache *c);
/* 0: miss. 1: hit, *m a fresh copy the caller owns. 2: a cached failure, *code and *msg (malloc'd)
 * filled. <0: out of memory copying (counted as a miss). */
int srv_meshcache_get(srv_meshcache *c, const srv_meshkey *k, obs_mesh *m, int *code, char **msg);
/* Stores a copy of `m` / the failure under `k` (replacing what was there), evicting the least
 * recently used entries to stay within the bound; an entry larger than the bound is not kept. */
void srv_meshcache_put_mesh(srv_meshcache *c, const srv_meshkey *k, const obs_mesh *m);
void srv_meshcache_put_error(srv_meshcache *c, const srv_meshkey *k, int code, const char *msg);
void srv_meshcache_stats_get(srv_meshcache *c, srv_meshcache_stats *s);

/* ---- the importer client ---------------------------------------------------------------------- */

typedef struct srv_meshimport srv_meshimport;
typedef struct srv_meshimport_opts {
  const char *exe;          /* the worker program */
  double seconds;           /* per request, enforced here */
  int64_t memory;           /* the worker's RLIMIT_AS in bytes (0 = none) */
  int64_t max_triangles;    /* per mesh */
  size_t cache_bytes;       /* 0 = no cache */
} srv_meshimport_opts;
typedef struct srv_meshimport_stats {
  uint64_t spawns, imports, crashes, timeouts, protocol_errors;
  srv_meshcache_stats cache;
} srv_meshimport_stats;

/* Checks that opts->exe is executable; the worker is started at the first import. */
int srv_meshimport_new(const srv_meshimport_opts *o, srv_meshimport **out, obs_err *err);
/* Stops the worker (closing its pipe, then SIGKILL if it lingers) and frees everything. */
void srv_meshimport_free(srv_meshimport *mi);
/* An obs_mesh_importer (user = the srv_meshimport): the cache, else the worker (one request at a
 * time), with `path` confined to `root` by the caller. */
int srv_meshimport_import(void *user, const char *path, const char *root, obs_mesh *m,
                          obs_err *err, const char *where);
void srv_meshimport_stats_get(srv_meshimport *mi, srv_meshimport_stats *s);

#endif
