/* Job outputs on disk: the names the registry declares, SHA-256 and size records, the start-up
 * sweep of half-written results, outputs as blobs of the store when several nodes share one
 * without a shared results directory (put by the node that rendered, fetched into a local cache by
 * any node that serves them), and serving files with ETag, Cache-Control and byte ranges. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <microhttpd.h>
#include <openssl/evp.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "obscurad.h"

/* Only these are ever recorded or served: a name from a URL is never used as a path unless it is
 * one of them. They are the files the registered techniques declare (obs_output_file_names),
 * then the error and FLIP images and the mapped reference the comparison metrics step writes into
 * a candidate's directory. */
#define MAX_KNOWN 64
static char known[MAX_KNOWN][OBS_OUTPUT_FILE_MAX];
static size_t nknown;
static pthread_once_t known_once = PTHREAD_ONCE_INIT;

static void known_init(void) {
  nknown = obs_output_file_names(known, MAX_KNOWN - 6);
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "error.exr");
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "error.png");
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "flip.exr");
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "flip.png");
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "%s", SRV_MAPPED_REFERENCE_PNG);
  snprintf(known[nknown++], OBS_OUTPUT_FILE_MAX, "%s", SRV_MAPPED_REFERENCE_EXR);
}

const char *srv_output_content_type(const char *name) {
  pthread_once(&known_once, known_init);
  for (size_t i = 0; name && i < nknown; i++)
    if (!strcmp(name, known[i])) return obs_output_content_type(known[i]);
  return NULL;
}

void srv_results_path(const srv_app *app, int64_t id, char *buf, size_t n) {
  snprintf(buf, n, "%s/%lld", app->results_dir, (long long)id);
}

void srv_sha256(const void *data, size_t len, unsigned char out[32]) {
  unsigned int n = 32;
  EVP_Digest(data, len, out, &n, EVP_sha256(), NULL);
}

static int hash_file(const char *path, char hex[65], int64_t *size, obs_err *err) {
  int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(errno));
  EVP_MD_CTX *ctx = EVP_MD_CTX_new();
  if (!ctx || !EVP_DigestInit_ex(ctx, EVP_sha256(), NULL)) {
    EVP_MD_CTX_free(ctx);
    close(fd);
    return obs_err_set(err, OBS_EINTERNAL, "SHA-256 unavailable");
  }
  static _Thread_local unsigned char chunk[1 << 16];
  int64_t total = 0;
  int rc = 0;
  for (;;) {
    ssize_t n = read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      rc = obs_err_set(err, OBS_EIO, "%s: read failed: %s", path, strerror(errno));
      break;
    }
    if (n == 0) break;
    EVP_DigestUpdate(ctx, chunk, (size_t)n);
    total += n;
  }
  unsigned char md[32];
  unsigned int mdlen = 32;
  EVP_DigestFinal_ex(ctx, md, &mdlen);
  EVP_MD_CTX_free(ctx);
  close(fd);
  if (rc) return rc;
  for (int i = 0; i < 32; i++) snprintf(hex + 2 * i, 3, "%02x", md[i]);
  *size = total;
  return 0;
}

int srv_outputs_describe(const char *dir, srv_output *outs, int max, int *n, obs_err *err) {
  *n = 0;
  pthread_once(&known_once, known_init);
  for (size_t i = 0; i < nknown && *n < max; i++) {
    char path[8400];
    snprintf(path, sizeof path, "%s/%s", dir, known[i]);
    struct stat st;
    if (lstat(path, &st) || !S_ISREG(st.st_mode)) continue;
    srv_output *o = &outs[*n];
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "%s", known[i]);
    snprintf(o->content_type, sizeof o->content_type, "%s", obs_output_content_type(known[i]));
    int rc = hash_file(path, o->sha256, &o->size, err);
    if (rc) return rc;
    (*n)++;
  }
  return 0;
}

void srv_outputs_remove(const srv_app *app, int64_t id) {
  srv_job_log_remove(app, id);
  char path[8400];
  srv_results_path(app, id, path, sizeof path);
  if (srv_remove_tree(path)) srv_log("job %lld: cannot remove %s: %s", (long long)id, path,
                                     strerror(errno));
  char prefix[48];
  int np = snprintf(prefix, sizeof prefix, ".tmp-%lld-", (long long)id);
  DIR *d = opendir(app->results_dir);
  if (!d) return;
  struct dirent *e;
  while ((e = readdir(d))) {
    if (strncmp(e->d_name, prefix, (size_t)np)) continue;
    snprintf(path, sizeof path, "%s/%s", app->results_dir, e->d_name);
    srv_remove_tree(path);
  }
  closedir(d);
}

/* Whether staging entry `name` (".tmp-<id>-<attempt>", ".tmp-<id>-preview...", or another
 * temporary) is stale: in a results directory other nodes share, an attempt or preview of a job
 * still running may be another node's; in this node's own, nothing running survives recovery. */
static int stale_stage(srv_app *app, const char *name) {
  if (!app->cfg.results_dir) return 1;
  const char *p = name + 5, *dash = strchr(p, '-');
  int64_t id;
  if (!dash || srv_parse_id(p, (size_t)(dash - p), &id)) return 1;
  srv_job j;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_get_job(app->db, id, &j, &err);
  obs_err_free(&err);
  if (rc == OBS_ENOTFOUND) return 1;
  if (rc) return 0; /* unknown: keep it */
  char *end;
  long attempt = strtol(dash + 1, &end, 10);
  int live = j.state == SRV_RUNNING && (!strncmp(dash + 1, "preview", 7) ||
                                        (end != dash + 1 && !*end && attempt == j.attempts));
  srv_job_free(&j);
  return !live;
}

void srv_outputs_sweep(srv_app *app) {
  DIR *d = opendir(app->results_dir);
  if (!d) return;
  struct dirent *e;
  char path[8400];
  while ((e = readdir(d))) {
    int64_t id;
    int stale = 0;
    if (!strncmp(e->d_name, ".tmp-", 5)) {
      stale = stale_stage(app, e->d_name);
    } else if (!srv_parse_id(e->d_name, strlen(e->d_name), &id)) {
      srv_state st;
      obs_err err = OBS_ERR_INIT;
      int ex = srv_db_job_exists(app->db, id, &st, &err);
      obs_err_free(&err);
      /* Only a succeeded job owns a results directory; anything else is what a crash (or a
       * deletion cut short) left behind. */
      stale = ex == 0 || (ex == 1 && st != SRV_SUCCEEDED &&
                          /* In a shared results directory, another node may have just
                           * published what it is about to commit. */
                          !(app->cfg.results_dir && st == SRV_RUNNING));
    }
    if (!stale) continue;
    snprintf(path, sizeof path, "%s/%s", app->results_dir, e->d_name);
    srv_log("start-up: removing stale %s", path);
    srv_remove_tree(path);
  }
  closedir(d);
}

/* ---- outputs as blobs of the store ---------------------------------------------------------- */

static int read_all(const char *path, void **data, size_t *n, obs_err *err) {
  *data = NULL;
  *n = 0;
  int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  struct stat st;
  if (fd < 0 || fstat(fd, &st)) {
    int e = errno;
    if (fd >= 0) close(fd);
    return obs_err_set(err, OBS_EIO, "%s: cannot open: %s", path, strerror(e));
  }
  char *buf = malloc(st.st_size ? (size_t)st.st_size : 1);
  if (!buf) {
    close(fd);
    return obs_err_set(err, OBS_ENOMEM, "%s: out of memory", path);
  }
  size_t got = 0;
  while (got < (size_t)st.st_size) {
    ssize_t r = read(fd, buf + got, (size_t)st.st_size - got);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      int e = r < 0 ? errno : EIO;
      free(buf);
      close(fd);
      return obs_err_set(err, OBS_EIO, "%s: read failed: %s", path, strerror(e));
    }
    got += (size_t)r;
  }
  close(fd);
  *data = buf;
  *n = got;
  return 0;
}

int srv_outputs_put_blobs(srv_app *app, const char *dir, const srv_output *outs, int n,
                          obs_err *err) {
  for (int i = 0; i < n; i++) {
    char path[8400];
    snprintf(path, sizeof path, "%s/%s", dir, outs[i].name);
    void *data;
    size_t len;
    int rc = read_all(path, &data, &len, err);
    if (!rc) rc = srv_db_put_blob(app->db, outs[i].sha256, data, len, err);
    free(data);
    if (rc) return rc;
  }
  return 0;
}

int srv_outputs_local(srv_app *app, int64_t id, const srv_output *o, obs_err *err) {
  char dir[4200], path[8400], tmp[8500];
  srv_results_path(app, id, dir, sizeof dir);
  snprintf(path, sizeof path, "%s/%s", dir, o->name);
  struct stat st;
  if (!lstat(path, &st)) return 0;
  if (!app->results_via_store)
    return obs_err_set(err, OBS_ENOTFOUND, "%s: %s", path, strerror(ENOENT));
  void *data = NULL;
  size_t n = 0;
  int rc = srv_db_get_blob(app->db, o->sha256, &data, &n, err);
  if (rc) return rc;
  unsigned char md[32];
  char hex[65];
  srv_sha256(data, n, md);
  for (int i = 0; i < 32; i++) snprintf(hex + 2 * i, 3, "%02x", md[i]);
  if ((int64_t)n != o->size || strcmp(hex, o->sha256)) {
    free(data);
    return obs_err_set(err, OBS_EIO, "job %lld: the stored blob of output %s does not match it",
                       (long long)id, o->name);
  }
  /* Written beside the name and renamed over it: a concurrent reader sees all or nothing. */
  snprintf(tmp, sizeof tmp, "%s/.%s.%ld.%lx", dir, o->name, (long)getpid(),
           (unsigned long)pthread_self());
  int fd = -1;
  if (obs_path_make_dirs(dir, NULL) ||
      (fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_CLOEXEC, 0644)) < 0) {
    free(data);
    return obs_err_set(err, OBS_EIO, "%s: cannot create: %s", tmp, strerror(errno));
  }
  size_t put = 0;
  while (put < n) {
    ssize_t w = write(fd, (char *)data + put, n - put);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) break;
    put += (size_t)w;
  }
  int e = put < n ? (errno ? errno : ENOSPC) : 0;
  if (close(fd) && !e) e = errno;
  free(data);
  if (!e && rename(tmp, path)) e = errno;
  if (e) {
    unlink(tmp);
    return obs_err_set(err, OBS_EIO, "%s: cannot write: %s", path, strerror(e));
  }
  return 0;
}

int srv_outputs_local_all(srv_app *app, int64_t id, obs_err *err) {
  if (!app->results_via_store) return 0;
  srv_job j;
  int rc = srv_db_get_job(app->db, id, &j, err);
  if (rc) return rc;
  for (int i = 0; !rc && i < j.noutputs; i++) rc = srv_outputs_local(app, id, &j.outputs[i], err);
  srv_job_free(&j);
  return rc;
}

/* ---- serving --------------------------------------------------------------------------------- */

/* Whether an If-None-Match list names `etag` (quoted) or is "*". Weak tags compare weakly. */
static int etag_matches(const char *list, const char *etag) {
  if (!list) return 0;
  size_t n = strlen(etag);
  const char *p = list;
  while (*p) {
    while (*p == ' ' || *p == '\t' || *p == ',') p++;
    if (*p == '*') return 1;
    if (!strncmp(p, "W/", 2)) p += 2;
    if (!strncmp(p, etag, n) && (p[n] == '\0' || p[n] == ',' || p[n] == ' ' || p[n] == '\t'))
      return 1;
    while (*p && *p != ',') p++;
  }
  return 0;
}

static int parse_u64(const char **p, uint64_t *out) {
  const char *s = *p;
  if (*s < '0' || *s > '9') return -1;
  uint64_t v = 0;
  while (*s >= '0' && *s <= '9') {
    if (v > (UINT64_MAX - 9) / 10) return -1;
    v = v * 10 + (uint64_t)(*s++ - '0');
  }
  *p = s;
  *out = v;
  return 0;
}

/* Parses a single "bytes=" range against `size`. Returns 1 with [*from, *to] when satisfiable,
 * 0 when the header should be ignored (absent, malformed, several ranges), -1 when it cannot
 * be satisfied (416). */
static int parse_range(const char *h, uint64_t size, uint64_t *from, uint64_t *to) {
  if (!h) return 0;
  while (*h == ' ') h++;
  if (strncmp(h, "bytes=", 6)) return 0;
  h += 6;
  if (strchr(h, ',')) return 0;
  while (*h == ' ') h++;
  uint64_t a, b = 0;
  if (*h == '-') {
    h++;
    if (parse_u64(&h, &b)) return 0;
    while (*h == ' ') h++;
    if (*h) return 0;
    if (b == 0 || size == 0) return -1;
    *from = b >= size ? 0 : size - b;
    *to = size - 1;
    return 1;
  }
  if (parse_u64(&h, &a) || *h++ != '-') return 0;
  int open_end = *h == '\0' || *h == ' ';
  if (!open_end && parse_u64(&h, &b)) return 0;
  while (*h == ' ') h++;
  if (*h) return 0;
  if (!open_end && b < a) return 0;
  if (a >= size) return -1;
  *from = a;
  *to = open_end || b >= size ? size - 1 : b;
  return 1;
}

static void add_cache_headers(struct MHD_Response *resp, const char *etag) {
  MHD_add_response_header(resp, "ETag", etag);
  MHD_add_response_header(resp, "Cache-Control", "public, max-age=31536000, immutable");
  MHD_add_response_header(resp, "Accept-Ranges", "bytes");
}

int srv_output_serve(srv_req *r, int64_t id, const char *name) {
  if (!srv_output_content_type(name)) {
    /* The name comes from the URL and need not be UTF-8, which the JSON answer must be. */
    char shown[65], list[MAX_KNOWN * OBS_OUTPUT_FILE_MAX];
    srv_printable(name, shown, sizeof shown);
    size_t len = 0;
    for (size_t i = 0; i < nknown && len < sizeof list; i++)
      len += (size_t)snprintf(list + len, sizeof list - len, "%s%s", i ? ", " : "", known[i]);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "no output named \"%s\" (outputs are %s)",
                             shown, list);
  }
  srv_output o;
  obs_err err = OBS_ERR_INIT;
  int rc = srv_db_get_output(r->app->db, id, name, &o, &err);
  if (rc == OBS_ENOTFOUND) {
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_NOT_FOUND, NULL, "job %lld has no output %s",
                             (long long)id, name);
  }
  if (rc) {
    int out = srv_respond_error(r, MHD_HTTP_SERVICE_UNAVAILABLE, &err, "database unavailable");
    obs_err_free(&err);
    return out;
  }
  /* Another node's output that travels through the store becomes a local file first. */
  if (srv_outputs_local(r->app, id, &o, &err) && r->app->results_via_store) {
    srv_log("job %lld: output %s: %s", (long long)id, o.name, obs_err_message(&err));
    obs_err_free(&err);
    return srv_respond_error(r, MHD_HTTP_SERVICE_UNAVAILABLE, NULL,
                             "output %s of job %lld cannot be fetched from the store", o.name,
                             (long long)id);
  }
  obs_err_free(&err);
  char path[8400];
  srv_results_path(r->app, id, path, sizeof path);
  size_t n = strlen(path);
  snprintf(path + n, sizeof path - n, "/%s", o.name);
  int fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  struct stat st;
  if (fd < 0 || fstat(fd, &st) || !S_ISREG(st.st_mode) || st.st_size != o.size) {
    if (fd >= 0) close(fd);
    srv_log("job %lld: output %s is missing or does not match the database", (long long)id,
            o.name);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL,
                             "output %s of job %lld is missing on disk", o.name, (long long)id);
  }
  char etag[70];
  snprintf(etag, sizeof etag, "\"%s\"", o.sha256);
  const char *inm =
      MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_NONE_MATCH);
  if (etag_matches(inm, etag)) {
    close(fd);
    struct MHD_Response *resp = MHD_create_response_from_buffer(0, "", MHD_RESPMEM_PERSISTENT);
    add_cache_headers(resp, etag);
    return srv_respond(r, MHD_HTTP_NOT_MODIFIED, resp);
  }
  uint64_t size = (uint64_t)st.st_size, from = 0, to = size ? size - 1 : 0;
  const char *range = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_RANGE);
  const char *if_range =
      MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_RANGE);
  if (if_range && strcmp(if_range, etag)) range = NULL;
  int pr = parse_range(range, size, &from, &to);
  char cr[96];
  if (pr < 0) {
    close(fd);
    snprintf(cr, sizeof cr, "bytes */%" PRIu64, size);
    struct MHD_Response *resp = srv_json_response(
        json_pack("{s:s, s:[]}", "error", "range not satisfiable", "problems"));
    if (!resp) return MHD_NO;
    MHD_add_response_header(resp, "Content-Range", cr);
    add_cache_headers(resp, etag);
    return srv_respond(r, MHD_HTTP_RANGE_NOT_SATISFIABLE, resp);
  }
  uint64_t len = pr ? to - from + 1 : size;
  struct MHD_Response *resp = MHD_create_response_from_fd_at_offset64(len, fd, (int64_t)from);
  if (!resp) {
    close(fd);
    return srv_respond_error(r, MHD_HTTP_INTERNAL_SERVER_ERROR, NULL, "cannot serve the file");
  }
  MHD_add_response_header(resp, "Content-Type", o.content_type);
  add_cache_headers(resp, etag);
  if (pr) {
    snprintf(cr, sizeof cr, "bytes %" PRIu64 "-%" PRIu64 "/%" PRIu64, from, to, size);
    MHD_add_response_header(resp, "Content-Range", cr);
  }
  return srv_respond(r, pr ? MHD_HTTP_PARTIAL_CONTENT : MHD_HTTP_OK, resp);
}

/* ---- fault probes ---------------------------------------------------------------------------- */

int srv_outputs_probe(const char *dir, char *code, size_t n, obs_err *err) {
  char path[4200];
  snprintf(path, sizeof path, "%s/.probe-%ld", dir, (long)getpid());
  /* A page, as a small output would need; fsync so that a disk that only fails on write-back
   * (quota, I/O errors) fails here too. */
  static const char block[4096];
  int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_CLOEXEC, 0644);
  /* ENOENT: the directory itself was removed. */
  if (fd < 0 && errno == ENOENT && !obs_path_make_dirs(dir, NULL))
    fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_CLOEXEC, 0644);
  int e = fd < 0 ? errno : 0;
  const char *what = "cannot create a file";
  if (!e) {
    ssize_t w = write(fd, block, sizeof block);
    if (w != (ssize_t)sizeof block) {
      e = w < 0 ? errno : ENOSPC;
      what = "cannot write a file";
    } else if (fsync(fd)) {
      e = errno;
      what = "cannot flush a file";
    }
    if (close(fd) && !e) {
      e = errno;
      what = "cannot close a file";
    }
    unlink(path);
  }
  if (!e) return 0;
  snprintf(code, n, "%s", srv_errno_name(e));
  return obs_err_set(err, OBS_ETRANSIENT, "%s: %s: %s", dir, what, strerror(e));
}

int srv_outputs_fault(const char *dir, const char *message, char *code, size_t n, obs_err *probe) {
  if (srv_outputs_probe(dir, code, n, probe)) return 1;
  /* The probe passed (a page fits, a big EXR may not): the renderer's messages end with
   * strerror(errno), so the environment's errors are recognised by their text. */
  static const int transient[] = {ENOSPC, EROFS, EACCES, EPERM, EIO, EDQUOT, EMFILE, ENFILE};
  for (size_t i = 0; message && i < sizeof transient / sizeof transient[0]; i++) {
    if (strstr(message, strerror(transient[i]))) {
      snprintf(code, n, "%s", srv_errno_name(transient[i]));
      obs_err_set(probe, OBS_ETRANSIENT, "%s", message);
      /* Out of room for these files while a page still fits: the disk serves smaller jobs. */
      return transient[i] == ENOSPC || transient[i] == EDQUOT ? SRV_OUTPUTS_NO_ROOM : 1;
    }
  }
  return 0;
}

double srv_outputs_free_bytes(const char *dir) {
  struct statvfs st;
  if (statvfs(dir, &st)) return -1;
  return (double)st.f_bavail * (double)st.f_frsize;
}
