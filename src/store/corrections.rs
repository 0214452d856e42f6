//! Health corrected for an instrument's step (`instrument_corrections`, migration 0009): what
//! the newest joint fit of the start-ups since the last firm wash (`advice`, `gap::sequence`)
//! made of the start-ups an instrument's error moved, e.g. a fuel meter reading 3 % high from
//! start-up k on. Written in the wash advice's transaction ([`Store::store_advice`]), read by
//! `history` beside the stored health, which it never replaces.
//!
//! SQL only: the correction is computed in `advice`; this module stores and reads it.

use super::{Store, StoreError};
use crate::health::HEALTH_NAMES;
use rusqlite::{params, Transaction};
use serde::Serialize;

/// One start-up's health corrected for an instrument's error.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InstrumentCorrection {
    pub segment_id: i64,
    /// The first start-up of the step (the instrument's error is taken to start there).
    pub onset_segment_id: i64,
    /// The instrument (`fuel_meter`, `inlet_temperature`, `sensor_bias:p1_kpa`, …).
    pub effect: String,
    /// Unit of `magnitude`: `fraction`, `K`, `kPa`, …
    pub unit: String,
    /// The instrument's error, fitted jointly over the start-ups, and its 1σ.
    pub magnitude: f64,
    pub magnitude_sigma: f64,
    /// Corrected health, percent (`HEALTH_NAMES` order), and its 1σ.
    pub health: [f64; 6],
    pub sigma: [f64; 6],
    /// The other instruments the health is corrected for, when several steps moved this
    /// start-up: each as [`InstrumentCorrection::describe`] says it, with its onset
    /// (`fuel_meter +3.03 ± 0.25 % from start-up 6`), '; '-joined; empty when none.
    pub also: String,
}

impl InstrumentCorrection {
    /// The error as people read it: a fraction in %, else in its unit (`fuel_meter +2.57 ±
    /// 0.21 %`).
    pub fn describe(&self) -> String {
        let (m, s, u) = if self.unit == "fraction" {
            (100.0 * self.magnitude, 100.0 * self.magnitude_sigma, "%")
        } else {
            (self.magnitude, self.magnitude_sigma, self.unit.as_str())
        };
        format!("{} {m:+.2} ± {s:.2} {u}", self.effect)
    }

    /// [`Self::describe`] with the other instruments the health is corrected for, if any.
    pub fn describe_all(&self) -> String {
        if self.also.is_empty() {
            self.describe()
        } else {
            format!("{}; also {}", self.describe(), self.also)
        }
    }
}

/// What one refresh of the advice says about corrections: the start-ups its joint fit saw (their
/// rows are replaced) and the corrections among them (none when no instrument was named).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CorrectionsWrite {
    pub fitted_segments: Vec<i64>,
    pub rows: Vec<InstrumentCorrection>,
    /// Start of the newest result the joint fit saw, Unix ms.
    pub refreshed_ms: i64,
}

/// Replaces the rows of `w.fitted_segments` by `w.rows`, inside the advice's transaction.
pub(super) fn replace(tx: &Transaction<'_>, w: &CorrectionsWrite) -> Result<(), StoreError> {
    for id in &w.fitted_segments {
        tx.execute(
            "DELETE FROM instrument_corrections WHERE segment_id = ?1",
            params![id],
        )?;
    }
    let mut st = tx.prepare_cached(concat!(
        "INSERT INTO instrument_corrections (segment_id, ",
        correction_columns!(""),
        ", refreshed_ms)
         VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17,
                 ?18, ?19, ?20)"
    ))?;
    for c in &w.rows {
        let h = &c.health;
        let s = &c.sigma;
        st.execute(params![
            c.segment_id,
            c.onset_segment_id,
            c.effect,
            c.unit,
            c.magnitude,
            c.magnitude_sigma,
            h[0],
            h[1],
            h[2],
            h[3],
            h[4],
            h[5],
            s[0],
            s[1],
            s[2],
            s[3],
            s[4],
            s[5],
            c.also,
            w.refreshed_ms
        ])?;
    }
    Ok(())
}

/// The correction from columns `first..first + 18` of `r` (`correction_columns!`, `segment_id`
/// given), `None` when the row has none (a LEFT JOIN's NULLs).
pub(super) fn from_row(
    r: &rusqlite::Row<'_>,
    segment_id: i64,
    first: usize,
) -> rusqlite::Result<Option<InstrumentCorrection>> {
    let Some(onset_segment_id) = r.get::<_, Option<i64>>(first)? else {
        return Ok(None);
    };
    let mut health = [0.0; 6];
    let mut sigma = [0.0; 6];
    for i in 0..HEALTH_NAMES.len() {
        health[i] = r.get(first + 5 + i)?;
        sigma[i] = r.get(first + 11 + i)?;
    }
    Ok(Some(InstrumentCorrection {
        segment_id,
        onset_segment_id,
        effect: r.get(first + 1)?,
        unit: r.get(first + 2)?,
        magnitude: r.get(first + 3)?,
        magnitude_sigma: r.get(first + 4)?,
        health,
        sigma,
        also: r.get(first + 17)?,
    }))
}

impl Store {
    /// Every stored correction, by start-up.
    pub fn instrument_corrections(&self) -> Result<Vec<InstrumentCorrection>, StoreError> {
        let mut st = self.conn.prepare(concat!(
            "SELECT segment_id, ",
            correction_columns!(""),
            " FROM instrument_corrections ORDER BY segment_id"
        ))?;
        let rows = st.query_map([], |r| from_row(r, r.get(0)?, 1))?;
        // onset_segment_id is NOT NULL: every row is a correction.
        let rows: Vec<Option<InstrumentCorrection>> = rows.collect::<Result<_, _>>()?;
        Ok(rows.into_iter().flatten().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::AdviceWrite;

    fn store_with_segments(n: i64) -> (tempfile::TempDir, Store) {
        let dir = tempfile::tempdir().expect("dir");
        let store = Store::open(&dir.path().join("c.db")).expect("db");
        for k in 0..n {
            store
                .conn()
                .execute(
                    "INSERT INTO segments (kind, start_ms, end_ms, outcome, status, updated_at_ms)
                     VALUES ('startup', ?1, ?2, 'completed', 'closed', 0)",
                    params![k * 1000, k * 1000 + 500],
                )
                .expect("segment");
        }
        (dir, store)
    }

    fn correction(segment_id: i64, onset: i64, magnitude: f64) -> InstrumentCorrection {
        InstrumentCorrection {
            segment_id,
            onset_segment_id: onset,
            effect: "fuel_meter".into(),
            unit: "fraction".into(),
            magnitude,
            magnitude_sigma: 0.002,
            health: [1.0, 0.5, -0.25, 0.5, 0.125, segment_id as f64],
            sigma: [0.1; 6],
            also: String::new(),
        }
    }

    fn write(store: &mut Store, fitted: &[i64], rows: Vec<InstrumentCorrection>) {
        store
            .store_advice(&AdviceWrite {
                corrections: Some(CorrectionsWrite {
                    fitted_segments: fitted.to_vec(),
                    rows,
                    refreshed_ms: 1,
                }),
                ..AdviceWrite::default()
            })
            .expect("write");
    }

    /// A refresh replaces what it fitted and nothing else: the start-ups before the last firm
    /// wash keep what an earlier joint fit said of them, and a step the newest fit no longer
    /// finds leaves no correction behind.
    #[test]
    fn a_refresh_replaces_the_corrections_of_the_start_ups_it_fitted_only() {
        let (_dir, mut store) = store_with_segments(6);
        write(
            &mut store,
            &[1, 2, 3],
            vec![correction(2, 2, 0.03), correction(3, 2, 0.03)],
        );
        assert_eq!(
            store.instrument_corrections().expect("read"),
            vec![correction(2, 2, 0.03), correction(3, 2, 0.03)]
        );
        // After a firm wash the joint fit sees 4..6 only: it finds another step from 5.
        write(&mut store, &[4, 5, 6], vec![correction(5, 5, -0.02)]);
        // A later refresh of the same start-ups finds no step any more.
        write(&mut store, &[4, 5, 6], Vec::new());
        assert_eq!(
            store.instrument_corrections().expect("read"),
            vec![correction(2, 2, 0.03), correction(3, 2, 0.03)]
        );
        // How `history` names the instrument's error.
        assert_eq!(
            correction(3, 2, 0.03).describe(),
            "fuel_meter +3.00 ± 0.20 %"
        );
        let k = InstrumentCorrection {
            unit: "K".into(),
            magnitude: 2.0,
            magnitude_sigma: 0.25,
            effect: "inlet_temperature".into(),
            ..correction(3, 2, 0.0)
        };
        assert_eq!(k.describe(), "inlet_temperature +2.00 ± 0.25 K");
    }
}
