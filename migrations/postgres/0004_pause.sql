-- Pause, resume and extend (src/engine/pause.rs). A paused job has state 'paused': no replica
-- claims it (the claim takes 'queued' jobs and 'running' ones whose lease ran out), and the
-- retention sweep, which takes finished jobs only, leaves it.

-- A client asked to pause the job while it ran on some replica: that replica writes a
-- checkpoint after the next step and parks the job at its next heartbeat.
ALTER TABLE jobs ADD COLUMN pause_requested BOOLEAN NOT NULL DEFAULT FALSE;

-- The checkpoint a succeeded job wrote after its last step, kept so that the job can be
-- extended to a later t_end; removed with the job.
CREATE TABLE final_states (
    id TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    step BIGINT NOT NULL,
    bytes BYTEA NOT NULL
);

-- An extension (a job continuing a succeeded job to a later t_end) and the job it extends.
CREATE TABLE extensions (
    id TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    extends TEXT NOT NULL
);
