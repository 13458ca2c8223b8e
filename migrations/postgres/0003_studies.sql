-- Studies (`[study]`) as jobs: a parent job whose `children` counts its runs (0 for every other
-- job), and child jobs whose `parent` names it. The parent is never queued or claimed (it is
-- `running` with no lease until the engine completes or cancels it); its children are ordinary
-- jobs of the queue, claimed by any replica.
ALTER TABLE jobs ADD COLUMN parent TEXT;
ALTER TABLE jobs ADD COLUMN children BIGINT NOT NULL DEFAULT 0;
CREATE INDEX jobs_parent ON jobs (parent, seq) WHERE parent IS NOT NULL;
-- The sweep for parents to complete scans only running parents.
CREATE INDEX jobs_running_studies ON jobs (seq) WHERE children > 0 AND state = 'running';
