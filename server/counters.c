/* obscurad's counters, kept in memory and cheap to bump from any thread: HTTP requests by route
 * and status, and the render-time histogram per technique and backend. Below the HTTP layer and
 * the scheduler, which bump them; the /metrics page (metrics.c) writes them out. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurad.h"

static const char *const route_names[SRV_NROUTES] = {
    [SRV_ROUTE_JOBS] = "/api/v1/jobs",
    [SRV_ROUTE_JOB] = "/api/v1/jobs/{id}",
    [SRV_ROUTE_JOB_CANCEL] = "/api/v1/jobs/{id}/cancel",
    [SRV_ROUTE_JOB_OUTPUT] = "/api/v1/jobs/{id}/outputs/{name}",
    [SRV_ROUTE_JOB_RETRY] = "/api/v1/jobs/{id}/retry",
    [SRV_ROUTE_JOB_DOCUMENT] = "/api/v1/jobs/{id}/document",
    [SRV_ROUTE_JOB_LOG] = "/api/v1/jobs/{id}/log",
    [SRV_ROUTE_JOB_PREVIEW] = "/api/v1/jobs/{id}/preview.exr",
    [SRV_ROUTE_DIFF] = "/api/v1/diff",
    [SRV_ROUTE_TECHNIQUES] = "/api/v1/techniques",
    [SRV_ROUTE_METRIC_TABLE] = "/api/v1/metrics",
    [SRV_ROUTE_SCENES] = "/api/v1/scenes",
    [SRV_ROUTE_SCENE_DEFAULTS] = "/api/v1/scenes/{name}/defaults",
    [SRV_ROUTE_HEALTH] = "/api/v1/health",
    [SRV_ROUTE_METRICS] = "/metrics",
    [SRV_ROUTE_COMPARISONS] = "/api/v1/comparisons",
    [SRV_ROUTE_COMPARISON] = "/api/v1/comparisons/{id}",
    [SRV_ROUTE_SESSION] = "/api/v1/session",
    [SRV_ROUTE_STATIC] = "static",
    [SRV_ROUTE_UNKNOWN] = "unknown",
};

/* Status codes are 100..599: a flat array of counters keeps the hot path lock-free. */
static atomic_ullong http_counts[SRV_NROUTES][500];

static const double buckets[] = {0.01, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60, 120, 300, 600};
#define NBUCKETS (sizeof buckets / sizeof buckets[0])

typedef struct hist {
  char technique[64], backend[16];
  unsigned long long counts[NBUCKETS + 1]; /* last: +Inf */
  unsigned long long n;
  double sum;
} hist;

static pthread_mutex_t hist_mu = PTHREAD_MUTEX_INITIALIZER;
static hist *hists;
static size_t nhists;

void srv_metrics_init(void) {
  for (int r = 0; r < SRV_NROUTES; r++)
    for (int s = 0; s < 500; s++) atomic_init(&http_counts[r][s], 0);
}

void srv_metrics_http(srv_route route, unsigned status) {
  if (route >= SRV_NROUTES || status < 100 || status > 599) return;
  atomic_fetch_add_explicit(&http_counts[route][status - 100], 1, memory_order_relaxed);
}

void srv_metrics_render(const char *technique, const char *backend, double seconds) {
  pthread_mutex_lock(&hist_mu);
  hist *h = NULL;
  for (size_t i = 0; i < nhists; i++)
    if (!strcmp(hists[i].technique, technique) && !strcmp(hists[i].backend, backend)) h = &hists[i];
  if (!h) {
    hist *g = realloc(hists, (nhists + 1) * sizeof *g);
    if (!g) {
      pthread_mutex_unlock(&hist_mu);
      return;
    }
    hists = g;
    h = &hists[nhists++];
    memset(h, 0, sizeof *h);
    snprintf(h->technique, sizeof h->technique, "%s", technique);
    snprintf(h->backend, sizeof h->backend, "%s", backend);
  }
  size_t b = 0;
  while (b < NBUCKETS && seconds > buckets[b]) b++;
  h->counts[b]++;
  h->n++;
  h->sum += seconds;
  pthread_mutex_unlock(&hist_mu);
}

void srv_metrics_counters(srv_buf *b) {
  srv_buf_put(b,
              "# HELP obscura_render_seconds Time of succeeded jobs from load to written outputs.\n"
              "# TYPE obscura_render_seconds histogram\n");
  pthread_mutex_lock(&hist_mu);
  for (size_t i = 0; i < nhists; i++) {
    const hist *h = &hists[i];
    unsigned long long cum = 0;
    for (size_t k = 0; k <= NBUCKETS; k++) {
      cum += h->counts[k];
      char le[32];
      if (k < NBUCKETS)
        snprintf(le, sizeof le, "%g", buckets[k]);
      else
        snprintf(le, sizeof le, "+Inf");
      srv_buf_put(b,
                  "obscura_render_seconds_bucket{technique=\"%s\",backend=\"%s\",le=\"%s\"} %llu\n",
                  h->technique, h->backend, le, cum);
    }
    srv_buf_put(b, "obscura_render_seconds_sum{technique=\"%s\",backend=\"%s\"} %.6f\n",
                h->technique, h->backend, h->sum);
    srv_buf_put(b, "obscura_render_seconds_count{technique=\"%s\",backend=\"%s\"} %llu\n",
                h->technique, h->backend, h->n);
  }
  pthread_mutex_unlock(&hist_mu);
  srv_buf_put(b,
              "# HELP obscura_http_requests_total HTTP requests by route template and status.\n"
              "# TYPE obscura_http_requests_total counter\n");
  for (int r = 0; r < SRV_NROUTES; r++)
    for (int s = 0; s < 500; s++) {
      unsigned long long n = atomic_load_explicit(&http_counts[r][s], memory_order_relaxed);
      if (n)
        srv_buf_put(b, "obscura_http_requests_total{route=\"%s\",status=\"%d\"} %llu\n",
                    route_names[r], s + 100, n);
    }
}

void srv_metrics_free(void) {
  pthread_mutex_lock(&hist_mu);
  free(hists);
  hists = NULL;
  nhists = 0;
  pthread_mutex_unlock(&hist_mu);
}
