-- Jobs, their artifacts, idempotency keys and uploads, as the embedded SQLite store keeps them.
-- Timestamps and JSON are text: exactly what the job model wrote, byte for byte.
CREATE TABLE jobs (
    id                TEXT PRIMARY KEY,   -- UUIDv7: text order is creation order
    kind              TEXT NOT NULL,
    status            TEXT NOT NULL,
    label             TEXT,
    created_at        TEXT NOT NULL,
    started_at        TEXT,
    finished_at       TEXT,
    progress          TEXT NOT NULL,
    request           TEXT NOT NULL,
    result            TEXT,
    error             TEXT,
    replay_of         TEXT,
    replay_until_step BIGINT,
    attempts          INTEGER NOT NULL DEFAULT 0,
    cost              TEXT,
    owner             TEXT
);
CREATE INDEX jobs_by_kind ON jobs (kind, id);
CREATE INDEX jobs_by_status ON jobs (status, id);
CREATE INDEX jobs_by_owner ON jobs (owner, id);

CREATE TABLE artifacts (
    job_id     TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    name       TEXT NOT NULL,
    ordinal    INTEGER NOT NULL,
    media_type TEXT NOT NULL,
    bytes      BIGINT NOT NULL,
    sha256     TEXT NOT NULL,
    data       BYTEA NOT NULL,
    PRIMARY KEY (job_id, name),
    UNIQUE (job_id, ordinal)
);

CREATE TABLE idempotency_keys (
    key         TEXT PRIMARY KEY,
    body_sha256 TEXT NOT NULL,
    job_id      TEXT NOT NULL REFERENCES jobs (id) ON DELETE CASCADE
);
CREATE INDEX idempotency_keys_by_job ON idempotency_keys (job_id);

CREATE TABLE inputs (
    sha256     TEXT PRIMARY KEY,
    bytes      BIGINT NOT NULL,
    created_at TIMESTAMPTZ NOT NULL DEFAULT now(),
    data       BYTEA NOT NULL
);
