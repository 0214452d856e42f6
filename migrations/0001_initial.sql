-- gtwatch schema, version 1. Designed once for acquisition, detection and diagnosis.
-- Times are Unix epoch milliseconds, UTC (INTEGER). Documented in README "Database schema".

CREATE TABLE tags (
    id            INTEGER PRIMARY KEY,
    name          TEXT    NOT NULL UNIQUE,
    unit          TEXT    NOT NULL DEFAULT '',
    signal        TEXT,                      -- Signal column name (n1_rpm, fuel_kg_s, ...) or NULL
    created_at_ms INTEGER NOT NULL
);

CREATE TABLE samples (
    tag_id  INTEGER NOT NULL REFERENCES tags(id),
    t_ms    INTEGER NOT NULL,
    value   REAL    NOT NULL,
    quality INTEGER NOT NULL DEFAULT 0 CHECK (quality IN (0, 1, 2)),  -- 0 good, 1 out of range, 2 bad
    PRIMARY KEY (tag_id, t_ms)
) WITHOUT ROWID;

CREATE TABLE gaps (
    id       INTEGER PRIMARY KEY,
    start_ms INTEGER NOT NULL,
    end_ms   INTEGER NOT NULL CHECK (end_ms >= start_ms),
    source   TEXT    NOT NULL,
    reason   TEXT    NOT NULL,
    UNIQUE (source, start_ms, end_ms)
);
CREATE INDEX gaps_by_time ON gaps(start_ms, end_ms);

CREATE TABLE segments (
    id             INTEGER PRIMARY KEY,
    kind           TEXT    NOT NULL DEFAULT 'startup' CHECK (kind IN ('startup')),
    start_ms       INTEGER NOT NULL,
    end_ms         INTEGER,                  -- NULL while the segment is open
    outcome        TEXT    NOT NULL CHECK (outcome IN ('in_progress', 'completed', 'aborted')),
    abort_cause    TEXT    CHECK (abort_cause IN ('trip', 'flame_out', 'operator_stop', 'unknown')),
    status         TEXT    NOT NULL DEFAULT 'open' CHECK (status IN ('open', 'closed', 'diagnosed')),
    hot_restart    INTEGER NOT NULL DEFAULT 0 CHECK (hot_restart IN (0, 1)),
    has_gap        INTEGER NOT NULL DEFAULT 0 CHECK (has_gap IN (0, 1)),
    updated_at_ms  INTEGER NOT NULL,
    UNIQUE (kind, start_ms)
);

CREATE TABLE segment_phases (
    segment_id INTEGER NOT NULL REFERENCES segments(id) ON DELETE CASCADE,
    phase      TEXT    NOT NULL,             -- Phase name: crank, purge, light_off, ...
    phase_code INTEGER NOT NULL,             -- Phase::code(), stable
    start_ms   INTEGER NOT NULL,
    end_ms     INTEGER,                      -- NULL while the phase is running
    PRIMARY KEY (segment_id, phase)
) WITHOUT ROWID;

CREATE TABLE diagnoses (
    id             INTEGER PRIMARY KEY,
    segment_id     INTEGER NOT NULL REFERENCES segments(id),
    method         TEXT    NOT NULL,         -- 'A' steady-state, 'B' transient, or a named variant
    d_gc REAL NOT NULL, d_ec REAL NOT NULL, d_gt REAL NOT NULL,
    d_et REAL NOT NULL, d_gp REAL NOT NULL, d_ep REAL NOT NULL,
    sigma_gc REAL, sigma_ec REAL, sigma_gt REAL, sigma_et REAL, sigma_gp REAL, sigma_ep REAL,
    objective      REAL    NOT NULL,
    model_runs     INTEGER NOT NULL,
    wall_s         REAL    NOT NULL,
    model_version  TEXT    NOT NULL,
    seed           INTEGER,
    created_at_ms  INTEGER NOT NULL
);
CREATE INDEX diagnoses_by_segment ON diagnoses(segment_id);

CREATE TABLE washes (
    id    INTEGER PRIMARY KEY,
    t_ms  INTEGER NOT NULL,
    kind  TEXT    NOT NULL CHECK (kind IN ('online', 'offline')),
    note  TEXT    NOT NULL DEFAULT ''
);
CREATE INDEX washes_by_time ON washes(t_ms);

CREATE TABLE recommendations (
    id      INTEGER PRIMARY KEY,
    t_ms    INTEGER NOT NULL,
    kind    TEXT    NOT NULL,               -- e.g. 'wash_online', 'wash_offline', 'inspect'
    message TEXT    NOT NULL,
    basis   TEXT    NOT NULL DEFAULT ''     -- what the advice rests on (diagnosis ids, trend, ...)
);
CREATE INDEX recommendations_by_time ON recommendations(t_ms);

-- One row: where the start-up detector has got to (see src/detect/mod.rs).
CREATE TABLE detector_state (
    id               INTEGER PRIMARY KEY CHECK (id = 1),
    scanned_to_ms    INTEGER,               -- last frame time fed to the detector
    rescan_from_ms   INTEGER,               -- older samples arrived after the scan: rescan from here
    last_fuel_off_ms INTEGER,               -- for the hot-restart rule
    updated_at_ms    INTEGER NOT NULL
);
INSERT INTO detector_state (id, updated_at_ms) VALUES (1, 0);

-- ---------------------------------------------------------------- views

CREATE VIEW v_samples AS
SELECT t.name AS tag, t.unit, s.t_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', s.t_ms / 1000.0, 'unixepoch') AS time_utc,
       s.value, s.quality
FROM samples s JOIN tags t ON t.id = s.tag_id;

CREATE VIEW v_tag_latest AS
SELECT t.id AS tag_id, t.name AS tag, t.unit, t.signal, s.t_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', s.t_ms / 1000.0, 'unixepoch') AS time_utc,
       s.value, s.quality
FROM tags t
JOIN samples s ON s.tag_id = t.id
 AND s.t_ms = (SELECT MAX(t_ms) FROM samples WHERE tag_id = t.id);

CREATE VIEW v_gaps AS
SELECT id, source, reason, start_ms, end_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', start_ms / 1000.0, 'unixepoch') AS start_utc,
       strftime('%Y-%m-%dT%H:%M:%fZ', end_ms / 1000.0, 'unixepoch') AS end_utc,
       (end_ms - start_ms) / 1000.0 AS duration_s
FROM gaps ORDER BY start_ms;

CREATE VIEW v_startups AS
SELECT g.id, g.start_ms, g.end_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', g.start_ms / 1000.0, 'unixepoch') AS start_utc,
       strftime('%Y-%m-%dT%H:%M:%fZ', g.end_ms / 1000.0, 'unixepoch') AS end_utc,
       g.outcome, g.abort_cause, g.status, g.hot_restart, g.has_gap,
       (g.end_ms - g.start_ms) / 1000.0 AS duration_s,
       MAX(CASE WHEN p.phase = 'crank'           THEN (p.end_ms - p.start_ms) / 1000.0 END) AS crank_s,
       MAX(CASE WHEN p.phase = 'purge'           THEN (p.end_ms - p.start_ms) / 1000.0 END) AS purge_s,
       MAX(CASE WHEN p.phase = 'light_off'       THEN (p.end_ms - p.start_ms) / 1000.0 END) AS light_off_s,
       MAX(CASE WHEN p.phase = 'acceleration'    THEN (p.end_ms - p.start_ms) / 1000.0 END) AS acceleration_s,
       MAX(CASE WHEN p.phase = 'idle'            THEN (p.end_ms - p.start_ms) / 1000.0 END) AS idle_s,
       MAX(CASE WHEN p.phase = 'synchronisation' THEN (p.end_ms - p.start_ms) / 1000.0 END) AS synchronisation_s,
       MAX(CASE WHEN p.phase = 'loading'         THEN (p.end_ms - p.start_ms) / 1000.0 END) AS loading_s,
       MAX(CASE WHEN p.phase = 'steady'          THEN p.start_ms END) AS steady_from_ms
FROM segments g LEFT JOIN segment_phases p ON p.segment_id = g.id
WHERE g.kind = 'startup'
GROUP BY g.id
ORDER BY g.start_ms;

CREATE VIEW v_health_trend AS
SELECT d.id AS diagnosis_id, d.segment_id, g.start_ms AS segment_start_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', g.start_ms / 1000.0, 'unixepoch') AS segment_start_utc,
       g.outcome, g.hot_restart, d.method,
       d.d_gc, d.d_ec, d.d_gt, d.d_et, d.d_gp, d.d_ep,
       d.sigma_gc, d.sigma_ec, d.sigma_gt, d.sigma_et, d.sigma_gp, d.sigma_ep,
       d.objective, d.model_version, d.created_at_ms
FROM diagnoses d JOIN segments g ON g.id = d.segment_id
ORDER BY g.start_ms, d.method, d.created_at_ms;

CREATE VIEW v_latest_health AS
SELECT h.* FROM v_health_trend h
WHERE h.diagnosis_id = (
    SELECT d2.id FROM diagnoses d2 JOIN segments g2 ON g2.id = d2.segment_id
    WHERE d2.method = h.method
    ORDER BY g2.start_ms DESC, d2.created_at_ms DESC, d2.id DESC LIMIT 1);
