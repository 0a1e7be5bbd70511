/* Jobs split over Open MPI ranks ("ranks" > 1, docs/mpi.md): what submission refuses, and the run
 * itself. The daemon never links MPI: such a job is the CLI's `obscura render` started by
 * `mpirun -np N` in a process group of its own, writing straight into the job's staging directory,
 * which jobs.c then publishes as it does a local render's. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <dirent.h>

#include "obscura/path.h"
#include "obscurad.h"

extern char **environ;

/* How long the process group has to end after SIGTERM before SIGKILL: mpirun forwards the
 * signal to its ranks and reaps them, which takes a moment under load. */
#define MPI_GRACE_MS 5000.0
/* After SIGKILL: the kernel ends the group at once; this only bounds a wait that cannot hang. */
#define MPI_REAP_MS 5000.0
/* How much of mpirun's output a failure message quotes. */
#define MPI_TAIL_BYTES 1500

/* Whether the scene reads a mesh: the ranks would parse it themselves, outside the daemon's
 * contained importer. Volume files and environment maps are read by the renderer in a local
 * job too; the ranks resolve them against the scenes directory (--base-dir), as the daemon does. */
static int reads_mesh(const obs_scene *sc) {
  for (size_t i = 0; i < sc->nobjects; i++)
    if (sc->objects[i].shape.type == OBS_SHAPE_MESH) return 1;
  return 0;
}

int srv_mpi_check(srv_app *app, const obs_scene *sc, obs_backend be, int ranks, obs_err *problems) {
  int before = problems->count;
  if (!app->cfg.mpirun)
    obs_err_set(problems, OBS_EINVAL,
                "request: /ranks: ranks > 1 needs the daemon started with --mpirun (got %d)",
                ranks);
  else if (be != OBS_BACKEND_CPU)
    obs_err_set(problems, OBS_EINVAL,
                "request: /ranks: ranks > 1 renders on the cpu backend only (this job's backend "
                "is %s; ask for \"backend\": \"cpu\")",
                obs_backend_name(be));
  else if (reads_mesh(sc))
    obs_err_set(problems, OBS_EUNSUPPORTED,
                "request: /ranks: ranks > 1 is not supported for scenes that read a mesh file "
                "(the ranks would parse it outside the daemon's contained mesh importer)");
  /* What each rank's process holds is counted by the per-job limits (srv_submit_check_limits). */
  return problems->count > before;
}

/* The CLI each rank runs: --obscura-cli, else obscura beside this executable (the build puts
 * them together, as it does obscura-import). */
static int cli_path(const srv_app *app, char *buf, size_t n) {
  if (app->cfg.obscura_cli)
    return (size_t)snprintf(buf, n, "%s", app->cfg.obscura_cli) < n ? 0 : -1;
  char self[PATH_MAX];
  ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
  if (len <= 0) return -1;
  self[len] = '\0';
  char *slash = strrchr(self, '/');
  if (!slash) return -1;
  *slash = '\0';
  return (size_t)snprintf(buf, n, "%s/obscura", self) < n ? 0 : -1;
}

static int write_text(const char *path, const char *text, obs_err *err) {
  int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return obs_err_set(err, OBS_EIO, "%s: cannot create: %s", path, strerror(errno));
  size_t len = strlen(text), off = 0;
  while (off < len) {
    ssize_t w = write(fd, text + off, len - off);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      int e = errno;
      close(fd);
      return obs_err_set(err, OBS_EIO, "%s: cannot write: %s", path, strerror(e));
    }
    off += (size_t)w;
  }
  if (close(fd)) return obs_err_set(err, OBS_EIO, "%s: cannot write: %s", path, strerror(errno));
  return 0;
}

/* A small file's text (malloc'ed; NULL when unreadable); keeps at most its last `max` bytes. */
static char *read_tail(const char *path, size_t max) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long size = ftell(f);
  if (size < 0) size = 0;
  long from = (size_t)size > max ? size - (long)max : 0;
  fseek(f, from, SEEK_SET);
  char *buf = malloc((size_t)(size - from) + 1);
  size_t got = buf ? fread(buf, 1, (size_t)(size - from), f) : 0;
  if (buf) buf[got] = '\0';
  fclose(f);
  return buf;
}

static void nap_ms(long ms) {
  struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
  while (nanosleep(&ts, &ts) && errno == EINTR) {
  }
}

/* SIGKILL to every process of ours with a command-line argument equal to `doc`, or, with `prefix`
 * set, starting with `doc`: an MPI job's ranks name its document (under the results directory's
 * `.tmp-` staging names, which nothing else uses), so a whole-argument match finds them and not
 * a pager or editor showing the file under another path. */
static int kill_matching(const char *doc, int prefix) {
  DIR *d = opendir("/proc");
  int hit = 0;
  if (!d) return 0;
  struct dirent *e;
  uid_t me = geteuid();
  size_t dn = strlen(doc);
  while ((e = readdir(d))) {
    char *end;
    long pid = strtol(e->d_name, &end, 10);
    if (*end || pid <= 1 || pid == getpid()) continue;
    char path[64], cmd[8192];
    snprintf(path, sizeof path, "/proc/%ld/cmdline", pid);
    struct stat st;
    if (stat(path, &st) || st.st_uid != me) continue;
    FILE *f = fopen(path, "rb");
    if (!f) continue;
    size_t n = fread(cmd, 1, sizeof cmd - 1, f);
    fclose(f);
    cmd[n] = '\0';
    for (size_t a = 0; a < n; a += strlen(cmd + a) + 1)
      if (prefix ? !strncmp(cmd + a, doc, dn) : !strcmp(cmd + a, doc)) {
        kill((pid_t)pid, SIGKILL);
        hit++;
        break;
      }
  }
  closedir(d);
  return hit;
}

/* Kills the job's stragglers and waits until none is left (a process killed while it renders
 * keeps its command line until its memory is released): a job that ends has no rank left. */
static void kill_stragglers(const char *doc) {
  for (double t0 = obs_now_ms(); kill_matching(doc, 0) && obs_now_ms() - t0 < MPI_REAP_MS;)
    nap_ms(10);
}

void srv_mpi_kill_orphans(const srv_app *app) {
  /* A daemon that died (OOM, SIGKILL) leaves its mpirun and ranks running, writing into staging
   * names the start-up sweep removes and a retried attempt may reuse: they end first. */
  char prefix[4200];
  snprintf(prefix, sizeof prefix, "%s/.tmp-", app->results_dir);
  kill_matching(prefix, 1);
}

/* Where rank 0 writes the fraction done (the CLI's --progress-file) and the job's slot. */
typedef struct progress_src {
  const char *path;
  atomic_int *ppm; /* millionths */
} progress_src;

static void read_progress(const progress_src *ps) {
  int fd = open(ps->path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return; /* not written yet */
  char text[32];
  ssize_t n = pread(fd, text, sizeof text - 1, 0);
  close(fd);
  if (n <= 0) return;
  text[n] = '\0';
  char *end;
  double f = strtod(text, &end);
  if (end != text && *end == '\n' && f >= 0 && f <= 1) atomic_store(ps->ppm, (int)(f * 1e6));
}

/* Waits for `pid` to end without reaping it (so its process-group id cannot be reused while the
 * group is signalled), polling: 1 once it ended, 0 when `cancel` was raised (or, with cancel
 * NULL, when `limit_ms` passed) first. */
static int wait_child(pid_t pid, atomic_int *cancel, double limit_ms, const progress_src *ps) {
  double t0 = obs_now_ms();
  for (int polls = 0;; polls++) {
    siginfo_t info;
    memset(&info, 0, sizeof info);
    int r = waitid(P_PID, (id_t)pid, &info, WEXITED | WNOHANG | WNOWAIT);
    if ((r == 0 && info.si_pid == pid) || (r < 0 && errno == ECHILD)) return 1;
    if (cancel && atomic_load(cancel)) return 0;
    if (!cancel && obs_now_ms() - t0 > limit_ms) return 0;
    if (ps && polls % 10 == 0) read_progress(ps);
    nap_ms(20);
  }
}

/* mpirun ended (or must): whatever is left of its process group is killed, and it is reaped.
 * Returns its wait status (-1 when it could not be reaped). */
static int reap(pid_t pid, const char *doc) {
  kill(-pid, SIGKILL);
  int status = -1;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  kill_stragglers(doc);
  return status;
}

/* Ends the process group: SIGTERM (mpirun forwards it to the ranks), SIGKILL after the grace
 * period; reaped either way. */
static void stop_group(pid_t pid, const char *doc) {
  kill(-pid, SIGTERM);
  if (!wait_child(pid, NULL, MPI_GRACE_MS, NULL)) {
    kill(-pid, SIGKILL);
    if (!wait_child(pid, NULL, MPI_REAP_MS, NULL)) {
      srv_log("mpirun (pid %d) did not end after SIGKILL; not waiting for it", (int)pid);
      kill_stragglers(doc);
      return;
    }
  }
  reap(pid, doc);
}

/* Starts `mpirun ... -np N <cli> render <doc> -o <stage> --threads T` in a process group of its
 * own (so a cancel reaches every rank it started), stdout and stderr into `logp`. */
static int spawn_mpirun(srv_app *app, int ranks, const char *cli, const char *doc,
                        const char *stage, const char *logp, const char *progress, pid_t *pid,
                        obs_err *err) {
  char np[16], threads[16];
  snprintf(np, sizeof np, "%d", ranks);
  /* The job's share of the cores (what a local render gets) spread over its ranks. */
  int t = app->cpu_threads / ranks;
  snprintf(threads, sizeof threads, "%d", t < 1 ? 1 : t);
  char *argv[24];
  int n = 0;
  argv[n++] = app->cfg.mpirun;
  if (app->cfg.hostfile) {
    argv[n++] = "--hostfile";
    argv[n++] = app->cfg.hostfile;
  }
  /* More ranks than slots is the user's choice here, not an error. */
  argv[n++] = "--oversubscribe";
  if (geteuid() == 0) argv[n++] = "--allow-run-as-root"; /* Open MPI refuses root without it */
  argv[n++] = "-np";
  argv[n++] = np;
  argv[n++] = (char *)cli;
  argv[n++] = "render";
  argv[n++] = (char *)doc;
  argv[n++] = "-o";
  argv[n++] = (char *)stage;
  argv[n++] = "--threads";
  argv[n++] = threads;
  argv[n++] = "--base-dir";
  argv[n++] = app->scenes_real;
  argv[n++] = "--progress-file";
  argv[n++] = (char *)progress;
  /* The lane chose the CPU; pinned so no rank's "auto" can pick a GPU it finds. */
  argv[n++] = "--backend";
  argv[n++] = "cpu";
  argv[n] = NULL;
  posix_spawn_file_actions_t fa;
  posix_spawnattr_t at;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, logp, O_WRONLY | O_CREAT | O_APPEND, 0600);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  /* mpirun gets the default signal state back, or it could not be stopped; its own process group
   * lets a stop reach its ranks. */
  srv_spawnattr_init(&at, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&at, 0);
  /* posix_spawnp: a bare "--mpirun mpirun" is looked up in PATH. */
  int rc = posix_spawnp(pid, app->cfg.mpirun, &fa, &at, argv, environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&at);
  if (rc)
    return obs_err_set(err, OBS_EIO, "cannot start --mpirun %s: %s", app->cfg.mpirun, strerror(rc));
  return 0;
}

/* mpirun's output into the job's log (its last lines: a sanitizer report can be long), and its
 * last MPI_TAIL_BYTES into `tail` for a failure message. */
static void log_output(srv_app *app, int64_t id, const char *logp, char *tail, size_t n) {
  char *text = read_tail(logp, 8192);
  tail[0] = '\0';
  if (!text) return;
  size_t len = strlen(text);
  while (len && (text[len - 1] == '\n' || text[len - 1] == '\r')) text[--len] = '\0';
  const char *from = len > MPI_TAIL_BYTES ? text + len - MPI_TAIL_BYTES : text;
  srv_printable(from, tail, n);
  for (char *line = text, *next; line && *line; line = next) {
    next = strchr(line, '\n');
    if (next) *next++ = '\0';
    char safe[512];
    srv_printable(line, safe, sizeof safe);
    if (*safe) srv_job_log(app, id, "mpirun: %s", safe);
  }
  free(text);
}

int srv_mpi_render(srv_app *app, const srv_job *j, const char *stage, atomic_int *cancel,
                   atomic_int *progress_ppm, char **summary, obs_err *err) {
  *summary = NULL;
  char cli[PATH_MAX], work[4400], doc[4600], logp[4600], prog[4600];
  /* Accepted by a daemon with --mpirun, left queued, and this start has none. */
  if (!app->cfg.mpirun)
    return obs_err_set(err, OBS_EUNSUPPORTED, "ranks %d needs the daemon started with --mpirun",
                       j->ranks);
  if (cli_path(app, cli, sizeof cli) || access(cli, X_OK))
    return obs_err_set(err, OBS_EIO,
                       "cannot run the obscura CLI %s for mpirun (pass "
                       "--obscura-cli)",
                       cli_path(app, cli, sizeof cli) ? "beside obscurad" : cli);
  /* The document and mpirun's output live beside the staging directory (same `.tmp-<id>-`
   * prefix: the start-up sweep and a job's deletion remove it with the rest). */
  snprintf(work, sizeof work, "%s-mpi", stage);
  srv_remove_tree(work);
  srv_remove_tree(stage);
  if (mkdir(work, 0700))
    return obs_err_set(err, OBS_EIO, "%s: cannot create: %s", work, strerror(errno));
  /* Named as the job's scene, so summary.json names the same scene as a local render's. */
  const char *base = j->scene && strrchr(j->scene, '/') ? strrchr(j->scene, '/') + 1 : j->scene;
  if (!base || !*base || !strcmp(base, ".") || !strcmp(base, "..")) base = "scene.json";
  snprintf(doc, sizeof doc, "%s/%s", work, base);
  snprintf(logp, sizeof logp, "%s/mpirun.log", work);
  snprintf(prog, sizeof prog, "%s/progress", work);
  pid_t pid = 0;
  int rc = write_text(doc, j->doc ? j->doc : "", err);
  if (!rc) rc = spawn_mpirun(app, j->ranks, cli, doc, stage, logp, prog, &pid, err);
  if (rc) {
    srv_remove_tree(work);
    return rc;
  }
  srv_job_log(app, j->id, "mpirun started (pid %d): %d ranks of %s", (int)pid, j->ranks, cli);
  int status = -1;
  progress_src ps = {prog, progress_ppm};
  if (wait_child(pid, cancel, 0, &ps)) {
    status = reap(pid, doc);
  } else {
    stop_group(pid, doc);
    rc = obs_err_set(err, OBS_ECANCELED, "mpirun stopped");
  }
  char tail[MPI_TAIL_BYTES + 1];
  log_output(app, j->id, logp, tail, sizeof tail);
  if (!rc && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    char why[64];
    if (status != -1 && WIFSIGNALED(status))
      snprintf(why, sizeof why, "was killed by signal %d", WTERMSIG(status));
    else
      snprintf(why, sizeof why, "exited with status %d", status == -1 ? -1 : WEXITSTATUS(status));
    rc = obs_err_set(err, OBS_EIO, "mpirun -np %d %s: %s", j->ranks, why,
                     *tail ? tail : "(no output)");
  }
  if (!rc) {
    char sum[4600];
    snprintf(sum, sizeof sum, "%s/summary.json", stage);
    *summary = read_tail(sum, 64u << 20);
    if (!*summary)
      rc = obs_err_set(err, OBS_EIO, "mpirun -np %d succeeded but wrote no %s", j->ranks, sum);
  }
  srv_remove_tree(work);
  return rc;
}

void srv_mpi_succeeded(srv_app *app, const srv_job *j, const char *summary) {
  json_t *sum = json_loads(summary, 0, NULL);
  json_t *warn = json_object_get(sum, "warnings");
  size_t k;
  json_t *w;
  json_array_foreach(warn, k, w) {
    char safe[1024];
    srv_printable(json_is_string(w) ? json_string_value(w) : "?", safe, sizeof safe);
    srv_job_log(app, j->id, "warning: %s", safe);
  }
  double total = json_number_value(json_object_get(json_object_get(sum, "timings_ms"), "total"));
  srv_metrics_render(j->technique, "cpu", total / 1e3);
  srv_job_log(app, j->id, "running -> succeeded (%s/cpu %dx%d on %d Open MPI ranks, %.1f ms)",
              j->technique, j->width, j->height, j->ranks, total);
  json_decref(sum);
}
