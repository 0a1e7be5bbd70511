/* Each job's own log, <data-dir>/logs/<id>.log: the daemon's lines about the job (queued, claimed,
 * waiting at the render gate, the renderer's warnings, its timings, why it failed or stopped,
 * retries), one timestamped line each, served by GET /api/v1/jobs/{id}/log. A file per job rather
 * than database rows: appending costs no transaction, and the log outlives a database fault. */
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

static void log_path(const srv_app *app, int64_t id, char *buf, size_t n) {
  snprintf(buf, n, "%s/logs/%lld.log", app->cfg.data_dir, (long long)id);
}

void srv_job_log(const srv_app *app, int64_t id, const char *fmt, ...) {
  char msg[1800];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(msg, sizeof msg, fmt, ap);
  va_end(ap);
  srv_log("job %lld: %s", (long long)id, msg);
  if (!app) return;
  char line[1900];
  srv_format_time(srv_now_unix_ms(), line, sizeof line);
  size_t len = strlen(line);
  /* One line per write with O_APPEND: lines of the HTTP and worker threads never interleave. */
  len += (size_t)snprintf(line + len, sizeof line - len, " %s", msg);
  if (len > sizeof line - 2) len = sizeof line - 2;
  for (size_t i = 0; i < len; i++)
    if (line[i] == '\n') line[i] = ' ';
  line[len++] = '\n';
  char path[4200];
  log_path(app, id, path, sizeof path);
  int fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0 && errno == ENOENT) {
    char dir[4200];
    snprintf(dir, sizeof dir, "%s/logs", app->cfg.data_dir);
    if (mkdir(dir, 0755) == 0 || errno == EEXIST)
      fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  }
  /* A log that cannot be written (a full disk) costs the job its log lines, never its render. */
  if (fd < 0) return;
  ssize_t w = write(fd, line, len);
  (void)w;
  close(fd);
}

char *srv_job_log_read(const srv_app *app, int64_t id, size_t *len) {
  *len = 0;
  char path[4200];
  log_path(app, id, path, sizeof path);
  FILE *f = fopen(path, "rb");
  if (!f) return errno == ENOENT ? calloc(1, 1) : NULL;
  size_t cap = 4096;
  char *buf = malloc(cap);
  size_t k;
  while (buf && (k = fread(buf + *len, 1, cap - *len - 1, f)) > 0) {
    *len += k;
    if (cap - *len - 1 == 0) {
      /* Logs are a few lines; the cap bounds a file grown by something else. */
      if (cap >= (size_t)1 << 20) break;
      char *g = realloc(buf, cap * 2);
      if (!g) {
        free(buf);
        buf = NULL;
        break;
      }
      buf = g;
      cap *= 2;
    }
  }
  fclose(f);
  if (buf) buf[*len] = '\0';
  return buf;
}

void srv_job_log_remove(const srv_app *app, int64_t id) {
  char path[4200];
  log_path(app, id, path, sizeof path);
  if (unlink(path) && errno != ENOENT)
    srv_log("job %lld: cannot remove %s: %s", (long long)id, path, strerror(errno));
}
