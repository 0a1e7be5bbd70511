-- obscurad's SQLite schema as numbered migrations, embedded into the daemon at build time and
-- applied in order at start (server/db.c). Never edit a migration that has shipped: append a new
-- "-- migration N" section instead. Each section runs in one transaction with its version recorded
-- in schema_migrations.

-- migration 1
CREATE TABLE jobs (
  id INTEGER PRIMARY KEY AUTOINCREMENT,      -- AUTOINCREMENT: ids are never reused after DELETE
  state TEXT NOT NULL DEFAULT 'queued'
    CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  priority INTEGER NOT NULL DEFAULT 50 CHECK (priority BETWEEN 0 AND 100),
  label TEXT,
  scene TEXT NOT NULL,                       -- bundled file name, or 'inline'
  doc TEXT NOT NULL,                         -- the validated scene document as it will render
  technique TEXT NOT NULL,
  backend_requested TEXT NOT NULL CHECK (backend_requested IN ('auto', 'cpu', 'vulkan')),
  lane TEXT NOT NULL CHECK (lane IN ('cpu', 'vulkan')),
  backend TEXT CHECK (backend IN ('cpu', 'vulkan')),  -- the one that ran, set at claim
  width INTEGER NOT NULL,
  height INTEGER NOT NULL,
  spp INTEGER NOT NULL,
  attempts INTEGER NOT NULL DEFAULT 0,       -- times a worker started the job
  cancel_requested INTEGER NOT NULL DEFAULT 0,
  created_ms INTEGER NOT NULL,               -- Unix time in milliseconds
  started_ms INTEGER,
  finished_ms INTEGER,
  error TEXT,
  summary TEXT                               -- summary.json of the successful attempt
);
-- The claim query walks this index: queued jobs of a lane, highest priority first, then FIFO.
CREATE INDEX jobs_claim ON jobs (lane, state, priority DESC, id);
CREATE INDEX jobs_state ON jobs (state, id);

CREATE TABLE outputs (
  job_id INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  name TEXT NOT NULL,
  size INTEGER NOT NULL,
  sha256 TEXT NOT NULL,
  content_type TEXT NOT NULL,
  PRIMARY KEY (job_id, name)
) WITHOUT ROWID;

-- migration 2
-- The progress a job had reached when it ended, so a cancelled or failed job still shows how far
-- it got (running jobs report live progress from the scheduler instead).
ALTER TABLE jobs ADD COLUMN progress REAL NOT NULL DEFAULT 0;

-- migration 3
-- Speed/accuracy comparisons (docs/comparisons.md): timed runs of every job with the machine that
-- ran them, comparisons and their candidates, and what learned "auto" and time budgets read.
CREATE TABLE machines (
  id INTEGER PRIMARY KEY,
  cpu_model TEXT NOT NULL,                   -- "model name" of /proc/cpuinfo
  cores INTEGER NOT NULL,                    -- threads a render used
  vulkan_device TEXT                         -- NULL: no Vulkan lane
);
-- coalesce: UNIQUE treats NULLs as distinct, and a machine without Vulkan must be one row.
CREATE UNIQUE INDEX machines_facts ON machines (cpu_model, cores, coalesce(vulkan_device, ''));

-- repeats: timed renders per attempt; warmup: one untimed render first (comparison jobs);
-- work: width x height x spp x samples, what learned "auto" compares; backend_reason: why the
-- backend was chosen (shown as backend.reason).
ALTER TABLE jobs ADD COLUMN repeats INTEGER NOT NULL DEFAULT 1 CHECK (repeats BETWEEN 1 AND 20);
ALTER TABLE jobs ADD COLUMN warmup INTEGER NOT NULL DEFAULT 0 CHECK (warmup IN (0, 1));
ALTER TABLE jobs ADD COLUMN work REAL;
ALTER TABLE jobs ADD COLUMN backend_reason TEXT;
CREATE INDEX jobs_work ON jobs (technique, work);

-- One row per timed render of a succeeded attempt (written in the transaction that marks the job
-- succeeded). total = build + render + post = the renderer's wall time for the render.
CREATE TABLE runs (
  job INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  run INTEGER NOT NULL,                      -- 1 .. repeats
  build_ms REAL NOT NULL,
  render_ms REAL NOT NULL,
  post_ms REAL NOT NULL,
  total_ms REAL NOT NULL,
  machine INTEGER REFERENCES machines (id),
  PRIMARY KEY (job, run)
) WITHOUT ROWID;

CREATE TABLE comparisons (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  label TEXT,
  scene TEXT NOT NULL,                       -- bundled file name, or 'inline'
  width INTEGER NOT NULL,
  height INTEGER NOT NULL,
  repeats INTEGER NOT NULL,
  request TEXT NOT NULL,                     -- the accepted request body
  created_ms INTEGER NOT NULL
);

-- Jobs of a comparison cannot be deleted on their own (no ON DELETE on job/reference_job): the
-- API answers 409 before SQLite would refuse.
CREATE TABLE comparison_candidates (
  comparison INTEGER NOT NULL REFERENCES comparisons (id) ON DELETE CASCADE,
  idx INTEGER NOT NULL,                      -- the candidate's index in the expansion
  job INTEGER NOT NULL REFERENCES jobs (id),
  reference_job INTEGER NOT NULL REFERENCES jobs (id),
  technique TEXT NOT NULL,
  backend TEXT NOT NULL CHECK (backend IN ('cpu', 'vulkan')),
  params TEXT NOT NULL,                      -- JSON, defaults filled in
  reference_params TEXT NOT NULL,            -- JSON, the reference's rt_ao parameters
  response TEXT NOT NULL,                    -- how the reference is mapped (obs_response_name)
  metrics TEXT,                              -- JSON; NULL until both jobs succeeded
  metrics_error TEXT,                        -- why metrics could not be computed
  PRIMARY KEY (comparison, idx)
) WITHOUT ROWID;
CREATE INDEX comparison_candidates_job ON comparison_candidates (job);
CREATE INDEX comparison_candidates_reference ON comparison_candidates (reference_job);

-- migration 4
-- Who queued each job: the remote address, or "token" when a bearer token is configured. Queued
-- work is bounded per client (--max-queued-work); the partial index keeps that sum to the queue.
ALTER TABLE jobs ADD COLUMN client TEXT;
CREATE INDEX jobs_active_client ON jobs (client, state) WHERE state IN ('queued', 'running');

-- migration 5
-- The name of an inline scene (the request's scene_name: the submitting file's name); NULL for
-- bundled scenes (their name is the scene column) and for inline ones submitted without one.
ALTER TABLE jobs ADD COLUMN scene_name TEXT;

-- migration 6
-- Why parameters differ from what was asked: the values derived from the scene's size when a
-- technique's own defaults would not fit it (a JSON array of sentences; NULL: none).
ALTER TABLE jobs ADD COLUMN notes TEXT;
ALTER TABLE comparisons ADD COLUMN notes TEXT;

-- migration 7
-- Open MPI ranks a job renders on (obscurad --mpirun; docs/mpi.md): 1 renders in the daemon.
ALTER TABLE jobs ADD COLUMN ranks INTEGER NOT NULL DEFAULT 1 CHECK (ranks BETWEEN 1 AND 256);

-- migration 8
-- The bytes a job stores while it waits: its document and texts, its candidate row, and for a
-- comparison's first reference the comparison's request. Queued bytes are bounded per client and
-- in total (--max-queued-bytes); jobs that had finished before no longer count and stay 0.
ALTER TABLE jobs ADD COLUMN stored_bytes INTEGER NOT NULL DEFAULT 0;
UPDATE jobs SET stored_bytes = length(CAST(doc AS BLOB)) WHERE state IN ('queued', 'running');

-- migration 9
-- What a candidate row measures (docs/comparisons.md): 'own', the candidate against its own
-- reference; 'common', the candidate's job against the comparison's common reference; 'output',
-- another output of the candidate's job against the reference its technique declares for it.
-- Rows other than 'own' reuse their candidate's job, under indices after the candidates'.
-- output: the candidate's output an 'output' row compares with its own reference job's (NULL:
-- the output the reference technique decides, as for 'own' rows).
ALTER TABLE comparison_candidates ADD COLUMN role TEXT NOT NULL DEFAULT 'own'
  CHECK (role IN ('own', 'common', 'output'));
ALTER TABLE comparison_candidates ADD COLUMN output TEXT;

-- migration 10
-- The Vulkan device's kind, from its VkPhysicalDeviceType: 'gpu' (integrated, discrete or
-- virtual GPU), 'software' (VK_PHYSICAL_DEVICE_TYPE_CPU: a CPU rasteriser such as llvmpipe) or
-- 'other'. Timings of one kind never predict another (learned auto, time budgets); NULL on rows
-- recorded before kinds were, whose Vulkan runs therefore predict nothing.
ALTER TABLE machines ADD COLUMN vulkan_kind TEXT;
-- A time-budget job's choice (JSON: the pick's expected time and RMSE, the alternatives
-- considered and why each lost), made at submission; NULL for every other job.
ALTER TABLE jobs ADD COLUMN choice TEXT;

-- migration 11
-- Several nodes on one store (docs/cluster.md): the worker ("<node>/<boot>") holding a running
-- job and until when its lease lasts, the node that ran the last attempt (kept: the figures say
-- which host timed them), when a requeued job may run again (back-off), how many attempts a job
-- gets, and which nodes failed which jobs (a node that failed one 3 times no longer claims it).
-- One daemon owns a SQLite file, so its leases never lapse while it lives; the columns keep both
-- stores to one contract.
ALTER TABLE jobs ADD COLUMN worker TEXT;
ALTER TABLE jobs ADD COLUMN node TEXT;
ALTER TABLE jobs ADD COLUMN lease_expires_ms INTEGER;
ALTER TABLE jobs ADD COLUMN run_after INTEGER;           -- Unix ms; NULL: as soon as queued
ALTER TABLE jobs ADD COLUMN max_attempts INTEGER NOT NULL DEFAULT 3 CHECK (max_attempts >= 1);
CREATE TABLE job_node_failures (
  job INTEGER NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  node TEXT NOT NULL,
  failures INTEGER NOT NULL DEFAULT 0,
  PRIMARY KEY (job, node)
) WITHOUT ROWID;

-- migration 12
-- A history of a million jobs must not slow what every request does. Jobs per state are kept by
-- triggers, so health and metrics read five rows instead of counting the history.
CREATE TABLE job_counts (
  state TEXT PRIMARY KEY,
  n INTEGER NOT NULL
) WITHOUT ROWID;
INSERT INTO job_counts (state, n)
  SELECT s.state, (SELECT count(*) FROM jobs WHERE jobs.state = s.state)
  FROM (SELECT 'queued' AS state UNION ALL SELECT 'running' UNION ALL SELECT 'succeeded'
        UNION ALL SELECT 'failed' UNION ALL SELECT 'cancelled') s;
CREATE TRIGGER jobs_count_insert AFTER INSERT ON jobs BEGIN
  UPDATE job_counts SET n = n + 1 WHERE state = NEW.state;
END;
CREATE TRIGGER jobs_count_delete AFTER DELETE ON jobs BEGIN
  UPDATE job_counts SET n = n - 1 WHERE state = OLD.state;
END;
CREATE TRIGGER jobs_count_update AFTER UPDATE OF state ON jobs WHEN OLD.state <> NEW.state BEGIN
  UPDATE job_counts SET n = n - 1 WHERE state = OLD.state;
  UPDATE job_counts SET n = n + 1 WHERE state = NEW.state;
END;
-- A page of the job list under any combination of filters walks one index in id order and stops
-- after the page (the list statements are one per combination, server/db.c, so each plan can use
-- its index): state, technique, backend (as shown: the one that ran, else the one requested).
CREATE INDEX jobs_list_t ON jobs (technique, id);
CREATE INDEX jobs_list_b ON jobs (coalesce(backend, backend_requested), id);
CREATE INDEX jobs_list_st ON jobs (state, technique, id);
CREATE INDEX jobs_list_sb ON jobs (state, coalesce(backend, backend_requested), id);
CREATE INDEX jobs_list_tb ON jobs (technique, coalesce(backend, backend_requested), id);
CREATE INDEX jobs_list_stb ON jobs (state, technique, coalesce(backend, backend_requested), id);
-- Learned "auto" and the render-time estimate read the newest succeeded jobs of a technique
-- (newest first, a bounded window), covered by this index without touching the rows.
CREATE INDEX jobs_succeeded ON jobs (technique, id, backend, work) WHERE state = 'succeeded';
-- Retention by age reads the finished jobs in the order they finished.
CREATE INDEX jobs_finished ON jobs (finished_ms) WHERE state IN ('succeeded', 'failed', 'cancelled');
-- Retention by count finds the oldest job kept (the keep-jobs-th newest) by stepping through the
-- ids alone: this index holds nothing else, where the table's own B-tree holds whole rows (5 KB
-- a job: a million of them, 1.2 s per step through a million, against 18 ms here).
CREATE INDEX jobs_ids ON jobs (id);
