-- gtwatch schema, version 8: hourly roll-ups, retention's second tier (issue 24, README
-- "Retention and roll-ups"). 1-minute roll-ups older than `[storage] rollup_1m_days` are merged
-- into one row per tag and hour here; the minute rows merged are deleted in the same
-- transaction (`Store::apply_retention`), so a minute is summarised either in `rollups_1m` or
-- in its hour's row here, never both.
-- Combined exactly from the minute rows: n_good and n_all are sums, min the min of the
-- minutes' mins, max the max of their maxes, mean the minutes' means weighted by n_good, last
-- (with last_ms) the latest good value. As in `rollups_1m` only good samples (quality 0) count
-- in min/mean/max/last and n_good; they are NULL when the hour had no good sample. An hour
-- holding a kept start-up window summarises only the minutes that were rolled up (the rest
-- stays raw).

CREATE TABLE rollups_1h (
    tag_id  INTEGER NOT NULL REFERENCES tags(id),
    t_ms    INTEGER NOT NULL CHECK (t_ms % 3600000 = 0),  -- start of the hour, Unix ms UTC
    n_good  INTEGER NOT NULL CHECK (n_good >= 0),         -- good samples in the hour
    n_all   INTEGER NOT NULL CHECK (n_all >= n_good AND n_all > 0),  -- all samples summarised
    min     REAL,                                         -- of the good values
    mean    REAL,
    max     REAL,
    last    REAL,                                         -- the hour's last good value
    last_ms INTEGER,                                      -- and its time
    PRIMARY KEY (tag_id, t_ms)
) WITHOUT ROWID;

-- One row per tag and hour, for sqlite3 and Grafana's SQLite data source:
--   SELECT time_utc, mean FROM samples_1h WHERE tag = 'power_mw' ORDER BY t_ms;
CREATE VIEW samples_1h AS
SELECT t.name AS tag, t.unit, r.t_ms,
       strftime('%Y-%m-%dT%H:%M:%SZ', r.t_ms / 1000, 'unixepoch') AS time_utc,
       r.min, r.mean, r.max, r.last, r.n_good, r.n_all
FROM rollups_1h r JOIN tags t ON t.id = r.tag_id;
