/* Shared declarations of the job server obscurad: configuration, the application context every
 * module receives, and the interfaces between the modules (one .c file per concern). */
#ifndef OBSCURAD_H
#define OBSCURAD_H

#include <jansson.h>
#include <spawn.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "obscura/obscura.h"

#define SRV_MAX_ATTEMPTS 3
/* Timed renders per attempt (jobs.repeats) at most. */
#define SRV_MAX_REPEATS 20
/* Open MPI ranks one job may ask for (its "ranks"). */
#define SRV_MAX_RANKS 256
/* What a comparison request that omits repeats or reference.samples gets (GET /api/v1/techniques
 * shows both, so the dashboard's form starts from them). */
#define SRV_COMPARE_REPEATS 3
#define SRV_COMPARE_REF_SAMPLES 1024

/* ---- configuration (config.c) ---------------------------------------------------------------- */

/* Every option of the daemon. Strings are owned (heap) and released by srv_config_free. */
typedef struct srv_config {
  char *listen;          /* IPv4 or IPv6 literal; default 127.0.0.1 */
  int port;              /* 0 = ephemeral */
  char *db;              /* default <data-dir>/obscura.db */
  char *data_dir;        /* default var */
  char *scenes_dir;      /* default scenes */
  char *web_dir;         /* default web */
  char *vendor_dir;      /* default node_modules: only an allowlist of files is served from it */
  char *token_file;      /* NULL = no authentication (loopback only) */
  int session_seconds;   /* lifetime of a dashboard session cookie (session.c) */
  int workers;           /* CPU lane workers, default 1 */
  int vulkan;            /* 1 = run a Vulkan lane when a device exists (default), 0 = never */
  int http_threads;      /* libmicrohttpd thread pool size, default: cores (at least 2) */
  int64_t max_body;      /* bytes, default 16 MiB */
  int64_t max_pixels;    /* width x height */
  double max_work;       /* width x height x spp x samples */
  int64_t max_triangles;
  int64_t max_voxels;    /* volume samples a job's processes hold on this machine */
  int max_render_seconds;
  int worker_nice;        /* nice value of render threads (0..19), default 10 */
  int checkpoint_seconds; /* WAL checkpoint period */
  int checkpoint_jobs;    /* ... or after this many finished jobs */
  int db_check_seconds;   /* PRAGMA quick_check period */
  int quiet;              /* no per-request log lines (job lines stay) */
  /* Connection hardening (guard.c). */
  int header_timeout;          /* seconds to send a request's headers, in all; default 10 */
  int max_connections;         /* connections held at once; default 1000 */
  int max_pending_per_address; /* connections of one address still sending headers; 32 */
  int64_t max_inflight;        /* request-body bytes buffered across connections; 64 MiB */
  int body_timeout;            /* seconds a body has beyond one per min_body_rate bytes; 10 */
  int64_t min_body_rate;       /* bytes per second an upload averages at least; 64 KiB */
  /* Mesh import (meshimport.c) and queued-work limits (limits.c). */
  char *mesh_importer;        /* the worker program; NULL = obscura-import next to obscurad */
  int mesh_import_seconds;    /* per import, default 10 */
  int64_t mesh_import_memory; /* the worker's address-space limit in bytes, default 2 GiB */
  int64_t mesh_cache_bytes;   /* imported meshes kept in memory, default 256 MiB */
  double max_queued_work;       /* per client: work of its queued and running jobs */
  double max_queued_work_total; /* the same over all clients */
  int max_queued_jobs;          /* per client: queued and running jobs (MPI ranks each count) */
  int max_queued_jobs_total;    /* the same over all clients */
  int64_t max_queued_bytes;     /* per client: bytes its queued and running jobs store */
  int64_t max_queued_bytes_total;
  int max_comparison_jobs;      /* jobs (references and candidates) of one comparison */
  int output_space_retries;     /* tries of a job whose outputs alone do not fit the disk */
  int estimate_render_time;     /* refuse jobs estimated to outlast max_render_seconds */
  /* Jobs split over Open MPI ranks (mpi_jobs.c). */
  char *mpirun;      /* the mpirun executable; NULL = jobs with ranks > 1 are refused */
  char *hostfile;    /* mpirun --hostfile; NULL = none */
  char *obscura_cli; /* the CLI each rank runs; NULL = obscura next to obscurad */
} srv_config;

/* Fills defaults, reads --config FILE (if any) and then the command line, which wins. Returns 0,
 * 1 when --help was printed, or -1 after printing the problem to stderr. */
int srv_config_parse(srv_config *cfg, int argc, char **argv);
void srv_config_free(srv_config *cfg);

/* ---- logging and small helpers (util.c) ------------------------------------------------------ */

/* One line to stderr, prefixed with the UTC time; written with a single write(2) so lines from
 * different threads never interleave. */
void srv_log(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;
int64_t srv_now_unix_ms(void);
/* RFC 3339 UTC with milliseconds into buf (at least 32 bytes). */
void srv_format_time(int64_t unix_ms, char *buf, size_t n);
/* The same as a JSON string, or null for 0 (not yet). */
json_t *srv_json_time(int64_t unix_ms);
/* A stored JSON array (e.g. a job's notes) as a new array; NULL text or anything else: []. */
json_t *srv_json_array_of(const char *text);
/* Strict decimal id (1..2^63-1, no sign, no leading zero). Returns 0 on success. */
int srv_parse_id(const char *s, size_t len, int64_t *out);
/* rm -rf of a directory we created (no symlink following). Returns 0 when gone. */
int srv_remove_tree(const char *path);
/* Median of v[0..n) (sorts v in place); NaN when n is 0. */
double srv_median(double *v, size_t n);
/* Client text made safe to quote in a message (and the log): control characters, non-ASCII and
 * double quotes become '?'; truncated to n - 1 bytes. */
void srv_printable(const char *in, char *out, size_t n);

/* ---- database (db.h) ------------------------------------------------------------------------- */

#include "db.h"

/* ---- faults (faults.c) ----------------------------------------------------------------------- */

/* Environment faults. The first two pause the lanes until a probe succeeds (health "degraded");
 * the last two refuse new work (health "error"). */
typedef enum {
  SRV_FAULT_RESULTS,
  SRV_FAULT_DB,
  SRV_FAULT_DB_LOST,
  SRV_FAULT_DB_CORRUPT,
  SRV_NFAULTS
} srv_fault_kind;
const char *srv_fault_kind_name(srv_fault_kind k);
/* Records (or updates) an active fault; the first raise logs it and sets the next probe time.
 * `action` (may be NULL) replaces the kind's default advice. */
void srv_fault_raise(srv_fault_kind k, const char *path, const char *code, const char *message,
                     const char *action);
/* Whether an active fault's next probe is due. */
int srv_fault_due(srv_fault_kind k);
/* The probe failed again: doubles the back-off (at most 60 s). */
void srv_fault_probe_failed(srv_fault_kind k, const char *code, const char *message);
void srv_fault_clear(srv_fault_kind k);
int srv_fault_active(srv_fault_kind k);

/* Spawn attributes that give a child process the signal state the daemon's threads lack: nothing
 * blocked, and SIGPIPE, SIGINT and SIGTERM at their default actions (the daemon blocks the last
 * two for sigwait and ignores SIGPIPE, and a child inherits both). `flags` adds POSIX_SPAWN_*
 * flags (e.g. POSIX_SPAWN_SETPGROUP). Release with posix_spawnattr_destroy. */
void srv_spawnattr_init(posix_spawnattr_t *at, short flags);

struct srv_app;
/* When the maintenance thread last checked the database file (fault_checks.c). */
typedef struct srv_fault_clock {
  double identity_ms, check_ms;
  int lost_settled; /* the file was replaced and copied aside: nothing more to do until restart */
} srv_fault_clock;
/* Probes due faults, checks the database file's identity every 2 s and its integrity every
 * --db-check-seconds (at once after a statement met SQLITE_CORRUPT). Without the scheduler
 * lock: probes may wait for the disk. Returns 1 when a fault was cleared; sets *metrics_due when
 * a cleared results or database fault lets postponed comparison metrics run. */
int srv_faults_check(struct srv_app *app, srv_fault_clock *mc, int *metrics_due);
int srv_fault_any(void);
/* 1 with a message when work must be refused (database lost or corrupt). */
int srv_fault_refusing(char *msg, size_t n);
/* The active faults as the health route's `faults` list; *level 0 ok, 1 degraded, 2 error. */
json_t *srv_fault_json(int *level);
/* Faults cleared in the last 10 minutes (kind, what, path, message, since, cleared). */
json_t *srv_fault_recent_json(void);
void srv_fault_counts(int active[SRV_NFAULTS], unsigned long long total[SRV_NFAULTS]);
const char *srv_errno_name(int e);
/* Errors of the environment rather than of a job: disk full, read-only, permissions, I/O. */
int srv_errno_transient(int e);

/* ---- refusals for capacity (refusals.c) -------------------------------------------------------- */

/* Counts one refusal (a 429 or 503) or ended upload, by the option name of the limit that decided
 * ("max-queued-jobs-total", "max-inflight-bytes", "min-body-rate", ...). */
void srv_refused(const char *limit);
/* Health's `capacity` part: {"refusing": [server-wide limits that refused in the last minute],
 * "refused": [{limit, scope, count, last}]}; *refusing set when the first list is not empty. */
json_t *srv_refusals_json(int *refusing);
/* The counters as Prometheus text into buf (truncated at n). */
void srv_refusals_metrics(char *buf, size_t n);

/* ---- metrics (metrics.c) --------------------------------------------------------------------- */

typedef enum {
  SRV_ROUTE_JOBS,
  SRV_ROUTE_JOB,
  SRV_ROUTE_JOB_CANCEL,
  SRV_ROUTE_JOB_OUTPUT,
  SRV_ROUTE_JOB_RETRY,
  SRV_ROUTE_JOB_DOCUMENT,
  SRV_ROUTE_JOB_LOG,
  SRV_ROUTE_JOB_PREVIEW,    /* /api/v1/jobs/{id}/preview.exr (preview.c) */
  SRV_ROUTE_DIFF,           /* /api/v1/diff (diff.c) */
  SRV_ROUTE_TECHNIQUES,
  SRV_ROUTE_METRIC_TABLE, /* /api/v1/metrics: the metric table (not /metrics, Prometheus's) */
  SRV_ROUTE_SCENES,
  SRV_ROUTE_SCENE_DEFAULTS, /* /api/v1/scenes/{name}/defaults */
  SRV_ROUTE_HEALTH,
  SRV_ROUTE_METRICS,
  SRV_ROUTE_COMPARISONS,
  SRV_ROUTE_COMPARISON,
  SRV_ROUTE_SESSION,
  SRV_ROUTE_STATIC,
  SRV_ROUTE_UNKNOWN,
  SRV_NROUTES
} srv_route;

/* A growing text buffer (util.c): srv_buf_put appends printf-style; oom is set, and later puts
 * ignored, when memory runs out. The caller frees p. */
typedef struct srv_buf {
  char *p;
  size_t len, cap;
  int oom;
} srv_buf;
void srv_buf_put(srv_buf *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* The counters (counters.c). */
void srv_metrics_init(void);
void srv_metrics_free(void);
void srv_metrics_http(srv_route route, unsigned status);
void srv_metrics_render(const char *technique, const char *backend, double seconds);
/* Appends the histogram and the HTTP counters in Prometheus's text format. */
void srv_metrics_counters(srv_buf *b);
struct srv_app;
/* The Prometheus text (malloc'd). */
char *srv_metrics_text(struct srv_app *app, size_t *len);

/* ---- scheduler (jobs.c) ---------------------------------------------------------------------- */

typedef struct srv_sched srv_sched;
int srv_sched_start(struct srv_app *app, obs_err *err);
/* Wakes idle workers: a job was queued. */
void srv_sched_notify(struct srv_app *app);
/* Live progress of a running job; returns 0 when it is not running here. */
int srv_sched_progress(struct srv_app *app, int64_t id, double *progress);
/* Cancels a job: queued ones at once in the database, running ones by raising their render's
 * cancel flag (the worker then records `cancelled`). */
int srv_sched_cancel(struct srv_app *app, int64_t id, srv_cancel_result *res, obs_err *err);
int srv_sched_running(struct srv_app *app);
/* Workers holding a finished job while they wait for a fault to clear. */
int srv_sched_paused(struct srv_app *app);
/* Stops workers: running renders are cancelled and their jobs go back to the queue. */
void srv_sched_stop(struct srv_app *app);

/* ---- outputs (outputs.c) --------------------------------------------------------------------- */

/* The reference as a comparison candidate was measured against it (mapped through the candidate's
 * response), written beside the candidate's error images when the mapping changes it. */
#define SRV_MAPPED_REFERENCE_PNG "reference_mapped.png"
/* The same values as floats (its channel named as the candidate's), for the viewer's A - B. */
#define SRV_MAPPED_REFERENCE_EXR "reference_mapped.exr"

/* The fixed set of output files: content type, or NULL when `name` is not one. */
const char *srv_output_content_type(const char *name);
/* <data>/results/<id> into buf. */
void srv_results_path(const struct srv_app *app, int64_t id, char *buf, size_t n);
/* Hashes and describes every file of the fixed set present in `dir`. */
int srv_outputs_describe(const char *dir, srv_output *outs, int max, int *n, obs_err *err);
/* Removes results/<id> and any staging directory of job `id`. */
void srv_outputs_remove(const struct srv_app *app, int64_t id);
/* A line about job `id`: to the daemon's log and appended to the job's own log (joblog.c). */
void srv_job_log(const struct srv_app *app, int64_t id, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* The job's log as text (malloc'ed, "" when it has none; NULL when it cannot be read). */
char *srv_job_log_read(const struct srv_app *app, int64_t id, size_t *len);
void srv_job_log_remove(const struct srv_app *app, int64_t id);
/* Removes staging directories and result directories of jobs that are not succeeded. */
void srv_outputs_sweep(struct srv_app *app);
/* Writes, fsyncs and removes a small file in `dir`: 0 when the directory takes files, else
 * OBS_ETRANSIENT with the errno name in `code`. */
int srv_outputs_probe(const char *dir, char *code, size_t n, obs_err *err);
/* Whether a failure to write outputs (its message) is the environment's: 1 for a failing probe of
 * `dir` or an errno such as EROFS/EACCES/EIO named in the message; SRV_OUTPUTS_NO_ROOM when the
 * message says ENOSPC or EDQUOT but the probe's page fits (the disk has no room for these files
 * only); 0 when it is the job's. */
#define SRV_OUTPUTS_NO_ROOM 2
int srv_outputs_fault(const char *dir, const char *message, char *code, size_t n, obs_err *probe);
/* Bytes an unprivileged writer may still put in `dir`'s file system; -1 when unknown. */
double srv_outputs_free_bytes(const char *dir);

/* ---- HTTP (http.c, api.c, static.c) ----------------------------------------------------------- */

typedef struct srv_req srv_req;
struct MHD_Connection;
struct MHD_Response;

/* The request as the handlers see it; http.c allocates and frees it (with `path` and `body`)
 * when libmicrohttpd reports the request complete. */
struct srv_req {
  struct srv_app *app;
  struct MHD_Connection *conn;
  const char *method;
  char *path;          /* decoded URL path (owned copy) */
  char *body;          /* NUL-terminated, may contain NULs; owned */
  size_t len, cap;
  int too_big;
  int responded;
  unsigned status;
  srv_route route;
  double t0;
  char client[80]; /* who queued work is counted against: "token:<hash>" or the remote address */
};

/* ---- answers (respond.c) ---------------------------------------------------------------------- */

/* Queues `resp` (adding the security headers) and records the status. Consumes resp. */
int srv_respond(srv_req *r, unsigned status, struct MHD_Response *resp);
/* JSON body (consumes `body`). */
/* A response holding `body` as compact JSON with its Content-Type, for callers that add headers
 * of their own; consumes `body`; NULL when out of memory. */
struct MHD_Response *srv_json_response(json_t *body);
int srv_respond_json(srv_req *r, unsigned status, json_t *body);
/* A request body whose Content-Type is not the media type application/json (parameters allowed;
 * absent is refused when there is a body): answers 415 and returns 1 with the handler's result in
 * *ret; else 0. */
int srv_refuse_non_json(srv_req *r, int *ret);
/* While the database is lost or corrupt (see faults.c): answers 503 naming the fault and
 * returns 1 with the handler's result in *ret; else 0. */
int srv_refuse_when_faulted(srv_req *r, int *ret);
/* 503 for a database error (logged; consumes the messages of `err`). */
int srv_respond_unavailable(srv_req *r, obs_err *err);
/* 201 with a JSON body (consumed) and a Location header. */
int srv_respond_created(srv_req *r, json_t *body, const char *location);
/* {"error": msg, "problems": [lines of problems]}; problems may be NULL. */
int srv_respond_error(srv_req *r, unsigned status, const obs_err *problems, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* 405 with Allow. */
int srv_respond_method(srv_req *r, const char *allow);
/* 503 with Retry-After: the request was fine, the server has no room for it right now. */
int srv_respond_busy(srv_req *r, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* The HTTP layer's Content-Type check of a request with or without a body: 0 to go on, or
 * the result of the 415 it answered. */
int srv_refuse_content_type(srv_req *r, int has_body);
/* 429 with Retry-After and {"error", "problems"}. */
int srv_respond_too_busy(srv_req *r, int retry_after, const obs_err *problems);

/* Routes one complete request (api.c). */
int srv_api_dispatch(srv_req *r);
/* The route a path belongs to, for auth and metrics (api.c). */
srv_route srv_api_route(const char *path);
/* Serves a static file of --web-dir (static.c). */
int srv_static_serve(srv_req *r);
/* Dashboard sessions (session.c): a signed, expiring HttpOnly cookie that stands in for the bearer
 * token on GET and HEAD. init draws the signing key (0 or OBS_EIO); check says what the request's
 * cookie is; serve answers POST (log in) and DELETE (log out) on /api/v1/session. */
enum { SRV_SESSION_OK = 0, SRV_SESSION_NONE = -1, SRV_SESSION_INVALID = -2, SRV_SESSION_EXPIRED = -3 };
int srv_session_init(struct srv_app *app);
int srv_session_check(struct srv_app *app, struct MHD_Connection *c);
int srv_session_serve(srv_req *r);
/* Serves one output file with ETag/Range handling (outputs.c). */
int srv_output_serve(srv_req *r, int64_t id, const char *name);

/* Previews of running jobs (preview.c): begin() before a job's renders (NULL when out of
 * memory or the technique is unknown), its watch passed to obs_render (obs_render_opts.watch), finish() once the renders are
 * over (removes the file); tick() from the maintenance thread writes each preview with new tiles,
 * at most every SRV_PREVIEW_MS; serve() answers GET /api/v1/jobs/{id}/preview.exr. */
#define SRV_PREVIEW_MS 500
typedef struct srv_preview srv_preview;
srv_preview *srv_preview_begin(const struct srv_app *app, int64_t job, const char *technique);
const obs_tile_watch *srv_preview_watch(const srv_preview *p);
void srv_preview_finish(srv_preview *p);
void srv_preview_tick(void);
int srv_preview_serve(srv_req *r, int64_t id);

/* GET /api/v1/diff (diff.c): the FLIP map of one succeeded job's EXR output against another's. */
int srv_diff_serve(srv_req *r);
/* Submission: body -> validated job spec (submit.c). Owns its strings; release with
 * srv_submission_free (a zeroed struct is fine). */
typedef struct srv_submission {
  int priority;
  char *label, *scene, *doc, *technique, *backend_requested;
  char *scene_name; /* an inline scene's name (the request's scene_name), may be NULL */
  srv_lane lane;
  int width, height, spp;
  double work;
  char *backend_reason;
  json_t *choice; /* time-budget mode: what was chosen and why (owned), else NULL */
  json_t *notes;  /* strings: parameters derived from the scene's size (owned), or NULL */
  int ranks;      /* Open MPI ranks, 1..SRV_MAX_RANKS */
} srv_submission;
/* Returns 0 or the HTTP status to answer with; *message is a static summary, problems the list. */
unsigned srv_submit_parse(struct srv_app *app, const char *body, size_t len, srv_submission *s,
                          const char **message, obs_err *problems);
void srv_submission_free(srv_submission *s);
/* Bounds on a request body, checked by a pre-scan of the text before it is parsed: nesting
 * (OBS_JSON_MAX_DEPTH), JSON values and the bytes of one string. A job or comparison needs a few
 * hundred values (the largest bundled scene has 445) and short strings. */
#define SRV_MAX_REQUEST_VALUES 100000
#define SRV_MAX_REQUEST_STRING 65536
/* Pre-scans and parses a request body into *out (a JSON object). Returns 0, or 400 (empty, not
 * JSON) / 422 (a bound broken, not an object) with *message and the problems. */
unsigned srv_submit_read_body(const char *body, size_t len, const char *shape, json_t **out,
                              const char **message, obs_err *problems);
struct obs_jpath;
/* Helpers shared with comparisons (submit.c). Loads bundled scene `v` (a name) reporting under
 * /scene_file; applies `set` overrides; adds the per-job limit problems; samples per pixel sample
 * (samples, or directions x steps, else 1). */
json_t *srv_submit_load_bundled(struct srv_app *app, struct obs_jpath *p, const json_t *v);
/* The optional "set" object of a request (at most 64 entries), NULL after reporting. */
json_t *srv_submit_get_sets(struct obs_jpath *p, const json_t *req);
void srv_submit_apply_sets(struct obs_jpath *p, const json_t *sets, json_t *doc);
void srv_submit_check_limits(struct srv_app *app, const obs_scene *sc, int ranks,
                             obs_err *problems);
/* The volume samples one render of sc holds: every volume's dims multiplied and summed when the
 * technique reads volumes (OBS_NEED_VOLUME), else 0. */
double srv_scene_voxels(const obs_scene *sc);
/* Sets the technique of bundled scene `doc` (named `docname`) to request member `tech` ({"name",
 * "backend", "params"}): the params are obs_technique_defaults_for the loaded scene with the
 * request's over them, so the scene's own params stay for its technique and lengths follow the
 * scene's size for another (one note each into `notes`, may be NULL). The backend is the
 * request's (absent: auto). Problems of the scene are left to its validation. */
void srv_submit_set_technique(struct srv_app *app, json_t *doc, const char *docname,
                              const json_t *tech, json_t *notes);
/* ---- backend choice (pick.c) ------------------------------------------------------------------ */

/* The backend a job runs on in this daemon: the renderer's choice, except that "auto" falls back
 * to the CPU when the renderer would pick Vulkan but no Vulkan lane runs (--no-vulkan). An
 * explicit "vulkan" without a lane is an error naming the flag. */
int srv_pick_backend(const obs_technique *t, obs_backend requested, int vulkan_lane,
                     obs_backend *out, obs_err *err);
/* The scheduler's lane for a job left queued by the last process: 0 and *lane (which may differ
 * from the stored one when the Vulkan device came or went), or an error whose message the job
 * fails with. `user` is the srv_app. */
int srv_pick_lane_recovered(void *user, const char *technique, const char *backend_requested,
                            srv_lane stored, srv_lane *lane, obs_err *err);
/* srv_pick_backend plus learned "auto": with stored timed runs of both backends for technique `t`
 * at similar work (within 2x), the one with the lower median total; `reason` says which rule
 * decided (at most n bytes). */
int srv_pick_backend_learned(struct srv_app *app, const obs_technique *t, obs_backend requested,
                             double work, obs_backend *out, char *reason, size_t n, obs_err *err);

/* ---- comparisons (compare.c) ----------------------------------------------------------------- */

int srv_compare_post(srv_req *r);
int srv_compare_list(srv_req *r);
/* GET /api/v1/comparisons/{id} (csv = 0) or {id}.csv (csv = 1). */
int srv_compare_get(srv_req *r, int64_t id, int csv);
/* Computes the metrics of every candidate whose job and reference have both succeeded and whose
 * metrics are missing, involving job `job` (0 = all: recovery at start). */
void srv_compare_metrics(struct srv_app *app, int64_t job);
/* Compares the result in `dir` with the reference result in `rdir` on the primary output of the
 * candidate's technique (compare_output.c): fills `m` with every metric of the table that applies
 * (obs_metrics_compare_all; patch_rmse for per-patch outputs), the error image `eimg`, FLIP's map
 * `flip` (zeroed where FLIP does not apply) and, in `extra` (an object), "output" (when not
 * "ao"). `resp` maps the reference. */
int srv_compare_primary(const char *dir, const char *rdir, obs_response resp,
                        obs_metric_values *m, json_t *extra, obs_image *eimg, obs_image *flip,
                        obs_err *err);
/* Compares output `output` of the result in `dir` with the output its technique pairs it with
 * (obs_output_pair) in the reference result in `rdir`, over the reference's covered pixels:
 * every metric of the table that applies (angle_deg for vector outputs) into `metrics` (an
 * object, obs_metric_values_json) with "output" and "reference_output". */
int srv_compare_output(const char *dir, const char *rdir, const char *output, json_t *metrics,
                       obs_err *err);
/* A comparison's answer (compare_budget.c), from its candidate objects: per reference (only
 * candidates measured against one reference are ranked together) the best candidate (the fastest
 * at reference accuracy, else the fastest of the lowest RMSE, with the Pareto set's margins) and,
 * with a budget (finite and > 0), the best whose median total time fits it; docs/comparisons.md. */
json_t *srv_compare_answer(const json_t *candidates, double budget_ms);
/* The `budget_ms` query parameter of GET /api/v1/comparisons/{id}: 0 with *budget_ms NaN when
 * absent or the number; OBS_EINVAL naming it when it is not a time above 0. */
struct srv_req;
int srv_compare_budget_arg(struct srv_req *r, double *budget_ms, obs_err *err);
/* A time-budget job's stored choice with, once it ran, its median timed total ("actual_ms",
 * comparable with "expected_ms"); null for any other job. */
json_t *srv_job_choice_json(struct srv_app *app, int64_t job);
/* Time-budget mode of POST /api/v1/jobs: the most accurate measured configuration for `scene`
 * (or any scene at similar pixel count) whose median time fits `budget_ms`. Returns 0 with
 * *choice (new object: technique, backend, params, expected_ms, expected_rmse, comparison_id,
 * reason), or OBS_EINVAL with the problem under `pointer`. */
int srv_compare_budget_choice(struct srv_app *app, const char *scene, double pixels,
                              double budget_ms, json_t **choice, obs_err *problems);
/* Binds and listens on --listen/--port (the daemon's first act after its checks, so that a port
 * in use stops it before it touches the database); sets app->port. */
int srv_http_bind(struct srv_app *app, obs_err *err);
/* Serves on the bound socket (binding first if srv_http_bind was not called). */
int srv_http_start(struct srv_app *app, obs_err *err);
void srv_http_stop(struct srv_app *app);

/* ---- connection guard (guard.c) -------------------------------------------------------------- */

/* Closes connections that take longer than cfg->header_timeout to send their request headers,
 * keeps at most cfg->max_pending_per_address of them per client address and room in the pool,
 * and counts request-body bytes in flight. The connection calls come from libmicrohttpd's
 * threads; `ctx` is what srv_guard_started returned (NULL when it could not track one). */
typedef struct srv_guard srv_guard;
struct sockaddr;
int srv_guard_create(const srv_config *cfg, srv_guard **out, obs_err *err);
/* After libmicrohttpd has stopped. */
void srv_guard_free(srv_guard *g);
/* Slots kept beyond the soft limit for answering while every other connection is busy. */
int srv_guard_reserve_slots(int max_connections);
void *srv_guard_started(srv_guard *g, int fd, const struct sockaddr *addr);
/* The request headers are complete (a body follows when has_body). Returns 1 when the pool is
 * over its soft limit with no waiting connection left to close: serve only what the reserve is
 * for. */
int srv_guard_headers_done(srv_guard *g, void *ctx, int has_body);
/* The whole body has arrived. */
void srv_guard_body_done(srv_guard *g, void *ctx);
struct sockaddr;
/* One client as the guard and the queued-work caps count them: an IPv4 address (IPv4-mapped
 * IPv6 folded), or an IPv6 /64 ("2001:db8::/64"); "unknown" without an address. */
void srv_guard_client_name(const struct sockaddr *sa, char *buf, size_t n);
/* A request ended: the connection waits for the next one's headers from now. */
void srv_guard_request_done(srv_guard *g, void *ctx);
/* Must come before the descriptor is closed. */
void srv_guard_closed(srv_guard *g, void *ctx);
/* Takes `bytes` of the in-flight budget (0), or refuses (-1) when it would exceed it. */
int srv_guard_reserve(srv_guard *g, int64_t bytes);
void srv_guard_release(srv_guard *g, int64_t bytes);
/* Request-body bytes held now. */
int64_t srv_guard_inflight(srv_guard *g);
/* `n` more bytes of the connection's body arrived (its upload's pace, --min-body-rate). */
void srv_guard_body_progress(srv_guard *g, void *ctx, size_t n);

/* ---- the application ------------------------------------------------------------------------- */

typedef struct srv_app {
  srv_config cfg;
  srv_db *db;
  srv_sched *sched;
  struct MHD_Daemon *mhd;
  srv_guard *guard;
  char scenes_real[4096];  /* resolved --scenes-dir */
  char web_real[4096];     /* resolved --web-dir, "" when it does not exist */
  char vendor_real[4096];  /* resolved --vendor-dir, "" when it does not exist */
  char results_dir[4096];  /* <data-dir>/results */
  int has_token;
  unsigned char token_digest[32]; /* SHA-256 of the token: compared in constant time */
  unsigned char session_key[32];  /* random per start: signs session cookies (session.c) */
  int vk_available;        /* the renderer found a Vulkan device */
  int vulkan_lane;         /* a Vulkan lane runs */
  int cpu_threads;         /* threads per render */
  int64_t machine_id;      /* machines row of this daemon (CPU model, threads, Vulkan device) */
  const char *vulkan_kind; /* the Vulkan lane's device kind (backend.h device_kind), else NULL */
  int port;                /* the bound port */
  int listen_fd;           /* the bound socket, until libmicrohttpd takes it (listening) */
  int listening;
  int data_lock_fd;        /* flock of the results directory: one daemon per data directory */
  double start_ms;
  struct srv_meshimport *meshimport; /* the contained mesh importer (meshimport.c) */
} srv_app;

/* ---- mesh import and work limits (meshimport.c, limits.c) ------------------------------------ */

/* Starts the contained mesh importer (the worker process starts at the first import) and routes
 * every mesh import of the renderer through it; stop undoes both. */
int srv_meshimport_start(srv_app *app, obs_err *err);
void srv_meshimport_stop(srv_app *app);
/* Its counters as Prometheus text into buf (NUL-terminated, truncated at n). */
void srv_meshimport_metrics(srv_app *app, char *buf, size_t n);
/* Admission: what queued and running jobs hold, per client and in total, is capped in work
 * (work x renders; --max-queued-work[-total]), jobs (renderer processes, a job on N ranks counting
 * N; --max-queued-jobs[-total]) and stored bytes (documents and comparison rows;
 * --max-queued-bytes[-total]). Each call inserts (or requeues) tagged with `client` only when
 * what it adds fits every cap. Returns 0 with *id; 429 with every cap exceeded in `problems` and
 * *retry_after (seconds); 503 on a database error (in `problems`). The check and the change are
 * atomic with respect to other admissions. */
unsigned srv_admit_job(srv_app *app, const char *client, const srv_new_job *nj, int64_t *id,
                       int *retry_after, obs_err *problems);
unsigned srv_admit_comparison(srv_app *app, const char *client, const srv_new_comparison *c,
                              int64_t *id, int *retry_after, obs_err *problems);
/* POST /jobs/{id}/retry through the same caps: also 404 (no such job) and 409 (not failed or
 * cancelled, *state filled). */
unsigned srv_admit_retry(srv_app *app, const char *client, int64_t id, srv_state *state,
                         int *retry_after, obs_err *problems);
/* Refuses (adds a problem naming /image or /technique/params) a job whose estimated render time
 * exceeds --max-render-seconds: work x the median ms per unit of work of this machine's stored
 * runs of the technique and backend, or the technique's built-in rate. */
void srv_submit_check_estimate(srv_app *app, const obs_scene *sc, obs_err *problems);
/* The client a request's queued work counts against, into buf (filled when a request starts). */
void srv_req_client(srv_app *app, struct MHD_Connection *c, char *buf, size_t n);
/* What jobs hold in the queue: work x renders, renderer processes, stored bytes. */
typedef struct srv_load {
  double work, jobs, bytes;
} srv_load;
/* The queued and running jobs' load: of `client`, and of all (db_limits.c). */
int srv_db_queued(srv_db *db, const char *client, srv_load *mine, srv_load *total, obs_err *err);
/* What job `id` adds to the queue when it is queued again, and its state; OBS_ENOTFOUND. */
int srv_db_job_load(srv_db *db, int64_t id, srv_load *load, srv_state *state, obs_err *err);
/* Records the client of job `job`, or of every job of comparison `comparison` (db.c). */
int srv_db_set_job_client(srv_db *db, int64_t job, int64_t comparison, const char *client,
                          obs_err *err);
/* total_ms / work of this machine's newest timed runs (at most 1000) of `technique` on `backend`
 * whose job's work is at least min_work; *rates malloc'd (db.c). */
int srv_db_run_rates(srv_db *db, const char *technique, const char *backend, int64_t machine,
                     double min_work, double **rates, size_t *n, obs_err *err);

/* ---- jobs on Open MPI ranks (mpi_jobs.c, docs/mpi.md) ---------------------------------------- */

/* Submission of a job with ranks > 1 on backend `be`: adds a problem under /ranks and returns 1
 * when this daemon cannot run it (no --mpirun, not the CPU backend, a scene that reads files). */
int srv_mpi_check(srv_app *app, const obs_scene *sc, obs_backend be, int ranks,
                  obs_err *problems);
/* Renders claimed job `j` (j->ranks > 1) with `mpirun -np ranks obscura render` into `stage`
 * (created by the CLI: every output and summary.json), the scene's relative files resolved
 * against --scenes-dir. Stores rank 0's fraction done in `progress_ppm` (millionths) every
 * 200 ms. Polls `cancel` and, once raised, ends
 * mpirun's process group (SIGTERM, SIGKILL after a grace period) and returns OBS_ECANCELED.
 * Returns 0 with *summary (summary.json's text, malloc'ed), or an error whose message quotes the
 * end of mpirun's output; mpirun's output goes to the job's log either way. */
int srv_mpi_render(srv_app *app, const srv_job *j, const char *stage, atomic_int *cancel,
                   atomic_int *progress_ppm, char **summary, obs_err *err);

/* The log lines, warnings and metrics of an mpirun job's success (written before it is
 * recorded). */
void srv_mpi_succeeded(srv_app *app, const srv_job *j, const char *summary);
/* Kills what a previous daemon on the same results directory left running of its MPI jobs
 * (mpirun and ranks naming a document under its `.tmp-` staging names); at start-up. */
void srv_mpi_kill_orphans(const srv_app *app);

/* SHA-256 of a buffer (outputs.c). */
void srv_sha256(const void *data, size_t len, unsigned char out[32]);

#endif
