-- Which uploads each job reads: an upload belongs to the keys whose jobs sent or read it, is
-- stored only with an admitted job, and goes with the last job that reads it. Jobs stored
-- before name theirs in their requests (`png_sha256`); uploads no job reads are dropped.
CREATE TABLE job_inputs (
    job_id TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    sha256 TEXT NOT NULL,
    PRIMARY KEY (job_id, sha256)
);
CREATE INDEX job_inputs_by_sha256 ON job_inputs (sha256);
INSERT INTO job_inputs (job_id, sha256)
    SELECT DISTINCT jobs.id, found #>> '{}'
    FROM jobs, jsonb_path_query(jobs.request::jsonb, 'strict $.**.png_sha256') AS found
    WHERE jsonb_typeof(found) = 'string'
    ON CONFLICT DO NOTHING;
DELETE FROM inputs WHERE sha256 NOT IN (SELECT sha256 FROM job_inputs);
