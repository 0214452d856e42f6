-- gtwatch schema, version 6: the archive tier (issue 24, README "Storage tiers").
-- Old samples move from `samples` (the hot tier, one row each) into compressed per-tag chunks
-- here, in the same file. A sample is in exactly one tier: `Store::compact` inserts a chunk
-- and deletes its hot rows in one transaction. Readers go through the store, which merges
-- both tiers; the views v_samples and v_tag_latest show the hot tier only (SQL cannot decode
-- the blobs).

CREATE TABLE archive_chunks (
    id         INTEGER PRIMARY KEY,
    tag_id     INTEGER NOT NULL REFERENCES tags(id),
    t_start_ms INTEGER NOT NULL,                -- time of the chunk's first sample
    t_end_ms   INTEGER NOT NULL CHECK (t_end_ms >= t_start_ms),  -- and of its last
    n          INTEGER NOT NULL CHECK (n > 0),  -- samples in the chunk
    codec      INTEGER NOT NULL,                -- 1: pco streams (src/store/archive/codec.rs)
    t_blob     BLOB    NOT NULL,                -- times, i64 ms
    v_blob     BLOB    NOT NULL,                -- values, f64, bit-exact
    q_blob     BLOB    NOT NULL,                -- quality codes 0..4
    UNIQUE (tag_id, t_start_ms)
);
CREATE INDEX archive_chunks_by_end ON archive_chunks(tag_id, t_end_ms);
