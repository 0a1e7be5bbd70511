/* obscurad's entry point: options, security checks on the listen address and token, directories,
 * the node's identity and the store's recovery, then the scheduler, the node loop and the HTTP
 * server until SIGINT/SIGTERM. */
#include <arpa/inet.h>
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "obscurad.h"

/* Loopback means 127.0.0.0/8, ::1 or "localhost": the only addresses allowed without a token. */
static int is_loopback(const char *host) {
  if (!strcmp(host, "localhost")) return 1;
  struct in_addr a4;
  struct in6_addr a6;
  if (inet_pton(AF_INET, host, &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
  if (inet_pton(AF_INET6, host, &a6) == 1) return IN6_IS_ADDR_LOOPBACK(&a6);
  return 0;
}

static int read_token(srv_app *app) {
  const char *path = app->cfg.token_file;
  FILE *f = fopen(path, "r");
  if (!f) {
    fprintf(stderr, "obscurad: --token-file %s: cannot open: %s\n", path, strerror(errno));
    return -1;
  }
  char buf[4097];
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  int too_long = !feof(f);
  fclose(f);
  buf[n] = '\0';
  char *s = buf;
  while (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r') s++;
  size_t len = strlen(s);
  while (len &&
         (s[len - 1] == ' ' || s[len - 1] == '\t' || s[len - 1] == '\n' || s[len - 1] == '\r'))
    s[--len] = '\0';
  if (too_long || len == 0 || strpbrk(s, " \t\r\n")) {
    fprintf(stderr,
            "obscurad: --token-file %s: must hold one token of 1 to 4096 characters "
            "without spaces\n",
            path);
    return -1;
  }
  if (len < 16) srv_log("warning: the token in %s is short (%zu characters)", path, len);
  struct stat st;
  if (!stat(path, &st) && (st.st_mode & 077))
    srv_log("warning: %s is readable by other users (chmod 600 it)", path);
  srv_sha256(s, len, app->token_digest);
  memset(buf, 0, sizeof buf);
  app->has_token = 1;
  return 0;
}

static void clean_outputs(void *user, int64_t id) { srv_outputs_remove(user, id); }

static int resolve_dir(const char *opt, const char *dir, char *out, int required) {
  struct stat st;
  if (realpath(dir, out) && !stat(out, &st) && S_ISDIR(st.st_mode)) return 0;
  out[0] = '\0';
  if (!required) {
    srv_log("warning: --%s %s is not a directory; nothing will be served from it", opt, dir);
    return 0;
  }
  fprintf(stderr, "obscurad: --%s %s: not a directory\n", opt, dir);
  return -1;
}

/* What the daemon checks and prepares before it opens anything: authentication off loopback,
 * the token and session key, and the data, database, scenes, web and vendor directories. Returns
 * 0, or the exit status after saying why on stderr. */
static int prepare(srv_app *app) {
  if (!is_loopback(app->cfg.listen) && !app->cfg.token_file) {
    fprintf(stderr,
            "obscurad: refusing to listen on %s without --token-file: only loopback "
            "addresses may run without authentication\n",
            app->cfg.listen);
    return 2;
  }
  if (app->cfg.token_file && read_token(app)) return 2;
  if (app->has_token && srv_session_init(app)) {
    fprintf(stderr, "obscurad: cannot draw the random key that signs session cookies\n");
    return 2;
  }
  if (app->cfg.results_dir)
    snprintf(app->results_dir, sizeof app->results_dir, "%s", app->cfg.results_dir);
  else
    snprintf(app->results_dir, sizeof app->results_dir, "%s/results", app->cfg.data_dir);
  const char *results_opt = app->cfg.results_dir ? "results-dir" : "data-dir";
  char dbdir[PATH_MAX];
  snprintf(dbdir, sizeof dbdir, "%s", app->cfg.db ? app->cfg.db : "");
  char *slash = strrchr(dbdir, '/');
  if (slash && slash != dbdir) *slash = '\0';
  /* A results directory that exists but cannot be written is not refused here: that is a fault
   * the render lanes report and wait out, like one that appears while running. */
  if (obs_path_make_dirs(app->cfg.data_dir, NULL) || obs_path_make_dirs(app->results_dir, NULL)) {
    int e = errno;
    fprintf(stderr, "obscurad: --%s %s: cannot create %s: %s%s\n", results_opt,
            app->cfg.results_dir ? app->cfg.results_dir : app->cfg.data_dir, app->results_dir,
            strerror(e),
            e == EROFS                  ? " (the data directory is on a read-only file system)"
            : e == EACCES || e == EPERM ? " (the data directory is not writable by this user)"
                                        : "");
    return 1;
  }
  if (slash && slash != dbdir && obs_path_make_dirs(dbdir, NULL)) {
    fprintf(stderr, "obscurad: --db %s: cannot create the database's directory %s: %s\n",
            app->cfg.db, dbdir, strerror(errno));
    return 1;
  }
  char real[PATH_MAX];
  if (resolve_dir("scenes-dir", app->cfg.scenes_dir, app->scenes_real, 1) ||
      resolve_dir("web-dir", app->cfg.web_dir, app->web_real, 0) ||
      resolve_dir("vendor-dir", app->cfg.vendor_dir, app->vendor_real, 0) ||
      resolve_dir(results_opt, app->results_dir, real, 1))
    return 2;
  snprintf(app->results_dir, sizeof app->results_dir, "%s", real);
  return 0;
}

/* One daemon per data directory: a second one's start-up recovery would requeue the running jobs
 * of the first and sweep its staging directories. The lock goes with the process (kill -9
 * included). It is the data directory's, not the results directory's: several nodes share a
 * --results-dir. */
static int lock_data_dir(srv_app *app, obs_err *err) {
  app->data_lock_fd = open(app->cfg.data_dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (app->data_lock_fd < 0)
    return obs_err_set(err, OBS_EIO, "--data-dir %s: cannot open: %s", app->cfg.data_dir,
                       strerror(errno));
  if (flock(app->data_lock_fd, LOCK_EX | LOCK_NB)) {
    int e = errno;
    close(app->data_lock_fd);
    app->data_lock_fd = -1;
    return obs_err_set(err, OBS_EIO, "--data-dir %s: %s", app->cfg.data_dir,
                       e == EWOULDBLOCK ? "another obscurad uses this data directory (stop it, or "
                                          "give this one another --data-dir)"
                                        : strerror(e));
  }
  return 0;
}

/* This daemon as a node of the store: --node-name, else "<hostname>:<port>" (the bound port, so
 * several daemons on one machine differ), stable across restarts so that a restarted node finds
 * what its previous boot left running. */
static void node_identity(const srv_app *app, srv_node *node) {
  char name[128];
  if (app->cfg.node_name) {
    snprintf(name, sizeof name, "%s", app->cfg.node_name);
  } else {
    char host[96] = "";
    if (gethostname(host, sizeof host - 1) || !host[0]) snprintf(host, sizeof host, "localhost");
    snprintf(name, sizeof name, "%s:%d", host, app->port);
  }
  srv_node_init(node, name, app->cfg.lease_seconds);
}

int main(int argc, char **argv) {
  static srv_app app;
  obs_render_keep_memory();
  int rc = srv_config_parse(&app.cfg, argc, argv);
  if (rc) {
    srv_config_free(&app.cfg);
    return rc > 0 ? 0 : 2;
  }
  app.start_ms = obs_now_ms();
  int status = 1;
  obs_err err = OBS_ERR_INIT;

  /* Signals are taken by sigwait below; every thread started later inherits the mask. */
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGINT);
  sigaddset(&sigs, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &sigs, NULL);
  signal(SIGPIPE, SIG_IGN);

  int pre = prepare(&app);
  if (pre) {
    srv_config_free(&app.cfg);
    return pre;
  }
  srv_metrics_init();
  /* Before anything that changes state: a second daemon on this port or this data directory
   * must stop here, not after its recovery requeued the first one's running jobs. */
  if (lock_data_dir(&app, &err) || srv_http_bind(&app, &err)) goto out;
  if (srv_meshimport_start(&app, &err)) goto out;
  /* No probe with --no-vulkan: loading the driver only to leave it unused costs start-up time
   * and leaves its process-lifetime allocations for LeakSanitizer to report at exit. */
  const obs_backend_ops *vk = obs_backend_ops_get(OBS_BACKEND_VULKAN);
  app.vk_available = app.cfg.vulkan && vk->available();
  app.vulkan_lane = app.vk_available;
  app.cpu_threads = obs_cpu_count() / app.cfg.workers;
  if (app.cpu_threads < 1) app.cpu_threads = 1;

  /* One connection per thread that can hold one: HTTP pool, workers, maintenance, node loop,
   * main. */
  int nconn = app.cfg.http_threads + app.cfg.workers + 4;
  srv_node node;
  node_identity(&app, &node);
  if (srv_db_open(&app.db, app.cfg.store, nconn, &node, &err)) goto out;
  app.results_via_store = srv_db_results_shared(app.db) && !app.cfg.results_dir;
  srv_log("node %s (boot %s), lease %d s; store %s (%s); outputs %s", node.name, node.boot,
          node.lease_seconds,
          srv_db_kind(app.db) == SRV_STORE_POSTGRESQL ? "PostgreSQL" : "SQLite",
          srv_db_path(app.db),
          app.results_via_store ? "travel through the store" : app.cfg.results_dir
                                                                   ? "in the shared --results-dir"
                                                                   : "in this node's data directory");
  if (srv_db_recover(app.db, srv_pick_lane_recovered, clean_outputs, &app, &err)) goto out;
  srv_mpi_kill_orphans(&app);
  srv_outputs_sweep(&app);
  /* The facts every timed run is recorded with: this CPU, the threads a render uses, and the
   * Vulkan device when a Vulkan lane runs. */
  app.vulkan_kind = app.vulkan_lane ? vk->device_kind() : NULL;
  if (srv_db_machine(app.db, obs_backend_ops_get(OBS_BACKEND_CPU)->device_name(), app.cpu_threads,
                     app.vulkan_lane ? vk->device_name() : NULL, app.vulkan_kind, &app.machine_id,
                     &err))
    goto out;
  /* Recovery of comparisons: metrics of candidates whose jobs both succeeded but which the last
   * process did not get to (it died between a job's commit and its metrics). */
  srv_compare_metrics(&app, 0);
  if (srv_sched_start(&app, &err)) goto out;
  if (srv_lease_start(&app, &err)) goto out;
  if (srv_http_start(&app, &err)) goto out;
  if (srv_retention_start(&app, &err)) goto out;

  const char *host = app.cfg.listen;
  int v6 = strchr(host, ':') != NULL;
  fprintf(stderr, "obscurad: listening on http://%s%s%s:%d\n", v6 ? "[" : "", host, v6 ? "]" : "",
          app.port);
  srv_log(
      "obscurad %s: database %s, results %s, scenes %s, web %s; %d CPU worker(s) x %d "
      "thread(s), Vulkan lane %s; token %s",
      OBSCURA_VERSION, srv_db_path(app.db), app.results_dir, app.scenes_real,
      app.web_real[0] ? app.web_real : "(none)", app.cfg.workers, app.cpu_threads,
      app.vulkan_lane   ? "on"
      : !app.cfg.vulkan ? "off (--no-vulkan)"
                        : "off (no device)",
      app.has_token ? "required" : "not required (loopback)");

  int sig = 0;
  sigwait(&sigs, &sig);
  srv_log("signal %d: stopping (running renders are cancelled and requeued)", sig);
  status = 0;

out:
  if (err.count) fprintf(stderr, "obscurad: %s\n", obs_err_message(&err));
  srv_retention_stop(&app);
  srv_http_stop(&app);
  srv_lease_stop(&app);
  srv_sched_stop(&app);
  srv_meshimport_stop(&app);
  if (app.db) {
    obs_err e2 = OBS_ERR_INIT;
    srv_db_checkpoint(app.db, &e2);
    obs_err_free(&e2);
  }
  srv_db_close(app.db);
  srv_metrics_free();
  if (app.data_lock_fd > 0) close(app.data_lock_fd);
  obs_err_free(&err);
  srv_config_free(&app.cfg);
  return status;
}
