/* The /metrics page of obscurad in Prometheus's text format: the job gauges read from the store at
 * scrape time, the scheduler's, faults', imports' and guards' gauges, and the counters that
 * counters.c keeps. */
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurad.h"

char *srv_metrics_text(srv_app *app, size_t *len) {
  srv_buf b = {0};
  int64_t counts[SRV_NSTATES];
  obs_err err = OBS_ERR_INIT;
  int dbok = srv_db_counts(app->db, counts, &err) == 0;
  obs_err_free(&err);
  srv_buf_put(&b,
              "# HELP obscura_jobs Jobs in the database by state.\n# TYPE obscura_jobs gauge\n");
  for (int s = 0; dbok && s < SRV_NSTATES; s++)
    srv_buf_put(&b, "obscura_jobs{state=\"%s\"} %lld\n", srv_state_name((srv_state)s),
                (long long)counts[s]);
  srv_buf_put(&b,
              "# HELP obscura_queue_depth Jobs waiting for a worker.\n"
              "# TYPE obscura_queue_depth gauge\n");
  if (dbok) srv_buf_put(&b, "obscura_queue_depth %lld\n", (long long)counts[SRV_QUEUED]);
  srv_metrics_counters(&b);
  int active[SRV_NFAULTS];
  unsigned long long total[SRV_NFAULTS];
  srv_fault_counts(active, total);
  srv_buf_put(&b,
              "# HELP obscura_fault Environment faults now active (1) by kind.\n"
              "# TYPE obscura_fault gauge\n");
  for (int k = 0; k < SRV_NFAULTS; k++)
    srv_buf_put(&b, "obscura_fault{kind=\"%s\"} %d\n", srv_fault_kind_name((srv_fault_kind)k),
                active[k]);
  srv_buf_put(&b,
              "# HELP obscura_faults_total Environment faults raised since start by kind.\n"
              "# TYPE obscura_faults_total counter\n");
  for (int k = 0; k < SRV_NFAULTS; k++)
    srv_buf_put(&b, "obscura_faults_total{kind=\"%s\"} %llu\n",
                srv_fault_kind_name((srv_fault_kind)k), total[k]);
  srv_buf_put(&b,
              "# HELP obscura_workers_paused Workers holding a finished job until a fault clears.\n"
              "# TYPE obscura_workers_paused gauge\nobscura_workers_paused %d\n",
              srv_sched_paused(app));
  char mesh[2048];
  srv_meshimport_metrics(app, mesh, sizeof mesh);
  srv_buf_put(&b, "%s", mesh);
  srv_refusals_metrics(mesh, sizeof mesh);
  srv_buf_put(&b, "%s", mesh);
  srv_buf_put(&b,
              "# HELP obscura_inflight_bytes Request-body bytes held for uploads in progress.\n"
              "# TYPE obscura_inflight_bytes gauge\nobscura_inflight_bytes %lld\n",
              (long long)srv_guard_inflight(app->guard));
  srv_buf_put(&b,
              "# HELP obscura_uptime_seconds Seconds since the daemon started.\n"
              "# TYPE obscura_uptime_seconds gauge\nobscura_uptime_seconds %.3f\n",
              (obs_now_ms() - app->start_ms) / 1e3);
  if (b.oom) {
    free(b.p);
    return NULL;
  }
  *len = b.len;
  return b.p;
}
