//! Retention's second tier: 1-minute roll-ups older than `[storage] rollup_1m_days` are merged
//! into hourly roll-ups (`rollups_1h`, view `samples_1h`; README "Retention and roll-ups"), so
//! that a unit's file stops growing by 50 tags × 1 440 minute rows a day once retention
//! applies.
//!
//! Guarantees, as the minute tier's:
//! - **One transaction per batch** (one tag's minute rows of one aligned day, before the
//!   cutoff): the hourly rows are inserted (merged into an existing hour's row, should there be
//!   one) and exactly the minute rows read are deleted, checked, in ONE `IMMEDIATE`
//!   transaction: `kill -9` leaves every minute either in `rollups_1m` or in its hour's row of
//!   `rollups_1h`, never both, never neither.
//! - **Exact combination** ([`combine`]): `n_good`/`n_all` summed, min of the mins, max of the
//!   maxes, mean of the means weighted by `n_good`, last the latest good value; a minute
//!   without good samples adds to `n_all` only (NULL min/mean/max/last, as in `rollups_1m`).
//! - **Idempotent:** a second run finds no minute row before the cutoff.
//! - **The cutoff** is whole hours: `now − rollup_1m_days`, never after the minute tier's
//!   cutoff (an hour is merged only once every minute of it that can be rolled up is).
//!
//! Also checks its own setting (`[storage] rollup_1m_days`, [`StorageConfig::validate`]).
//!
//! Must not: touch raw samples (the minute tier's batches do), decide the policy, or hold the
//! write lock for more than one batch.

use super::{
    finish_mean, floor_to, insert_rollup, Batch, RetainStats, RetentionPolicy, Rollup, Span,
};
use crate::config_problem::{check_range, Bounds, ConfigProblem};
use crate::store::{StorageConfig, Store, StoreError, TagId};
use rusqlite::{params, Connection, TransactionBehavior};

/// One hour, the second tier's period.
pub const HOUR_MS: i64 = 3_600_000;

/// Minute rows merged per transaction: one tag's aligned day (1 440 rows at most).
const BATCH_SPAN_MS: i64 = 86_400_000;

/// Which roll-up table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RollupTier {
    /// `rollups_1m`.
    Minute,
    /// `rollups_1h`.
    Hour,
}

impl RollupTier {
    /// The period, ms.
    pub fn period_ms(self) -> i64 {
        match self {
            RollupTier::Minute => super::MINUTE_MS,
            RollupTier::Hour => HOUR_MS,
        }
    }
}

/// Minute rows before this are merged (whole hours), or None when `rollup_1m_days` is 0.
pub(super) fn cutoff(
    now_ms: i64,
    policy: &RetentionPolicy,
    minute_cut: Option<i64>,
) -> Option<i64> {
    if policy.rollup_1m_days == 0 {
        return None;
    }
    let age = now_ms.saturating_sub(i64::from(policy.rollup_1m_days).saturating_mul(86_400_000));
    Some(floor_to(minute_cut.map_or(age, |m| m.min(age)), HOUR_MS))
}

/// Combines time-ordered roll-ups into roll-ups of `period_ms` (a multiple of their period):
/// counts summed, min of the mins, max of the maxes, mean weighted by `n_good`, the latest
/// good `last`. Exact but for the mean's rounding.
pub fn combine(rows: &[Rollup], period_ms: i64) -> Vec<Rollup> {
    let mut out: Vec<Rollup> = Vec::new();
    // Σ mean × n_good of the current period.
    let mut sum = 0.0f64;
    for r in rows {
        let t = floor_to(r.t_ms, period_ms);
        if out.last().is_none_or(|o| o.t_ms != t) {
            finish_mean(out.last_mut(), sum);
            sum = 0.0;
            out.push(Rollup::empty(t));
        }
        let Some(o) = out.last_mut() else { continue };
        o.n_all += r.n_all;
        o.n_good += r.n_good;
        if let (Some(m), true) = (r.mean, r.n_good > 0) {
            sum += m * r.n_good as f64;
        }
        o.min = min_opt(o.min, r.min, f64::min);
        o.max = min_opt(o.max, r.max, f64::max);
        if let (Some(v), Some(at)) = (r.last, r.last_ms) {
            if o.last_ms.is_none_or(|prev| at >= prev) {
                o.last = Some(v);
                o.last_ms = Some(at);
            }
        }
    }
    finish_mean(out.last_mut(), sum);
    out
}

fn min_opt(a: Option<f64>, b: Option<f64>, pick: fn(f64, f64) -> f64) -> Option<f64> {
    match (a, b) {
        (Some(x), Some(y)) => Some(pick(x, y)),
        (x, None) => x,
        (None, y) => y,
    }
}

/// Every batch with minute rows before `cut`: per tag, the aligned days holding any.
pub(super) fn plan(conn: &Connection, cut: i64) -> Result<Vec<Batch>, StoreError> {
    let tags: Vec<TagId> = {
        let mut st = conn.prepare_cached("SELECT id FROM tags ORDER BY id")?;
        let rows = st.query_map([], |r| r.get(0))?;
        rows.collect::<Result<_, _>>()?
    };
    let mut first = conn.prepare_cached(
        "SELECT MIN(t_ms) FROM rollups_1m WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3",
    )?;
    let mut out = Vec::new();
    for tag in tags {
        let mut cur = i64::MIN;
        while cur < cut {
            let t: Option<i64> = first.query_row(params![tag, cur, cut], |r| r.get(0))?;
            let Some(t) = t else { break };
            let from = floor_to(t, BATCH_SPAN_MS);
            let span = Span {
                from,
                to: from.saturating_add(BATCH_SPAN_MS).min(cut),
            };
            out.push(Batch { tag, span });
            cur = span.to;
        }
    }
    Ok(out)
}

/// Minute rows of one tag in `[from, to)`, time-ordered.
fn read_rollups(
    conn: &Connection,
    tier: RollupTier,
    tag: TagId,
    span: Span,
) -> Result<Vec<Rollup>, StoreError> {
    let sql = match tier {
        RollupTier::Minute => {
            "SELECT t_ms, n_good, n_all, min, mean, max, last, last_ms FROM rollups_1m
             WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3 ORDER BY t_ms"
        }
        RollupTier::Hour => {
            "SELECT t_ms, n_good, n_all, min, mean, max, last, last_ms FROM rollups_1h
             WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3 ORDER BY t_ms"
        }
    };
    let mut st = conn.prepare_cached(sql)?;
    let rows = st.query_map(params![tag, span.from, span.to], |r| {
        Ok(Rollup {
            t_ms: r.get(0)?,
            n_good: r.get(1)?,
            n_all: r.get(2)?,
            min: r.get(3)?,
            mean: r.get(4)?,
            max: r.get(5)?,
            last: r.get(6)?,
            last_ms: r.get(7)?,
        })
    })?;
    Ok(rows.collect::<Result<_, _>>()?)
}

/// One hourly merge in one IMMEDIATE transaction.
pub(super) fn run_batch(
    conn: &mut Connection,
    b: Batch,
    stats: &mut RetainStats,
) -> Result<(), StoreError> {
    let tx = conn.transaction_with_behavior(TransactionBehavior::Immediate)?;
    let minutes = read_rollups(&tx, RollupTier::Minute, b.tag, b.span)?;
    let hours = combine(&minutes, HOUR_MS);
    for h in &hours {
        insert_rollup(&tx, RollupTier::Hour, b.tag, h)?;
    }
    let deleted = tx
        .prepare_cached("DELETE FROM rollups_1m WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3")?
        .execute(params![b.tag, b.span.from, b.span.to])?;
    if deleted != minutes.len() {
        // Dropping the transaction rolls it back: nothing changed.
        return Err(StoreError::Corrupt(format!(
            "hourly merge of tag {} at {}: read {} minute rows, deleted {deleted}",
            b.tag,
            b.span.from,
            minutes.len()
        )));
    }
    tx.commit()?;
    stats.hourly_batches += 1;
    stats.minutes_merged += minutes.len() as u64;
    stats.hours += hours.len() as u64;
    Ok(())
}

/// Minute rows a batch would merge.
pub(super) fn count_minutes(conn: &Connection, b: &Batch) -> Result<u64, StoreError> {
    let n: i64 = conn
        .prepare_cached(
            "SELECT COUNT(*) FROM rollups_1m WHERE tag_id = ?1 AND t_ms >= ?2 AND t_ms < ?3",
        )?
        .query_row(params![b.tag, b.span.from, b.span.to], |r| r.get(0))?;
    Ok(u64::try_from(n).unwrap_or(0))
}

impl Store {
    /// The stored roll-up rows of `tag` in `tier` whose period starts in `[from_ms, to_ms]`,
    /// time-ordered (for `gtwatch export --resolution`).
    pub fn tag_rollups_between(
        &self,
        tag: TagId,
        tier: RollupTier,
        from_ms: i64,
        to_ms: i64,
    ) -> Result<Vec<Rollup>, StoreError> {
        let span = Span {
            from: from_ms,
            to: to_ms.saturating_add(1),
        };
        read_rollups(&self.conn, tier, tag, span)
    }
}

impl StorageConfig {
    /// `rollup_1m_days`: in range, and only with `raw_days`, and longer than it (minute rows
    /// are made at `raw_days` of age; merged sooner they would never be seen).
    pub(in crate::store) fn validate_rollup_1m_days(&self, p: &mut Vec<ConfigProblem>) {
        let before = p.len();
        check_range(
            p,
            "storage.rollup_1m_days",
            u64::from(self.rollup_1m_days),
            Bounds {
                lo: 0,
                hi: 36_500,
                unit: " days",
                why: "0 (keep 1-minute roll-ups forever) … 100 years",
            },
        );
        if p.len() > before || self.rollup_1m_days == 0 {
            return;
        }
        if self.raw_days == 0 {
            p.push(ConfigProblem::new(
                "storage.rollup_1m_days",
                format!(
                    "{} days needs storage.raw_days > 0: without retention there are no 1-minute roll-ups to merge into hourly ones",
                    self.rollup_1m_days
                ),
            ));
        } else if self.rollup_1m_days <= self.raw_days {
            p.push(ConfigProblem::new(
                "storage.rollup_1m_days",
                format!(
                    "{} days must be more than storage.raw_days ({} days): 1-minute roll-ups are made at raw_days of age and kept until rollup_1m_days, then merged into hourly roll-ups",
                    self.rollup_1m_days, self.raw_days
                ),
            ));
        }
    }
}
