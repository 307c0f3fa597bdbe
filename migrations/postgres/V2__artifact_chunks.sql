-- Artifact bytes in chunks (one row each, see src/store/artifacts.rs), so neither storing nor
-- serving an artifact needs it whole in memory. Artifacts stored before move over as one
-- chunk each.
CREATE TABLE artifact_chunks (
    job_id TEXT NOT NULL,
    name   TEXT NOT NULL,
    seq    INTEGER NOT NULL,  -- from 0; chunk k holds bytes k * chunk_bytes ..
    data   BYTEA NOT NULL,
    PRIMARY KEY (job_id, name, seq),
    FOREIGN KEY (job_id, name) REFERENCES artifacts (job_id, name) ON DELETE CASCADE
);
-- Most artifacts are compressed already (PNG, deflated sequences): keep chunks uncompressed
-- out of line rather than try again on every write.
ALTER TABLE artifact_chunks ALTER COLUMN data SET STORAGE EXTERNAL;
ALTER TABLE artifacts ADD COLUMN chunk_bytes BIGINT NOT NULL DEFAULT 1;
INSERT INTO artifact_chunks (job_id, name, seq, data) SELECT job_id, name, 0, data FROM artifacts;
UPDATE artifacts SET chunk_bytes = GREATEST(bytes, 1);
ALTER TABLE artifacts DROP COLUMN data;
