-- gtwatch fleet centre, schema version 3 (src/fleet/rediagnose.rs, src/fleet/regap.rs): the
-- re-diagnosis queue also holds gap-analysis jobs (`gtwatch fleet rediagnose --gap`), and their
-- reports are stored once per (unit, start-up, engine/config hash).

-- A job is a diagnosis or a gap analysis of its start-up; one of each per hash.
ALTER TABLE rediagnosis_jobs
    ADD COLUMN kind TEXT NOT NULL DEFAULT 'diagnose' CHECK (kind IN ('diagnose', 'gap'));
ALTER TABLE rediagnosis_jobs DROP CONSTRAINT rediagnosis_jobs_unit_id_segment_id_config_hash_key;
ALTER TABLE rediagnosis_jobs
    ADD CONSTRAINT rediagnosis_jobs_unit_segment_hash_kind_key
    UNIQUE (unit_id, segment_id, config_hash, kind);

-- One gap analysis per (unit, segment, hash), written in the transaction that marks its job
-- done (only while the worker holds the lease): the columns of the edges' gap_analyses.
CREATE TABLE regap_analyses (
    unit_id              TEXT             NOT NULL,
    segment_id           BIGINT           NOT NULL,   -- the segment's edge id
    config_hash          TEXT             NOT NULL,
    job_id               BIGINT           NOT NULL REFERENCES rediagnosis_jobs (id),
    holdout_segment_id   BIGINT,                      -- NULL: blocked cross-validation
    effect               TEXT             NOT NULL,
    shrinkage            DOUBLE PRECISION,
    confidence           DOUBLE PRECISION,
    baseline_fit_quality TEXT             NOT NULL,
    normalised_residual  DOUBLE PRECISION,
    report_json          TEXT             NOT NULL,
    worker_id            TEXT             NOT NULL,
    wall_s               DOUBLE PRECISION NOT NULL,
    gtwatch_version      TEXT             NOT NULL,
    created_at           TIMESTAMPTZ      NOT NULL DEFAULT now(),
    PRIMARY KEY (unit_id, segment_id, config_hash),
    UNIQUE (job_id)
);
