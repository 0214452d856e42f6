-- gtwatch fleet centre, schema version 4 (src/fleet/sync.rs, src/fleet/history.rs): each unit's
-- health corrected for an instrument's step, as its edge's wash advice last said
-- (`instrument_corrections`, the edge's migration 0009). Sent whole at every sync, like the
-- washes: a refresh at the edge replaces or drops rows, and the centre keeps exactly the edge's.
-- `gtwatch fleet history` shows them under the fitted health, which they never replace, and the
-- fleet report's fouling rates and trends use them.

CREATE TABLE instrument_corrections (
    unit_id          TEXT   NOT NULL,
    edge_id          BIGINT NOT NULL,   -- the corrected start-up's segment id at its edge
    onset_segment_id BIGINT,            -- first start-up of the step (edge segment id)
    effect           TEXT,              -- the instrument (`fuel_meter`, ...)
    unit             TEXT,              -- of magnitude: 'fraction', 'K', 'kPa', ...
    magnitude        DOUBLE PRECISION,
    magnitude_sigma  DOUBLE PRECISION,
    d_gc DOUBLE PRECISION, d_ec DOUBLE PRECISION, d_gt DOUBLE PRECISION,
    d_et DOUBLE PRECISION, d_gp DOUBLE PRECISION, d_ep DOUBLE PRECISION,
    sigma_gc DOUBLE PRECISION, sigma_ec DOUBLE PRECISION, sigma_gt DOUBLE PRECISION,
    sigma_et DOUBLE PRECISION, sigma_gp DOUBLE PRECISION, sigma_ep DOUBLE PRECISION,
    refreshed_ms     BIGINT,
    also             TEXT,              -- the other instruments the health is corrected for
    PRIMARY KEY (unit_id, edge_id)
);
