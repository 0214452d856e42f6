//! Washes and wash recommendations in the store: the operator's records, the washes the trend
//! detected (pending the operator's confirmation), and the advice with its basis.
//!
//! SQL only; what counts as a wash and when to wash next are decided in `trend` and `wash`.

use super::corrections::{self, CorrectionsWrite};
use super::{Store, StoreError};
use rusqlite::{params, OptionalExtension};
use serde::Serialize;

/// One stored wash.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WashRow {
    pub id: i64,
    pub t_ms: i64,
    /// "online" or "offline".
    pub kind: String,
    /// Free text; washes found in the trend start with [`DETECTED_PREFIX`].
    pub note: String,
}

impl WashRow {
    /// Whether the trend detected this wash (the operator did not record it).
    pub fn is_detected(&self) -> bool {
        self.note.starts_with(DETECTED_PREFIX)
    }
}

/// Note prefix of a wash detected as a recovery step in the health trend.
pub const DETECTED_PREFIX: &str = "detected:";

/// A wash to record.
#[derive(Debug, Clone, PartialEq)]
pub struct NewWash {
    pub t_ms: i64,
    pub kind: String,
    pub note: String,
}

/// A recommendation to store.
#[derive(Debug, Clone, PartialEq)]
pub struct NewRecommendation {
    pub t_ms: i64,
    pub kind: String,
    pub message: String,
    pub basis: String,
}

/// What one refresh of the wash advice writes ([`Store::store_advice`]): the washes the trend
/// detected, the new recommendation, if any, and the health corrected for an instrument's step
/// of the start-ups its joint fit saw, when that changed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AdviceWrite {
    pub washes: Vec<NewWash>,
    pub recommendation: Option<NewRecommendation>,
    pub corrections: Option<CorrectionsWrite>,
}

/// One stored recommendation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecommendationRow {
    pub id: i64,
    pub t_ms: i64,
    pub kind: String,
    pub message: String,
    /// JSON of what the advice rests on.
    pub basis: String,
}

impl Store {
    /// Records a wash; returns its id.
    pub fn record_wash(&mut self, t_ms: i64, kind: &str, note: &str) -> Result<i64, StoreError> {
        self.conn.execute(
            "INSERT INTO washes (t_ms, kind, note) VALUES (?1, ?2, ?3)",
            params![t_ms, kind, note],
        )?;
        Ok(self.conn.last_insert_rowid())
    }

    /// Removes a wash (an operator rejecting a detected one); true if it existed.
    pub fn delete_wash(&mut self, id: i64) -> Result<bool, StoreError> {
        Ok(self
            .conn
            .execute("DELETE FROM washes WHERE id = ?1", params![id])?
            > 0)
    }

    /// Removes a wash if the trend detected it, in one short transaction (the check and the
    /// delete see the same file, also beside a running daemon): the wash as it was, if any.
    pub fn reject_detected_wash(&mut self, id: i64) -> Result<Option<WashRow>, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let row = tx
            .query_row(
                "SELECT id, t_ms, kind, note FROM washes WHERE id = ?1",
                params![id],
                |r| {
                    Ok(WashRow {
                        id: r.get(0)?,
                        t_ms: r.get(1)?,
                        kind: r.get(2)?,
                        note: r.get(3)?,
                    })
                },
            )
            .optional()?;
        if row.as_ref().is_some_and(WashRow::is_detected) {
            tx.execute("DELETE FROM washes WHERE id = ?1", params![id])?;
        }
        tx.commit()?;
        Ok(row)
    }

    /// Stores one refresh of the wash advice in one transaction: the detected washes (their
    /// ids, in order), the recommendation and the corrected health.
    pub fn store_advice(&mut self, a: &AdviceWrite) -> Result<Vec<i64>, StoreError> {
        let tx = self
            .conn
            .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)?;
        let mut ids = Vec::with_capacity(a.washes.len());
        for w in &a.washes {
            tx.execute(
                "INSERT INTO washes (t_ms, kind, note) VALUES (?1, ?2, ?3)",
                params![w.t_ms, w.kind, w.note],
            )?;
            ids.push(tx.last_insert_rowid());
        }
        if let Some(r) = &a.recommendation {
            tx.execute(
                "INSERT INTO recommendations (t_ms, kind, message, basis) VALUES (?1, ?2, ?3, ?4)",
                params![r.t_ms, r.kind, r.message, r.basis],
            )?;
        }
        if let Some(c) = &a.corrections {
            corrections::replace(&tx, c)?;
        }
        tx.commit()?;
        Ok(ids)
    }

    /// Marks a detected wash as confirmed by the operator (its note loses the detected prefix).
    pub fn confirm_wash(&mut self, id: i64) -> Result<bool, StoreError> {
        let n = self.conn.execute(
            "UPDATE washes SET note = 'confirmed; ' || substr(note, ?2) WHERE id = ?1
               AND note LIKE 'detected:%'",
            params![id, DETECTED_PREFIX.len() as i64 + 1],
        )?;
        Ok(n > 0)
    }

    /// All washes, oldest first.
    pub fn washes(&self) -> Result<Vec<WashRow>, StoreError> {
        let mut st = self
            .conn
            .prepare_cached("SELECT id, t_ms, kind, note FROM washes ORDER BY t_ms, id")?;
        let rows = st.query_map([], |r| {
            Ok(WashRow {
                id: r.get(0)?,
                t_ms: r.get(1)?,
                kind: r.get(2)?,
                note: r.get(3)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Stores a recommendation; returns its id.
    pub fn insert_recommendation(
        &mut self,
        t_ms: i64,
        kind: &str,
        message: &str,
        basis: &str,
    ) -> Result<i64, StoreError> {
        self.conn.execute(
            "INSERT INTO recommendations (t_ms, kind, message, basis) VALUES (?1, ?2, ?3, ?4)",
            params![t_ms, kind, message, basis],
        )?;
        Ok(self.conn.last_insert_rowid())
    }

    /// The newest recommendation, if any.
    pub fn latest_recommendation(&self) -> Result<Option<RecommendationRow>, StoreError> {
        let mut st = self.conn.prepare_cached(
            "SELECT id, t_ms, kind, message, basis FROM recommendations
             ORDER BY t_ms DESC, id DESC LIMIT 1",
        )?;
        let mut rows = st.query_map([], |r| {
            Ok(RecommendationRow {
                id: r.get(0)?,
                t_ms: r.get(1)?,
                kind: r.get(2)?,
                message: r.get(3)?,
                basis: r.get(4)?,
            })
        })?;
        Ok(rows.next().transpose()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::Engine;
    use crate::store::{NewDiagnosis, NewGapAnalysis};
    use crate::trend::WashDetection;
    use crate::wash::{advise, sensitivity, FoulingTrend, WashEconomics};

    const DAY: i64 = 86_400_000;

    /// The wash advice refreshed with the default detection and health limits.
    fn refresh_advice(
        store: &mut Store,
        engine: &Engine,
        econ: &WashEconomics,
    ) -> crate::advice::AdviceReport {
        crate::advice::refresh(
            store,
            engine,
            econ,
            &WashDetection::default(),
            &crate::health::HealthBounds::default(),
        )
        .unwrap()
    }

    /// Every Method B result, as the gap task's selection reads them.
    fn history(store: &Store) -> Vec<crate::store::HistoryRow> {
        crate::worker::gap::method_b_history(store).unwrap()
    }

    /// A closed start-up at `start` with one `good` Method B result `health`; its segment id.
    fn insert_result(store: &mut Store, start: i64, health: [f64; 6]) -> i64 {
        insert_result_of_quality(store, start, health, "good")
    }

    fn insert_result_of_quality(
        store: &mut Store,
        start: i64,
        health: [f64; 6],
        fit_quality: &str,
    ) -> i64 {
        insert_result_with_residual(store, start, health, fit_quality, 0.8)
    }

    fn insert_result_with_residual(
        store: &mut Store,
        start: i64,
        health: [f64; 6],
        fit_quality: &str,
        residual_level: f64,
    ) -> i64 {
        store
            .conn
            .execute(
                "INSERT INTO segments (kind, start_ms, end_ms, outcome, status, updated_at_ms)
                 VALUES ('startup', ?1, ?2, 'completed', 'closed', 0)",
                params![start, start + 900_000],
            )
            .unwrap();
        let id = store.conn.last_insert_rowid();
        let d = NewDiagnosis {
            segment_id: id,
            method: "B".into(),
            health,
            sigma: [0.05, 0.03, 0.05, 0.05, 0.05, 0.05],
            objective: 1.0,
            residual_level,
            fit_quality: fit_quality.into(),
            model_runs: 300,
            wall_s: 5.0,
            seed: 1,
            config_hash: "h".into(),
            gtwatch_version: "test".into(),
        };
        store.insert_outcome(id, &[d], &[], "h").unwrap();
        id
    }

    /// A history of daily Method B results: D_GC grows 0.1 %/day (D_EC a third of it), an
    /// offline wash on day 12 resets both; small alternating noise.
    fn fill(store: &mut Store) {
        let t0 = 1_700_000_000_000_i64;
        for day in 0..24_i64 {
            let age = if day < 12 { day } else { day - 12 } as f64;
            let noise = if day % 2 == 0 { 0.02 } else { -0.02 };
            let health = [0.1 * age + noise, 0.1 / 3.0 * age, 0.2, 0.1, 0.0, 0.0];
            insert_result(store, t0 + day * DAY, health);
        }
    }

    /// The gap task's trigger (issue 23 items 3–4): the wash's recovery is no step; a day whose
    /// HP-turbine flow jumps 1.5 points against its trend is selected, and only it.
    #[test]
    fn a_health_step_against_the_trend_is_selected_and_a_wash_is_not() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("w.db")).unwrap();
        fill(&mut store);
        assert_eq!(crate::worker::gap::health_steps(&history(&store)), vec![]);
        let t0 = 1_700_000_000_000_i64;
        let stepped = insert_result(&mut store, t0 + 24 * DAY, [1.2, 0.4, 1.7, 0.1, 0.0, 0.0]);
        insert_result(&mut store, t0 + 25 * DAY, [1.3, 0.43, 0.2, 0.1, 0.0, 0.0]);
        let steps = crate::worker::gap::health_steps(&history(&store));
        assert_eq!(steps.len(), 1, "{steps:?}");
        assert_eq!(steps[0].0, stepped);
        assert_eq!(steps[0].1.len(), 1, "{steps:?}");
        assert_eq!(steps[0].1[0].param, 2);
    }

    /// A step that persists (an input instrument changed for good) is selected at its first
    /// start-up only, while the fouling goes on under it; a second step on top of it, and the
    /// step seen again after it went away, are new.
    #[test]
    fn a_persisting_step_is_selected_once() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("w.db")).unwrap();
        fill(&mut store);
        let t0 = 1_700_000_000_000_i64;
        // D_GC follows its trend (0.1 %/day since the wash on day 12); D_GT 1.5 points up
        // from day 24 on.
        let day = |store: &mut Store, d: i64, gt: f64, et: f64| {
            let age = (d - 12) as f64;
            insert_result(
                store,
                t0 + d * DAY,
                [0.1 * age, 0.1 / 3.0 * age, gt, et, 0.0, 0.0],
            )
        };
        let first = day(&mut store, 24, 1.7, 0.1);
        for d in 25..28 {
            day(&mut store, d, 1.7, 0.1);
        }
        let steps = crate::worker::gap::health_steps(&history(&store));
        assert_eq!(steps.len(), 1, "{steps:?}");
        assert_eq!(steps[0].0, first);
        // D_ET steps too on day 28: a new step, though D_GT's persists.
        let second = day(&mut store, 28, 1.7, 1.6);
        day(&mut store, 29, 1.7, 1.6);
        // Both back to the trend on day 30, then D_GT's step again on day 31: new.
        day(&mut store, 30, 0.2, 0.1);
        let again = day(&mut store, 31, 1.7, 0.1);
        let ids: Vec<i64> = crate::worker::gap::health_steps(&history(&store))
            .into_iter()
            .map(|(id, _)| id)
            .collect();
        assert_eq!(ids, vec![first, second, again]);
    }

    /// A poor fit that carries on one whose analysis named its cause (an instrument that
    /// stays wrong) is not analysed again; one with more residual, another health shift, after
    /// a good fit, or after an analysis that named nothing, is.
    #[test]
    fn a_persisting_misfit_is_analysed_once() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("w.db")).unwrap();
        fill(&mut store);
        let t0 = 1_700_000_000_000_i64;
        // D_GC on its trend (0.1 %/day since the wash on day 12); `gt` on top of D_GT's 0.2.
        let day = |store: &mut Store, d: i64, gt: f64, quality: &str, residual: f64| {
            let age = (d - 12) as f64;
            let health = [0.1 * age, 0.1 / 3.0 * age, 0.2 + gt, 0.1, 0.0, 0.0];
            insert_result_with_residual(store, t0 + d * DAY, health, quality, residual)
        };
        let analysed = |store: &mut Store, id: i64, effect: &str| {
            store
                .insert_gap_analysis(&NewGapAnalysis {
                    segment_id: id,
                    holdout_segment_id: None,
                    effect: effect.into(),
                    shrinkage: 0.9,
                    confidence: 0.9,
                    baseline_fit_quality: "suspect".into(),
                    normalised_residual: 3.0,
                    report_json: "{}".into(),
                })
                .unwrap();
        };
        let covered = |store: &Store| {
            let mut ids: Vec<i64> = crate::worker::gap::covered_poor_fits(&history(store))
                .into_iter()
                .collect();
            ids.sort_unstable();
            ids
        };
        let first = day(&mut store, 24, 1.5, "suspect", 3.0);
        let same = day(&mut store, 25, 1.5, "suspect", 3.3);
        let worse = day(&mut store, 26, 1.5, "suspect", 6.0);
        // Nothing is covered before the first is analysed.
        assert_eq!(covered(&store), Vec::<i64>::new());
        analysed(&mut store, first, "fuel_meter");
        assert_eq!(covered(&store), vec![same]);
        // Back to a good fit on the trend: the misfit after it is a new run.
        day(&mut store, 27, 0.0, "good", 0.8);
        let again = day(&mut store, 28, 1.5, "suspect", 3.0);
        analysed(&mut store, again, "ambiguous");
        let after_ambiguous = day(&mut store, 29, 1.5, "suspect", 3.0);
        day(&mut store, 30, 0.0, "good", 0.8);
        let third = day(&mut store, 31, 1.5, "poor", 3.0);
        analysed(&mut store, third, "inlet_temperature");
        let shifted = day(&mut store, 32, 3.5, "poor", 3.0);
        let covered_now = covered(&store);
        assert_eq!(
            covered_now,
            vec![same],
            "worse {worse}, after an ambiguous {after_ambiguous}, shifted {shifted}"
        );
    }

    #[test]
    fn wash_detected_on_its_day_and_advice_recomputes_from_the_stored_basis() {
        let dir = tempfile::tempdir().unwrap();
        let mut store = Store::open(&dir.path().join("w.db")).unwrap();
        fill(&mut store);
        let engine = Engine::reference().unwrap();
        let econ = WashEconomics::default();
        let r = refresh_advice(&mut store, &engine, &econ);
        // The wash is found between day 11 and day 12, and only there.
        let washes = store.washes().unwrap();
        assert_eq!(washes.len(), 1, "{washes:?}");
        assert!(washes[0].is_detected());
        let t0 = 1_700_000_000_000_i64;
        assert_eq!(washes[0].t_ms, t0 + 12 * DAY - 1);
        assert_eq!(r.results_since_wash, 12);
        // Trend since the wash: 0.1 %/day D_GC.
        let gc = r.trends[0].fit.unwrap();
        assert!((gc.rate_per_day - 0.1).abs() < 0.01, "{gc:?}");
        // Recompute the advised date from the stored basis (trend and prices) and the engine.
        let rec = store.latest_recommendation().unwrap().unwrap();
        let basis: serde_json::Value = serde_json::from_str(&rec.basis).unwrap();
        let tr = &basis["trend"];
        let f = |k: &str| tr[k].as_f64().unwrap();
        let trend = FoulingTrend {
            age_days: f("age_days"),
            d_gc_now: f("d_gc_now"),
            d_ec_now: f("d_ec_now"),
            d_gc_rate: f("d_gc_rate"),
            d_gc_rate_sigma: f("d_gc_rate_sigma"),
            d_ec_rate: f("d_ec_rate"),
            d_ec_rate_sigma: f("d_ec_rate_sigma"),
        };
        let econ2: WashEconomics = serde_json::from_value(basis["economics"].clone()).unwrap();
        let again = advise(&trend, &sensitivity(&engine).unwrap(), &econ2);
        let stored_days = basis["advice"]["advised_days"].as_f64().unwrap();
        assert_eq!(again.advised_days, Some(stored_days));
        assert_eq!(
            r.advised_ms,
            Some(washes[0].t_ms + (stored_days * DAY as f64).round() as i64)
        );
        // A second refresh records no second wash.
        refresh_advice(&mut store, &engine, &econ);
        assert_eq!(store.washes().unwrap().len(), 1);
    }

    /// A result whose fit is `poor` (here a start-up with heat soak the model lacks: the health
    /// points off on every turbine) is left out of the trends and listed: the advice is the
    /// one without it. Stored as `good`, the same health moves the advice, so the test means
    /// something.
    #[test]
    fn a_poorly_fitting_start_up_does_not_move_the_advice() {
        let engine = Engine::reference().unwrap();
        let econ = WashEconomics::default();
        let t0 = 1_700_000_000_000_i64;
        let advice_with = |odd: Option<&str>| {
            let dir = tempfile::tempdir().unwrap();
            let mut store = Store::open(&dir.path().join("p.db")).unwrap();
            fill(&mut store);
            let mut odd_id = None;
            for day in 24..30_i64 {
                let age = (day - 12) as f64;
                let health = [0.1 * age, 0.1 / 3.0 * age, 0.2, 0.1, 0.0, 0.0];
                insert_result(&mut store, t0 + day * DAY, health);
                if day == 26 {
                    if let Some(q) = odd {
                        let off = [-1.45, 0.48, -2.99, 0.58, -3.0, 4.05];
                        let at = t0 + day * DAY + DAY / 2;
                        odd_id = Some(insert_result_of_quality(&mut store, at, off, q));
                    }
                }
            }
            (refresh_advice(&mut store, &engine, &econ), odd_id)
        };
        let (without, _) = advice_with(None);
        let (poor, poor_id) = advice_with(Some("poor"));
        let (as_good, _) = advice_with(Some("good"));
        assert!(without.poor_fits.is_empty());
        let listed: Vec<i64> = poor.poor_fits.iter().map(|p| p.segment_id).collect();
        assert_eq!(listed, poor_id.into_iter().collect::<Vec<_>>());
        assert_eq!(poor.advised_ms, without.advised_ms);
        assert_eq!(poor.results_since_wash, without.results_since_wash);
        assert_ne!(
            as_good.advised_ms, without.advised_ms,
            "the odd health must move the advice when used, for this test to mean anything"
        );
    }

    /// Issue 23 item 4: a start-up whose stored gap analysis names an instrument's error (or
    /// doubts one, `ambiguous` with `verdict.doubted`) is set aside by the wash advice, so the
    /// step that instrument made does not move the advice; the same step without the analysis,
    /// or with an `ambiguous` one that doubted nothing, does.
    #[test]
    fn a_step_an_instrument_explains_does_not_move_the_advice() {
        let engine = Engine::reference().unwrap();
        let econ = WashEconomics::default();
        let t0 = 1_700_000_000_000_i64;
        // From day 24 on, a fuel meter reading high makes every start-up look 2 points more
        // fouled; `analysed`: the gap task analysed those start-ups and stored the meter.
        let advice_with = |step: bool, analysed: Option<(&str, &str)>| {
            let dir = tempfile::tempdir().unwrap();
            let mut store = Store::open(&dir.path().join("w.db")).unwrap();
            fill(&mut store);
            let extra = if step { 2.0 } else { 0.0 };
            let mut stepped = Vec::new();
            for day in 24..28_i64 {
                let age = (day - 12) as f64;
                let health = [
                    0.1 * age + extra,
                    0.1 / 3.0 * age + extra / 3.0,
                    0.2,
                    0.1,
                    0.0,
                    0.0,
                ];
                let seg = insert_result(&mut store, t0 + day * DAY, health);
                stepped.push(seg);
                if let Some((effect, report_json)) = analysed {
                    store
                        .insert_gap_analysis(&crate::store::NewGapAnalysis {
                            segment_id: seg,
                            holdout_segment_id: None,
                            effect: effect.into(),
                            shrinkage: 0.8,
                            confidence: 0.6,
                            baseline_fit_quality: "good".into(),
                            normalised_residual: 1.1,
                            report_json: report_json.into(),
                        })
                        .unwrap();
                }
            }
            let r = refresh_advice(&mut store, &engine, &econ);
            (r, stepped)
        };
        let (clean, _) = advice_with(false, None);
        let (explained, stepped) = advice_with(true, Some(("fuel_meter", "{}")));
        let (unexplained, _) = advice_with(true, None);
        // An `ambiguous` verdict that doubted an instrument (the meter's offset, with the
        // meter's scale hidden behind the health) sets the start-ups aside as well; one that
        // only lists what could hide behind a good fit does not.
        let doubted = r#"{"verdict":{"effect":"ambiguous","doubted":"fuel_meter_offset","aliases":["fuel_meter"]}}"#;
        let (doubted, _) = advice_with(true, Some(("ambiguous", doubted)));
        let hidden =
            r#"{"verdict":{"effect":"ambiguous","doubted":null,"aliases":["fuel_meter"]}}"#;
        let (hidden, _) = advice_with(true, Some(("ambiguous", hidden)));
        let aside: Vec<i64> = doubted.set_aside.iter().map(|a| a.segment_id).collect();
        assert_eq!(aside, stepped);
        assert!(doubted
            .set_aside
            .iter()
            .all(|a| a.effect == "fuel_meter_offset"));
        assert_eq!(doubted.advised_ms, explained.advised_ms);
        assert!(hidden.set_aside.is_empty());
        assert_eq!(hidden.advised_ms, unexplained.advised_ms);
        let days = |r: &crate::advice::AdviceReport| r.advised_ms.unwrap() as f64 / DAY as f64;
        let aside: Vec<i64> = explained.set_aside.iter().map(|a| a.segment_id).collect();
        assert_eq!(aside, stepped);
        assert!(explained.set_aside.iter().all(|a| a.effect == "fuel_meter"));
        assert_eq!(explained.results_since_wash, clean.results_since_wash - 4);
        assert!(unexplained.set_aside.is_empty());
        assert!(
            (days(&explained) - days(&clean)).abs() <= 1.0,
            "set aside: {:.2} d vs {:.2} d without the step",
            days(&explained),
            days(&clean)
        );
        assert!(
            (days(&unexplained) - days(&clean)).abs() > 1.0,
            "the step alone must move the advice for this test to mean anything: {:.2} d vs {:.2} d",
            days(&unexplained),
            days(&clean)
        );
    }
}
