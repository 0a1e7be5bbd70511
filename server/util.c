/* Small helpers of obscurad: the log line, wall-clock times, id parsing, directory handling and
 * the signal state of spawned children. */
#include <dirent.h>
#include <signal.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "obscurad.h"

int64_t srv_now_unix_ms(void) {
  struct timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

void srv_format_time(int64_t ms, char *buf, size_t n) {
  time_t s = (time_t)(ms / 1000);
  struct tm tm;
  gmtime_r(&s, &tm);
  char base[24];
  strftime(base, sizeof base, "%Y-%m-%dT%H:%M:%S", &tm);
  snprintf(buf, n, "%s.%03dZ", base, (int)(ms % 1000));
}

void srv_log(const char *fmt, ...) {
  char line[2048];
  srv_format_time(srv_now_unix_ms(), line, sizeof line);
  size_t len = strlen(line);
  line[len++] = ' ';
  va_list ap;
  va_start(ap, fmt);
  int k = vsnprintf(line + len, sizeof line - len - 1, fmt, ap);
  va_end(ap);
  if (k < 0) return;
  len += (size_t)k < sizeof line - len - 1 ? (size_t)k : sizeof line - len - 2;
  line[len++] = '\n';
  /* One write per line: stderr is shared by every HTTP and worker thread. */
  ssize_t w = write(2, line, len);
  (void)w;
}

int srv_parse_id(const char *s, size_t len, int64_t *out) {
  if (len == 0 || len > 19 || s[0] < '1' || s[0] > '9') return -1;
  int64_t v = 0;
  for (size_t i = 0; i < len; i++) {
    if (s[i] < '0' || s[i] > '9') return -1;
    int d = s[i] - '0';
    if (v > (INT64_MAX - d) / 10) return -1;
    v = v * 10 + d;
  }
  *out = v;
  return 0;
}

static int remove_at(int parent, const char *name) {
  if (!unlinkat(parent, name, 0)) return 0;
  if (errno == ENOENT) return 0;
  if (errno != EISDIR && errno != EPERM) return -1;
  /* A directory: O_NOFOLLOW so a symlink planted inside never leads the removal elsewhere. */
  int fd = openat(parent, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return -1;
  DIR *d = fdopendir(fd);
  if (!d) {
    close(fd);
    return -1;
  }
  struct dirent *e;
  int rc = 0;
  while ((e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    if (remove_at(dirfd(d), e->d_name)) rc = -1;
  }
  closedir(d);
  if (unlinkat(parent, name, AT_REMOVEDIR) && errno != ENOENT) rc = -1;
  return rc;
}

int srv_remove_tree(const char *path) { return remove_at(AT_FDCWD, path); }

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

double srv_median(double *v, size_t n) {
  if (!n) return NAN;
  qsort(v, n, sizeof *v, cmp_double);
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void srv_printable(const char *in, char *out, size_t n) {
  snprintf(out, n, "%s", in ? in : "");
  for (char *p = out; *p; p++)
    if ((unsigned char)*p < 0x20 || (unsigned char)*p >= 0x7f || *p == '"') *p = '?';
}

json_t *srv_json_array_of(const char *text) {
  json_t *a = text ? json_loads(text, 0, NULL) : NULL;
  if (json_is_array(a)) return a;
  json_decref(a);
  return json_array();
}

json_t *srv_json_time(int64_t unix_ms) {
  if (!unix_ms) return json_null();
  char buf[40];
  srv_format_time(unix_ms, buf, sizeof buf);
  return json_string(buf);
}

void srv_spawnattr_init(posix_spawnattr_t *at, short flags) {
  sigset_t none, defs;
  sigemptyset(&none);
  sigemptyset(&defs);
  sigaddset(&defs, SIGPIPE);
  sigaddset(&defs, SIGINT);
  sigaddset(&defs, SIGTERM);
  posix_spawnattr_init(at);
  posix_spawnattr_setsigmask(at, &none);
  posix_spawnattr_setsigdefault(at, &defs);
  posix_spawnattr_setflags(at, (short)(POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF | flags));
}

void srv_buf_put(srv_buf *b, const char *fmt, ...) {
  for (;;) {
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(b->p ? b->p + b->len : NULL, b->p ? b->cap - b->len : 0, fmt, ap);
    va_end(ap);
    if (n < 0 || b->oom) return;
    if (b->p && b->len + (size_t)n < b->cap) {
      b->len += (size_t)n;
      return;
    }
    size_t cap = (b->cap ? b->cap * 2 : 8192) + (size_t)n;
    char *p = realloc(b->p, cap);
    if (!p) {
      b->oom = 1;
      return;
    }
    b->p = p;
    b->cap = cap;
  }
}
