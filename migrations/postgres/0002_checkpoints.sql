-- Checkpoints of running jobs: the latest one per job, written by the replica that holds the job
-- (never by one that lost its lease). A replica that claims the job after its holder died
-- continues from it: it copies the chunks the checkpoint counts from the attempt that wrote them
-- (`series_attempt`) to its own attempt, and runs on from the checkpoint's step.
CREATE TABLE checkpoints (
    id TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    -- The run number the engine counts (one more per resume).
    attempt BIGINT NOT NULL,
    step BIGINT NOT NULL,
    bytes BYTEA NOT NULL,
    -- The claim (jobs.attempt) whose stored chunks the checkpoint counts.
    series_attempt BIGINT NOT NULL
);
