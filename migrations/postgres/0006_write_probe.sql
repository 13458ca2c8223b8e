-- A degraded store (a write refused for want of room, or read-only) is probed by writing one
-- chunk of a series here and removing it again; each replica probes under its own name.
CREATE TABLE write_probe (
    replica TEXT PRIMARY KEY,
    bytes BYTEA NOT NULL
);
ALTER TABLE write_probe ALTER COLUMN bytes SET STORAGE EXTERNAL;
