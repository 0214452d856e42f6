-- gtwatch schema, version 7: retention roll-ups (issue 24 item 2, README "Storage tiers").
-- Steady operation older than `[storage] raw_days` (outside every start-up segment ± 
-- `segment_margin_s`) is replaced by one row per tag and minute here; its raw samples are
-- deleted from both tiers in the same transaction (`Store::apply_retention`).
-- Only good samples (quality 0) count in min/mean/max/last and n_good; n_all counts every
-- raw sample the minute held. min/mean/max/last are NULL when the minute had no good sample.

CREATE TABLE rollups_1m (
    tag_id  INTEGER NOT NULL REFERENCES tags(id),
    t_ms    INTEGER NOT NULL CHECK (t_ms % 60000 = 0),  -- start of the minute, Unix ms UTC
    n_good  INTEGER NOT NULL CHECK (n_good >= 0),       -- good samples in the minute
    n_all   INTEGER NOT NULL CHECK (n_all >= n_good AND n_all > 0),  -- all samples
    min     REAL,                                       -- of the good values
    mean    REAL,
    max     REAL,
    last    REAL,                                       -- the minute's last good value
    last_ms INTEGER,                                    -- and its time
    PRIMARY KEY (tag_id, t_ms)
) WITHOUT ROWID;

-- One row per tag and minute, for sqlite3 and Grafana's SQLite data source:
--   SELECT time_utc, mean FROM samples_1m WHERE tag = 'power_mw' ORDER BY t_ms;
CREATE VIEW samples_1m AS
SELECT t.name AS tag, t.unit, r.t_ms,
       strftime('%Y-%m-%dT%H:%M:%SZ', r.t_ms / 1000, 'unixepoch') AS time_utc,
       r.min, r.mean, r.max, r.last, r.n_good, r.n_all
FROM rollups_1m r JOIN tags t ON t.id = r.tag_id;
