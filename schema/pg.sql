-- obscurad's PostgreSQL schema as numbered migrations, embedded into the daemon at build time and
-- applied in order at start (server/pg.c), all in one transaction under an advisory lock so that
-- daemons starting together apply them once. Never edit a migration that has shipped:
-- append a new "-- migration N" section instead. The rows the API reads look like the SQLite
-- store's (schema/db.sql): times are *_ms bigint columns; leases and back-off are timestamptz
-- judged by the database's clock, never a host's.

-- migration 1
CREATE TABLE comparisons (
  id bigserial PRIMARY KEY,
  label text,
  scene text NOT NULL,
  width integer NOT NULL,
  height integer NOT NULL,
  repeats integer NOT NULL,
  request text NOT NULL,                     -- the accepted request body
  created_ms bigint NOT NULL,
  notes text
);

CREATE TABLE jobs (
  id bigserial PRIMARY KEY,                  -- never reused after DELETE
  state text NOT NULL DEFAULT 'queued'
    CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
  priority integer NOT NULL DEFAULT 50 CHECK (priority BETWEEN 0 AND 100),
  label text,
  scene text NOT NULL,
  doc text NOT NULL,
  technique text NOT NULL,
  backend_requested text NOT NULL CHECK (backend_requested IN ('auto', 'cpu', 'vulkan')),
  lane text NOT NULL CHECK (lane IN ('cpu', 'vulkan')),
  backend text CHECK (backend IN ('cpu', 'vulkan')),
  width integer NOT NULL,
  height integer NOT NULL,
  spp integer NOT NULL,
  attempts integer NOT NULL DEFAULT 0,
  cancel_requested integer NOT NULL DEFAULT 0,
  created_ms bigint NOT NULL,
  started_ms bigint,
  finished_ms bigint,
  error text,
  summary text,
  progress double precision NOT NULL DEFAULT 0,
  repeats integer NOT NULL DEFAULT 1 CHECK (repeats BETWEEN 1 AND 20),
  warmup integer NOT NULL DEFAULT 0 CHECK (warmup IN (0, 1)),
  work double precision,
  backend_reason text,
  client text,
  scene_name text,
  notes text,
  ranks integer NOT NULL DEFAULT 1 CHECK (ranks BETWEEN 1 AND 256),
  stored_bytes bigint NOT NULL DEFAULT 0,
  choice text,
  -- The comparison the job belongs to (set when the comparison inserts it): read with every job
  -- and what keeps a comparison's jobs from being deleted or pruned on their own.
  comparison bigint,
  worker text,                               -- "<node>/<boot>" while running, NULL otherwise
  node text,                                 -- the node that ran the last attempt
  lease_expires_at timestamptz,              -- while running: the reaper requeues it after this
  run_after timestamptz NOT NULL DEFAULT now(), -- back-off after a lost lease
  max_attempts integer NOT NULL DEFAULT 3
);
-- The claim walks this index in its ORDER BY, reading queued rows only.
CREATE INDEX jobs_claim ON jobs (lane, priority DESC, run_after, id) WHERE state = 'queued';
-- The reaper and a restarted node's recovery read the running rows only.
CREATE INDEX jobs_running ON jobs (lease_expires_at) WHERE state = 'running';
-- The admission limits sum the active jobs' load without touching the history.
CREATE INDEX jobs_active ON jobs (client) INCLUDE (work, repeats, warmup, ranks, stored_bytes)
  WHERE state IN ('queued', 'running');
-- A page of the job list under each filter, newest first or after a key.
CREATE INDEX jobs_state ON jobs (state, id);
CREATE INDEX jobs_technique ON jobs (technique, id);
CREATE INDEX jobs_backend ON jobs ((coalesce(backend, backend_requested)), id);
CREATE INDEX jobs_work ON jobs (technique, work);
CREATE INDEX jobs_comparison ON jobs (comparison) WHERE comparison IS NOT NULL;
-- Retention by age.
CREATE INDEX jobs_finished ON jobs (finished_ms) WHERE state IN ('succeeded', 'failed', 'cancelled');

CREATE TABLE outputs (
  job_id bigint NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  name text NOT NULL,
  size bigint NOT NULL,
  sha256 text NOT NULL,
  content_type text NOT NULL,
  PRIMARY KEY (job_id, name)
);
CREATE INDEX outputs_sha256 ON outputs (sha256);

CREATE TABLE machines (
  id bigserial PRIMARY KEY,
  cpu_model text NOT NULL,
  cores integer NOT NULL,
  vulkan_device text,
  vulkan_kind text,
  host text                                  -- the node name whose facts these are
);
CREATE UNIQUE INDEX machines_facts ON machines (cpu_model, cores, coalesce(vulkan_device, ''),
                                                coalesce(host, ''));

CREATE TABLE runs (
  job bigint NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  run integer NOT NULL,
  build_ms double precision NOT NULL,
  render_ms double precision NOT NULL,
  post_ms double precision NOT NULL,
  total_ms double precision NOT NULL,
  machine bigint REFERENCES machines (id),
  PRIMARY KEY (job, run)
);

-- No ON DELETE on job/reference_job: a comparison's job is not deleted on its own.
CREATE TABLE comparison_candidates (
  comparison bigint NOT NULL REFERENCES comparisons (id) ON DELETE CASCADE,
  idx integer NOT NULL,
  job bigint NOT NULL REFERENCES jobs (id),
  reference_job bigint NOT NULL REFERENCES jobs (id),
  technique text NOT NULL,
  backend text NOT NULL CHECK (backend IN ('cpu', 'vulkan')),
  params text NOT NULL,
  reference_params text NOT NULL,
  response text NOT NULL,
  metrics text,
  metrics_error text,
  role text NOT NULL DEFAULT 'own' CHECK (role IN ('own', 'common', 'output')),
  output text,
  PRIMARY KEY (comparison, idx)
);
CREATE INDEX comparison_candidates_job ON comparison_candidates (job);
CREATE INDEX comparison_candidates_reference ON comparison_candidates (reference_job);
-- Candidates waiting for their metrics (the metrics thread's scan).
CREATE INDEX comparison_candidates_pending ON comparison_candidates (comparison, idx)
  WHERE metrics IS NULL AND metrics_error IS NULL;

-- A node whose lease on a job expired this many times is excluded from claiming it.
CREATE TABLE job_node_failures (
  job bigint NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
  node text NOT NULL,
  failures integer NOT NULL DEFAULT 0,
  PRIMARY KEY (job, node)
);

-- Outputs travel through the database when the nodes share no results directory.
CREATE TABLE blobs (
  sha256 text PRIMARY KEY,
  data bytea NOT NULL,
  put_at timestamptz NOT NULL DEFAULT now() -- pruning leaves blobs put lately for a finish to come
);

-- Jobs per state, kept by statement triggers so that health never counts the history. Each
-- backend adds to its own slot, so concurrent transactions rarely wait on one hot row; the rows
-- are upserted in state order so two transactions sharing a slot lock them in the same order.
CREATE TABLE job_counts (
  state text NOT NULL,
  slot integer NOT NULL,
  n bigint NOT NULL,
  PRIMARY KEY (state, slot)
);

CREATE FUNCTION job_counts_add() RETURNS trigger LANGUAGE plpgsql AS $$
BEGIN
  IF TG_OP = 'INSERT' THEN
    INSERT INTO job_counts AS c (state, slot, n)
      SELECT state, pg_backend_pid() % 32, count(*) FROM new_rows GROUP BY state ORDER BY state
      ON CONFLICT (state, slot) DO UPDATE SET n = c.n + excluded.n;
  ELSIF TG_OP = 'DELETE' THEN
    INSERT INTO job_counts AS c (state, slot, n)
      SELECT state, pg_backend_pid() % 32, -count(*) FROM old_rows GROUP BY state ORDER BY state
      ON CONFLICT (state, slot) DO UPDATE SET n = c.n + excluded.n;
  ELSE
    INSERT INTO job_counts AS c (state, slot, n)
      SELECT state, pg_backend_pid() % 32, sum(d) FROM (
        SELECT state, 1 AS d FROM new_rows UNION ALL SELECT state, -1 FROM old_rows) x
      GROUP BY state HAVING sum(d) <> 0 ORDER BY state
      ON CONFLICT (state, slot) DO UPDATE SET n = c.n + excluded.n;
  END IF;
  RETURN NULL;
END $$;
CREATE TRIGGER jobs_count_insert AFTER INSERT ON jobs REFERENCING NEW TABLE AS new_rows
  FOR EACH STATEMENT EXECUTE FUNCTION job_counts_add();
CREATE TRIGGER jobs_count_delete AFTER DELETE ON jobs REFERENCING OLD TABLE AS old_rows
  FOR EACH STATEMENT EXECUTE FUNCTION job_counts_add();
CREATE TRIGGER jobs_count_update AFTER UPDATE ON jobs REFERENCING OLD TABLE AS old_rows
  NEW TABLE AS new_rows FOR EACH STATEMENT EXECUTE FUNCTION job_counts_add();
