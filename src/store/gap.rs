//! Stored gap analyses (`gap_analyses`, migration 0004): one row per `gtwatch gap --segment`
//! run, the verdict's numbers as columns and the whole report as JSON. Knows nothing of how the
//! analysis is made (`crate::gap`); only stores and reads what it is given.

use super::{now_ms, Store, StoreError};
use rusqlite::params;

/// A gap analysis to store.
#[derive(Debug, Clone, PartialEq)]
pub struct NewGapAnalysis {
    pub segment_id: i64,
    pub holdout_segment_id: Option<i64>,
    pub effect: String,
    pub shrinkage: f64,
    pub confidence: f64,
    pub baseline_fit_quality: String,
    pub normalised_residual: f64,
    pub report_json: String,
}

/// A stored gap analysis (the columns, without the JSON report).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct GapAnalysisRow {
    pub id: i64,
    pub segment_id: i64,
    pub holdout_segment_id: Option<i64>,
    pub effect: String,
    pub shrinkage: f64,
    pub confidence: f64,
    pub baseline_fit_quality: String,
    pub normalised_residual: f64,
    pub created_at_ms: i64,
    /// Start of the analysed segment (Unix ms).
    pub segment_start_ms: i64,
    /// The input instruments an `ambiguous` verdict names (`verdict.aliases` of the stored
    /// report; empty for other verdicts and for reports stored before it existed).
    pub aliases: Vec<String>,
    /// The candidate an `ambiguous` verdict doubted (`verdict.doubted`): it explained the
    /// residual but needed a less plausible health. `None` otherwise.
    pub doubted: Option<String>,
}

const ROW_COLUMNS: &str = concat!(
    "g.id, g.segment_id, g.holdout_segment_id, g.effect, g.shrinkage,
    g.confidence, g.baseline_fit_quality, g.normalised_residual, g.created_at_ms, s.start_ms,
    json_extract(g.report_json, '$.verdict.aliases'), ",
    doubted_sql!("g"),
    "
    FROM gap_analyses g JOIN segments s ON s.id = g.segment_id"
);

fn row(r: &rusqlite::Row<'_>) -> rusqlite::Result<GapAnalysisRow> {
    Ok(GapAnalysisRow {
        id: r.get(0)?,
        segment_id: r.get(1)?,
        holdout_segment_id: r.get(2)?,
        effect: r.get(3)?,
        shrinkage: r.get(4)?,
        confidence: r.get(5)?,
        baseline_fit_quality: r.get(6)?,
        normalised_residual: r.get(7)?,
        created_at_ms: r.get(8)?,
        segment_start_ms: r.get(9)?,
        // A report that is not the JSON this version writes reads as naming nothing.
        aliases: r
            .get::<_, Option<String>>(10)
            .ok()
            .flatten()
            .and_then(|j| serde_json::from_str(&j).ok())
            .unwrap_or_default(),
        doubted: r.get::<_, Option<String>>(11).ok().flatten(),
    })
}

/// Which start-ups the daemon's gap analysis looks at ([`Store::segments_for_gap`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GapSelection {
    /// Start-ups whose Method B fit is stored as not `good`, or refused as `residual_too_high`.
    pub not_good: bool,
    /// Also every `every_n`-th start-up with a Method B result (by segment id; 0 = none).
    pub every_n: u32,
}

impl Store {
    /// Start-ups without a stored gap analysis that `sel` selects, oldest first, at most
    /// `limit`.
    pub fn segments_for_gap(
        &self,
        sel: GapSelection,
        limit: usize,
    ) -> Result<Vec<i64>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT s.id FROM segments s
             WHERE NOT EXISTS (SELECT 1 FROM gap_analyses a WHERE a.segment_id = s.id)
               AND ((?1 AND (EXISTS (SELECT 1 FROM diagnoses d WHERE d.segment_id = s.id
                                       AND d.method = 'B' AND d.fit_quality IS NOT NULL
                                       AND d.fit_quality <> 'good')
                             OR EXISTS (SELECT 1 FROM undiagnosable u
                                        WHERE u.segment_id = s.id AND u.method = 'B'
                                          AND u.reason = 'residual_too_high')))
                    OR (?2 > 0 AND s.id % ?2 = 0
                        AND EXISTS (SELECT 1 FROM diagnoses d WHERE d.segment_id = s.id
                                      AND d.method = 'B')))
             ORDER BY s.start_ms, s.id LIMIT ?3",
        )?;
        let limit = i64::try_from(limit).unwrap_or(i64::MAX);
        let rows = st.query_map(params![sel.not_good, sel.every_n, limit], |r| r.get(0))?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Stores one analysis; returns its id.
    pub fn insert_gap_analysis(&mut self, g: &NewGapAnalysis) -> Result<i64, StoreError> {
        self.conn.execute(
            "INSERT INTO gap_analyses (segment_id, holdout_segment_id, effect, shrinkage,
                confidence, baseline_fit_quality, normalised_residual, report_json,
                gtwatch_version, created_at_ms)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
            params![
                g.segment_id,
                g.holdout_segment_id,
                g.effect,
                g.shrinkage,
                g.confidence,
                g.baseline_fit_quality,
                g.normalised_residual,
                g.report_json,
                env!("CARGO_PKG_VERSION"),
                now_ms(),
            ],
        )?;
        Ok(self.conn.last_insert_rowid())
    }

    /// The whole report (JSON) of a segment's newest analysis, if it has one.
    pub fn newest_gap_report_json(&self, segment_id: i64) -> Result<Option<String>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT report_json FROM gap_analyses WHERE segment_id = ?1 ORDER BY id DESC LIMIT 1",
        )?;
        let mut rows = st.query_map(params![segment_id], |r| r.get::<_, String>(0))?;
        Ok(rows.next().transpose()?)
    }

    /// The analyses of a segment, newest first.
    pub fn gap_analyses(&self, segment_id: i64) -> Result<Vec<GapAnalysisRow>, StoreError> {
        let mut st = self.conn.prepare_cached(&format!(
            "SELECT {ROW_COLUMNS} WHERE g.segment_id = ?1 ORDER BY g.id DESC"
        ))?;
        let rows = st.query_map(params![segment_id], row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// The analyses of segments starting in `[from_ms, to_ms]`, newest segment first, at most
    /// `limit`.
    pub fn gap_analyses_between(
        &self,
        from_ms: i64,
        to_ms: i64,
        limit: usize,
    ) -> Result<Vec<GapAnalysisRow>, StoreError> {
        let mut st = self.conn.prepare_cached(&format!(
            "SELECT {ROW_COLUMNS} WHERE s.start_ms BETWEEN ?1 AND ?2
             ORDER BY s.start_ms DESC, g.id DESC LIMIT ?3"
        ))?;
        let rows = st.query_map(
            params![from_ms, to_ms, i64::try_from(limit).unwrap_or(i64::MAX)],
            row,
        )?;
        Ok(rows.collect::<Result<_, _>>()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_analysis_is_stored_and_read_back_by_segment() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut store = Store::open(&dir.path().join("g.db")).expect("open");
        store
            .conn
            .execute(
                "INSERT INTO segments (kind, start_ms, end_ms, outcome, status, updated_at_ms)
                 VALUES ('startup', 1000, 2000, 'completed', 'closed', 0)",
                [],
            )
            .expect("segment");
        let seg = store.conn.last_insert_rowid();
        let g = NewGapAnalysis {
            segment_id: seg,
            holdout_segment_id: None,
            effect: "sensor_lag:t34_k".into(),
            shrinkage: 0.6,
            confidence: 0.5,
            baseline_fit_quality: "suspect".into(),
            normalised_residual: 1.3,
            report_json: "{}".into(),
        };
        let id = store.insert_gap_analysis(&g).expect("insert");
        let rows = store.gap_analyses(seg).expect("read");
        assert_eq!(rows.len(), 1);
        assert_eq!(
            (rows[0].id, rows[0].effect.as_str()),
            (id, "sensor_lag:t34_k")
        );
        assert_eq!(rows[0].shrinkage, 0.6);
        assert_eq!(rows[0].segment_start_ms, 1000);
        assert!(store.gap_analyses(seg + 1).expect("read").is_empty());
        assert_eq!(
            store.gap_analyses_between(0, 5000, 10).expect("between"),
            rows
        );
        assert!(store
            .gap_analyses_between(1001, 5000, 10)
            .expect("between")
            .is_empty());
        assert!(
            rows[0].aliases.is_empty(),
            "a report without verdict aliases"
        );
        // An ambiguous verdict's instruments, and the candidate it doubted, are read from its
        // report.
        let amb = NewGapAnalysis {
            effect: "ambiguous".into(),
            report_json:
                r#"{"verdict":{"effect":"ambiguous","aliases":["fuel_meter","inlet_temperature"],"doubted":"fuel_meter_offset"}}"#
                    .into(),
            ..g.clone()
        };
        store.insert_gap_analysis(&amb).expect("insert");
        let newest = &store.gap_analyses(seg).expect("read")[0];
        assert_eq!(newest.aliases, ["fuel_meter", "inlet_temperature"]);
        assert_eq!(newest.doubted.as_deref(), Some("fuel_meter_offset"));
        assert_eq!(
            rows[0].doubted, None,
            "a report without a doubted candidate"
        );
        // A row must name a real segment.
        let bad = NewGapAnalysis {
            segment_id: seg + 99,
            ..g
        };
        assert!(store.insert_gap_analysis(&bad).is_err());
    }
}
