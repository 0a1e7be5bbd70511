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
