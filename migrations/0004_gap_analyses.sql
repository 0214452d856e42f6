-- gtwatch schema, version 4: sim-to-real gap analyses (`gtwatch gap --segment`, src/gap).

CREATE TABLE gap_analyses (
    id                   INTEGER PRIMARY KEY,
    segment_id           INTEGER NOT NULL REFERENCES segments(id),
    holdout_segment_id   INTEGER REFERENCES segments(id),   -- scored on this start-up, if any
    effect               TEXT    NOT NULL,   -- winning effect instance, 'unexplained' or 'none'
    shrinkage            REAL    NOT NULL,   -- 1 - SSR(with effect)/SSR(baseline), 0..1
    confidence           REAL    NOT NULL,   -- score margin over the runner-up
    baseline_fit_quality TEXT    NOT NULL,   -- 'good', 'suspect' or 'poor'
    normalised_residual  REAL    NOT NULL,   -- baseline SSR per compared sample (noise units)
    report_json          TEXT    NOT NULL,   -- the whole report (localisation, candidates, verdict)
    gtwatch_version      TEXT    NOT NULL,
    created_at_ms        INTEGER NOT NULL
);
CREATE INDEX gap_analyses_by_segment ON gap_analyses(segment_id);
