/* GET /api/v1/diff: the FLIP error map of one finished job's EXR output against another's,
 * computed by the renderer's obs_metrics_flip (the implementation the comparison metrics and
 * `obscura diff` use), answered as an EXR with the single channel "flip" and the mean in a header.
 * The dashboard's viewer shows it as its FLIP error mode. */
#include <errno.h>
#include <fcntl.h>
#include <microhttpd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

#define DIFF_USAGE "a=<job>/<file>.exr&b=<job>/<file>.exr&channel=<name>[&hdr=0|1][&mask=<channel>]"

typedef struct diff_query {
  const char *a, *b, *channel, *hdr, *mask;
  char unknown[65];
} diff_query;

static enum MHD_Result on_arg(void *cls, enum MHD_ValueKind kind, const char *key,
                              const char *value) {
  diff_query *q = cls;
  (void)kind;
  const char **slot = !strcmp(key, "a")         ? &q->a
                      : !strcmp(key, "b")       ? &q->b
                      : !strcmp(key, "channel") ? &q->channel
                      : !strcmp(key, "hdr")     ? &q->hdr
                      : !strcmp(key, "mask")    ? &q->mask
                                                : NULL;
  if (slot) *slot = value ? value : "";
  else if (!q->unknown[0]) srv_printable(key, q->unknown, sizeof q->unknown);
  return MHD_YES;
}

/* Reads the EXR output `spec` ("<job>/<file>.exr") of a succeeded job into img. Returns 0, or
 * answers the request (the HTTP status in *status, the message in msg) and returns -1. */
static int read_output(srv_req *r, const char *which, const char *spec, obs_image *img,
                       unsigned *status, char *msg, size_t n) {
  char shown[96];
  srv_printable(spec, shown, sizeof shown);
  const char *slash = strchr(spec, '/');
  int64_t id;
  const char *file = slash ? slash + 1 : "";
  size_t fl = strlen(file);
  if (!slash || srv_parse_id(spec, (size_t)(slash - spec), &id) || fl < 5 ||
      strcmp(file + fl - 4, ".exr") || !srv_output_content_type(file)) {
    *status = MHD_HTTP_BAD_REQUEST;
    snprintf(msg, n, "%s=%s: not <job>/<file>.exr naming an EXR output (e.g. %s=12/ao.exr)", which,
             shown, which);
    return -1;
  }
  srv_output o;
  obs_err err = OBS_ERR_INIT;
  srv_state st;
  int ex = srv_db_job_exists(r->app->db, id, &st, &err);
  int rc = ex == 1 && st == SRV_SUCCEEDED ? srv_db_get_output(r->app->db, id, file, &o, &err) : 0;
  if (ex < 0 || (rc && rc != OBS_ENOTFOUND)) {
    *status = MHD_HTTP_SERVICE_UNAVAILABLE;
    snprintf(msg, n, "database unavailable: %s", obs_err_message(&err));
  } else if (ex == 0) {
    *status = MHD_HTTP_NOT_FOUND;
    snprintf(msg, n, "%s=%s: no job %lld", which, shown, (long long)id);
  } else if (st != SRV_SUCCEEDED) {
    *status = MHD_HTTP_CONFLICT;
    snprintf(msg, n, "%s=%s: job %lld is %s; only a succeeded job's outputs can be compared", which,
             shown, (long long)id, srv_state_name(st));
  } else if (rc) {
    *status = MHD_HTTP_NOT_FOUND;
    snprintf(msg, n, "%s=%s: job %lld has no output %s", which, shown, (long long)id, file);
  }
  if (ex != 1 || st != SRV_SUCCEEDED || rc) {
    obs_err_free(&err);
    return -1;
  }
  char path[8400];
  srv_results_path(r->app, id, path, sizeof path);
  size_t len = strlen(path);
  snprintf(path + len, sizeof path - len, "/%s", o.name);
  /* Rendered by another node of a shared store: its output comes through the store first. */
  if (srv_outputs_local(r->app, id, &o, &err) || obs_image_read_exr(img, path, &err)) {
    *status = MHD_HTTP_INTERNAL_SERVER_ERROR;
    snprintf(msg, n, "%s=%s: cannot read the file: %s", which, shown, obs_err_message(&err));
    obs_err_free(&err);
    return -1;
  }
  obs_err_free(&err);
  return 0;
}

/* Writes `map` to a file that is unlinked at once and returns its descriptor (-1 on failure). */
static int map_file(const srv_app *app, const obs_image *map, obs_err *err) {
  char path[4400];
  static atomic_uint seq;
  snprintf(path, sizeof path, "%s/.tmp-diff-%ld-%u.exr", app->results_dir, (long)getpid(),
           atomic_fetch_add(&seq, 1));
  if (obs_image_write_exr(map, path, err)) return -1;
  int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(errno));
  unlink(path);
  return fd;
}

int srv_diff_serve(srv_req *r) {
  diff_query q;
  memset(&q, 0, sizeof q);
  MHD_get_connection_values(r->conn, MHD_GET_ARGUMENT_KIND, on_arg, &q);
  if (q.unknown[0])
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "unknown query parameter \"%s\" (the route takes " DIFF_USAGE ")",
                             q.unknown);
  const char *missing = !q.a ? "a" : !q.b ? "b" : !q.channel || !q.channel[0] ? "channel" : NULL;
  if (missing)
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "query parameter %s is missing (the route takes " DIFF_USAGE ")",
                             missing);
  if (q.hdr && strcmp(q.hdr, "0") && strcmp(q.hdr, "1"))
    return srv_respond_error(r, MHD_HTTP_BAD_REQUEST, NULL,
                             "hdr must be 0 (LDR-FLIP) or 1 (HDR-FLIP of an RGB output)");
  obs_image a, b, map;
  memset(&a, 0, sizeof a);
  memset(&b, 0, sizeof b);
  memset(&map, 0, sizeof map);
  unsigned status = 0;
  char msg[600];
  if (read_output(r, "a", q.a, &a, &status, msg, sizeof msg) ||
      read_output(r, "b", q.b, &b, &status, msg, sizeof msg)) {
    obs_image_free(&a);
    return srv_respond_error(r, status, NULL, "%s", msg);
  }
  obs_err err = OBS_ERR_INIT;
  double mean = 0;
  int rc = a.width != b.width || a.height != b.height
               ? obs_err_set(&err, OBS_EINVAL, "a is %dx%d, b %dx%d: FLIP compares images of one "
                                               "size", a.width, a.height, b.width, b.height)
               : obs_metrics_flip(&a, &b, q.channel, q.mask && q.mask[0] ? q.mask : NULL,
                                  q.hdr && !strcmp(q.hdr, "1"), &map, &mean, &err);
  obs_image_free(&a);
  obs_image_free(&b);
  if (rc) {
    int out = srv_respond_error(r, 422, &err, "cannot compute FLIP of a (the test image) against b (the reference)");
    obs_err_free(&err);
    return out;
  }
  int fd = map_file(r->app, &map, &err);
  obs_image_free(&map);
  struct stat sb;
  if (fd < 0 || fstat(fd, &sb)) {
    if (fd >= 0) close(fd);
    srv_log("diff: %s", obs_err_message(&err));
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "cannot write the FLIP map");
  }
  obs_err_free(&err);
  struct MHD_Response *resp = MHD_create_response_from_fd64((uint64_t)sb.st_size, fd);
  if (!resp) {
    close(fd);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "cannot serve the FLIP map");
  }
  char m[40];
  snprintf(m, sizeof m, "%.9g", mean);
  MHD_add_response_header(resp, "Content-Type", "image/x-exr");
  MHD_add_response_header(resp, "Cache-Control", "no-store");
  MHD_add_response_header(resp, "X-Obscura-Flip-Mean", m);
  return srv_respond(r, MHD_HTTP_OK, resp);
}
