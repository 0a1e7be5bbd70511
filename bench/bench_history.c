/* bench_history: what a long job history costs the requests every client makes. Builds a history
 * of N finished jobs through the store interface (insert, claim, finish with outputs rows and a
 * timed run, as a daemon records them), then starts a real obscurad on that store on loopback and
 * measures, over one keep-alive connection: a submission (POST /api/v1/jobs of a small "auto" job
 * whose technique and work match the history, so learned auto and the render-time estimate read
 * it; each waited for before the next is timed), /api/v1/health, and pages of 50 jobs under every
 * filter, deep pages included. Prints p50/p99 of each with the CPU model and the store kind.
 *
 *   bench_history [--jobs N] [--store PATH|postgresql://...] [--reps R] [--submits S]
 *                 [--obscurad PATH] [--scenes DIR] [--reuse] [--measure-only]
 *
 * Defaults: 100000 jobs, a SQLite file in a fresh directory under /tmp (removed afterwards unless
 * --reuse, which also skips building when the store already holds N jobs). --measure-only times
 * an existing store without opening it here (so that another build of obscurad, one with an older
 * schema, can be timed on a copy of it). */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "bench_args.h"
#include "obscurad.h"

static const char *const TECHS[] = {"rt_ao", "rt_ao", "ssao", "hbao", "proximity_ao"};
#define NTECHS (sizeof TECHS / sizeof TECHS[0])

static double now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1e3 + t.tv_nsec / 1e6;
}

static char *slurp(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *s = malloc((size_t)n + 1);
  if (s && fread(s, 1, (size_t)n, f) != (size_t)n) n = 0;
  if (s) s[n] = 0;
  fclose(f);
  return s;
}

static void die(const char *what, obs_err *e) {
  fprintf(stderr, "bench_history: %s: %s\n", what, e ? obs_err_message(e) : strerror(errno));
  exit(1);
}

/* ---- building the history through the store interface --------------------------------------- */

/* summary.json of a 16x16 rt_ao render as obscurad stores it, so that every page of the history
 * costs what a page of real jobs does. */
static const char SUMMARY[] =
    "{\"scene\":\"sphere_on_plane.json\",\"technique\":\"rt_ao\",\"backend\":\"cpu\",\"width\":16,\"height\":"
    "16,\"spp\":1,\"samples\":4,\"params\":{\"samples\":4,\"sampler\":\"sobol\",\"seed\":1,\"max_distance\":n"
    "ull,\"falloff\":\"binary\",\"tau\":1,\"weighting\":\"cosine\"},\"work_per_pixel_sample\":4.0,\"thread"
    "s\":2,\"timings_ms\":{\"load\":0.116682999,\"build\":0.38634,\"render\":0.544034004,\"write\":1.883"
    "402,\"total\":2.96108501,\"stages\":{\"load\":0.116682999,\"bvh\":0.380314,\"prepare\":0.006025999"
    "78,\"prior\":0.169933006,\"shade\":0.374100998,\"other\":0.030625999,\"write\":1.883402}},\"rays\""
    ":1440,\"rays_per_second\":2646893.37,\"ao\":{\"mean\":0.926757812,\"min\":0.0,\"max\":1.0},\"ao_std"
    "err_mean\":0.0886307526,\"nan_count\":0,\"primary_output\":\"ao\",\"outputs\":{\"ao\":{\"kind\":\"scal"
    "ar\",\"channels\":{\"ao\":{\"mean\":0.926757812,\"min\":0.0,\"max\":1.0,\"count\":256,\"nonfinite\":0}}"
    "},\"ao_stderr\":{\"kind\":\"scalar\",\"channels\":{\"ao_stderr\":{\"mean\":0.0886307526,\"min\":0.0493"
    "463762,\"max\":0.288675129,\"count\":256,\"nonfinite\":0}}},\"bent_normal\":{\"kind\":\"vector\",\"ch"
    "annels\":{\"bent_normal.X\":{\"mean\":0.0106628515,\"min\":-0.96203804,\"max\":0.782178164,\"count"
    "\":256,\"nonfinite\":0},\"bent_normal.Y\":{\"mean\":0.84045959,\"min\":-0.62799418,\"max\":0.999979"
    "317,\"count\":256,\"nonfinite\":0},\"bent_normal.Z\":{\"mean\":-0.0441171767,\"min\":-0.932325482,"
    "\"max\":0.790865302,\"count\":256,\"nonfinite\":0}}},\"depth\":{\"kind\":\"depth\",\"channels\":{\"dept"
    "h.Z\":{\"mean\":6.07365393,\"min\":3.40392423,\"max\":12.6257305,\"count\":256,\"nonfinite\":0}}},\""
    "normal\":{\"kind\":\"vector\",\"channels\":{\"normal.X\":{\"mean\":0.0,\"min\":-0.64496547,\"max\":0.64"
    "496547,\"count\":256,\"nonfinite\":0},\"normal.Y\":{\"mean\":0.956463514,\"min\":-0.62799418,\"max\""
    ":1.0,\"count\":256,\"nonfinite\":0},\"normal.Z\":{\"mean\":-0.0403566285,\"min\":-0.977936864,\"max"
    "\":0.0,\"count\":256,\"nonfinite\":0}}},\"alpha\":{\"kind\":\"scalar\",\"channels\":{\"alpha\":{\"mean\":"
    "1.0,\"min\":1.0,\"max\":1.0,\"count\":256,\"nonfinite\":0}}}},\"warnings\":[],\"built\":[{\"name\":\"bv"
    "h\",\"triangles\":2,\"spheres\":1,\"bytes\":2380,\"peak_bytes\":2412}]}";

static void build(srv_db *db, int64_t njobs, const char *doc, int64_t machine) {
  const char *summary = SUMMARY;
  srv_output outs[5] = {{"ao.exr", 8108, "", "image/x-exr"},
                        {"ao.png", 154, "", "image/png"},
                        {"bent_normal.png", 852, "", "image/png"},
                        {"depth.png", 144, "", "image/png"},
                        {"summary.json", 3207, "", "application/json"}};
  double t0 = now_ms();
  for (int64_t i = 0; i < njobs; i++) {
    obs_err e = OBS_ERR_INIT;
    const char *tech = TECHS[i % NTECHS];
    int vulkan = (i / NTECHS) % 2;
    srv_new_job nj = {.priority = 50, .scene = "sphere_on_plane.json", .doc = doc,
                      .technique = tech, .backend_requested = "auto",
                      .lane = vulkan ? SRV_LANE_VULKAN : SRV_LANE_CPU, .width = 16, .height = 16,
                      .spp = 1, .repeats = 1, .work = 1024.0 * (1 + i % 3)};
    int64_t id;
    srv_job j;
    if (srv_db_insert_job(db, &nj, &id, &e)) die("inserting a job", &e);
    if (srv_db_claim(db, nj.lane, &j, &e) != 0) die("claiming it", &e);
    if (j.id != id) {
      fprintf(stderr, "bench_history: claimed job %lld, expected %lld\n", (long long)j.id,
              (long long)id);
      exit(1);
    }
    const char *be = vulkan ? "vulkan" : "cpu";
    if (i % 20 == 7) {
      if (srv_db_finish(db, id, j.attempts, i % 40 == 7 ? SRV_FAILED : SRV_CANCELLED,
                        "benchmark history", 0.5, &e))
        die("finishing it", &e);
    } else {
      for (int o = 0; o < 5; o++) snprintf(outs[o].sha256, sizeof outs[o].sha256, "%064llx",
                                           (unsigned long long)(id * 5 + o));
      srv_run run = {1, 2 + (double)(i % 5), 0.5, 3.5 + (double)(i % 5)};
      if (srv_db_finish_success(db, id, j.attempts, be, summary, outs, 5, &run, 1, machine, &e))
        die("finishing it", &e);
    }
    srv_job_free(&j);
    if ((i + 1) % 50000 == 0 || i + 1 == njobs)
      fprintf(stderr, "  built %lld / %lld jobs (%.0f s)\n", (long long)(i + 1),
              (long long)njobs, (now_ms() - t0) / 1e3);
  }
}

/* ---- a minimal HTTP/1.1 client over one keep-alive connection -------------------------------- */

typedef struct hconn {
  int fd;
  int port;
  char buf[1 << 20];
} hconn;

static void hconnect(hconn *c) {
  c->fd = socket(AF_INET, SOCK_STREAM, 0);
  struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)c->port)};
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(c->fd, (struct sockaddr *)&a, sizeof a)) die("connecting to obscurad", NULL);
  int one = 1;
  setsockopt(c->fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

/* Sends one request and reads the whole response; returns the status, the body in c->buf. */
static int hrequest(hconn *c, const char *method, const char *path, const char *body) {
  char req[4096];
  int n = snprintf(req, sizeof req,
                   "%s %s HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                   "Content-Length: %zu\r\n\r\n%s",
                   method, path, body ? strlen(body) : 0, body ? body : "");
  for (int tries = 0; tries < 2; tries++) {
    if (write(c->fd, req, (size_t)n) == n) {
      size_t got = 0;
      long need = -1;
      char *hdr_end = NULL;
      for (;;) {
        ssize_t r = read(c->fd, c->buf + got, sizeof c->buf - 1 - got);
        if (r <= 0) break;
        got += (size_t)r;
        c->buf[got] = 0;
        if (!hdr_end && (hdr_end = strstr(c->buf, "\r\n\r\n"))) {
          char *cl = strcasestr(c->buf, "content-length:");
          need = cl && cl < hdr_end ? atol(cl + 15) : 0;
        }
        if (hdr_end && (long)(got - (size_t)(hdr_end + 4 - c->buf)) >= need) {
          int status = atoi(c->buf + 9);
          memmove(c->buf, hdr_end + 4, got - (size_t)(hdr_end + 4 - c->buf) + 1);
          return status;
        }
      }
    }
    close(c->fd); /* the server closed the connection: once more on a new one */
    hconnect(c);
  }
  die("no response", NULL);
  return 0;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

static void report(const char *what, double *v, int n) {
  qsort(v, (size_t)n, sizeof *v, cmp_d);
  int i99 = (int)ceil(0.99 * n) - 1;
  printf("  %-46s p50 %7.2f ms  p99 %7.2f ms  (n=%d)\n", what, v[n / 2], v[i99 < 0 ? 0 : i99], n);
}

static void time_get(hconn *c, const char *label, const char *path, int reps) {
  double *v = malloc(sizeof(double) * (size_t)reps);
  for (int i = 0; i < reps; i++) {
    double t = now_ms();
    int st = hrequest(c, "GET", path, NULL);
    v[i] = now_ms() - t;
    if (st != 200) {
      fprintf(stderr, "bench_history: GET %s: %d %s\n", path, st, c->buf);
      exit(1);
    }
  }
  report(label, v, reps);
  free(v);
}

static void time_submits(hconn *c, int n) {
  const char *body = "{\"scene_file\": \"sphere_on_plane.json\", \"set\": {\"/image/width\": 16, "
                     "\"/image/height\": 16, \"/technique/backend\": \"auto\", "
                     "\"/technique/params/samples\": 4}}";
  double *v = malloc(sizeof(double) * (size_t)n);
  for (int i = 0; i < n; i++) {
    double t = now_ms();
    int st = hrequest(c, "POST", "/api/v1/jobs", body);
    v[i] = now_ms() - t;
    if (st != 201) {
      fprintf(stderr, "bench_history: POST /api/v1/jobs: %d %s\n", st, c->buf);
      exit(1);
    }
    long long id = 0;
    char *p = strstr(c->buf, "\"id\"");
    if (p) sscanf(strchr(p, ':') + 1, "%lld", &id);
    /* Untimed: the render ends before the next submission is timed, so it never competes. */
    char path[64];
    snprintf(path, sizeof path, "/api/v1/jobs/%lld", id);
    for (int k = 0; k < 20000; k++) {
      hrequest(c, "GET", path, NULL);
      if (strstr(c->buf, "\"state\": \"succeeded\"") || strstr(c->buf, "\"state\":\"succeeded\"") ||
          strstr(c->buf, "failed\"") || strstr(c->buf, "cancelled\""))
        break;
      usleep(2000);
    }
  }
  report("POST /api/v1/jobs (auto rt_ao, 16x16)", v, n);
  free(v);
}

/* ---- the daemon ------------------------------------------------------------------------------ */

static pid_t start_daemon(const char *obscurad, const char *store, const char *dir,
                          const char *scenes, int *port) {
  char log[4200], data[4200];
  snprintf(log, sizeof log, "%s/obscurad.log", dir);
  snprintf(data, sizeof data, "%s/data", dir);
  pid_t pid = fork();
  if (pid == 0) {
    int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 2);
    dup2(fd, 1);
    execl(obscurad, obscurad, "--listen", "127.0.0.1", "--port", "0", "--db", store, "--data-dir",
          data, "--scenes-dir", scenes, "--workers", "1", "--no-vulkan", "--quiet", (char *)NULL);
    _exit(127);
  }
  for (int i = 0; i < 6000; i++) {
    char *s = slurp(log);
    char *m = s ? strstr(s, "listening on http://127.0.0.1:") : NULL;
    if (m) {
      *port = atoi(m + strlen("listening on http://127.0.0.1:"));
      free(s);
      return pid;
    }
    free(s);
    if (waitpid(pid, NULL, WNOHANG) == pid) break;
    usleep(10000);
  }
  fprintf(stderr, "bench_history: obscurad did not start; see %s\n", log);
  exit(1);
}

/* Opens the store, adds jobs until it holds njobs (all of them unless reuse), and says what it
 * built and how long that took. */
static void build_store(const char *store, int64_t njobs, int reuse, const char *doc) {
  const obs_backend_ops *cpu = obs_backend_ops_get(OBS_BACKEND_CPU);
  srv_node node;
  srv_node_init(&node, "bench_history", 0);
  srv_db *db;
  obs_err e = OBS_ERR_INIT;
  if (srv_db_open(&db, store, 2, &node, &e)) die("opening the store", &e);
  int is_pg = srv_db_kind(db) == SRV_STORE_POSTGRESQL;
  /* The daemon's own machine row (its CPU, all cores on one worker, no Vulkan lane), so that the
   * render-time estimate finds its rates in the history. */
  int64_t machine;
  if (srv_db_machine(db, cpu->device_name(), obs_cpu_count(), NULL, NULL, &machine, &e))
    die("recording the machine", &e);
  int64_t counts[SRV_NSTATES];
  if (srv_db_counts(db, counts, &e)) die("counting", &e);
  int64_t have = 0;
  for (int s = 0; s < SRV_NSTATES; s++) have += counts[s];
  double t0 = now_ms();
  int64_t add = reuse && have >= njobs ? 0 : njobs - (reuse ? have : 0);
  if (!reuse && have) {
    fprintf(stderr, "bench_history: the store already holds %lld jobs (use --reuse)\n",
            (long long)have);
    exit(1);
  }
  build(db, add, doc, machine);
  double build_s = (now_ms() - t0) / 1e3;
  srv_db_checkpoint(db, &e);
  srv_db_close(db);

  printf("bench_history: %s store, %lld jobs in the history (%lld built in %.1f s, %.0f jobs/s, "
         "one insert + claim + finish each, autocommit)\n",
         is_pg ? "PostgreSQL" : "SQLite", (long long)(have + add), (long long)add, build_s,
         add ? add / build_s : 0);
  struct stat st;
  if (!is_pg && !stat(store, &st))
    printf("  file %s: %.0f MB (%.1f KB a job)\n", store, st.st_size / 1e6,
           st.st_size / 1e3 / (double)(have + add));
}

static void usage(FILE *f) {
  fprintf(f, "usage: bench_history [--jobs N] [--store PATH|postgresql://...] [--reps R] "
             "[--submits S] [--obscurad PATH] [--scenes DIR] [--reuse] [--measure-only]\n");
}

/* --jobs N: a whole number of at least 1, 64 bits wide. */
static int parse_jobs(const char *v, void *dst) {
  char *end;
  long long n = strtoll(v, &end, 10);
  if (end == v || *end || n < 1) return -1;
  *(int64_t *)dst = n;
  return 0;
}

int main(int argc, char **argv) {
  int64_t njobs = 100000;
  int reps = 200, submits = 200, reuse = 0, measure_only = 0;
  const char *store = NULL, *obscurad = "build/obscurad", *scenes = "scenes";
  const bench_opt opts[] = {
      BENCH_OPT_CUSTOM("--jobs", parse_jobs, "a whole number of at least 1", &njobs),
      BENCH_OPT_STR("--store", &store),
      BENCH_OPT_INT("--reps", 1, INT_MAX, &reps),
      BENCH_OPT_INT("--submits", 1, INT_MAX, &submits),
      BENCH_OPT_STR("--obscurad", &obscurad),
      BENCH_OPT_STR("--scenes", &scenes),
      BENCH_OPT_FLAG("--reuse", &reuse),
      BENCH_OPT_FLAG("--measure-only", &measure_only),
  };
  if (bench_parse_opts(argc, argv, opts, (int)(sizeof opts / sizeof *opts), usage)) return 2;
  if (measure_only) reuse = 1; /* measuring an existing store must not remove it */
  char dir[] = "/tmp/bench_history.XXXXXX";
  if (!mkdtemp(dir)) die("mkdtemp", NULL);
  char dbpath[4200];
  if (!store) {
    snprintf(dbpath, sizeof dbpath, "%s/history.db", dir);
    store = dbpath;
  }
  char docpath[4200];
  snprintf(docpath, sizeof docpath, "%s/sphere_on_plane.json", scenes);
  char *doc = slurp(docpath);
  if (!doc) die(docpath, NULL);

  const obs_backend_ops *cpu = obs_backend_ops_get(OBS_BACKEND_CPU);
  if (!measure_only) build_store(store, njobs, reuse, doc);
  else printf("bench_history: timing %s as it is, with %s\n", store, obscurad);
  printf("  CPU: %s (%d threads)\n", cpu->device_name(), obs_cpu_count());
  int port = 0;
  pid_t pid = start_daemon(obscurad, store, dir, scenes, &port);
  static hconn c;
  c.port = port;
  hconnect(&c);
  time_get(&c, "GET /api/v1/health", "/api/v1/health", reps);
  time_submits(&c, submits);
  time_get(&c, "GET /api/v1/health (after)", "/api/v1/health", reps);
  static const char *const lists[][2] = {
      {"jobs?limit=50", "/api/v1/jobs?limit=50"},
      {"jobs?state=succeeded", "/api/v1/jobs?limit=50&state=succeeded"},
      {"jobs?state=failed", "/api/v1/jobs?limit=50&state=failed"},
      {"jobs?state=running (none)", "/api/v1/jobs?limit=50&state=running"},
      {"jobs?technique=hbao", "/api/v1/jobs?limit=50&technique=hbao"},
      {"jobs?backend=vulkan", "/api/v1/jobs?limit=50&backend=vulkan"},
      {"jobs?state=cancelled&technique=ssao&backend=cpu",
       "/api/v1/jobs?limit=50&state=cancelled&technique=ssao&backend=cpu"},
      {"jobs?technique=ssao&backend=auto (unclaimed)",
       "/api/v1/jobs?limit=50&technique=ssao&backend=auto"},
  };
  for (size_t i = 0; i < sizeof lists / sizeof lists[0]; i++)
    time_get(&c, lists[i][0], lists[i][1], reps);
  char deep[128];
  snprintf(deep, sizeof deep, "/api/v1/jobs?limit=50&after=%lld", (long long)(njobs / 2));
  time_get(&c, "jobs?after=<middle of the history>", deep, reps);
  snprintf(deep, sizeof deep, "/api/v1/jobs?limit=50&order=asc&after=%lld", (long long)(njobs / 2));
  time_get(&c, "jobs?order=asc&after=<middle>", deep, reps);
  close(c.fd);
  kill(pid, SIGTERM);
  waitpid(pid, NULL, 0);
  free(doc);
  if (!reuse) {
    char cmd[4300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd)) fprintf(stderr, "bench_history: could not remove %s\n", dir);
  } else {
    printf("  kept %s\n", dir);
  }
  return 0;
}
