/* Refusals for capacity, as health and /metrics show them: every answer a limit of the queue or of
 * the HTTP layer forced (429 for the queue's caps, 503 for request bodies in flight or a full
 * connection pool) and every upload ended for being too slow, counted by the limit that decided,
 * with the time of the last one. A server-wide limit that refused within the last minute makes
 * health "degraded": submissions are failing for want of room, which a monitor must see. */
#include <pthread.h>
#include <stdatomic.h>
#include <string.h>

#include "obscurad.h"

/* How long a server-wide refusal keeps health degraded. */
#define REFUSING_WINDOW_MS 60000.0

typedef struct limit_count {
  const char *name;
  const char *scope;      /* what the limit bounds: "server", one "client", one "connection" */
  atomic_ullong count;
  _Atomic int64_t last_ms; /* unix ms of the last refusal, 0 = none */
} limit_count;

static limit_count limits[] = {
    {"max-queued-work", "client", 0, 0},       {"max-queued-work-total", "server", 0, 0},
    {"max-queued-jobs", "client", 0, 0},       {"max-queued-jobs-total", "server", 0, 0},
    {"max-queued-bytes", "client", 0, 0},      {"max-queued-bytes-total", "server", 0, 0},
    {"max-inflight-bytes", "server", 0, 0},    {"max-connections", "server", 0, 0},
    {"min-body-rate", "connection", 0, 0},
};
#define NLIMITS (sizeof limits / sizeof limits[0])

void srv_refused(const char *limit) {
  for (size_t i = 0; i < NLIMITS; i++) {
    if (strcmp(limits[i].name, limit)) continue;
    atomic_fetch_add(&limits[i].count, 1);
    atomic_store(&limits[i].last_ms, srv_now_unix_ms());
    return;
  }
}

json_t *srv_refusals_json(int *refusing) {
  json_t *list = json_array(), *now_refusing = json_array();
  int64_t now = srv_now_unix_ms();
  for (size_t i = 0; i < NLIMITS; i++) {
    const limit_count *l = &limits[i];
    int64_t last = atomic_load(&l->last_ms);
    json_array_append_new(list, json_pack("{s:s, s:s, s:I, s:o}", "limit", l->name, "scope",
                                          l->scope, "count",
                                          (json_int_t)atomic_load(&l->count), "last",
                                          srv_json_time(last)));
    if (!strcmp(l->scope, "server") && last && now - last < REFUSING_WINDOW_MS)
      json_array_append_new(now_refusing, json_string(l->name));
  }
  *refusing = json_array_size(now_refusing) > 0;
  return json_pack("{s:o, s:o}", "refusing", now_refusing, "refused", list);
}

void srv_refusals_metrics(char *buf, size_t n) {
  size_t k = (size_t)snprintf(buf, n,
                              "# HELP obscura_refusals_total Requests refused and uploads ended "
                              "by the limit that decided.\n"
                              "# TYPE obscura_refusals_total counter\n");
  for (size_t i = 0; i < NLIMITS && k < n; i++)
    k += (size_t)snprintf(buf + k, n - k, "obscura_refusals_total{limit=\"%s\"} %llu\n",
                          limits[i].name, (unsigned long long)atomic_load(&limits[i].count));
}
