/* obscurad's options: defaults, the `key = value` config file and the command line (which wins). */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "obscurad.h"

typedef enum { OPT_STR, OPT_INT, OPT_I64, OPT_SIZE, OPT_REAL, OPT_BOOL } opt_type;

typedef struct opt {
  const char *name;
  opt_type type;
  size_t offset;
  double lo, hi;
  const char *help;
} opt;

#define OFF(f) offsetof(srv_config, f)
static const opt opts[] = {
    {"listen", OPT_STR, OFF(listen), 0, 0,
     "address to listen on (default 127.0.0.1); anything but loopback needs --token-file"},
    {"port", OPT_INT, OFF(port), 0, 65535, "TCP port (default 8080; 0 = pick a free one)"},
    {"db", OPT_STR, OFF(db), 0, 0, "SQLite database file (default DATA-DIR/obscura.db)"},
    {"store", OPT_STR, OFF(store), 0, 0,
     "the store: a postgresql:// URL shared by several daemons (docs/cluster.md), or a SQLite "
     "file like --db (not both)"},
    {"node-name", OPT_STR, OFF(node_name), 0, 0,
     "this daemon's name in a shared store, stable across restarts (default HOSTNAME:PORT)"},
    {"lease-seconds", OPT_INT, OFF(lease_seconds), 2, 3600,
     "a running job stays this node's for this long without a heartbeat; heartbeats every "
     "third of it (default 30)"},
    {"results-dir", OPT_STR, OFF(results_dir), 0, 0,
     "outputs go here instead of DATA-DIR/results; with a PostgreSQL store, a filesystem every "
     "node shares, so outputs are not copied into the store"},
    {"data-dir", OPT_STR, OFF(data_dir), 0, 0, "results go to DATA-DIR/results (default var)"},
    {"scenes-dir", OPT_STR, OFF(scenes_dir), 0, 0,
     "bundled scenes; scene and mesh paths resolve only inside it (default scenes)"},
    {"web-dir", OPT_STR, OFF(web_dir), 0, 0, "static files served at / (default web)"},
    {"vendor-dir", OPT_STR, OFF(vendor_dir), 0, 0,
     "npm modules directory the dashboard's /vendor/ files come from (default node_modules)"},
    {"token-file", OPT_STR, OFF(token_file), 0, 0,
     "file holding the bearer token every /api request and /metrics must carry"},
    {"session-seconds", OPT_INT, OFF(session_seconds), 1, 86400 * 30,
     "lifetime of the dashboard's session cookie from POST /api/v1/session (default 43200)"},
    {"workers", OPT_INT, OFF(workers), 1, 256,
     "CPU render workers (default 1); each render uses cores/workers threads"},
    {"vulkan", OPT_BOOL, OFF(vulkan), 0, 1,
     "run a Vulkan lane when a device exists (default true; --no-vulkan turns it off)"},
    {"http-threads", OPT_INT, OFF(http_threads), 1, 256,
     "HTTP thread pool size (default: cores, at least 2)"},
    {"max-body", OPT_SIZE, OFF(max_body), 1024, 1024.0 * 1024 * 1024,
     "request body limit in bytes, K/M/G suffixes allowed (default 16M)"},
    {"max-pixels", OPT_I64, OFF(max_pixels), 1, 268435456.0,
     "per-job limit on width x height (default 16777216)"},
    {"max-work", OPT_REAL, OFF(max_work), 1, 1e18,
     "per-job limit on width x height x spp x samples (default 1e10)"},
    {"max-triangles", OPT_I64, OFF(max_triangles), 1, 1e10,
     "per-job limit on triangles (default 4194304)"},
    {"max-voxels", OPT_I64, OFF(max_voxels), 1, 1e12,
     "per-job limit on the volume samples its renders hold on this machine, every local MPI "
     "rank counted (default 268435456)"},
    {"max-render-seconds", OPT_INT, OFF(max_render_seconds), 1, 86400 * 7,
     "a render running longer is stopped and the job fails (default 600)"},
    {"worker-nice", OPT_INT, OFF(worker_nice), 0, 19,
     "nice value of render threads, so the API stays responsive while rendering (default 10)"},
    {"checkpoint-seconds", OPT_INT, OFF(checkpoint_seconds), 1, 86400,
     "WAL checkpoint (TRUNCATE) period (default 30)"},
    {"checkpoint-jobs", OPT_INT, OFF(checkpoint_jobs), 1, 1000000,
     "... or after this many finished jobs (default 64)"},
    {"db-check-seconds", OPT_INT, OFF(db_check_seconds), 1, 86400,
     "PRAGMA quick_check period of the database (default 60)"},
    {"keep-jobs", OPT_I64, OFF(keep_jobs), 0, 1e15,
     "retention: finished jobs beyond the newest N are deleted with their outputs, a comparison "
     "only whole (default 0 = keep all)"},
    {"keep-days", OPT_REAL, OFF(keep_days), 0, 36500,
     "retention: finished jobs older than this many days are deleted likewise (default 0 = "
     "keep all)"},
    {"quiet", OPT_BOOL, OFF(quiet), 0, 1, "no per-request log lines (default false)"},
    {"header-timeout", OPT_INT, OFF(header_timeout), 1, 3600,
     "seconds a connection has, in all, to send a request's headers (default 10)"},
    {"max-connections", OPT_INT, OFF(max_connections), 16, 100000,
     "connections held at once, a reserve for health included (default 1000)"},
    {"max-pending-per-address", OPT_INT, OFF(max_pending_per_address), 1, 100000,
     "connections of one client address still sending headers; its oldest close (default 32)"},
    {"max-inflight-bytes", OPT_SIZE, OFF(max_inflight), 1024, 1024.0 * 1024 * 1024 * 1024,
     "request-body bytes buffered across all connections; more get 503 (default 64M)"},
    {"body-timeout", OPT_INT, OFF(body_timeout), 1, 3600,
     "seconds a request body has, beyond one second per --min-body-rate bytes received, from "
     "the end of its headers; a slower upload is ended (default 10)"},
    {"min-body-rate", OPT_SIZE, OFF(min_body_rate), 1, 1024.0 * 1024 * 1024,
     "bytes per second an upload must average beyond --body-timeout (default 64K)"},
    {"mesh-importer", OPT_STR, OFF(mesh_importer), 0, 0,
     "the mesh-import worker program (default: obscura-import next to obscurad)"},
    {"mesh-import-seconds", OPT_INT, OFF(mesh_import_seconds), 1, 3600,
     "time limit of one mesh import; the worker is killed after it (default 10)"},
    {"mesh-import-memory", OPT_SIZE, OFF(mesh_import_memory), 64.0 * 1024 * 1024,
     1024.0 * 1024 * 1024 * 1024, "address-space limit of the mesh-import worker (default 2G)"},
    {"mesh-cache-bytes", OPT_SIZE, OFF(mesh_cache_bytes), 0, 1024.0 * 1024 * 1024 * 1024,
     "imported meshes kept in memory, K/M/G suffixes allowed (default 256M; 0 = none)"},
    {"max-queued-work", OPT_REAL, OFF(max_queued_work), 1, 1e21,
     "per client: limit on the work of its queued and running jobs (default 5e10)"},
    {"max-queued-work-total", OPT_REAL, OFF(max_queued_work_total), 1, 1e21,
     "limit on the work of all queued and running jobs (default 2e11)"},
    {"max-queued-jobs", OPT_INT, OFF(max_queued_jobs), 1, 1e8,
     "per client: limit on its queued and running jobs, a job on N MPI ranks counting N "
     "(default 500)"},
    {"max-queued-jobs-total", OPT_INT, OFF(max_queued_jobs_total), 1, 1e8,
     "limit on all queued and running jobs, counted as for --max-queued-jobs (default 2000)"},
    {"max-queued-bytes", OPT_SIZE, OFF(max_queued_bytes), 1024, 1024.0 * 1024 * 1024 * 1024,
     "per client: limit on the bytes its queued and running jobs store (documents, comparison "
     "requests; default 64M)"},
    {"max-queued-bytes-total", OPT_SIZE, OFF(max_queued_bytes_total), 1024,
     1024.0 * 1024 * 1024 * 1024,
     "limit on the bytes all queued and running jobs store (default 256M)"},
    {"max-comparison-jobs", OPT_INT, OFF(max_comparison_jobs), 2, 4096,
     "jobs one comparison may create, references and candidates (default 128)"},
    {"output-space-retries", OPT_INT, OFF(output_space_retries), 0, 20,
     "a job whose outputs do not fit the results disk (while smaller files do) is retried this "
     "often, waiting 1, 2, 4 ... s, then fails (default 5)"},
    {"estimate-render-time", OPT_BOOL, OFF(estimate_render_time), 0, 1,
     "refuse at submission a job estimated to outlast --max-render-seconds (default true)"},
    {"mpirun", OPT_STR, OFF(mpirun), 0, 0,
     "Open MPI's mpirun: jobs with \"ranks\" > 1 run under it (default: none, such jobs are "
     "refused)"},
    {"hostfile", OPT_STR, OFF(hostfile), 0, 0,
     "passed to mpirun as --hostfile FILE (default: none, every rank on this machine)"},
    {"obscura-cli", OPT_STR, OFF(obscura_cli), 0, 0,
     "the obscura CLI that mpirun starts per rank (default: obscura next to obscurad)"},
};
#define NOPTS (sizeof opts / sizeof opts[0])

int srv_store_is_url(const char *where) {
  return !strncmp(where, "postgresql://", 13) || !strncmp(where, "postgres://", 11);
}

const char *srv_url_redacted(const char *where, char *buf, size_t n) {
  snprintf(buf, n, "%s", where);
  if (!srv_store_is_url(where)) return buf;
  /* scheme://user:password@host...: the password is what lies between the first ':' after the
   * scheme and the last '@' of the authority. */
  char *auth = strstr(buf, "://") + 3, *end = auth + strcspn(auth, "/?#");
  char *at = NULL;
  for (char *p = auth; p < end; p++)
    if (*p == '@') at = p;
  char *colon = at ? memchr(auth, ':', (size_t)(at - auth)) : NULL;
  if (!colon) return buf;
  char tail[1024];
  snprintf(tail, sizeof tail, "%s", at);
  snprintf(colon + 1, n - (size_t)(colon + 1 - buf), "***%s", tail);
  return buf;
}

static void usage(FILE *f) {
  fputs("usage: obscurad [--config FILE] [options]\n"
        "The obscura job server: an HTTP API that queues render jobs, runs them on the CPU and\n"
        "Vulkan backends, and serves their images and the dashboard. Options (also `key = value`\n"
        "lines of the config file, without the dashes; the command line wins):\n",
        f);
  for (size_t i = 0; i < NOPTS; i++)
    fprintf(f, "  --%-20s %s\n", opts[i].name, opts[i].help);
  fputs("  --config FILE          read options from FILE first\n"
        "  --help                 this text\n",
        f);
}

static char *xstrdup(const char *s) {
  char *d = strdup(s);
  if (!d) {
    fputs("obscurad: out of memory\n", stderr);
    exit(1);
  }
  return d;
}

static int parse_size(const char *v, double *out) {
  errno = 0;
  char *end;
  double d = strtod(v, &end);
  if (end == v || errno || !isfinite(d)) return -1;
  if (*end == 'k' || *end == 'K') d *= 1024, end++;
  else if (*end == 'm' || *end == 'M') d *= 1024 * 1024, end++;
  else if (*end == 'g' || *end == 'G') d *= 1024.0 * 1024 * 1024, end++;
  if (*end) return -1;
  *out = d;
  return 0;
}

/* Applies one option; `where` names its origin for messages ("--port", "file.conf:3"). */
static int apply(srv_config *cfg, const opt *o, const char *value, const char *where) {
  char *base = (char *)cfg + o->offset;
  if (o->type == OPT_STR) {
    if (!*value) {
      fprintf(stderr, "obscurad: %s: %s must not be empty\n", where, o->name);
      return -1;
    }
    char **p = (char **)base;
    free(*p);
    *p = xstrdup(value);
    return 0;
  }
  if (o->type == OPT_BOOL) {
    int b;
    if (!strcmp(value, "1") || !strcmp(value, "true") || !strcmp(value, "yes")) b = 1;
    else if (!strcmp(value, "0") || !strcmp(value, "false") || !strcmp(value, "no")) b = 0;
    else {
      fprintf(stderr, "obscurad: %s: %s must be true or false (got \"%s\")\n", where, o->name,
              value);
      return -1;
    }
    *(int *)base = b;
    return 0;
  }
  double d;
  char *end;
  errno = 0;
  if (o->type == OPT_SIZE) {
    if (parse_size(value, &d)) d = NAN;
  } else {
    d = strtod(value, &end);
    if (end == value || *end || errno) d = NAN;
  }
  int integral = o->type != OPT_REAL;
  if (!isfinite(d) || d < o->lo || d > o->hi || (integral && d != floor(d))) {
    fprintf(stderr, "obscurad: %s: %s must be %s from %.15g to %.15g (got \"%s\")\n", where,
            o->name, integral ? "an integer" : "a number", o->lo, o->hi, value);
    return -1;
  }
  if (o->type == OPT_INT) *(int *)base = (int)d;
  else if (o->type == OPT_REAL) *(double *)base = d;
  else *(int64_t *)base = (int64_t)d;
  return 0;
}

static const opt *find(const char *name) {
  for (size_t i = 0; i < NOPTS; i++)
    if (!strcmp(opts[i].name, name)) return &opts[i];
  return NULL;
}

static char *trim(char *s) {
  while (*s == ' ' || *s == '\t') s++;
  size_t n = strlen(s);
  while (n && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r' || s[n - 1] == '\n'))
    s[--n] = '\0';
  return s;
}

static int read_file(srv_config *cfg, const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) {
    fprintf(stderr, "obscurad: --config %s: cannot open: %s\n", path, strerror(errno));
    return -1;
  }
  char line[4096];
  int lineno = 0, rc = 0;
  while (fgets(line, sizeof line, f)) {
    lineno++;
    char where[4200];
    snprintf(where, sizeof where, "%s:%d", path, lineno);
    char *s = trim(line);
    if (!*s || *s == '#') continue;
    char *eq = strchr(s, '=');
    if (!eq) {
      fprintf(stderr, "obscurad: %s: expected `key = value` (got \"%s\")\n", where, s);
      rc = -1;
      continue;
    }
    *eq = '\0';
    char *key = trim(s), *val = trim(eq + 1);
    const opt *o = find(key);
    if (!o) {
      fprintf(stderr, "obscurad: %s: unknown key \"%s\"\n", where, key);
      rc = -1;
    } else if (apply(cfg, o, val, where)) {
      rc = -1;
    }
  }
  fclose(f);
  return rc;
}

int srv_config_parse(srv_config *cfg, int argc, char **argv) {
  memset(cfg, 0, sizeof *cfg);
  cfg->listen = xstrdup("127.0.0.1");
  cfg->port = 8080;
  cfg->data_dir = xstrdup("var");
  cfg->scenes_dir = xstrdup("scenes");
  cfg->web_dir = xstrdup("web");
  cfg->vendor_dir = xstrdup("node_modules");
  cfg->workers = 1;
  cfg->vulkan = 1;
  cfg->max_body = 16 * 1024 * 1024;
  cfg->max_pixels = 4096 * 4096;
  cfg->max_work = 1e10;
  cfg->max_triangles = 4194304;
  cfg->max_voxels = 268435456;
  cfg->max_render_seconds = 600;
  cfg->session_seconds = 12 * 3600;
  cfg->worker_nice = 10;
  cfg->checkpoint_seconds = 30;
  cfg->checkpoint_jobs = 64;
  cfg->header_timeout = 10;
  cfg->max_connections = 1000;
  cfg->max_pending_per_address = 32;
  cfg->max_inflight = 64 * 1024 * 1024;
  cfg->db_check_seconds = 60;
  cfg->mesh_import_seconds = 10;
  cfg->mesh_import_memory = 2LL * 1024 * 1024 * 1024;
  cfg->mesh_cache_bytes = 256LL * 1024 * 1024;
  cfg->max_queued_work = 5e10;
  cfg->max_queued_work_total = 2e11;
  cfg->max_queued_jobs = 500;
  cfg->max_queued_jobs_total = 2000;
  cfg->max_queued_bytes = 64LL * 1024 * 1024;
  cfg->max_queued_bytes_total = 256LL * 1024 * 1024;
  cfg->max_comparison_jobs = 128;
  cfg->output_space_retries = 5;
  cfg->body_timeout = 10;
  cfg->min_body_rate = 64 * 1024;
  cfg->estimate_render_time = 1;
  cfg->lease_seconds = 30;
  /* The config file first, wherever --config stands, so the command line always wins. */
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage(stdout);
      return 1;
    }
    if (!strcmp(argv[i], "--config") || !strncmp(argv[i], "--config=", 9)) {
      const char *path = argv[i][8] == '=' ? argv[i] + 9 : i + 1 < argc ? argv[++i] : NULL;
      if (!path) {
        fputs("obscurad: --config needs a file\n", stderr);
        return -1;
      }
      if (read_file(cfg, path)) return -1;
    }
  }
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--config")) {
      i++;
      continue;
    }
    if (!strncmp(a, "--config=", 9)) continue;
    if (strncmp(a, "--", 2)) {
      fprintf(stderr, "obscurad: unexpected argument \"%s\" (see --help)\n", a);
      return -1;
    }
    char name[64];
    const char *val = NULL;
    const char *eq = strchr(a + 2, '=');
    size_t n = eq ? (size_t)(eq - a - 2) : strlen(a + 2);
    if (n >= sizeof name) n = sizeof name - 1;
    memcpy(name, a + 2, n);
    name[n] = '\0';
    if (eq) val = eq + 1;
    int negated = 0;
    const opt *o = find(name);
    if (!o && !strncmp(name, "no-", 3) && (o = find(name + 3)) && o->type == OPT_BOOL) negated = 1;
    if (!o || (negated && val)) {
      fprintf(stderr, "obscurad: unknown option \"%s\" (see --help)\n", a);
      return -1;
    }
    if (o->type == OPT_BOOL && !val) {
      val = negated ? "false" : "true";
    } else if (!val) {
      if (i + 1 >= argc) {
        fprintf(stderr, "obscurad: --%s needs a value\n", o->name);
        return -1;
      }
      val = argv[++i];
    }
    char where[80];
    snprintf(where, sizeof where, "--%s", o->name);
    if (apply(cfg, o, val, where)) return -1;
  }
  if (cfg->store && cfg->db) {
    char shown[1024];
    srv_url_redacted(cfg->store, shown, sizeof shown);
    fprintf(stderr,
            "obscurad: --store %s and --db %s: give one of them (--db is the SQLite file "
            "option, --store takes a SQLite file or a postgresql:// URL)\n",
            shown, cfg->db);
    return -1;
  }
  /* A SQLite file given as --store is the --db option by another name. */
  if (cfg->store && !srv_store_is_url(cfg->store)) {
    cfg->db = cfg->store;
    cfg->store = NULL;
  }
  if (!cfg->store && !cfg->db) {
    size_t n = strlen(cfg->data_dir) + 16;
    cfg->db = malloc(n);
    if (!cfg->db) return -1;
    snprintf(cfg->db, n, "%s/obscura.db", cfg->data_dir);
  }
  if (!cfg->store) cfg->store = xstrdup(cfg->db);
  if (cfg->max_inflight < cfg->max_body + 1) {
    fprintf(stderr,
            "obscurad: --max-inflight-bytes (%lld) must exceed --max-body (%lld), or no "
            "body of the largest allowed size could ever be accepted\n",
            (long long)cfg->max_inflight, (long long)cfg->max_body);
    return -1;
  }
  if (!cfg->http_threads) {
    int c = obs_cpu_count();
    cfg->http_threads = c < 2 ? 2 : c;
  }
  return 0;
}

void srv_config_free(srv_config *cfg) {
  free(cfg->listen);
  free(cfg->db);
  free(cfg->store);
  free(cfg->node_name);
  free(cfg->results_dir);
  free(cfg->data_dir);
  free(cfg->scenes_dir);
  free(cfg->web_dir);
  free(cfg->vendor_dir);
  free(cfg->token_file);
  free(cfg->mesh_importer);
  free(cfg->mpirun);
  free(cfg->hostfile);
  free(cfg->obscura_cli);
  memset(cfg, 0, sizeof *cfg);
}
