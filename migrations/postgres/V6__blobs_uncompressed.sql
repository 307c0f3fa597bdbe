-- Artifact chunks and live snapshots are PNG, glb, NumPy and JSON bytes of up to 1 MiB: stored
-- out of line without compression (EXTERNAL), so PostgreSQL does not spend CPU trying pglz on
-- every write of bytes that are mostly compressed already (measured under load: see
-- loadtests/README.md). Range reads of EXTERNAL values also read only the slices they need.
ALTER TABLE artifact_chunks ALTER COLUMN data SET STORAGE EXTERNAL;
ALTER TABLE job_snapshots ALTER COLUMN png SET STORAGE EXTERNAL;
ALTER TABLE inputs ALTER COLUMN data SET STORAGE EXTERNAL;
