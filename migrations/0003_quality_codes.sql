-- gtwatch schema, version 3: more sample quality codes (issue 12, one bad-value policy).
-- Codes 0-2 keep their meaning; 3 stuck (frozen sensor), 4 spike (isolated jump beyond the
-- signal's rate limit). SQLite cannot change a CHECK constraint in place: the samples table is
-- rebuilt (same columns, same primary key) and the views that read it are recreated unchanged.

DROP VIEW v_samples;
DROP VIEW v_tag_latest;

CREATE TABLE samples_v3 (
    tag_id  INTEGER NOT NULL REFERENCES tags(id),
    t_ms    INTEGER NOT NULL,
    value   REAL    NOT NULL,
    quality INTEGER NOT NULL DEFAULT 0 CHECK (quality BETWEEN 0 AND 4),  -- 0 good, 1 out of range, 2 bad (NaN/inf/undecodable), 3 stuck, 4 spike
    PRIMARY KEY (tag_id, t_ms)
) WITHOUT ROWID;
INSERT INTO samples_v3 (tag_id, t_ms, value, quality) SELECT tag_id, t_ms, value, quality FROM samples;
DROP TABLE samples;
ALTER TABLE samples_v3 RENAME TO samples;

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
