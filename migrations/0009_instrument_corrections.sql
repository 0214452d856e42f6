-- gtwatch schema, version 9: health corrected for an instrument's step (issue 23 item 4).
-- Each refresh of the wash advice fits the Method B results since the last firm wash jointly
-- (src/gap/sequence); when it names an instrument (a fuel meter reading high from start-up k
-- on), the health of start-up k and later is the fitted one minus that instrument's signature.
-- One row per start-up so corrected; the refresh replaces the rows of the start-ups it fitted in
-- the same transaction as its advice, so a row is what the newest joint fit said, and start-ups
-- before the last firm wash keep what was said when they were fitted.
-- `gtwatch history` shows them beside the stored health, which is never overwritten.

CREATE TABLE instrument_corrections (
    segment_id        INTEGER PRIMARY KEY REFERENCES segments(id),
    onset_segment_id  INTEGER NOT NULL REFERENCES segments(id),  -- first start-up of the step
    effect            TEXT    NOT NULL,   -- the instrument (`fuel_meter`, `inlet_temperature`, ...)
    unit              TEXT    NOT NULL,   -- of magnitude: 'fraction', 'K', 'kPa', ...
    magnitude         REAL    NOT NULL,   -- the instrument's error, fitted
    magnitude_sigma   REAL    NOT NULL,   -- its 1σ
    d_gc REAL NOT NULL, d_ec REAL NOT NULL, d_gt REAL NOT NULL,  -- corrected health, percent
    d_et REAL NOT NULL, d_gp REAL NOT NULL, d_ep REAL NOT NULL,
    sigma_gc REAL NOT NULL, sigma_ec REAL NOT NULL, sigma_gt REAL NOT NULL,  -- its 1σ
    sigma_et REAL NOT NULL, sigma_gp REAL NOT NULL, sigma_ep REAL NOT NULL,
    refreshed_ms      INTEGER NOT NULL    -- newest result the joint fit saw (Unix ms)
);
