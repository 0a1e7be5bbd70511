/* Every statement of the PostgreSQL store. The read-only queries of srv_query return the same
 * columns, named alike and of the same JSON kinds, as the SQLite store's (db.c). Times shown in
 * rows are milliseconds from the database's clock; leases and back-off compare timestamptz with
 * now(), so no host's clock decides who holds a job. */
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "pg_internal.h"

/* Unix milliseconds of the database's clock. */
#define NOW_MS "(extract(epoch FROM clock_timestamp()) * 1000)::bigint"
#define FINISHED "('succeeded', 'failed', 'cancelled')"
#define CMP_JOBS "(SELECT id FROM jobs WHERE comparison = $1::bigint)"
#define JOB_ARRAYS                                                                                \
  "unnest($1::int[], $2::text[], $3::text[], $4::text[], $5::text[], $6::text[], $7::text[], "    \
  "$8::int[], $9::int[], $10::int[], $11::int[], $12::int[], $13::float8[], $14::text[], "        \
  "$15::text[], $16::text[], $17::int[], $18::bigint[], $19::text[]) WITH ORDINALITY AS "         \
  "u(priority, label, scene, doc, technique, backend_requested, lane, width, height, spp, "       \
  "repeats, warmup, work, backend_reason, scene_name, notes, ranks, stored_bytes, choice, ord)"
#define JOB_NAMES                                                                                 \
  "priority, label, scene, doc, technique, backend_requested, lane, width, height, spp, repeats, " \
  "warmup, work, backend_reason, scene_name, notes, ranks, stored_bytes, choice"
/* Per comparison: jobs still to run, candidates that can no longer get metrics, and with them. */
#define CMP_COUNTS                                                                                \
  "(SELECT count(*) FROM jobs WHERE comparison = c.id AND state IN ('queued', 'running')) "       \
  "AS active, "                                                                                   \
  "(SELECT count(*) FROM comparison_candidates x JOIN jobs j ON j.id = x.job JOIN jobs r ON "     \
  "r.id = x.reference_job WHERE x.comparison = c.id AND x.role = 'own' AND x.metrics IS NULL AND " \
  "(x.metrics_error IS NOT NULL OR j.state IN ('failed', 'cancelled') OR "                        \
  "r.state IN ('failed', 'cancelled'))) AS broken, "                                              \
  "(SELECT count(*) FROM comparison_candidates x WHERE x.comparison = c.id AND x.role = 'own' "   \
  "AND x.metrics IS NOT NULL) AS measured, "                                                      \
  "(SELECT count(*) FROM comparison_candidates x WHERE x.comparison = c.id AND x.role = 'own') "  \
  "AS candidates, "                                                                               \
  "(SELECT count(*) FROM comparison_candidates x JOIN jobs j ON j.id = x.job JOIN jobs r ON "     \
  "r.id = x.reference_job WHERE x.comparison = c.id AND x.role <> 'own' AND x.metrics IS NULL "   \
  "AND x.metrics_error IS NULL AND j.state = 'succeeded' AND r.state NOT IN ('failed', "          \
  "'cancelled')) AS measuring"
/* The retention limits: ids below keep_from are beyond the newest $1 jobs; cutoff is $2 days ago
 * (each NULL when its limit is 0). */
#define PRUNE_LIMITS                                                                              \
  "WITH lim AS (SELECT CASE WHEN $1::bigint > 0 THEN (SELECT id FROM jobs ORDER BY id DESC "     \
  "OFFSET $1::bigint - 1 LIMIT 1) END AS keep_from, CASE WHEN $2::float8 > 0 THEN " NOW_MS        \
  " - ($2::float8 * 86400000)::bigint END AS cutoff) "
#define PAST "(j.id < lim.keep_from OR j.finished_ms < lim.cutoff)"
/* The newest succeeded jobs of technique $1 (and `more`), at most 1000, from the covering index
 * jobs_succeeded (migration 2): what learned "auto" and the render-time estimate draw their runs
 * from. A window, so a submission's cost stays flat as the history grows (the SQLite store's
 * RECENT_SUCCEEDED reads the same window). */
#define RECENT_SUCCEEDED(more)                                                                    \
  "SELECT id, backend, work FROM jobs WHERE technique = $1 AND state = 'succeeded' " more         \
  " ORDER BY id DESC LIMIT 1000"
/* The timed runs of window job j (at most 20: repeats' range), looked up per job through the
 * primary key: the LIMIT keeps the planner from joining the whole runs table instead, which it
 * prefers when few runs match (another host's machine) and which grows with the history. */
#define JOB_RUNS(more)                                                                            \
  "SELECT run, total_ms, machine FROM runs WHERE runs.job = j.id " more " LIMIT 20"

static const char *const sql[PGS_LIST] = {
    /* One statement for one job or a comparison's fan-out, and one wake-up for every node. */
    [PGS_INSERT_JOBS] = "WITH i AS (INSERT INTO jobs (" JOB_NAMES ", comparison, created_ms) "
                        "SELECT " JOB_NAMES ", $20::bigint, " NOW_MS " FROM " JOB_ARRAYS
                        " ORDER BY ord RETURNING id) "
                        "SELECT i.id, pg_notify('obscura_jobs', '') FROM i",
    [PGS_GET] = "SELECT " PG_JOB_COLS " FROM jobs WHERE id = $1::bigint",
    [PGS_OUTPUTS] = "SELECT job_id, name, size, sha256, content_type FROM outputs "
                    "WHERE job_id = ANY($1::bigint[]) ORDER BY job_id, name",
    /* SKIP LOCKED: nodes claiming at once each take another row; MATERIALIZED keeps the
     * LIMIT where the rows are locked. A node that lost the job's lease 3 times is skipped. */
    [PGS_CLAIM] = "WITH c AS MATERIALIZED (SELECT id FROM jobs j WHERE state = 'queued' AND "
                  "lane = $1 AND run_after <= now() AND NOT EXISTS (SELECT 1 FROM "
                  "job_node_failures f WHERE f.job = j.id AND f.node = $2 AND f.failures >= 3) "
                  "ORDER BY priority DESC, run_after, id LIMIT 1 FOR UPDATE SKIP LOCKED) "
                  "UPDATE jobs SET state = 'running', attempts = attempts + 1, started_ms = " NOW_MS
                  ", finished_ms = NULL, progress = 0, backend = NULL, worker = $3, node = $2, "
                  "lease_expires_at = now() + make_interval(secs => $4::float8) FROM c "
                  "WHERE jobs.id = c.id RETURNING " PG_JOB_COLS ", jobs.doc",
    [PGS_SET_BACKEND] = "UPDATE jobs SET backend = $1 WHERE id = $2::bigint AND state = 'running' "
                        "AND worker = $3",
    [PGS_SUCCESS] = "UPDATE jobs SET state = 'succeeded', backend = $1, summary = $2, progress = 1, "
                    "finished_ms = " NOW_MS ", error = NULL, worker = NULL, lease_expires_at = NULL "
                    "WHERE id = $3::bigint AND worker = $4 AND attempts = $5::int AND "
                    "state = 'running' RETURNING id",
    [PGS_OUT_CLEAR] = "DELETE FROM outputs WHERE job_id = $1::bigint",
    [PGS_OUT_INSERT] = "INSERT INTO outputs (job_id, name, size, sha256, content_type) SELECT "
                       "$1::bigint, * FROM unnest($2::text[], $3::bigint[], $4::text[], $5::text[])",
    [PGS_OUT_UPSERT] = "INSERT INTO outputs (job_id, name, size, sha256, content_type) SELECT "
                       "$1::bigint, * FROM unnest($2::text[], $3::bigint[], $4::text[], $5::text[]) "
                       "ON CONFLICT (job_id, name) DO UPDATE SET size = excluded.size, "
                       "sha256 = excluded.sha256, content_type = excluded.content_type",
    [PGS_RUN_INSERT] = "INSERT INTO runs (job, run, build_ms, render_ms, post_ms, total_ms, machine) "
                       "SELECT $1::bigint, u.ord, u.b, u.r, u.p, u.t, $6::bigint FROM "
                       "unnest($2::float8[], $3::float8[], $4::float8[], $5::float8[]) WITH "
                       "ORDINALITY AS u(b, r, p, t, ord)",
    [PGS_FINISH] = "UPDATE jobs SET state = $1, error = $2, finished_ms = " NOW_MS ", progress = "
                   "$3::float8, worker = NULL, lease_expires_at = NULL WHERE id = $4::bigint AND "
                   "worker = $5 AND attempts = $6::int AND state = 'running' RETURNING id",
    /* A daemon shutting down hands the job back at once: its attempt does not count. */
    [PGS_REQUEUE] = "WITH u AS (UPDATE jobs SET state = 'queued', attempts = greatest(attempts - 1, "
                    "0), started_ms = NULL, backend = NULL, worker = NULL, lease_expires_at = NULL, "
                    "run_after = now() WHERE id = $1::bigint AND worker = $2 AND attempts = $3::int "
                    "AND state = 'running' RETURNING id) "
                    "SELECT u.id, pg_notify('obscura_jobs', '') FROM u",
    [PGS_STATE] = "SELECT state FROM jobs WHERE id = $1::bigint",
    [PGS_STATE_LOCK] = "SELECT state FROM jobs WHERE id = $1::bigint FOR UPDATE",
    [PGS_CANCEL_QUEUED] = "UPDATE jobs SET state = 'cancelled', cancel_requested = 1, "
                          "error = 'cancelled by request', finished_ms = " NOW_MS
                          " WHERE id = $1::bigint AND state = 'queued'",
    [PGS_CANCEL_RUNNING] = "UPDATE jobs SET cancel_requested = 1 WHERE id = $1::bigint AND "
                           "state = 'running'",
    [PGS_NOTIFY_CANCEL] = "SELECT pg_notify('obscura_cancel', $1::text)",
    [PGS_DELETE] = "DELETE FROM jobs WHERE id = $1::bigint AND state IN " FINISHED " AND "
                   "comparison IS NULL RETURNING id",
    [PGS_GET_OUTPUT] = "SELECT size, sha256, content_type FROM outputs WHERE job_id = $1::bigint "
                       "AND name = $2",
    [PGS_COUNTS] = "SELECT state, sum(n)::bigint FROM job_counts GROUP BY state",
    /* The same row goes back to the queue: its id, document and comparison stay, and so do the
     * nodes it is excluded from (as on SQLite): a node whose lease lapsed 3 times on this job
     * would most likely lapse again, and another node takes it. */
    [PGS_RETRY] = "WITH u AS (UPDATE jobs SET state = 'queued', error = NULL, cancel_requested = 0, "
                  "started_ms = NULL, finished_ms = NULL, progress = 0, backend = NULL, "
                  "worker = NULL, lease_expires_at = NULL, run_after = now() WHERE id = $1::bigint "
                  "AND state IN ('failed', 'cancelled') RETURNING id) "
                  "SELECT u.id, pg_notify('obscura_jobs', '') FROM u",
    [PGS_MACHINE_INSERT] =
        "WITH ins AS (INSERT INTO machines (cpu_model, cores, vulkan_device, vulkan_kind, host) "
        "VALUES ($1, $2::int, $3, $4, $5) ON CONFLICT DO NOTHING RETURNING id) "
        "SELECT id FROM ins UNION ALL SELECT id FROM machines WHERE cpu_model = $1 AND "
        "cores = $2::int AND coalesce(vulkan_device, '') = coalesce($3, '') AND "
        "coalesce(host, '') = coalesce($5, '') LIMIT 1",
    /* A row recorded before kinds were gets this device's kind (same name, same device). */
    [PGS_MACHINE_KIND] = "UPDATE machines SET vulkan_kind = $2 WHERE id = $1::bigint AND "
                         "vulkan_kind IS NULL AND $2::text IS NOT NULL",
    [PGS_CMP_INSERT] = "INSERT INTO comparisons (label, scene, width, height, repeats, request, "
                       "created_ms, notes) VALUES ($1, $2, $3::int, $4::int, $5::int, $6, " NOW_MS
                       ", $7) RETURNING id",
    [PGS_CAND_INSERT] = "INSERT INTO comparison_candidates (comparison, idx, job, reference_job, "
                        "technique, backend, params, reference_params, response, role, output) "
                        "SELECT $1::bigint, * FROM unnest($2::int[], $3::bigint[], $4::bigint[], "
                        "$5::text[], $6::text[], $7::text[], $8::text[], $9::text[], $10::text[], "
                        "$11::text[])",
    [PGS_SET_METRICS] = "UPDATE comparison_candidates SET metrics = $3, metrics_error = $4 "
                        "WHERE comparison = $1::bigint AND idx = $2::int AND metrics IS NULL AND "
                        "metrics_error IS NULL",
    /* A candidate whose jobs have succeeded but whose metrics are not stored yet is still being
     * measured: deleting it then would pull the rows from under the metrics being written. */
    [PGS_CMP_ACTIVE] = "SELECT (SELECT count(*) FROM comparisons WHERE id = $1::bigint), (SELECT "
                       "count(*) FROM jobs WHERE comparison = $1::bigint AND state IN ('queued', "
                       "'running')) + (SELECT count(*) FROM comparison_candidates cc JOIN jobs j ON "
                       "j.id = cc.job JOIN jobs r ON r.id = cc.reference_job WHERE cc.comparison = "
                       "$1::bigint AND cc.metrics IS NULL AND cc.metrics_error IS NULL AND "
                       "j.state = 'succeeded' AND r.state = 'succeeded')",
    [PGS_CMP_DELETE] = "DELETE FROM comparisons WHERE id = $1::bigint",
    [PGS_CMP_JOBS_DELETE] = "DELETE FROM jobs WHERE comparison = $1::bigint RETURNING id",
    /* Sums over the partial index of active jobs: the history is never read. */
    [PGS_QUEUED] = "SELECT coalesce(sum(coalesce(work, 0) * (repeats + warmup)), 0)::float8, "
                   "coalesce(sum(ranks), 0)::float8, coalesce(sum(stored_bytes), 0)::float8, "
                   "coalesce(sum(coalesce(work, 0) * (repeats + warmup)) FILTER (WHERE client = "
                   "$1), 0)::float8, coalesce(sum(ranks) FILTER (WHERE client = $1), 0)::float8, "
                   "coalesce(sum(stored_bytes) FILTER (WHERE client = $1), 0)::float8 "
                   "FROM jobs WHERE state IN ('queued', 'running')",
    [PGS_JOB_LOAD] = "SELECT coalesce(work, 0) * (repeats + warmup), ranks, stored_bytes, state "
                     "FROM jobs WHERE id = $1::bigint",
    [PGS_SET_CLIENT] = "UPDATE jobs SET client = $3 WHERE id = $1::bigint OR "
                       "comparison = $2::bigint",
    [PGS_RUN_RATES] = "SELECT ru.total_ms / j.work FROM (" RECENT_SUCCEEDED("AND backend = $2")
                      ") j CROSS JOIN LATERAL (" JOB_RUNS("AND runs.machine = $3::bigint") ") ru "
                      "WHERE j.work >= $4::float8 AND j.work > 0 ORDER BY j.id DESC, ru.run "
                      "LIMIT 1000",
    /* What this node's previous boot left running ($1 node name, $2 this boot's worker id). */
    [PGS_RECOVER] =
        "WITH x AS MATERIALIZED (SELECT id, attempts, max_attempts, cancel_requested, node FROM "
        "jobs WHERE state = 'running' AND node = $1 AND worker IS DISTINCT FROM $2 FOR UPDATE), "
        "f AS (INSERT INTO job_node_failures AS f (job, node, failures) SELECT id, node, 1 FROM x "
        "WHERE cancel_requested = 0 ORDER BY id ON CONFLICT (job, node) DO UPDATE SET failures = "
        "f.failures + 1), "
        "u AS (UPDATE jobs SET state = CASE WHEN x.cancel_requested <> 0 THEN 'cancelled' WHEN "
        "x.attempts >= x.max_attempts THEN 'failed' ELSE 'queued' END, error = CASE WHEN "
        "x.cancel_requested <> 0 THEN 'cancelled by request (the daemon stopped first)' WHEN "
        "x.attempts >= x.max_attempts THEN format('gave up after %s attempts: attempt %s was "
        "interrupted by a daemon crash', x.attempts, x.attempts) ELSE format('attempt %s was "
        "interrupted by a daemon crash; requeued', x.attempts) END, finished_ms = CASE WHEN "
        "x.cancel_requested = 0 AND x.attempts < x.max_attempts THEN NULL ELSE " NOW_MS " END, "
        "started_ms = CASE WHEN x.cancel_requested = 0 AND x.attempts < x.max_attempts THEN NULL "
        "ELSE jobs.started_ms END, backend = CASE WHEN x.cancel_requested = 0 AND x.attempts < "
        "x.max_attempts THEN NULL ELSE jobs.backend END, worker = NULL, lease_expires_at = NULL, "
        "run_after = now() FROM x WHERE jobs.id = x.id RETURNING jobs.id, jobs.state, jobs.error) "
        "SELECT id, state, error FROM u ORDER BY id",
    [PGS_NOTIFY_JOBS] = "SELECT pg_notify('obscura_jobs', '')",
    [PGS_HEARTBEAT] = "WITH h AS (SELECT * FROM unnest($1::bigint[], $2::int[]) AS h(id, attempt)), "
                      "u AS (UPDATE jobs SET lease_expires_at = now() + make_interval(secs => "
                      "$4::float8) FROM h WHERE jobs.id = h.id AND jobs.attempts = h.attempt AND "
                      "jobs.worker = $3 AND jobs.state = 'running' RETURNING jobs.id, "
                      "jobs.cancel_requested) SELECT id, cancel_requested FROM u",
    /* Expired leases, by the database's clock. Back-off: min(2^attempts, 60) s x 0.75..1.25. */
    [PGS_REAP] =
        "WITH x AS MATERIALIZED (SELECT id, attempts, max_attempts, cancel_requested, "
        "coalesce(node, '?') AS node FROM jobs WHERE state = 'running' AND lease_expires_at < "
        "now() ORDER BY id FOR UPDATE SKIP LOCKED), "
        "f AS (INSERT INTO job_node_failures AS f (job, node, failures) SELECT id, node, 1 FROM x "
        "ORDER BY id ON CONFLICT (job, node) DO UPDATE SET failures = f.failures + 1), "
        "u AS (UPDATE jobs SET state = CASE WHEN x.cancel_requested <> 0 THEN 'cancelled' WHEN "
        "x.attempts >= x.max_attempts THEN 'failed' ELSE 'queued' END, error = CASE WHEN "
        "x.cancel_requested <> 0 THEN format('cancelled by request (the lease of node %s expired "
        "first)', x.node) WHEN x.attempts >= x.max_attempts THEN format('lease of node %s expired "
        "%s times', x.node, x.attempts) ELSE format('the lease of node %s expired (attempt %s); "
        "requeued', x.node, x.attempts) END, finished_ms = CASE WHEN x.cancel_requested = 0 AND "
        "x.attempts < x.max_attempts THEN NULL ELSE " NOW_MS " END, started_ms = CASE WHEN "
        "x.cancel_requested = 0 AND x.attempts < x.max_attempts THEN NULL ELSE jobs.started_ms END, "
        "backend = CASE WHEN x.cancel_requested = 0 AND x.attempts < x.max_attempts THEN NULL ELSE "
        "jobs.backend END, worker = NULL, lease_expires_at = NULL, run_after = now() + "
        "make_interval(secs => least(power(2, x.attempts), 60) * (0.75 + random() * 0.5)) "
        "FROM x WHERE jobs.id = x.id RETURNING jobs.id, jobs.state) "
        "SELECT count(*) FILTER (WHERE state = 'queued'), count(*) FILTER (WHERE state <> "
        "'queued') FROM u",
    /* put_at: a blob put again is young again, so pruning keeps it for the finish to come. */
    [PGS_BLOB_PUT] = "INSERT INTO blobs (sha256, data) VALUES ($1, $2) ON CONFLICT (sha256) DO "
                     "UPDATE SET put_at = now()",
    [PGS_BLOB_GET] = "SELECT data FROM blobs WHERE sha256 = $1",
    /* Two walks, each stopping after a batch: the oldest ids below keep_from (the primary key)
     * and the earliest finished before the cutoff (jobs_finished), so that neither a first pass
     * over a long history nor a pass with nothing to do sorts the history. */
    [PGS_PRUNE_JOBS] = PRUNE_LIMITS "DELETE FROM jobs WHERE id IN (SELECT id FROM ((SELECT j.id FROM "
                       "jobs j, lim WHERE j.id < lim.keep_from AND j.state IN " FINISHED " AND "
                       "j.comparison IS NULL ORDER BY j.id LIMIT $3::int) UNION (SELECT j.id FROM "
                       "jobs j, lim WHERE j.finished_ms < lim.cutoff AND j.state IN " FINISHED
                       " AND j.comparison IS NULL ORDER BY j.finished_ms LIMIT $3::int)) x ORDER "
                       "BY id LIMIT $3::int) RETURNING id",
    /* A comparison goes whole once every job of it is finished and past the limits, and no
     * candidate waits for its metrics. */
    [PGS_PRUNE_CMPS] =
        PRUNE_LIMITS "SELECT j.comparison FROM jobs j, lim WHERE j.comparison IN (SELECT c.id FROM "
        "comparisons c WHERE c.created_ms <= greatest(lim.cutoff, (SELECT created_ms FROM jobs "
        "WHERE id = lim.keep_from))) "
        "GROUP BY j.comparison HAVING bool_and(j.state IN " FINISHED " AND coalesce(" PAST
        ", false)) AND NOT EXISTS (SELECT 1 FROM comparison_candidates cc JOIN jobs a ON "
        "a.id = cc.job JOIN jobs r ON r.id = cc.reference_job WHERE cc.comparison = j.comparison "
        "AND cc.metrics IS NULL AND cc.metrics_error IS NULL AND a.state = 'succeeded' AND "
        "r.state = 'succeeded') ORDER BY j.comparison LIMIT $3::int",
    [PGS_PRUNE_CMP_JOBS] = "WITH c AS (DELETE FROM comparisons WHERE id = ANY($1::bigint[]) "
                           "RETURNING id) DELETE FROM jobs WHERE comparison IN (SELECT id FROM c) "
                           "RETURNING id",
    [PGS_PRUNE_BLOBS] = "DELETE FROM blobs b WHERE put_at < now() - interval '1 hour' AND NOT "
                        "EXISTS (SELECT 1 FROM outputs o WHERE o.sha256 = b.sha256)",
};

static const char *const queries[SRV_NQUERIES] = {
    [SRV_Q_COMPARISON] = "SELECT c.id, c.label, c.scene, c.width, c.height, c.repeats, "
                         "c.created_ms, c.notes, (c.request::jsonb -> 'budget_ms') AS budget_ms, "
                         CMP_COUNTS " FROM comparisons c WHERE c.id = $1::bigint",
    [SRV_Q_CANDIDATES] =
        "SELECT cc.idx, cc.job, cc.reference_job, cc.technique, cc.backend, cc.params, "
        "cc.reference_params, cc.response, cc.role, cc.output, cc.metrics, cc.metrics_error, "
        "j.state, j.progress, r.state AS ref_state, r.progress AS ref_progress, r.summary AS "
        "ref_summary, r.technique AS ref_technique "
        "FROM comparison_candidates cc JOIN jobs j ON j.id = cc.job "
        "JOIN jobs r ON r.id = cc.reference_job WHERE cc.comparison = $1::bigint ORDER BY cc.idx",
    [SRV_Q_COMPARISON_RUNS] =
        "SELECT ru.job, ru.run, ru.build_ms, ru.render_ms, ru.post_ms, ru.total_ms, m.cpu_model, "
        "m.cores, m.vulkan_device, m.vulkan_kind, j.node AS host FROM runs ru LEFT JOIN machines m "
        "ON m.id = ru.machine JOIN jobs j ON j.id = ru.job WHERE ru.job IN " CMP_JOBS
        " ORDER BY ru.job, ru.run",
    [SRV_Q_COMPARISON_OUTPUTS] = "SELECT job_id AS job, name FROM outputs WHERE job_id IN " CMP_JOBS
                                 " ORDER BY job_id, name",
    [SRV_Q_COMPARISONS] = "SELECT c.id, c.label, c.scene, c.created_ms, " CMP_COUNTS
                          " FROM comparisons c WHERE ($1::bigint = 0 OR c.id < $1::bigint) "
                          "ORDER BY c.id DESC LIMIT $2::bigint",
    [SRV_Q_JOB_COMPARISON] = "SELECT comparison FROM jobs WHERE id = $1::bigint AND "
                             "comparison IS NOT NULL",
    [SRV_Q_METRICS_PENDING] =
        "SELECT cc.comparison, cc.idx, cc.job, cc.reference_job, cc.response, cc.role, cc.output "
        "FROM comparison_candidates cc JOIN jobs j ON j.id = cc.job "
        "JOIN jobs r ON r.id = cc.reference_job WHERE cc.metrics IS NULL AND "
        "cc.metrics_error IS NULL AND j.state = 'succeeded' AND r.state = 'succeeded' AND "
        "($1::bigint = 0 OR cc.job = $1::bigint OR cc.reference_job = $1::bigint) "
        "ORDER BY cc.comparison, cc.idx",
    /* The newest 5000 runs are plenty for a median and bound the work of one submission. */
    [SRV_Q_AUTO_RUNS] =
        "SELECT j.backend, ru.total_ms FROM (" RECENT_SUCCEEDED("") ") j CROSS JOIN LATERAL ("
        JOB_RUNS("") ") ru LEFT JOIN machines m ON m.id = ru.machine "
        "WHERE j.work BETWEEN $2::float8 / 2.0 AND $2::float8 * 2.0 AND j.backend IS NOT NULL AND "
        "(j.backend <> 'vulkan' OR m.vulkan_kind = $3::text) AND (m.cpu_model, m.cores) = (SELECT "
        "cpu_model, cores FROM machines WHERE id = $4::bigint) ORDER BY j.id DESC LIMIT 5000",
    [SRV_Q_BUDGET] =
        "SELECT c.id AS comparison, c.scene, cc.idx, cc.job, cc.technique, cc.backend, cc.params, "
        "cc.metrics, cc.role, cc.reference_params, cc.response, rj.technique AS "
        "reference_technique, j.width::bigint * j.height * j.spp AS pixels, (SELECT m.vulkan_kind "
        "FROM runs ru JOIN machines m ON m.id = ru.machine WHERE ru.job = cc.job LIMIT 1) AS "
        "vulkan_kind FROM comparison_candidates cc "
        "JOIN comparisons c ON c.id = cc.comparison JOIN jobs j ON j.id = cc.job "
        "JOIN jobs rj ON rj.id = cc.reference_job "
        "WHERE cc.metrics IS NOT NULL AND cc.role IN ('own', 'common') AND j.state = 'succeeded' "
        "ORDER BY c.id DESC, cc.idx LIMIT 2000",
    [SRV_Q_JOB_RUNS] = "SELECT total_ms FROM runs WHERE job = $1::bigint ORDER BY run",
    [SRV_Q_JOB_DOC] = "SELECT doc, scene, scene_name, label, priority FROM jobs "
                      "WHERE id = $1::bigint",
    [SRV_Q_JOB_MACHINE] = "SELECT m.cpu_model, m.cores, m.vulkan_device, m.vulkan_kind "
                          "FROM runs ru JOIN machines m ON m.id = ru.machine WHERE "
                          "ru.job = $1::bigint ORDER BY ru.run DESC LIMIT 1",
    [SRV_Q_JOB_CHOICE] = "SELECT choice FROM jobs WHERE id = $1::bigint",
    [SRV_Q_MACHINE] = "SELECT cpu_model, cores, vulkan_device, vulkan_kind FROM "
                      "machines WHERE id = $1::bigint",
};

/* The list statements, one per filter combination so that each plan uses its index: built once
 * from fixed fragments (no input ever becomes SQL). Parameters in order: the filters set, then
 * the key (after), then the limit. */
static char list_sql[PGS_LIST_VARIANTS][1024];
static pthread_once_t list_once = PTHREAD_ONCE_INIT;

static void build_lists(void) {
  for (int v = 0; v < PGS_LIST_VARIANTS; v++) {
    char where[400] = "";
    int k = 1;
    size_t n = 0;
    if (v & 1) n += (size_t)snprintf(where + n, sizeof where - n, "state = $%d AND ", k++);
    if (v & 2) n += (size_t)snprintf(where + n, sizeof where - n, "technique = $%d AND ", k++);
    if (v & 4)
      n += (size_t)snprintf(where + n, sizeof where - n,
                            "coalesce(backend, backend_requested) = $%d AND ", k++);
    int asc = (v & 8) != 0;
    snprintf(list_sql[v], sizeof list_sql[v],
             "SELECT " PG_JOB_COLS " FROM jobs WHERE %sid %s $%d::bigint ORDER BY id %s "
             "LIMIT $%d::int",
             where, asc ? ">" : "<", k, asc ? "ASC" : "DESC", k + 1);
  }
}

int srv_pgi_list_variant(int has_state, int has_technique, int has_backend, int ascending) {
  return (has_state ? 1 : 0) | (has_technique ? 2 : 0) | (has_backend ? 4 : 0) |
         (ascending ? 8 : 0);
}

const char *srv_pgi_sql(int which) {
  if (which < PGS_LIST) return sql[which];
  if (which < PGS_QUERY) {
    pthread_once(&list_once, build_lists);
    return list_sql[which - PGS_LIST];
  }
  return queries[which - PGS_QUERY];
}
