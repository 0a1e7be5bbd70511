/* obscurad's contained mesh importer: assimp runs in a long-lived worker process (obscura-import,
 * started with posix_spawn, never a fork of this multithreaded daemon), one request at a time;
 * this side enforces the time limit with poll(), checks every answer, kills and reaps a worker
 * that crashed, hung or spoke garbage, and starts the next one when a mesh is next needed. Results
 * (failures included) are cached by file identity, so validation and renders import a file once
 * and a file that kills the worker costs one worker, not one per request. */
#define _GNU_SOURCE /* pipe2 */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "meshimport.h"
#include "obscurad.h"

extern char **environ;

struct srv_meshimport {
  srv_meshimport_opts o;
  char exe[PATH_MAX];
  pthread_mutex_t mu; /* the worker: one request at a time */
  pid_t pid;          /* 0: none running */
  int to_fd, from_fd;
  srv_meshcache *cache;
  atomic_ullong spawns, imports, crashes, timeouts, protocol_errors;
};

int srv_meshimport_new(const srv_meshimport_opts *o, srv_meshimport **out, obs_err *err) {
  *out = NULL;
  if (access(o->exe, X_OK))
    return obs_err_set(err, OBS_EIO, "mesh importer %s: %s (it is built next to obscurad; "
                       "--mesh-importer names another)", o->exe, strerror(errno));
  srv_meshimport *mi = calloc(1, sizeof *mi);
  if (!mi) return obs_err_set(err, OBS_ENOMEM, "out of memory");
  mi->o = *o;
  snprintf(mi->exe, sizeof mi->exe, "%s", o->exe);
  mi->o.exe = mi->exe;
  mi->to_fd = mi->from_fd = -1;
  pthread_mutex_init(&mi->mu, NULL);
  mi->cache = srv_meshcache_new(o->cache_bytes);
  if (!mi->cache) {
    free(mi);
    return obs_err_set(err, OBS_ENOMEM, "out of memory");
  }
  *out = mi;
  return 0;
}

/* Reaps the worker. `kill_it`: SIGKILL first (hung or misbehaving); otherwise it is known to
 * have exited or to exit on EOF. Returns the wait status, or -1 when there was none. */
static int stop_worker(srv_meshimport *mi, int kill_it) {
  if (!mi->pid) return -1;
  if (mi->to_fd >= 0) close(mi->to_fd);
  if (mi->from_fd >= 0) close(mi->from_fd);
  mi->to_fd = mi->from_fd = -1;
  int status = -1;
  if (!kill_it) {
    /* A worker that closed its pipe is normally dying already; one that closed it and lives on
     * must not hold the importer's lock: it gets 100 ms, then the kill. */
    for (int i = 0; i < 20 && waitpid(mi->pid, &status, WNOHANG) == 0; i++) usleep(5000);
    if (waitpid(mi->pid, &status, WNOHANG) != 0) {
      mi->pid = 0;
      return status;
    }
  }
  kill(mi->pid, SIGKILL);
  while (waitpid(mi->pid, &status, 0) < 0 && errno == EINTR) {
  }
  mi->pid = 0;
  return status;
}

void srv_meshimport_free(srv_meshimport *mi) {
  if (!mi) return;
  if (mi->pid) {
    /* Closing its input ends an idle worker; one still busy is not waited for. */
    close(mi->to_fd);
    mi->to_fd = -1;
    int status;
    for (int i = 0; i < 50 && waitpid(mi->pid, &status, WNOHANG) == 0; i++) usleep(10000);
    if (waitpid(mi->pid, &status, WNOHANG) == 0) stop_worker(mi, 1);
    else mi->pid = 0;
    if (mi->from_fd >= 0) close(mi->from_fd);
  }
  srv_meshcache_free(mi->cache);
  pthread_mutex_destroy(&mi->mu);
  free(mi);
}

static int spawn_worker(srv_meshimport *mi, char *msg, size_t n) {
  int in[2], outp[2];
  if (pipe2(in, O_CLOEXEC)) {
    snprintf(msg, n, "cannot start the mesh importer: pipe: %s", strerror(errno));
    return -1;
  }
  if (pipe2(outp, O_CLOEXEC)) {
    snprintf(msg, n, "cannot start the mesh importer: pipe: %s", strerror(errno));
    close(in[0]);
    close(in[1]);
    return -1;
  }
  char mem[32], cpu[32];
  snprintf(mem, sizeof mem, "%lld", (long long)mi->o.memory);
  snprintf(cpu, sizeof cpu, "%d", (int)ceil(mi->o.seconds) + 1);
  char *argv[] = {mi->exe, "--memory", mem, "--cpu-seconds", cpu, NULL};
  posix_spawn_file_actions_t fa;
  posix_spawnattr_t at;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, in[0], 0);
  posix_spawn_file_actions_adddup2(&fa, outp[1], 1);
  /* The daemon's signal state is not the worker's: a terminal's ^C or a dead daemon's pipe must
   * end it. */
  srv_spawnattr_init(&at, 0);
  pid_t pid;
  int rc = posix_spawn(&pid, mi->exe, &fa, &at, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&at);
  close(in[0]);
  close(outp[1]);
  if (rc) {
    close(in[1]);
    close(outp[0]);
    snprintf(msg, n, "cannot start the mesh importer %s: %s", mi->exe, strerror(rc));
    return -1;
  }
  mi->pid = pid;
  mi->to_fd = in[1];
  mi->from_fd = outp[0];
  atomic_fetch_add(&mi->spawns, 1);
  srv_log("mesh importer: started %s (pid %d)", mi->exe, (int)pid);
  return 0;
}

/* Why the worker ended, for a message: "crashed (signal 6)" or "exited with status 2". */
static void describe_exit(int status, char *buf, size_t n) {
  if (status >= 0 && WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU)
    snprintf(buf, n, "the mesh importer ran out of CPU time (signal %d)", SIGXCPU);
  else if (status >= 0 && WIFSIGNALED(status))
    snprintf(buf, n, "the mesh importer crashed (signal %d)", WTERMSIG(status));
  else if (status >= 0 && WIFEXITED(status))
    snprintf(buf, n, "the mesh importer exited with status %d", WEXITSTATUS(status));
  else
    snprintf(buf, n, "the mesh importer died");
}

/* One request to the worker (started when needed). Returns 0 with *m, or a code with msg; sets
 * *cacheable when the outcome belongs to the file (not to a failure to start a worker). */
static int run_request(srv_meshimport *mi, const char *path, const char *root, const char *rel,
                       obs_mesh *m, char *msg, size_t n, int *cacheable) {
  *cacheable = 0;
  int status;
  if (mi->pid && waitpid(mi->pid, &status, WNOHANG) == mi->pid) {
    /* It died between requests (killed from outside): not this file's fault. */
    close(mi->to_fd);
    close(mi->from_fd);
    mi->to_fd = mi->from_fd = -1;
    mi->pid = 0;
  }
  for (int attempt = 0;; attempt++) {
    if (!mi->pid && spawn_worker(mi, msg, n)) return OBS_EIO;
    if (!srv_meshproto_write_request(mi->to_fd, path, root, (uint64_t)mi->o.max_triangles)) break;
    /* EPIPE: the worker ended before reading; one fresh worker may try. */
    int err = errno;
    stop_worker(mi, 1);
    if (attempt > 0 || err != EPIPE) {
      snprintf(msg, n, "%s: cannot send to the mesh importer: %s", rel, strerror(err));
      return OBS_EIO;
    }
  }
  atomic_fetch_add(&mi->imports, 1);
  srv_mesh_limits lim = {(uint64_t)mi->o.max_triangles, 3 * (uint64_t)mi->o.max_triangles};
  char why[512];
  int code = OBS_EINVAL;
  int r = srv_meshproto_read_reply(mi->from_fd, 1e3 * mi->o.seconds, &lim, m, &code, why,
                                   sizeof why);
  *cacheable = 1;
  switch (r) {
    case SRV_MESH_REPLY_MESH: return 0;
    case SRV_MESH_REPLY_ERROR:
      snprintf(msg, n, "%s", why);
      /* The worker's word is trusted for nothing but the ordinary import failures. */
      return code == OBS_ENOMEM || code == OBS_EIO ? code : OBS_EINVAL;
    case SRV_MESH_REPLY_TIMEOUT:
      stop_worker(mi, 1);
      atomic_fetch_add(&mi->timeouts, 1);
      snprintf(msg, n, "%s: the mesh importer timed out after %g s", rel, mi->o.seconds);
      return OBS_EINVAL;
    case SRV_MESH_REPLY_EOF: {
      char how[64];
      describe_exit(stop_worker(mi, 0), how, sizeof how);
      atomic_fetch_add(&mi->crashes, 1);
      snprintf(msg, n, "%s: %s", rel, how);
      return OBS_EINVAL;
    }
    default:
      stop_worker(mi, 1);
      atomic_fetch_add(&mi->protocol_errors, 1);
      snprintf(msg, n, "%.1024s: the mesh importer answered malformed data (%.300s)", rel, why);
      return OBS_EINVAL;
  }
}

/* `path` relative to `root` for messages, else its last component. */
static const char *relative(const char *path, const char *root) {
  if (obs_path_is_inside(root, path)) {
    const char *r = path + strlen(root);
    while (*r == '/') r++;
    return r;
  }
  const char *s = strrchr(path, '/');
  return s ? s + 1 : path;
}

int srv_meshimport_import(void *user, const char *path, const char *root, obs_mesh *m,
                          obs_err *err, const char *where) {
  srv_meshimport *mi = user;
  memset(m, 0, sizeof *m);
  char real_root[PATH_MAX], real[PATH_MAX];
  struct stat st;
  if (!realpath(root, real_root))
    return obs_err_set(err, OBS_EIO, "%s: scene directory cannot be resolved", where);
  if (!realpath(path, real) || stat(real, &st) || !S_ISREG(st.st_mode))
    return obs_err_set(err, OBS_EINVAL, "%s: %s: not a readable regular file", where,
                       relative(path, real_root));
  if (!obs_path_is_inside(real_root, real))
    return obs_err_set(err, OBS_EINVAL, "%s: must stay inside the scene's directory tree", where);
  srv_meshkey k = {real, real_root, st.st_dev, st.st_ino, st.st_size, st.st_mtim};
  int code = 0;
  char *cached = NULL;
  int hit = srv_meshcache_get(mi->cache, &k, m, &code, &cached);
  if (hit == 0 || hit < 0) {
    /* Checked again under the worker's lock: a request waiting for the same file finds the
     * answer the one before it got, rather than asking the worker a second time. */
    pthread_mutex_lock(&mi->mu);
    hit = srv_meshcache_get(mi->cache, &k, m, &code, &cached);
    if (hit <= 0) {
      char msg[SRV_MESH_MAX_MSG + 256];
      int cacheable;
      code = run_request(mi, real, real_root, relative(real, real_root), m, msg, sizeof msg,
                         &cacheable);
      if (!code && cacheable) srv_meshcache_put_mesh(mi->cache, &k, m);
      else if (code && cacheable) srv_meshcache_put_error(mi->cache, &k, code, msg);
      if (code) {
        srv_log("mesh importer: %s", msg);
        cached = strdup(msg);
        hit = 2;
      } else {
        hit = 1;
      }
    }
    pthread_mutex_unlock(&mi->mu);
  }
  if (hit == 1) return 0;
  int rc = obs_err_set(err, code < 0 ? code : OBS_EINVAL, "%s: %s", where,
                       cached ? cached : "out of memory");
  free(cached);
  return rc;
}

void srv_meshimport_stats_get(srv_meshimport *mi, srv_meshimport_stats *s) {
  s->spawns = atomic_load(&mi->spawns);
  s->imports = atomic_load(&mi->imports);
  s->crashes = atomic_load(&mi->crashes);
  s->timeouts = atomic_load(&mi->timeouts);
  s->protocol_errors = atomic_load(&mi->protocol_errors);
  srv_meshcache_stats_get(mi->cache, &s->cache);
}

/* obscura-import in the directory of this executable, which is where the build puts it. */
static int default_exe(char *buf, size_t n) {
  char self[PATH_MAX];
  ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
  if (len <= 0) return -1;
  self[len] = '\0';
  char *slash = strrchr(self, '/');
  if (!slash) return -1;
  *slash = '\0';
  return (size_t)snprintf(buf, n, "%s/obscura-import", self) < n ? 0 : -1;
}

int srv_meshimport_start(srv_app *app, obs_err *err) {
  const srv_config *c = &app->cfg;
  char exe[PATH_MAX];
  if (c->mesh_importer) snprintf(exe, sizeof exe, "%s", c->mesh_importer);
  else if (default_exe(exe, sizeof exe))
    return obs_err_set(err, OBS_EIO, "cannot find obscurad's own directory for the mesh "
                       "importer (pass --mesh-importer)");
  srv_meshimport_opts o = {.exe = exe,
                           .seconds = c->mesh_import_seconds,
                           .memory = c->mesh_import_memory,
                           .max_triangles = c->max_triangles,
                           .cache_bytes = (size_t)c->mesh_cache_bytes};
  int rc = srv_meshimport_new(&o, &app->meshimport, err);
  if (rc) return rc;
  obs_geometry_set_importer(srv_meshimport_import, app->meshimport);
  return 0;
}

void srv_meshimport_stop(srv_app *app) {
  if (!app->meshimport) return;
  obs_geometry_set_importer(NULL, NULL);
  srv_meshimport_free(app->meshimport);
  app->meshimport = NULL;
}

void srv_meshimport_metrics(srv_app *app, char *buf, size_t n) {
  buf[0] = '\0';
  if (!app->meshimport) return;
  srv_meshimport_stats s;
  srv_meshimport_stats_get(app->meshimport, &s);
  snprintf(buf, n,
           "# HELP obscura_mesh_importer_spawns_total Mesh-import worker processes started.\n"
           "# TYPE obscura_mesh_importer_spawns_total counter\n"
           "obscura_mesh_importer_spawns_total %llu\n"
           "# HELP obscura_mesh_imports_total Imports the worker was asked for (cache misses).\n"
           "# TYPE obscura_mesh_imports_total counter\n"
           "obscura_mesh_imports_total %llu\n"
           "# HELP obscura_mesh_import_failures_total Worker imports that killed the worker.\n"
           "# TYPE obscura_mesh_import_failures_total counter\n"
           "obscura_mesh_import_failures_total{reason=\"crashed\"} %llu\n"
           "obscura_mesh_import_failures_total{reason=\"timed_out\"} %llu\n"
           "obscura_mesh_import_failures_total{reason=\"malformed_reply\"} %llu\n"
           "# HELP obscura_mesh_cache_hits_total Mesh imports answered from the cache.\n"
           "# TYPE obscura_mesh_cache_hits_total counter\n"
           "obscura_mesh_cache_hits_total %llu\n"
           "# HELP obscura_mesh_cache_bytes Bytes the mesh cache holds.\n"
           "# TYPE obscura_mesh_cache_bytes gauge\n"
           "obscura_mesh_cache_bytes %llu\n"
           "# HELP obscura_mesh_cache_entries Meshes and failures the mesh cache holds.\n"
           "# TYPE obscura_mesh_cache_entries gauge\n"
           "obscura_mesh_cache_entries %llu\n",
           (unsigned long long)s.spawns, (unsigned long long)s.imports,
           (unsigned long long)s.crashes, (unsigned long long)s.timeouts,
           (unsigned long long)s.protocol_errors, (unsigned long long)s.cache.hits,
           (unsigned long long)s.cache.bytes, (unsigned long long)s.cache.entries);
}
