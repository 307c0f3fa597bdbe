-- Job events and live snapshots across processes (src/store/events.rs), and cancel requests
-- a job's worker reads when it renews its lease.
CREATE TABLE job_events (
    id     BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,  -- one sequence: Last-Event-ID on any replica
    job_id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    event  TEXT NOT NULL,
    data   TEXT NOT NULL
);
CREATE INDEX job_events_by_job ON job_events (job_id, id);
CREATE TABLE job_snapshots (
    job_id   TEXT PRIMARY KEY REFERENCES jobs (id) ON DELETE CASCADE,
    event_id BIGINT NOT NULL,
    png      BYTEA NOT NULL
);
ALTER TABLE jobs ADD COLUMN cancel_requested BOOLEAN NOT NULL DEFAULT false;
