/* The daemon's record of environment faults (results directory or database unwritable, database
 * file lost or corrupt): what failed, since when, the back-off of the probe that will clear it,
 * and the views of it that health, /metrics and the scheduler read. One daemon per process, so
 * the record is process-wide. */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "obscurad.h"

#define BACKOFF_MIN_S 1.0
#define BACKOFF_MAX_S 60.0
/* A fault that comes back within this time of clearing continues its back-off instead of
 * starting again at BACKOFF_MIN_S, so a flapping disk is not hammered. */
#define BACKOFF_MEMORY_MS 60000
/* How long health lists a fault after it cleared. */
#define RECENT_MS 600000

typedef struct fault {
  int active;
  char path[1024];
  char code[40];
  char message[1024];
  char action[2048]; /* what an operator should do, when the kind's default does not say it */
  int64_t since_ms, next_ms, cleared_ms;
  double backoff_s;
  int probes;
  unsigned long long total;
} fault;

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static fault faults[SRV_NFAULTS];

static const struct {
  const char *kind, *what, *action;
  int error; /* 1: work is refused (health "error"); 0: the lanes pause (health "degraded") */
} info[SRV_NFAULTS] = {
    [SRV_FAULT_RESULTS] = {"results", "the results directory cannot be written",
                           "free space or make the directory writable; the lanes resume by "
                           "themselves",
                           0},
    [SRV_FAULT_DB] = {"database", "the database cannot be written",
                      "free space on the database's disk or make it writable; the lanes resume "
                      "by themselves",
                      0},
    [SRV_FAULT_DB_LOST] = {"database_lost", "the database file was deleted or replaced", NULL, 1},
    [SRV_FAULT_DB_CORRUPT] = {"database_corrupt", "the database failed PRAGMA quick_check",
                              "stop obscurad, restore the database from a backup (or try "
                              "`sqlite3 DB .recover`), then start it again",
                              1},
};

const char *srv_fault_kind_name(srv_fault_kind k) { return info[k].kind; }

const char *srv_errno_name(int e) {
  switch (e) {
    case ENOSPC: return "ENOSPC";
    case EACCES: return "EACCES";
    case EPERM: return "EPERM";
    case EROFS: return "EROFS";
    case EIO: return "EIO";
    case EDQUOT: return "EDQUOT";
    case ENOENT: return "ENOENT";
    case ENOTDIR: return "ENOTDIR";
    case EMFILE: return "EMFILE";
    case ENFILE: return "ENFILE";
    default: return "errno";
  }
}

int srv_errno_transient(int e) {
  return e == ENOSPC || e == EACCES || e == EPERM || e == EROFS || e == EIO || e == EDQUOT ||
         e == EMFILE || e == ENFILE || e == ENOENT || e == ENOTDIR;
}

void srv_fault_raise(srv_fault_kind k, const char *path, const char *code, const char *message,
                     const char *action) {
  int64_t now = srv_now_unix_ms();
  pthread_mutex_lock(&mu);
  fault *f = &faults[k];
  int fresh = !f->active;
  if (fresh) {
    f->active = 1;
    f->since_ms = now;
    f->probes = 0;
    f->total++;
    f->backoff_s = f->cleared_ms && now - f->cleared_ms < BACKOFF_MEMORY_MS && f->backoff_s > 0
                       ? (f->backoff_s * 2 > BACKOFF_MAX_S ? BACKOFF_MAX_S : f->backoff_s * 2)
                       : BACKOFF_MIN_S;
    f->next_ms = now + (int64_t)(f->backoff_s * 1e3);
  }
  snprintf(f->path, sizeof f->path, "%s", path ? path : "");
  if (code && *code) snprintf(f->code, sizeof f->code, "%s", code);
  else if (fresh) f->code[0] = 0;
  snprintf(f->message, sizeof f->message, "%s", message ? message : "");
  snprintf(f->action, sizeof f->action, "%s", action ? action : "");
  double backoff = f->backoff_s;
  pthread_mutex_unlock(&mu);
  if (fresh)
    srv_log("fault: %s (%s%s%s): %s; probing again in %.0f s", info[k].what, path ? path : "",
            code && *code ? ", " : "", code && *code ? code : "", message ? message : "",
            backoff);
}

int srv_fault_due(srv_fault_kind k) {
  pthread_mutex_lock(&mu);
  int due = faults[k].active && srv_now_unix_ms() >= faults[k].next_ms;
  pthread_mutex_unlock(&mu);
  return due;
}

void srv_fault_probe_failed(srv_fault_kind k, const char *code, const char *message) {
  pthread_mutex_lock(&mu);
  fault *f = &faults[k];
  if (f->active) {
    f->probes++;
    f->backoff_s = f->backoff_s * 2 > BACKOFF_MAX_S ? BACKOFF_MAX_S : f->backoff_s * 2;
    f->next_ms = srv_now_unix_ms() + (int64_t)(f->backoff_s * 1e3);
    if (code && *code) snprintf(f->code, sizeof f->code, "%s", code);
    if (message) snprintf(f->message, sizeof f->message, "%s", message);
  }
  pthread_mutex_unlock(&mu);
}

void srv_fault_clear(srv_fault_kind k) {
  pthread_mutex_lock(&mu);
  fault *f = &faults[k];
  int was = f->active;
  int64_t now = srv_now_unix_ms(), since = f->since_ms;
  f->active = 0;
  if (was) f->cleared_ms = now;
  pthread_mutex_unlock(&mu);
  if (was)
    srv_log("fault cleared: %s (after %.1f s)", info[k].what, (double)(now - since) / 1e3);
}

int srv_fault_active(srv_fault_kind k) {
  pthread_mutex_lock(&mu);
  int a = faults[k].active;
  pthread_mutex_unlock(&mu);
  return a;
}

int srv_fault_any(void) {
  int a = 0;
  pthread_mutex_lock(&mu);
  for (int k = 0; k < SRV_NFAULTS; k++) a |= faults[k].active;
  pthread_mutex_unlock(&mu);
  return a;
}

int srv_fault_refusing(char *msg, size_t n) {
  int refused = 0;
  pthread_mutex_lock(&mu);
  for (int k = 0; k < SRV_NFAULTS && !refused; k++) {
    if (faults[k].active && info[k].error) {
      snprintf(msg, n, "%s (%s): %s", info[k].what, faults[k].path, faults[k].message);
      refused = 1;
    }
  }
  pthread_mutex_unlock(&mu);
  return refused;
}

json_t *srv_fault_json(int *level) {
  json_t *list = json_array();
  *level = 0;
  pthread_mutex_lock(&mu);
  for (int k = 0; k < SRV_NFAULTS; k++) {
    const fault *f = &faults[k];
    if (!f->active) continue;
    int err = info[k].error;
    if (*level < 1 + err) *level = 1 + err;
    json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:s, s:o, s:i}", "kind", info[k].kind,
                          "severity", err ? "error" : "degraded", "what", info[k].what, "path",
                          f->path, "message", f->message, "since", srv_json_time(f->since_ms),
                          "probes", f->probes);
    if (!o) continue;
    json_object_set_new(o, "code", f->code[0] ? json_string(f->code) : json_null());
    json_object_set_new(o, "next_retry", err ? json_null() : srv_json_time(f->next_ms));
    json_object_set_new(o, "action", json_string(f->action[0] ? f->action
                                                 : info[k].action ? info[k].action
                                                                  : ""));
    json_array_append_new(list, o);
  }
  pthread_mutex_unlock(&mu);
  return list;
}

json_t *srv_fault_recent_json(void) {
  json_t *list = json_array();
  int64_t now = srv_now_unix_ms();
  pthread_mutex_lock(&mu);
  for (int k = 0; list && k < SRV_NFAULTS; k++) {
    const fault *f = &faults[k];
    if (f->active || !f->cleared_ms || now - f->cleared_ms > RECENT_MS) continue;
    json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:o, s:o}", "kind", info[k].kind, "what",
                          info[k].what, "path", f->path, "message", f->message, "since",
                          srv_json_time(f->since_ms), "cleared", srv_json_time(f->cleared_ms));
    if (o) json_array_append_new(list, o);
  }
  pthread_mutex_unlock(&mu);
  return list;
}

void srv_fault_counts(int active[SRV_NFAULTS], unsigned long long total[SRV_NFAULTS]) {
  pthread_mutex_lock(&mu);
  for (int k = 0; k < SRV_NFAULTS; k++) {
    active[k] = faults[k].active;
    total[k] = faults[k].total;
  }
  pthread_mutex_unlock(&mu);
}
