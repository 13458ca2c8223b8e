-- The latest checkpoint of each running job (signorini_core::checkpoint encoding): a job claimed
-- again after its replica died continues from it on whichever replica claims it. Written only
-- by the replica that holds the job.
CREATE TABLE checkpoints (
    id TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    -- The run number that wrote it (0 for the first run, one more per resume).
    attempt BIGINT NOT NULL,
    step BIGINT NOT NULL,
    bytes BYTEA NOT NULL
);
