/* The job server's store interface, the one door to persistence: job and lane states, the jobs,
 * comparisons, runs and machines rows, the named queries, recovery, and what several daemons
 * sharing one store need (node identity, leases, heartbeats, the reaper, wake-ups, results as
 * content-addressed blobs, retention). store.c dispatches every call to one of two
 * implementations with the same contract: SQLite (db.c, db_*.c; one daemon, the default) and
 * PostgreSQL (pg*.c; any number of daemons). Included by obscurad.h; SQL stays private to them. */
#ifndef SRV_DB_H
#define SRV_DB_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "obscura/obscura.h"

typedef struct srv_db srv_db;

/* Which implementation a store is. */
typedef enum { SRV_STORE_SQLITE, SRV_STORE_POSTGRESQL } srv_store_kind;

/* This daemon as a node of the store: `name` is stable across restarts (--node-name, by default
 * "<hostname>:<port>") and `boot` random per start; while a node runs a job the job's worker is
 * "<name>/<boot>", so a restarted node knows what its previous boot left and a late result from
 * an earlier boot is refused. */
typedef struct srv_node {
  char name[128];
  char boot[40];
  char worker[170];
  int lease_seconds; /* how long a claim holds without a heartbeat */
} srv_node;
/* Fills boot (random hex) and worker from name; lease_seconds 0 becomes 30. */
void srv_node_init(srv_node *n, const char *name, int lease_seconds);

typedef enum {
  SRV_QUEUED,
  SRV_RUNNING,
  SRV_SUCCEEDED,
  SRV_FAILED,
  SRV_CANCELLED,
  SRV_NSTATES
} srv_state;
const char *srv_state_name(srv_state s);
int srv_state_parse(const char *s, srv_state *out);

typedef enum { SRV_LANE_CPU, SRV_LANE_VULKAN, SRV_NLANES } srv_lane;
const char *srv_lane_name(srv_lane l);
/* The lane of a stored lane name ("cpu" or "vulkan"; anything else reads as the CPU lane). */
srv_lane srv_lane_parse(const char *name);

typedef struct srv_output {
  char name[32];
  int64_t size;
  char sha256[65];
  char content_type[40];
} srv_output;

/* A row of `jobs` with its outputs. Owns its strings; release with srv_job_free. */
typedef struct srv_job {
  int64_t id;
  srv_state state;
  int priority;
  char *label;             /* may be NULL */
  char *scene;
  char *technique;
  char *backend_requested;
  char *backend;           /* may be NULL until claimed */
  srv_lane lane;
  int width, height, spp;
  int attempts;
  int cancel_requested;
  int64_t created_ms, started_ms, finished_ms; /* 0 = not yet */
  char *error;             /* may be NULL */
  char *summary;           /* summary.json text, may be NULL */
  double progress;         /* stored at the end of an attempt; live value comes from the scheduler */
  int repeats;             /* timed renders per attempt */
  int warmup;              /* 1: one untimed render first (comparison jobs) */
  char *backend_reason;    /* why this backend, may be NULL */
  int64_t comparison;      /* the comparison it belongs to, 0 = none */
  char *scene_name;        /* an inline scene's name, may be NULL */
  char *notes;             /* JSON array of the values derived from the scene's size, may be NULL */
  int ranks;               /* Open MPI ranks (> 1: rendered by mpirun, mpi_jobs.c) */
  char *node;              /* the node that ran the last attempt, may be NULL */
  char *doc;               /* only filled by srv_db_claim */
  srv_output *outputs;
  int noutputs;
} srv_job;
void srv_job_free(srv_job *j);

/* What the submission path hands to srv_db_insert_job (borrowed). */
typedef struct srv_new_job {
  int priority;
  const char *label, *scene, *doc, *technique, *backend_requested;
  srv_lane lane;
  int width, height, spp;
  int repeats, warmup;        /* 0 repeats = 1 */
  double work;                /* width x height x spp x samples */
  const char *backend_reason; /* may be NULL */
  const char *scene_name;     /* an inline scene's name, may be NULL */
  const char *notes;          /* JSON array text of derived values, may be NULL */
  int ranks;                  /* Open MPI ranks; 0 = 1 */
  const char *choice;         /* a time-budget job's choice (JSON text), may be NULL */
} srv_new_job;

/* One timed render of a job (a row of `runs`). */
typedef struct srv_run {
  double build_ms, render_ms, post_ms, total_ms;
} srv_run;

typedef struct srv_job_filter {
  int has_state;
  srv_state state;
  const char *technique, *backend; /* NULL = any */
  int64_t after;                   /* 0 = from the start */
  int ascending;
  int limit;
} srv_job_filter;

/* Opens the store at `where` with `nconn` pooled connections and applies its migrations:
 * "postgresql://..." or "postgres://..." is a PostgreSQL URL (schema/pg.sql), anything else the
 * path of a SQLite file, created when missing (schema/db.sql). `node` is copied. */
int srv_db_open(srv_db **out, const char *where, int nconn, const srv_node *node, obs_err *err);
void srv_db_close(srv_db *db);
srv_store_kind srv_db_kind(const srv_db *db);
const srv_node *srv_db_node(const srv_db *db);
/* Returns running jobs to queued (or fails them at SRV_MAX_ATTEMPTS), and gives every queued job
 * the lane `pick` decides (storage records, the scheduler decides), failing those it refuses.
 * Calls `clean(user, id)` for every job whose half-written outputs must go. Run before any
 * worker. */
int srv_db_recover(srv_db *db,
                   int (*pick)(void *user, const char *technique, const char *backend_requested,
                               srv_lane stored, srv_lane *lane, obs_err *err),
                   void (*clean)(void *, int64_t), void *user, obs_err *err);

int srv_db_insert_job(srv_db *db, const srv_new_job *nj, int64_t *id, obs_err *err);
/* 0 and *j filled, OBS_ENOTFOUND, or another error. */
int srv_db_get_job(srv_db *db, int64_t id, srv_job *j, obs_err *err);
/* Fills up to f->limit + 1 jobs (the extra one only tells whether there is a next page). */
int srv_db_list_jobs(srv_db *db, const srv_job_filter *f, srv_job **jobs, int *n, obs_err *err);
void srv_jobs_free(srv_job *jobs, int n);
/* Claims the next queued job of `lane` whose run_after has come and that this node is not excluded
 * from (it failed the job 3 times), by priority then run_after then id: state running,
 * attempts + 1, started now, worker and node this node's, lease now + lease_seconds; in one
 * statement, so two workers of any nodes never claim the same job. Returns 0 with *j filled (doc
 * included; j->attempts is this attempt), 1 when none is ready, or <0. */
int srv_db_claim(srv_db *db, srv_lane lane, srv_job *j, obs_err *err);
/* Sets the resolved backend of a running job. */
int srv_db_set_backend(srv_db *db, int64_t id, const char *backend, obs_err *err);
/* Marks a running job succeeded with its summary and records its outputs and its timed runs (with
 * the machine that ran them, 0 = unknown), in one transaction. Like srv_db_finish and
 * srv_db_requeue, it is accepted only while this node's worker still holds attempt `attempt` of
 * the job (running, same worker, same attempts): otherwise OBS_ECONFLICT and nothing changes, so a
 * paused or partitioned node's late result is refused. */
int srv_db_finish_success(srv_db *db, int64_t id, int attempt, const char *backend,
                          const char *summary,
                          const srv_output *outs, int nouts, const srv_run *runs, int nruns,
                          int64_t machine, obs_err *err);
/* The id of the machines row with these facts, inserted when new. vulkan_device may be NULL. */
/* Where a time came from (device.c): {"backend", "name", "kind" ("cpu", "gpu", "software",
 * "other", null when unknown), "label"} for a job of `backend` timed on a machines row
 * (cpu_model, cores, vulkan_device, vulkan_kind); null without a machine. The label reads
 * "vulkan · llvmpipe (...) (software)" or "cpu · <model> (N threads)". */
json_t *srv_device_json(const char *backend, const json_t *machine);
/* This daemon's devices: {"cpu": device, "vulkan": device or null without a Vulkan lane}. */
struct srv_app;
json_t *srv_devices_json(const struct srv_app *app);

int srv_db_machine(srv_db *db, const char *cpu_model, int cores, const char *vulkan_device,
                   const char *vulkan_kind, int64_t *id, obs_err *err);

/* A comparison as submitted: its reference jobs and candidate jobs (borrowed). */
typedef struct srv_new_candidate {
  srv_new_job job;
  int reference; /* index into srv_new_comparison.references */
  const char *technique, *backend, *params, *reference_params, *response;
} srv_new_candidate;
/* A further measurement of a candidate's job (its own row, no job of its own): against the
 * common reference ("common") or another output against its declared reference ("output"). */
typedef struct srv_new_measure {
  int candidate, reference; /* indices into .candidates and .references */
  const char *role, *reference_params, *response;
  const char *output; /* a compared_outputs pair's candidate output, or NULL */
} srv_new_measure;
typedef struct srv_new_comparison {
  const char *label, *scene, *request;
  const char *notes; /* JSON array text of values derived from the scene's size, may be NULL */
  int width, height, repeats;
  const srv_new_job *references;
  int nreferences;
  const srv_new_candidate *candidates;
  int ncandidates;
  const srv_new_measure *measures; /* rows after the candidates' (indices ncandidates + k) */
  int nmeasures;
} srv_new_comparison;
/* The bytes (records.c) a new job's row stores (its texts), a candidate row's, a comparison row's. */
int64_t srv_job_stored_bytes(const srv_new_job *j);
int64_t srv_candidate_row_bytes(const srv_new_candidate *c);
int64_t srv_comparison_stored_bytes(const srv_new_comparison *c);
/* Inserts the comparison, every job, every candidate row and every further measurement's row in
 * one transaction. */
int srv_db_insert_comparison(srv_db *db, const srv_new_comparison *c, int64_t *id, obs_err *err);
/* Stores a candidate's metrics (JSON) or why they could not be computed, unless already stored,
 * and records `outs` (the error images) as outputs of `job`, in one transaction. */
int srv_db_set_metrics(srv_db *db, int64_t comparison, int idx, int64_t job, const char *metrics,
                       const char *error, const srv_output *outs, int nouts, obs_err *err);

/* Read-only queries (prepared like every statement) whose rows come back as JSON objects keyed by
 * column name: integers, reals, strings or null. See db.c for each statement. */
typedef enum {
  SRV_Q_COMPARISON,         /* ?1 comparison id */
  SRV_Q_CANDIDATES,         /* ?1 comparison id: candidates with their jobs' states */
  SRV_Q_COMPARISON_RUNS,    /* ?1 comparison id: runs of all its jobs, with machines and the
                             * host (the job's node) that timed them */
  SRV_Q_COMPARISON_OUTPUTS, /* ?1 comparison id: output names of all its jobs */
  SRV_Q_COMPARISONS,        /* ?1 after (0 = start), ?2 limit: newest first, with counts */
  SRV_Q_JOB_COMPARISON,     /* ?1 job id: the comparison it belongs to, if any */
  SRV_Q_METRICS_PENDING,    /* ?1 job id (0 = all): candidates ready for metrics */
  SRV_Q_AUTO_RUNS,          /* ?1 technique, ?2 work, ?3 this daemon's Vulkan kind, ?4 its
                             * machine: timed runs at similar work per backend on hosts of its
                             * kind (CPU model, threads), Vulkan ones on a device of that kind */
  SRV_Q_BUDGET,             /* candidates with metrics, newest comparisons first */
  SRV_Q_JOB_RUNS,           /* ?1 job id: its runs' totals */
  SRV_Q_JOB_DOC,            /* ?1 job id: its stored document, scene, label and priority */
  SRV_Q_JOB_MACHINE,        /* ?1 job id: the machine of its last timed run */
  SRV_Q_JOB_CHOICE,         /* ?1 job id: a time-budget job's stored choice (JSON text) */
  SRV_Q_MACHINE,            /* ?1 machine id: its facts */
  SRV_NQUERIES
} srv_query;
typedef struct srv_arg {
  int kind; /* SRV_ARG_* */
  int64_t i;
  double d;
  const char *s;
} srv_arg;
enum { SRV_ARG_INT, SRV_ARG_REAL, SRV_ARG_TEXT };
int srv_db_query(srv_db *db, srv_query q, const srv_arg *args, int nargs, json_t **rows,
                 obs_err *err);
/* Marks a running job failed or cancelled with `error`. */
/* Ends a running job as failed or cancelled, keeping the last progress it reached. */
int srv_db_finish(srv_db *db, int64_t id, int attempt, srv_state state, const char *error,
                  double progress, obs_err *err);
/* Returns a running job to the queue (daemon shutting down): its attempt does not count. */
int srv_db_requeue(srv_db *db, int64_t id, int attempt, obs_err *err);

/* Admission across nodes: between srv_db_admit_lock and srv_db_admit_unlock no other node admits
 * work, so the queue's caps (read with srv_db_queued) hold over every node's submissions. SQLite
 * has one daemon, whose own mutex (limits.c) already serializes: a no-op there. PostgreSQL: a
 * session advisory lock on a connection held for the section (released if the node dies). */
int srv_db_admit_lock(srv_db *db, obs_err *err);
void srv_db_admit_unlock(srv_db *db);

/* ---- several nodes on one store --------------------------------------------------------------- */

/* For each of the n jobs this node runs (ids[i] at attempt attempts[i]): extends its lease to now
 * + lease_seconds by the store's clock while this worker still holds it, and reports held[i] (0:
 * the job is no longer ours, so its render stops and its outputs are dropped) and cancel[i] (a
 * cancel was requested through any node). */
int srv_db_heartbeat(srv_db *db, const int64_t *ids, const int *attempts, int n, int *held,
                     int *cancel, obs_err *err);
/* Any node's reaper, idempotent: running jobs whose lease expired by the store's clock go back to
 * the queue after a back-off with jitter (the expired node's failure is counted against it), or
 * fail once they reached their max_attempts. SQLite leases cannot expire while the one daemon
 * lives (its start-up recovery requeues), so there it reaps nothing. */
int srv_db_reap(srv_db *db, int *requeued, int *failed, obs_err *err);
enum { SRV_WAKE_JOBS = 1, SRV_WAKE_CANCEL = 2 };
/* Waits up to timeout_ms for another node's news: 1 with *what (SRV_WAKE_*) when jobs were queued
 * or a cancel was requested, 0 on timeout, <0 when the listener was lost (the next call
 * reconnects). SQLite has no other node: it sleeps and returns 0. */
int srv_db_wait(srv_db *db, int timeout_ms, int *what, obs_err *err);
/* 1 when outputs must travel through the store (PostgreSQL without a shared results directory):
 * the node that renders puts every output as a blob and any node serves it from there. */
int srv_db_results_shared(const srv_db *db);
/* Content-addressed output bytes: put is idempotent; get fills a malloc'd copy or OBS_ENOTFOUND. */
int srv_db_put_blob(srv_db *db, const char *sha256, const void *data, size_t n, obs_err *err);
int srv_db_get_blob(srv_db *db, const char *sha256, void **data, size_t *n, obs_err *err);
/* Retention: deletes the finished jobs beyond the newest keep_jobs or finished more than keep_days
 * ago (0: no such limit), a comparison only whole (when every job of it is past a limit), and
 * returns the deleted jobs' ids (malloc'd, the caller frees) so their files go too. */
int srv_db_prune(srv_db *db, int64_t keep_jobs, double keep_days, int64_t **ids, int *nids,
                 obs_err *err);

typedef enum { SRV_CANCEL_DONE, SRV_CANCEL_RUNNING, SRV_CANCEL_FINISHED } srv_cancel_result;
/* Queued: cancelled now. Running: cancel_requested set (the scheduler stops the render). */
int srv_db_cancel(srv_db *db, int64_t id, srv_cancel_result *res, obs_err *err);
/* Deletes a finished job and its output rows and runs. OBS_ENOTFOUND, OBS_EINVAL when not
 * finished, OBS_EUNSUPPORTED when it belongs to a comparison (comparisons keep their jobs). */
int srv_db_delete(srv_db *db, int64_t id, obs_err *err);
/* A failed or cancelled job back to the queue (same id): OBS_ENOTFOUND, or OBS_EINVAL with
 * *state filled when it is not failed or cancelled. */
int srv_db_retry(srv_db *db, int64_t id, srv_state *state, obs_err *err);
/* Deletes a comparison and all its jobs in one transaction; fills ids (malloc'ed, the caller
 * frees) with the deleted jobs. OBS_ENOTFOUND, or OBS_EINVAL while any of its jobs is active. */
int srv_db_delete_comparison(srv_db *db, int64_t id, int64_t **ids, int *nids, obs_err *err);
int srv_db_get_output(srv_db *db, int64_t id, const char *name, srv_output *o, obs_err *err);
/* Job counts by state. */
int srv_db_counts(srv_db *db, int64_t counts[SRV_NSTATES], obs_err *err);
/* PRAGMA wal_checkpoint(TRUNCATE). */
int srv_db_checkpoint(srv_db *db, obs_err *err);
/* 1 with *state when job `id` exists, 0 when not, <0 on error. */
int srv_db_job_exists(srv_db *db, int64_t id, srv_state *state, obs_err *err);

/* Integrity and identity of the open database file (the maintenance thread's checks). */
typedef enum { SRV_DB_SAME, SRV_DB_DELETED, SRV_DB_REPLACED, SRV_DB_WAL_LOST } srv_db_identity;
/* Compares the file at the database's path (and its -wal) with the ones opened. */
srv_db_identity srv_db_check_identity(srv_db *db, char *detail, size_t n);
/* Writes the open (unlinked) database back: VACUUM INTO its path when nothing is there, else
 * into PATH.recovered-TIME; after writing its own path (or checkpointing a lost WAL), reopens
 * every connection on it. Returns 0 when the pool runs on the path again, 1 when the copy went
 * elsewhere (written to `where`), <0 on error. */
int srv_db_restore(srv_db *db, srv_db_identity what, char *where, size_t n, obs_err *err);
/* PRAGMA quick_check on a fresh read-only connection (no cached pages): 0 ok, 1 corrupt (the
 * report in err), <0 when it could not run. */
int srv_db_quick_check(srv_db *db, obs_err *err);
/* A trivial write transaction: 0 when the database takes writes again. */
int srv_db_probe(srv_db *db, char *code, size_t n, obs_err *err);
/* Set when a statement met SQLITE_CORRUPT or SQLITE_NOTADB; read and reset by the caller. */
int srv_db_take_corrupt_flag(srv_db *db);
/* While `msg` is set, inserting jobs or comparisons fails with it (NULL accepts work again). */
void srv_db_refuse(srv_db *db, const char *msg);
const char *srv_db_path(const srv_db *db);

#endif
