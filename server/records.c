/* What both store implementations share, below them: the names of job states and lanes, the
 * release of job rows, a node's identity, and the bytes a job or comparison stores (what the
 * queue's byte caps count and the stores record per job). */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "obscurad.h"

void srv_node_init(srv_node *n, const char *name, int lease_seconds) {
  snprintf(n->name, sizeof n->name, "%s", name && *name ? name : "local");
  unsigned char r[8] = {0};
  int fd = open("/dev/urandom", O_RDONLY | O_CLOEXEC);
  ssize_t got = fd >= 0 ? read(fd, r, sizeof r) : -1;
  if (fd >= 0) close(fd);
  if (got != (ssize_t)sizeof r) { /* no entropy device: the pid and clock still differ per boot */
    uint64_t v = (uint64_t)getpid() ^ (uint64_t)srv_now_unix_ms() << 16;
    memcpy(r, &v, sizeof r);
  }
  for (size_t i = 0; i < sizeof r; i++) snprintf(n->boot + 2 * i, 3, "%02x", r[i]);
  snprintf(n->worker, sizeof n->worker, "%s/%s", n->name, n->boot);
  n->lease_seconds = lease_seconds > 0 ? lease_seconds : 30;
}

const char *srv_state_name(srv_state s) {
  static const char *const n[] = {"queued", "running", "succeeded", "failed", "cancelled"};
  return s < SRV_NSTATES ? n[s] : "?";
}

int srv_state_parse(const char *s, srv_state *out) {
  for (int i = 0; s && i < SRV_NSTATES; i++)
    if (!strcmp(s, srv_state_name((srv_state)i))) {
      *out = (srv_state)i;
      return 0;
    }
  return -1;
}

const char *srv_lane_name(srv_lane l) {
  return obs_backend_name(l == SRV_LANE_VULKAN ? OBS_BACKEND_VULKAN : OBS_BACKEND_CPU);
}

srv_lane srv_lane_parse(const char *name) {
  obs_backend b = OBS_BACKEND_CPU;
  obs_backend_parse(name, &b);
  return b == OBS_BACKEND_VULKAN ? SRV_LANE_VULKAN : SRV_LANE_CPU;
}

void srv_job_free(srv_job *j) {
  if (!j) return;
  free(j->label);
  free(j->scene);
  free(j->technique);
  free(j->backend_requested);
  free(j->backend);
  free(j->error);
  free(j->summary);
  free(j->backend_reason);
  free(j->scene_name);
  free(j->notes);
  free(j->node);
  free(j->doc);
  free(j->outputs);
  memset(j, 0, sizeof *j);
}

void srv_jobs_free(srv_job *jobs, int n) {
  for (int i = 0; i < n; i++) srv_job_free(&jobs[i]);
  free(jobs);
}

static int64_t text_bytes(const char *s) { return s ? (int64_t)strlen(s) : 0; }

int64_t srv_job_stored_bytes(const srv_new_job *j) {
  return text_bytes(j->doc) + text_bytes(j->label) + text_bytes(j->scene) +
         text_bytes(j->scene_name) + text_bytes(j->notes) + text_bytes(j->backend_reason) +
         text_bytes(j->choice);
}

int64_t srv_candidate_row_bytes(const srv_new_candidate *c) {
  return text_bytes(c->params) + text_bytes(c->reference_params) + text_bytes(c->response);
}

int64_t srv_comparison_stored_bytes(const srv_new_comparison *c) {
  return text_bytes(c->request) + text_bytes(c->label) + text_bytes(c->notes);
}
