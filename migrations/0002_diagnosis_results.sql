-- gtwatch schema, version 2: what the diagnosis worker stores (see src/worker.rs).

-- Reproducibility and quality of each result.
ALTER TABLE diagnoses ADD COLUMN residual_level  REAL;   -- objective per signal: mean |residual| in noise σ (≈0.8 at pure noise)
ALTER TABLE diagnoses ADD COLUMN fit_quality     TEXT;   -- 'good' or 'fair' (see [diagnosis] max_residual_level)
ALTER TABLE diagnoses ADD COLUMN config_hash     TEXT;   -- FNV-1a of engine file + diagnosis settings
ALTER TABLE diagnoses ADD COLUMN gtwatch_version TEXT;

-- Segments the worker could not diagnose, with the reason (never silently dropped).
CREATE TABLE undiagnosable (
    id              INTEGER PRIMARY KEY,
    segment_id      INTEGER NOT NULL REFERENCES segments(id),
    method          TEXT,                 -- NULL: the segment as a whole; 'A'/'B': that method
    reason          TEXT    NOT NULL,     -- aborted, gaps, missing_signals, residual_too_high, error
    detail          TEXT    NOT NULL DEFAULT '',
    config_hash     TEXT,
    gtwatch_version TEXT,
    created_at_ms   INTEGER NOT NULL
);
CREATE INDEX undiagnosable_by_segment ON undiagnosable(segment_id);

-- The worker's queue: closed start-ups with neither a result nor a recorded reason.
CREATE VIEW v_diagnosis_queue AS
SELECT g.id AS segment_id, g.start_ms, g.end_ms, g.outcome, g.has_gap
FROM segments g
WHERE g.kind = 'startup' AND g.status = 'closed'
  AND NOT EXISTS (SELECT 1 FROM diagnoses d WHERE d.segment_id = g.id)
  AND NOT EXISTS (SELECT 1 FROM undiagnosable u WHERE u.segment_id = g.id)
ORDER BY g.start_ms;

-- The trend views gain the result's quality and what it can be reproduced from.
DROP VIEW v_latest_health;
DROP VIEW v_health_trend;

CREATE VIEW v_health_trend AS
SELECT d.id AS diagnosis_id, d.segment_id, g.start_ms AS segment_start_ms,
       strftime('%Y-%m-%dT%H:%M:%fZ', g.start_ms / 1000.0, 'unixepoch') AS segment_start_utc,
       g.outcome, g.hot_restart, d.method,
       d.d_gc, d.d_ec, d.d_gt, d.d_et, d.d_gp, d.d_ep,
       d.sigma_gc, d.sigma_ec, d.sigma_gt, d.sigma_et, d.sigma_gp, d.sigma_ep,
       d.objective, d.residual_level, d.fit_quality, d.model_version, d.config_hash,
       d.gtwatch_version, d.seed, d.created_at_ms
FROM diagnoses d JOIN segments g ON g.id = d.segment_id
ORDER BY g.start_ms, d.method, d.created_at_ms;

CREATE VIEW v_latest_health AS
SELECT h.* FROM v_health_trend h
WHERE h.diagnosis_id = (
    SELECT d2.id FROM diagnoses d2 JOIN segments g2 ON g2.id = d2.segment_id
    WHERE d2.method = h.method
    ORDER BY g2.start_ms DESC, d2.created_at_ms DESC, d2.id DESC LIMIT 1);
