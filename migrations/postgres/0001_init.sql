-- The PostgreSQL store of `signorini serve --store postgres://…`: jobs and their queue, results,
-- recorded series. Applied once, in a transaction, by the first replica that connects (under an
-- advisory lock, so replicas starting together do not race); recorded in schema_migrations.

CREATE TABLE jobs (
    seq BIGSERIAL PRIMARY KEY,
    id TEXT NOT NULL UNIQUE,
    name TEXT,
    spec_json TEXT NOT NULL,
    -- queued | running | succeeded | failed | cancelled
    state TEXT NOT NULL,
    created_ms BIGINT NOT NULL,
    started_ms BIGINT NOT NULL DEFAULT 0,
    finished_ms BIGINT NOT NULL DEFAULT 0,
    error_field TEXT,
    error_reason TEXT,
    done BIGINT NOT NULL DEFAULT 0,
    total BIGINT NOT NULL DEFAULT 0,
    t DOUBLE PRECISION NOT NULL DEFAULT 0,
    -- The queue: which run this is (one more per claim), the replica holding it (after the end:
    -- the replica that finished it) and until when (renewed by that replica's heartbeat; past
    -- it, any replica may claim a running job again).
    attempt BIGINT NOT NULL DEFAULT 0,
    owner TEXT,
    lease_until TIMESTAMPTZ,
    -- A client asked to cancel the job while it ran: its replica stops it at its next heartbeat.
    cancel_requested BOOLEAN NOT NULL DEFAULT FALSE
);

-- The claim scans only unfinished jobs, oldest first.
CREATE INDEX jobs_unfinished ON jobs (seq) WHERE state IN ('queued', 'running');
CREATE INDEX jobs_state ON jobs (state, seq);

-- One result per (job, attempt): the run that finished under a held lease writes it; a
-- replica that lost its lease writes nothing.
CREATE TABLE results (
    id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    attempt BIGINT NOT NULL,
    summary_json TEXT NOT NULL,
    columns_json TEXT NOT NULL,
    tables_json TEXT NOT NULL,
    figures_json TEXT NOT NULL,
    partial BOOLEAN NOT NULL DEFAULT FALSE,
    PRIMARY KEY (id, attempt)
);

-- A job's recorded series, in chunks of about 1 MiB (little-endian u64/f64 blobs), per attempt.
CREATE TABLE result_chunks (
    id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    attempt BIGINT NOT NULL,
    chunk BIGINT NOT NULL,
    first_row BIGINT NOT NULL,
    rows BIGINT NOT NULL,
    step_first BIGINT NOT NULL,
    step_last BIGINT NOT NULL,
    steps BYTEA NOT NULL,
    t BYTEA NOT NULL,
    vals BYTEA NOT NULL,
    batches BYTEA NOT NULL,
    PRIMARY KEY (id, attempt, chunk)
);
