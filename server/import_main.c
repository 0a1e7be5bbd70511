/* obscura-import: obscurad's mesh-import worker. It runs assimp on the files the daemon names on
 * its standard input and answers the triangles on its standard output (meshimport.h), under its
 * own memory and CPU limits, so that a file that makes assimp abort, crash or loop takes down
 * only this process, which the daemon kills after its time limit and starts again when needed.
 * Usage (by obscurad only): obscura-import [--memory BYTES] [--cpu-seconds N] */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "meshimport.h"

#if defined(__SANITIZE_ADDRESS__)
#define SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SANITIZED 1
#endif
#endif
#ifndef SANITIZED
#define SANITIZED 0
#endif

#if SANITIZED
/* Faults inside assimp (not instrumented) are this program's expected input: they end it with
 * their signal, which the daemon reports, rather than with a sanitizer report in the daemon's log
 * and exit status 1. Leak checking is off because a worker that ends on EOF still holds assimp's
 * process-lifetime allocations; the shared protocol code is checked in the daemon. */
const char *__asan_default_options(void);
const char *__asan_default_options(void) {
  return "handle_segv=0:handle_sigbus=0:handle_abort=0:handle_sigfpe=0:detect_leaks=0";
}
#endif

/* Closes every descriptor but the pipes and stderr: the daemon's database and sockets must not
 * be reachable from a process whose memory a hostile file may control. */
static void close_others(void) {
#ifdef SYS_close_range
  if (syscall(SYS_close_range, 3u, ~0u, 0u) == 0) return;
#endif
  long max = sysconf(_SC_OPEN_MAX);
  for (long fd = 3; fd < (max > 0 && max < 65536 ? max : 65536); fd++) close((int)fd);
}

static void set_limit(int which, rlim_t soft, rlim_t hard) {
  struct rlimit rl = {soft, hard};
  if (setrlimit(which, &rl)) fprintf(stderr, "obscura-import: setrlimit: %s\n", strerror(errno));
}

/* CPU seconds used so far; the soft RLIMIT_CPU is moved forward per request so the limit bounds
 * each import, not the worker's lifetime (the hard limit stays open, so it can be raised). */
static rlim_t cpu_used(void) {
  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru)) return 0;
  return (rlim_t)(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1);
}

/* `path` relative to `root` for messages ("models/x.ply"), else its last component. */
static const char *relative(const char *path, const char *root) {
  char real[PATH_MAX];
  if (realpath(root, real) && obs_path_is_inside(real, path)) {
    const char *r = path + strlen(real);
    while (*r == '/') r++;
    return r;
  }
  const char *s = strrchr(path, '/');
  return s ? s + 1 : path;
}

int main(int argc, char **argv) {
  long long memory = 0, cpu = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!strcmp(argv[i], "--memory")) memory = atoll(argv[i + 1]);
    else if (!strcmp(argv[i], "--cpu-seconds")) cpu = atoll(argv[i + 1]);
  }
  close_others();
  signal(SIGPIPE, SIG_DFL);
  set_limit(RLIMIT_CORE, 0, 0);  /* a crash here is expected input, not a bug to keep */
  /* AddressSanitizer reserves terabytes of address space: an address-space limit would stop it
   * from starting, so the sanitizer build relies on the daemon's time limit alone. */
  if (memory > 0 && !SANITIZED) set_limit(RLIMIT_AS, (rlim_t)memory, (rlim_t)memory);
  static char path[SRV_MESH_MAX_PATH + 1], root[SRV_MESH_MAX_PATH + 1];
  for (;;) {
    uint64_t max_tris = 0;
    int rc = srv_meshproto_read_request(0, path, root, &max_tris);
    if (rc) return rc > 0 ? 0 : 2;
    struct rlimit cur;
    if (cpu > 0 && !getrlimit(RLIMIT_CPU, &cur)) {
      rlim_t soft = cpu_used() + (rlim_t)cpu;
      set_limit(RLIMIT_CPU, cur.rlim_max != RLIM_INFINITY && soft > cur.rlim_max ? cur.rlim_max
                                                                                  : soft,
                cur.rlim_max);
    }
    obs_mesh m;
    obs_err err = OBS_ERR_INIT;
    int irc = obs_geometry_import_mesh_assimp(path, root, &m, &err, relative(path, root));
    if (!irc && m.ntris > max_tris) {
      irc = obs_err_set(&err, OBS_EINVAL, "%s: mesh has %zu triangles, more than the server's "
                        "limit max-triangles = %llu", relative(path, root), m.ntris,
                        (unsigned long long)max_tris);
      obs_geometry_mesh_free(&m);
    } else if (!irc && m.nverts > 3 * (size_t)max_tris) {
      /* The daemon refuses a reply with more vertices than three per allowed triangle. */
      irc = obs_err_set(&err, OBS_EINVAL, "%s: mesh has %zu vertices, more than three per "
                        "triangle of the server's limit max-triangles = %llu",
                        relative(path, root), m.nverts, (unsigned long long)max_tris);
      obs_geometry_mesh_free(&m);
    }
    int wrc = irc ? srv_meshproto_write_error(1, irc, obs_err_message(&err))
                  : srv_meshproto_write_mesh(1, &m);
    if (!irc) obs_geometry_mesh_free(&m);
    obs_err_free(&err);
    if (wrc) return 3;
  }
}
