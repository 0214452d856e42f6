-- gtwatch fleet centre, schema version 2 (src/fleet/rediagnose.rs): what a distributed
-- re-diagnosis needs. The edges now also send their tags (which tag is which engine signal) and
-- mark each start-up window whose samples (with the standstill context before the start) are
-- all at the centre; `gtwatch fleet rediagnose` queues one job per such window and engine/config
-- hash; `gtwatch fleet worker` processes claim jobs under a lease and store each result once.

-- Each edge's tags: name, engineering unit and the engine signal it measures (its column name,
-- e.g. n1_rpm; NULL for a free tag). Keyed like every edge row.
CREATE TABLE tags (
    unit_id TEXT   NOT NULL,
    edge_id BIGINT NOT NULL,
    name    TEXT,
    unit    TEXT,
    signal  TEXT,
    PRIMARY KEY (unit_id, edge_id)
);

-- A start-up window whose samples [from_ms, end_ms] are all at the centre (written by the sync
-- after the window's last batch committed).
CREATE TABLE sample_windows (
    unit_id      TEXT        NOT NULL,
    segment_id   BIGINT      NOT NULL,   -- the segment's edge id
    from_ms      BIGINT      NOT NULL,
    end_ms       BIGINT      NOT NULL,
    completed_at TIMESTAMPTZ NOT NULL DEFAULT now(),
    PRIMARY KEY (unit_id, segment_id)
);

-- What a job runs with: the engine file's text and the [diagnosis] settings (JSON), under the
-- hash the edge stores with its own results (FNV-1a of the engine text and the fit settings).
-- Immutable once written: the same hash is the same text.
CREATE TABLE rediagnosis_configs (
    config_hash   TEXT PRIMARY KEY,
    engine_name   TEXT        NOT NULL,
    engine_toml   TEXT        NOT NULL,
    settings_json TEXT        NOT NULL,
    created_at    TIMESTAMPTZ NOT NULL DEFAULT now()
);

-- The queue. A worker claims a pending job whose lease is free or expired
-- (SELECT … FOR UPDATE SKIP LOCKED), sets lease_owner/lease_until, renews while it fits, and
-- marks it done in the transaction that stores its result, only while it still holds the lease.
CREATE TABLE rediagnosis_jobs (
    id          BIGSERIAL PRIMARY KEY,
    unit_id     TEXT        NOT NULL,
    segment_id  BIGINT      NOT NULL,
    config_hash TEXT        NOT NULL REFERENCES rediagnosis_configs (config_hash),
    state       TEXT        NOT NULL DEFAULT 'pending'
                CHECK (state IN ('pending', 'done', 'failed')),
    attempts    INTEGER     NOT NULL DEFAULT 0,
    lease_owner TEXT,
    lease_until TIMESTAMPTZ,
    enqueued_at TIMESTAMPTZ NOT NULL DEFAULT now(),
    done_at     TIMESTAMPTZ,
    done_by     TEXT,
    error       TEXT,
    UNIQUE (unit_id, segment_id, config_hash)
);
CREATE INDEX rediagnosis_jobs_pending ON rediagnosis_jobs (id) WHERE state = 'pending';

-- One outcome per (unit, segment, hash): "exactly once" is also the schema's.
CREATE TABLE rediagnoses (
    unit_id         TEXT             NOT NULL,
    segment_id      BIGINT           NOT NULL,
    config_hash     TEXT             NOT NULL,
    job_id          BIGINT           NOT NULL REFERENCES rediagnosis_jobs (id),
    outcome         TEXT             NOT NULL CHECK (outcome IN ('diagnosed', 'undiagnosable')),
    failures_json   TEXT             NOT NULL,   -- [{method, reason, detail}] of what gave no result
    worker_id       TEXT             NOT NULL,
    wall_s          DOUBLE PRECISION NOT NULL,
    gtwatch_version TEXT             NOT NULL,
    created_at      TIMESTAMPTZ      NOT NULL DEFAULT now(),
    PRIMARY KEY (unit_id, segment_id, config_hash),
    UNIQUE (job_id)
);

-- Its estimates, one per method, with the columns of the edge's diagnoses.
CREATE TABLE rediagnosis_estimates (
    unit_id     TEXT   NOT NULL,
    segment_id  BIGINT NOT NULL,
    config_hash TEXT   NOT NULL,
    method      TEXT   NOT NULL,
    d_gc DOUBLE PRECISION, d_ec DOUBLE PRECISION, d_gt DOUBLE PRECISION,
    d_et DOUBLE PRECISION, d_gp DOUBLE PRECISION, d_ep DOUBLE PRECISION,
    sigma_gc DOUBLE PRECISION, sigma_ec DOUBLE PRECISION, sigma_gt DOUBLE PRECISION,
    sigma_et DOUBLE PRECISION, sigma_gp DOUBLE PRECISION, sigma_ep DOUBLE PRECISION,
    objective DOUBLE PRECISION, residual_level DOUBLE PRECISION, fit_quality TEXT,
    model_runs BIGINT, wall_s DOUBLE PRECISION, seed BIGINT,
    PRIMARY KEY (unit_id, segment_id, config_hash, method),
    FOREIGN KEY (unit_id, segment_id, config_hash)
        REFERENCES rediagnoses (unit_id, segment_id, config_hash) ON DELETE CASCADE
);
