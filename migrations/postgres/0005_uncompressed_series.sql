-- Recorded series and checkpoints are binary f64/u64 data, which PostgreSQL's default TOAST
-- compression (pglz) barely shrinks but spends CPU trying: with many short jobs, pglz_compress
-- was the largest single cost of the PostgreSQL server (perf: 28 % of its time). Stored out of
-- line and uncompressed (EXTERNAL) instead; values already written keep their form.
ALTER TABLE result_chunks
    ALTER COLUMN steps SET STORAGE EXTERNAL,
    ALTER COLUMN t SET STORAGE EXTERNAL,
    ALTER COLUMN vals SET STORAGE EXTERNAL,
    ALTER COLUMN batches SET STORAGE EXTERNAL;
ALTER TABLE checkpoints ALTER COLUMN bytes SET STORAGE EXTERNAL;
ALTER TABLE final_states ALTER COLUMN bytes SET STORAGE EXTERNAL;
