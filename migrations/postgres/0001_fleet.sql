-- gtwatch fleet centre, schema version 1 (src/fleet): what the edges of a fleet send.
-- Every row is keyed by (unit_id, edge_id): the unit's [fleet] unit_id and the row's id in that
-- unit's SQLite database, so a batch sent twice changes nothing. Column names and meanings are
-- those of the edge (README "Database schema"); times are Unix epoch ms, UTC. The version is
-- the highest row of schema_version; an edge refuses a centre newer than it knows.

CREATE TABLE schema_version (
    version    INTEGER PRIMARY KEY,
    applied_at TIMESTAMPTZ NOT NULL DEFAULT now()
);

-- One row: this centre's identity. Edges key their high-water marks by it, so an edge pointed
-- at a new (empty) centre sends everything again instead of trusting marks of another one.
CREATE TABLE centre (
    id         TEXT PRIMARY KEY,
    created_at TIMESTAMPTZ NOT NULL DEFAULT now()
);
INSERT INTO centre (id) VALUES (gen_random_uuid()::text);

CREATE TABLE units (
    unit_id         TEXT PRIMARY KEY,
    first_sync_at   TIMESTAMPTZ NOT NULL DEFAULT now(),
    last_sync_at    TIMESTAMPTZ NOT NULL DEFAULT now(),
    gtwatch_version TEXT NOT NULL DEFAULT ''
);

CREATE TABLE segments (
    unit_id       TEXT   NOT NULL,
    edge_id       BIGINT NOT NULL,
    kind          TEXT,
    start_ms      BIGINT,
    end_ms        BIGINT,
    outcome       TEXT,
    abort_cause   TEXT,
    status        TEXT,
    hot_restart   BIGINT,
    has_gap       BIGINT,
    updated_at_ms BIGINT,
    PRIMARY KEY (unit_id, edge_id)
);

CREATE TABLE segment_phases (
    unit_id    TEXT   NOT NULL,
    edge_id    BIGINT NOT NULL,   -- the segment's edge id
    phase      TEXT   NOT NULL,
    phase_code BIGINT,
    start_ms   BIGINT,
    end_ms     BIGINT,
    PRIMARY KEY (unit_id, edge_id, phase),
    FOREIGN KEY (unit_id, edge_id) REFERENCES segments (unit_id, edge_id) ON DELETE CASCADE
);

CREATE TABLE diagnoses (
    unit_id TEXT NOT NULL, edge_id BIGINT NOT NULL,
    segment_id BIGINT, method TEXT,
    d_gc DOUBLE PRECISION, d_ec DOUBLE PRECISION, d_gt DOUBLE PRECISION,
    d_et DOUBLE PRECISION, d_gp DOUBLE PRECISION, d_ep DOUBLE PRECISION,
    sigma_gc DOUBLE PRECISION, sigma_ec DOUBLE PRECISION, sigma_gt DOUBLE PRECISION,
    sigma_et DOUBLE PRECISION, sigma_gp DOUBLE PRECISION, sigma_ep DOUBLE PRECISION,
    objective DOUBLE PRECISION, model_runs BIGINT, wall_s DOUBLE PRECISION,
    model_version TEXT, seed BIGINT, created_at_ms BIGINT,
    residual_level DOUBLE PRECISION, fit_quality TEXT, config_hash TEXT, gtwatch_version TEXT,
    PRIMARY KEY (unit_id, edge_id)
);

CREATE TABLE gap_analyses (
    unit_id TEXT NOT NULL, edge_id BIGINT NOT NULL,
    segment_id BIGINT, holdout_segment_id BIGINT, effect TEXT,
    shrinkage DOUBLE PRECISION, confidence DOUBLE PRECISION, baseline_fit_quality TEXT,
    normalised_residual DOUBLE PRECISION, report_json TEXT, gtwatch_version TEXT,
    created_at_ms BIGINT,
    PRIMARY KEY (unit_id, edge_id)
);

CREATE TABLE washes (
    unit_id TEXT NOT NULL, edge_id BIGINT NOT NULL,
    t_ms BIGINT, kind TEXT, note TEXT,
    PRIMARY KEY (unit_id, edge_id)
);

CREATE TABLE recommendations (
    unit_id TEXT NOT NULL, edge_id BIGINT NOT NULL,
    t_ms BIGINT, kind TEXT, message TEXT, basis TEXT,
    PRIMARY KEY (unit_id, edge_id)
);

-- Full-resolution samples of each start-up window, keyed by tag name and time.
CREATE TABLE samples (
    unit_id    TEXT             NOT NULL,
    tag        TEXT             NOT NULL,
    t_ms       BIGINT           NOT NULL,
    value      DOUBLE PRECISION NOT NULL,
    quality    BIGINT           NOT NULL,
    segment_id BIGINT           NOT NULL,   -- edge id of the start-up window it was sent with
    PRIMARY KEY (unit_id, tag, t_ms)
);
