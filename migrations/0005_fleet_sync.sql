-- gtwatch schema, version 5: the fleet sync's high-water marks (`[fleet]`, src/fleet).
-- One row per (centre, unit, stream): how far this edge's rows have been committed at that
-- central PostgreSQL database. Advanced only after the centre committed the batch, so a crash
-- in between re-sends (idempotent there) and never skips. A new centre starts from nothing.

CREATE TABLE fleet_sync (
    centre        TEXT    NOT NULL,            -- the centre's own id (its `centre` table)
    unit_id       TEXT    NOT NULL,            -- [fleet] unit_id the rows were sent as
    stream        TEXT    NOT NULL,            -- segments, diagnoses, gap_analyses, recommendations, samples
    mark_a        INTEGER NOT NULL DEFAULT 0,  -- last key sent: id; segments updated_at_ms; samples segment id
    mark_b        INTEGER NOT NULL DEFAULT 0,  -- segments: id; samples: tag id (max = window done)
    mark_c        INTEGER NOT NULL DEFAULT 0,  -- samples: t_ms
    sent          INTEGER NOT NULL DEFAULT 0,  -- rows sent over all syncs
    synced_at_ms  INTEGER NOT NULL,
    PRIMARY KEY (centre, unit_id, stream)
) WITHOUT ROWID;
