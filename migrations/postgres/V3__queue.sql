-- The queue across processes (src/store/queue.rs): the estimate's memory for claims to
-- compare, a claim's lease by the database's clock, who holds it, and how often a holder's
-- lease ran out.
ALTER TABLE jobs ADD COLUMN memory_bytes BIGINT NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN lease_until TIMESTAMPTZ;
ALTER TABLE jobs ADD COLUMN lease_owner TEXT;
ALTER TABLE jobs ADD COLUMN lost_leases INTEGER NOT NULL DEFAULT 0;
UPDATE jobs SET memory_bytes = COALESCE((cost::jsonb ->> 'memory_bytes')::BIGINT, 0) WHERE cost IS NOT NULL;
