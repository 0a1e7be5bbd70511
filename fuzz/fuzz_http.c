/* libFuzzer target: the daemon's HTTP request parsing and dispatch. obscurad's application is
 * started once in this process (temporary directory and SQLite file, no Vulkan, no token, small
 * limits) on an ephemeral loopback port; each input is sent as raw bytes over a fresh TCP
 * connection, whose write side is then closed, and the first final answer is read to the end of
 * its framed body. A finding is: a crash or sanitizer report anywhere in the daemon, no complete
 * answer within ANSWER_MS, an answer that is not a well-formed HTTP response, a status the client could not
 * have caused (5xx other than 501, 503 and 505), a finished request (see request_finished) left
 * without an answer, or a daemon that stops answering its health check. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

/* Generous: a request validating a mesh scene under ASan on a loaded machine takes well under 1 s. */
#define ANSWER_MS 10000
/* How long an unfinished request may take to be answered early (413 for a large Content-Length,
 * 400 for a bad request line) before the connection is reset. */
#define QUIET_MS 1
#define KEEP 65536

static srv_app app;
static char tmpdir[4096];

static void fail(const char *what, const char *answer, size_t n) {
  fprintf(stderr, "fuzz_http: %s\n", what);
  if (answer) fprintf(stderr, "answer (%zu bytes):\n%.*s\n", n, (int)(n > 2048 ? 2048 : n), answer);
  abort();
}

static void clean_outputs(void *user, int64_t id) { srv_outputs_remove(user, id); }

static void stop_app(void) {
  srv_http_stop(&app);
  srv_sched_stop(&app);
  srv_db_close(app.db);
  app.db = NULL;
  srv_metrics_free();
  srv_config_free(&app.cfg);
  if (tmpdir[0]) srv_remove_tree(tmpdir);
}

static void die(const char *what, obs_err *err) {
  fprintf(stderr, "fuzz_http: cannot start the daemon: %s: %s\n", what,
          err ? obs_err_message(err) : strerror(errno));
  exit(1);
}

/* The start-up sequence of obscurad's main(), without its signal handling and messages. */
int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  const char *t = getenv("TMPDIR");
  snprintf(tmpdir, sizeof tmpdir, "%s/obsd-fuzz-XXXXXX", t && *t ? t : "/tmp");
  if (!mkdtemp(tmpdir)) die("mkdtemp", NULL);
  char data[4200], db[4200];
  snprintf(data, sizeof data, "%s/data", tmpdir);
  snprintf(db, sizeof db, "%s/obscura.db", tmpdir);
  char *args[] = {"obscurad", "--listen", "127.0.0.1", "--port", "0", "--data-dir", data, "--db",
                  db, "--scenes-dir", OBS_SOURCE_DIR "/scenes", "--web-dir", OBS_SOURCE_DIR "/web",
                  "--vendor-dir", OBS_SOURCE_DIR "/node_modules", "--workers", "1", "--no-vulkan",
                  "--quiet", "--http-threads", "2", "--max-body", "16K", "--max-pixels", "4096",
                  "--max-work", "1e5", "--max-triangles", "20000", "--max-render-seconds", "5",
                  NULL};
  int n = (int)(sizeof args / sizeof args[0]) - 1;
  if (srv_config_parse(&app.cfg, n, args)) die("options", NULL);
  /* libcrypto registers its own exit cleanup when first used; using it now puts stop_app after
   * it, so the daemon's threads are gone before libcrypto frees its per-thread state (as in
   * obscurad, whose threads end before main returns). */
  unsigned char digest[32];
  srv_sha256("", 0, digest);
  atexit(stop_app);
  obs_render_keep_memory();
  app.start_ms = obs_now_ms();
  snprintf(app.results_dir, sizeof app.results_dir, "%s/results", data);
  if (obs_path_make_dirs(app.results_dir, NULL)) die(app.results_dir, NULL);
  if (!realpath(app.cfg.scenes_dir, app.scenes_real)) die(app.cfg.scenes_dir, NULL);
  if (!realpath(app.cfg.web_dir, app.web_real)) app.web_real[0] = '\0';
  if (!realpath(app.cfg.vendor_dir, app.vendor_real)) app.vendor_real[0] = '\0';
  char real[4096];
  if (!realpath(app.results_dir, real)) die(app.results_dir, NULL);
  snprintf(app.results_dir, sizeof app.results_dir, "%s", real);
  srv_metrics_init();
  app.cpu_threads = 1;
  obs_err err = OBS_ERR_INIT;
  int nconn = app.cfg.http_threads + app.cfg.workers + 3;
  if (srv_db_open(&app.db, app.cfg.db, nconn, NULL, &err)) die("database", &err);
  if (srv_db_recover(app.db, srv_pick_lane_recovered, clean_outputs, &app, &err)) die("recovery", &err);
  if (srv_db_machine(app.db, "fuzz", 1, NULL, NULL, &app.machine_id, &err)) die("machine", &err);
  if (srv_sched_start(&app, &err)) die("scheduler", &err);
  if (srv_http_start(&app, &err)) die("HTTP", &err);
  obs_err_free(&err);
  return 0;
}

static int connect_daemon(void) {
  int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) fail("socket", NULL, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)app.port)};
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  struct timeval tv = {ANSWER_MS / 1000, 0};
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  /* Closed with a reset once the answer is in: no TIME_WAIT socket per input. */
  struct linger lg = {1, 0};
  setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
  /* A failed connect is retried for ANSWER_MS: libFuzzer's timer signal can interrupt it (EINTR)
   * and local ports can run out for a moment; a daemon that stops accepting is a finding. */
  double deadline = obs_now_ms() + ANSWER_MS;
  while (connect(fd, (struct sockaddr *)&a, sizeof a)) {
    int e = errno;
    close(fd);
    if (obs_now_ms() > deadline) {
      char msg[160];
      snprintf(msg, sizeof msg, "cannot connect to the daemon for %d ms: %s", ANSWER_MS, strerror(e));
      fail(msg, NULL, 0);
    }
    fprintf(stderr, "fuzz_http: connect: %s; retrying\n", strerror(e));
    usleep(10000);
    fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd < 0) fail("socket", NULL, 0);
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
  }
  return fd;
}

static int is_tchar(char c) {
  return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
         (c && strchr("!#$%&'*+-.^_`|~", c));
}

/* The end of a complete response head in buf[0..n) (past its empty line), or 0 while incomplete. */
static size_t head_end(const char *buf, size_t n) {
  for (size_t i = 3; i < n; i++)
    if (buf[i] == '\n' && buf[i - 1] == '\r' && buf[i - 2] == '\n' && buf[i - 3] == '\r')
      return i + 1;
  return 0;
}

/* Checks one complete response head buf[0..n): status line and `Name: value` lines. Returns the
 * status; *length is the Content-Length (-1 when absent), *chunked and *closes are set from
 * Transfer-Encoding and Connection. */
static int parse_head(const char *buf, size_t n, long long *length, int *chunked, int *closes) {
  *length = -1;
  *chunked = *closes = 0;
  if (n < 14 || (memcmp(buf, "HTTP/1.1 ", 9) && memcmp(buf, "HTTP/1.0 ", 9)))
    fail("the answer does not start with an HTTP/1.x status line", buf, n);
  for (int i = 9; i < 12; i++)
    if (buf[i] < '0' || buf[i] > '9') fail("the status is not three digits", buf, n);
  if (buf[12] != ' ' && buf[12] != '\r') fail("the status is not three digits", buf, n);
  int status = (buf[9] - '0') * 100 + (buf[10] - '0') * 10 + (buf[11] - '0');
  const char *p = memchr(buf, '\n', n);
  if (!p || p[-1] != '\r') fail("the status line does not end in CRLF", buf, n);
  p++;
  for (;;) {
    const char *eol = memchr(p, '\n', n - (size_t)(p - buf));
    if (!eol || eol[-1] != '\r') fail("a header line does not end in CRLF", buf, n);
    if (eol == p + 1) break;
    const char *q = p;
    while (q < eol && is_tchar(*q)) q++;
    if (q == p || *q != ':') fail("a header line is not `Name: value`", buf, n);
    size_t nlen = (size_t)(q - p);
    const char *v = q + 1;
    while (*v == ' ' || *v == '\t') v++;
    for (const char *c = v; c < eol - 1; c++)
      if ((unsigned char)*c < 0x20 && *c != '\t') fail("a control character in a header", buf, n);
    if (nlen == 14 && !strncasecmp(p, "Content-Length", 14)) {
      if (*length >= 0) fail("two Content-Length headers", buf, n);
      char *e;
      *length = strtoll(v, &e, 10);
      if (e == v || *length < 0 || (e != eol - 1 && *e != ' ')) fail("a bad Content-Length", buf, n);
    } else if (nlen == 17 && !strncasecmp(p, "Transfer-Encoding", 17)) {
      *chunked = !strncasecmp(v, "chunked", 7);
    } else if (nlen == 10 && !strncasecmp(p, "Connection", 10)) {
      *closes = !strncasecmp(v, "close", 5);
    }
    p = eol + 1;
  }
  return status;
}

/* A connection's bytes as they arrive: the first KEEP are kept, the rest only counted. */
typedef struct conn {
  int fd;
  char *buf;
  size_t kept, total;
  double deadline; /* for the whole answer */
  double quiet;    /* unfinished requests: for the first byte after `base` (0 = none) */
  size_t base;
  int silent;      /* nothing came before `quiet` */
} conn;

/* Reads more; 0 at the end of the stream or when an unfinished request stays unanswered. Aborts
 * at the deadline. */
static int more(conn *c) {
  for (;;) {
    int early = c->quiet && c->total == c->base;
    int left = (int)((early ? c->quiet : c->deadline) - obs_now_ms() + 0.999);
    if (left <= 0 && early) {
      c->silent = 1;
      return 0;
    }
    if (left <= 0) fail("no complete answer within the time limit", c->buf, c->kept);
    struct pollfd p = {c->fd, POLLIN, 0};
    int pr = poll(&p, 1, left);
    if (pr <= 0) continue;
    char chunk[16384];
    ssize_t r = recv(c->fd, chunk, sizeof chunk, 0);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return 0;
    size_t take = (size_t)r < KEEP - c->kept ? (size_t)r : KEEP - c->kept;
    memcpy(c->buf + c->kept, chunk, take);
    c->kept += take;
    c->total += (size_t)r;
    return 1;
  }
}

/* Waits until `n` bytes have arrived in all; 0 when the stream ended first. */
static int until(conn *c, size_t n) {
  while (c->total < n)
    if (!more(c)) return 0;
  return 1;
}

/* Reads a chunked body starting at byte `at`; returns the offset past it, aborting when the
 * framing is broken. Chunk-size lines must lie within the kept bytes (bodies here are small). */
static size_t chunked_end(conn *c, size_t at) {
  for (;;) {
    size_t eol;
    for (;;) {
      const char *nl = at < c->kept ? memchr(c->buf + at, '\n', c->kept - at) : NULL;
      if (nl) {
        eol = (size_t)(nl - c->buf);
        break;
      }
      if (c->kept >= KEEP || !more(c)) fail("a chunked body without its chunk size", c->buf, c->kept);
    }
    char *e;
    unsigned long long sz = strtoull(c->buf + at, &e, 16);
    if (e == c->buf + at) fail("a bad chunk size", c->buf, c->kept);
    at = eol + 1;
    if (sz == 0) {
      if (!until(c, at + 2)) fail("a chunked body without its last CRLF", c->buf, c->kept);
      return at + 2;
    }
    if (!until(c, at + sz + 2)) fail("a chunked body cut short", c->buf, c->kept);
    at += sz + 2;
  }
}

/* Sends `data` (its write side then closed) and reads the first final response. A response is
 * complete at the end of its framed body (Content-Length, chunked, none for HEAD, 204 and 304, or
 * the end of the stream). A finished request must be answered within ANSWER_MS; an unfinished
 * one (see request_finished) may be, within QUIET_MS. Returns the status, or 0 when no answer
 * came; the head is checked (aborting when malformed) and left in buf. */
static int exchange(const uint8_t *data, size_t size, int finished, char *buf, size_t *kept) {
  double now = obs_now_ms();
  conn c = {connect_daemon(), buf, 0, 0, now + ANSWER_MS, finished ? 0 : now + QUIET_MS, 0, 0};
  size_t off = 0;
  while (off < size) {
    ssize_t w = send(c.fd, data + off, size - off, MSG_NOSIGNAL);
    if (w <= 0) break; /* the daemon may answer and close before reading everything */
    off += (size_t)w;
  }
  /* libmicrohttpd does not always notice the end of a half-closed connection (it may keep it to
   * its idle timeout): the answer's framing, not the end of the stream, says when it is done. */
  shutdown(c.fd, SHUT_WR);
  /* HEAD answers carry no body; the method is the first token after any leading empty lines.
   * libmicrohttpd reads a line as a C string, so a line that starts with a NUL is empty to it. */
  size_t m = 0;
  while (m < size) {
    if (data[m] == '\r' || data[m] == '\n') {
      m++;
    } else if (data[m] == '\0') {
      const uint8_t *nl = memchr(data + m, '\n', size - m);
      if (!nl) break;
      m = (size_t)(nl - data) + 1;
    } else {
      break;
    }
  }
  int head_req = size - m >= 5 && !memcmp(data + m, "HEAD ", 5);
  size_t start = 0;
  int status = 0;
  for (;;) {
    size_t end;
    while (!(end = start < c.kept ? head_end(c.buf + start, c.kept - start) : 0)) {
      if (c.kept >= KEEP) fail("a response head larger than 64 KiB", c.buf, c.kept);
      if (!more(&c)) {
        if (c.total > start) fail("the answer ends inside a response head", c.buf, c.kept);
        close(c.fd);
        *kept = c.kept;
        return status ? -1 : 0;
      }
    }
    long long length;
    int chunked, conn_close;
    status = parse_head(c.buf + start, end, &length, &chunked, &conn_close);
    end += start;
    if (status >= 100 && status < 200) {
      /* An unfinished request may stop at its interim answer: the quiet rule starts again. */
      start = end;
      if (!finished) {
        c.quiet = obs_now_ms() + QUIET_MS;
        c.base = c.total;
      }
      continue;
    }
    if (head_req || status == 204 || status == 304) {
    } else if (chunked) {
      chunked_end(&c, end);
    } else if (length >= 0) {
      if (!until(&c, end + (size_t)length)) fail("a body shorter than its Content-Length", c.buf, c.kept);
    } else {
      while (more(&c)) {
      }
    }
    break;
  }
  close(c.fd);
  *kept = c.kept;
  return status;
}

static void check_health(void) {
  static const char req[] = "GET /api/v1/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  static char buf[KEEP];
  size_t n;
  if (exchange((const uint8_t *)req, sizeof req - 1, 1, buf, &n) != 200)
    fail("the health check is not answered 200", buf, n);
}

/* The end of the first line in d[at..n) (past its LF), or 0. */
static size_t line_end(const uint8_t *d, size_t n, size_t at) {
  const uint8_t *nl = at < n ? memchr(d + at, '\n', n - at) : NULL;
  return nl ? (size_t)(nl - d) + 1 : 0;
}

static int blank(const uint8_t *d, size_t from, size_t to) {
  return to - from == 1 || (to - from == 2 && d[from] == '\r');
}

/* `METHOD SP target SP HTTP/1.x CRLF` in d[0..end). */
static int request_line_ok(const uint8_t *d, size_t end) {
  size_t i = 0;
  while (i < end && is_tchar((char)d[i])) i++;
  if (!i || i >= end || d[i++] != ' ') return 0;
  size_t t = i;
  while (i < end && d[i] > ' ' && d[i] < 0x7f) i++;
  if (i == t || i >= end || d[i++] != ' ') return 0;
  return end - i == 10 && (!memcmp(d + i, "HTTP/1.1\r\n", 10) || !memcmp(d + i, "HTTP/1.0\r\n", 10));
}

/* Whether the request in d[0..n) is finished by unambiguous HTTP/1.1 framing: a well-formed
 * request line, `Name: value` header lines up to an empty line, and no body, one Content-Length
 * with that many bytes, or exactly `chunked` with its last chunk; no Expect. Anything else (cut off,
 * garbled, conflicting lengths, other transfer codings) is unfinished: libmicrohttpd may wait for more or
 * drop the connection, so the daemon is only watched for crashes, early answers and liveness
 * (tests/server/bad_requests.json holds what such requests must get). */
static int request_finished(const uint8_t *d, size_t n) {
  size_t at = 0, end;
  long long length = -1;
  int lengths = 0, te = 0, chunked = 0;
  if (!(end = line_end(d, n, 0)) || !request_line_ok(d, end)) return 0;
  for (at = end; (end = line_end(d, n, at)) && !blank(d, at, end); at = end) {
    const char *h = (const char *)d + at;
    size_t len = end - at;
    const char *colon = memchr(h, ':', len);
    if (!colon || colon == h) return 0;
    for (const char *q = h; q < colon; q++)
      if (!is_tchar(*q)) return 0;
    if (len > 15 && !strncasecmp(h, "content-length:", 15)) {
      char num[32];
      size_t k = 0;
      for (size_t i = 15; i < len && k + 1 < sizeof num; i++)
        if (h[i] != ' ' && h[i] != '\t' && h[i] != '\r' && h[i] != '\n') num[k++] = h[i];
      num[k] = '\0';
      char *e;
      length = strtoll(num, &e, 10);
      if (!k || *e || length < 0) return 0;
      lengths++;
    } else if (len > 7 && !strncasecmp(h, "expect:", 7)) {
      /* libmicrohttpd's 100-continue states can leave a bodiless request unanswerable (its
       * MHD_queue_response refuses), closing the connection after the interim answer. */
      return 0;
    } else if (len > 18 && !strncasecmp(h, "transfer-encoding:", 18)) {
      te++;
      size_t i = 18;
      while (i < len && (h[i] == ' ' || h[i] == '\t')) i++;
      chunked = len - i >= 8 && !strncasecmp(h + i, "chunked", 7) &&
                ((len - i == 8 && h[i + 7] == '\n') || (len - i == 9 && h[i + 7] == '\r'));
    }
  }
  if (!end) return 0;
  at = end; /* the body */
  if (te) {
    if (te > 1 || !chunked || lengths) return 0;
    for (;;) {
      if (!(end = line_end(d, n, at))) return 0;
      char *e;
      unsigned long long sz = strtoull((const char *)d + at, &e, 16);
      if ((const uint8_t *)e == d + at) return 0;
      at = end;
      if (sz == 0) break;
      if (sz > n || n - at < sz + 2) return 0;
      at += sz + 2;
    }
    for (; (end = line_end(d, n, at)); at = end) /* trailers, then the empty line */
      if (blank(d, at, end)) return 1;
    return 0;
  }
  if (lengths > 1) return 0;
  return lengths == 0 || (long long)(n - at) >= length;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static char buf[KEEP];
  static unsigned long count;
  size_t n;
  int finished = request_finished(data, size);
  int status = exchange(data, size, finished, buf, &n);
  if (status < 0 && finished) fail("an interim answer without a final one", buf, n);
  if (status == 0 && finished) fail("a finished request closed without an answer", buf, n);
  if (status <= 0 || ++count % 4096 == 0) {
    check_health();
    return 0;
  }
  if (status < 200 || status > 599) fail("a status outside 200..599", buf, n);
  if (status >= 500 && status != 501 && status != 503 && status != 505)
    fail("a server error the request should not be able to cause", buf, n);
  return 0;
}
