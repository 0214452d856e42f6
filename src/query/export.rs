//! `gtwatch export`'s CSV: raw samples and, where retention rolled them up, the 1-minute and
//! hourly roll-ups (README "Retention and roll-ups", `--resolution`).
//!
//! - `raw`: raw samples only, today's columns (`time,t_ms,<tag>…` or
//!   `time,t_ms,tag,value,quality`); rolled-up periods have no rows (the caller warns).
//! - `auto` (default): every period at the resolution the store keeps it: raw samples, minute
//!   rows, hour rows, marked in a `resolution` column (`raw`, `1m`, `1h`).
//! - `1m` / `1h`: every period at that resolution: raw samples are aggregated like retention
//!   does (good samples only in min/mean/max/last; `n_all` counts all), stored roll-ups
//!   combined with them exactly; `1m` keeps hourly rows where only those remain.
//!
//! A roll-up row's `value` is its mean (empty when the period had no good sample). Periods
//! overlapping `[from, to]` are exported whole in `1m`/`1h`. Must not write, nor hold SQL (the
//! store's read functions do).

use super::{ExportLayout, QueryError};
use crate::store::{
    combine_rollups, floor_to, minute_rollups, Rollup, RollupTier, Store, TagId, HOUR_MS, MINUTE_MS,
};
use crate::time::fmt_ms;
use std::io::Write;

/// `--resolution` of `export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default, clap::ValueEnum)]
pub enum Resolution {
    /// Raw samples only (rolled-up periods are absent).
    Raw,
    /// As stored: raw where raw, 1-minute and hourly roll-ups where retention made them.
    #[default]
    Auto,
    /// Everything at 1-minute resolution (hourly where only hourly roll-ups remain).
    #[value(name = "1m")]
    Minute,
    /// Everything at hourly resolution.
    #[value(name = "1h")]
    Hour,
}

/// What to export.
#[derive(Debug, Clone)]
pub(crate) struct ExportRequest {
    pub tags: Vec<String>,
    pub from_ms: i64,
    /// Inclusive.
    pub to_ms: i64,
    pub layout: ExportLayout,
    pub resolution: Resolution,
}

/// The resolution of one output row (ordered: a wide row is marked with its coarsest cell).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum RowRes {
    Raw,
    Minute,
    Hour,
}

impl RowRes {
    fn name(self) -> &'static str {
        match self {
            RowRes::Raw => "raw",
            RowRes::Minute => "1m",
            RowRes::Hour => "1h",
        }
    }
}

/// One output value of one tag: a raw sample or a roll-up.
#[derive(Debug, Clone, Copy)]
struct Cell {
    t_ms: i64,
    res: RowRes,
    /// The sample's value, or the roll-up's mean.
    value: Option<f64>,
    /// Raw samples only.
    quality: Option<i64>,
    /// Roll-ups only.
    rollup: Option<Rollup>,
}

fn rollup_cell(r: Rollup, res: RowRes) -> Cell {
    Cell {
        t_ms: r.t_ms,
        res,
        value: r.mean,
        quality: None,
        rollup: Some(r),
    }
}

/// Stored roll-ups of `tier` overlapping `[from, to]`.
fn stored(
    store: &Store,
    tag: TagId,
    tier: RollupTier,
    from: i64,
    to: i64,
) -> Result<Vec<Rollup>, QueryError> {
    Ok(store.tag_rollups_between(tag, tier, floor_to(from, tier.period_ms()), to)?)
}

/// Raw samples in whole `period`s overlapping `[from, to]`, rolled up per minute.
fn raw_minutes(
    store: &Store,
    tag: TagId,
    from: i64,
    to: i64,
    period: i64,
) -> Result<Vec<Rollup>, QueryError> {
    let end = floor_to(to, period).saturating_add(period - 1);
    let rows = store.tag_samples_between(tag, floor_to(from, period), end)?;
    Ok(minute_rollups(&rows))
}

/// Raw-derived and stored minute rows, one per minute (a minute in both is combined).
fn merge_minutes(mut a: Vec<Rollup>, b: Vec<Rollup>) -> Vec<Rollup> {
    a.extend(b);
    a.sort_by_key(|r| r.t_ms);
    combine_rollups(&a, MINUTE_MS)
}

/// One tag's cells, time-ordered.
fn tag_cells(store: &Store, tag: TagId, req: &ExportRequest) -> Result<Vec<Cell>, QueryError> {
    let (from, to) = (req.from_ms, req.to_ms);
    let raw_cells = |rows: Vec<crate::store::SampleRow>| -> Vec<Cell> {
        rows.into_iter()
            .map(|s| Cell {
                t_ms: s.t_ms,
                res: RowRes::Raw,
                value: Some(s.value),
                quality: Some(s.quality),
                rollup: None,
            })
            .collect()
    };
    let mut cells = match req.resolution {
        Resolution::Raw => raw_cells(store.tag_samples_between(tag, from, to)?),
        Resolution::Auto => {
            let mut c = raw_cells(store.tag_samples_between(tag, from, to)?);
            for (tier, res) in [
                (RollupTier::Minute, RowRes::Minute),
                (RollupTier::Hour, RowRes::Hour),
            ] {
                c.extend(
                    stored(store, tag, tier, from, to)?
                        .into_iter()
                        .map(|r| rollup_cell(r, res)),
                );
            }
            c
        }
        Resolution::Minute => {
            let minutes = merge_minutes(
                raw_minutes(store, tag, from, to, MINUTE_MS)?,
                stored(store, tag, RollupTier::Minute, from, to)?,
            );
            let mut c: Vec<Cell> = minutes
                .into_iter()
                .map(|r| rollup_cell(r, RowRes::Minute))
                .collect();
            c.extend(
                stored(store, tag, RollupTier::Hour, from, to)?
                    .into_iter()
                    .map(|r| rollup_cell(r, RowRes::Hour)),
            );
            c
        }
        Resolution::Hour => {
            let mut all = merge_minutes(
                raw_minutes(store, tag, from, to, HOUR_MS)?,
                stored(store, tag, RollupTier::Minute, from, to)?,
            );
            all.extend(stored(store, tag, RollupTier::Hour, from, to)?);
            all.sort_by_key(|r| r.t_ms);
            combine_rollups(&all, HOUR_MS)
                .into_iter()
                .map(|r| rollup_cell(r, RowRes::Hour))
                .collect()
        }
    };
    cells.sort_by_key(|c| (c.t_ms, c.res));
    Ok(cells)
}

fn opt<T: ToString>(v: Option<T>) -> String {
    v.map(|x| x.to_string()).unwrap_or_default()
}

/// Writes the samples (and roll-ups, per `req.resolution`) of `req.tags` in `[from_ms,
/// to_ms]` as CSV; returns the data rows written.
///
/// Wide: `time,t_ms,<tag>...` (and `resolution` unless raw), one row per time stamp at which
/// any of the tags has a value; an empty cell means that tag has none at that time. Long:
/// `time,t_ms,tag,value,quality` (and `resolution,min,max,n_good,n_all` unless raw).
pub(crate) fn export_csv(
    store: &Store,
    req: &ExportRequest,
    out: &mut dyn Write,
) -> Result<u64, QueryError> {
    let names: Vec<&str> = req.tags.iter().map(|t| t.trim()).collect();
    let ids = names
        .iter()
        .map(|t| store.tag_by_name(t).map(|r| r.id))
        .collect::<Result<Vec<_>, _>>()?;
    let cols = ids
        .iter()
        .map(|&id| tag_cells(store, id, req))
        .collect::<Result<Vec<_>, _>>()?;
    let marked = req.resolution != Resolution::Raw;
    let mut w = csv::Writer::from_writer(out);
    let rows = match req.layout {
        ExportLayout::Long => write_long(&mut w, &names, &cols, marked)?,
        ExportLayout::Wide => write_wide(&mut w, &names, &cols, marked)?,
    };
    w.flush()?;
    Ok(rows)
}

fn write_long<W: Write>(
    w: &mut csv::Writer<W>,
    names: &[&str],
    cols: &[Vec<Cell>],
    marked: bool,
) -> Result<u64, QueryError> {
    let mut head = vec!["time", "t_ms", "tag", "value", "quality"];
    if marked {
        head.extend(["resolution", "min", "max", "n_good", "n_all"]);
    }
    w.write_record(&head)?;
    // Merge by time so the output is time-ordered across tags.
    let mut all: Vec<(usize, &Cell)> = cols
        .iter()
        .enumerate()
        .flat_map(|(k, c)| c.iter().map(move |x| (k, x)))
        .collect();
    all.sort_by_key(|(k, c)| (c.t_ms, c.res, *k));
    for (k, c) in &all {
        let mut rec = vec![
            fmt_ms(c.t_ms),
            c.t_ms.to_string(),
            names[*k].to_string(),
            opt(c.value),
            opt(c.quality),
        ];
        if marked {
            let r = c.rollup;
            rec.extend([
                c.res.name().to_string(),
                opt(r.and_then(|r| r.min)),
                opt(r.and_then(|r| r.max)),
                opt(r.map(|r| r.n_good)),
                opt(r.map(|r| r.n_all)),
            ]);
        }
        w.write_record(&rec)?;
    }
    Ok(all.len() as u64)
}

fn write_wide<W: Write>(
    w: &mut csv::Writer<W>,
    names: &[&str],
    cols: &[Vec<Cell>],
    marked: bool,
) -> Result<u64, QueryError> {
    let mut head = vec!["time".to_string(), "t_ms".to_string()];
    head.extend(names.iter().map(|t| t.to_string()));
    if marked {
        head.push("resolution".into());
    }
    w.write_record(&head)?;
    let mut pos = vec![0usize; cols.len()];
    let mut rows = 0u64;
    loop {
        let next = cols
            .iter()
            .zip(&pos)
            .filter_map(|(c, &p)| c.get(p).map(|s| (s.t_ms, s.res)))
            .min();
        let Some((t, res)) = next else { break };
        let mut rec = vec![fmt_ms(t), t.to_string()];
        let mut coarsest = res;
        for (c, p) in cols.iter().zip(pos.iter_mut()) {
            match c.get(*p) {
                Some(cell) if cell.t_ms == t => {
                    rec.push(opt(cell.value));
                    coarsest = coarsest.max(cell.res);
                    *p += 1;
                }
                _ => rec.push(String::new()),
            }
        }
        if marked {
            rec.push(coarsest.name().to_string());
        }
        w.write_record(&rec)?;
        rows += 1;
    }
    Ok(rows)
}

/// Roll-up rows of `tags` overlapping `[from_ms, to_ms]`: (minute rows, hour rows), for the
/// warning of a `raw` export over rolled-up time.
pub(crate) fn rolled_up_in_range(
    store: &Store,
    tags: &[String],
    from_ms: i64,
    to_ms: i64,
) -> Result<(usize, usize), QueryError> {
    let (mut minutes, mut hours) = (0, 0);
    for t in tags {
        let id = store.tag_by_name(t.trim())?.id;
        minutes += stored(store, id, RollupTier::Minute, from_ms, to_ms)?.len();
        hours += stored(store, id, RollupTier::Hour, from_ms, to_ms)?.len();
    }
    Ok((minutes, hours))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quality::Quality;
    use crate::store::{RetentionPolicy, Sample, ScanWrite, TagInfo};

    const BASE: i64 = 1_700_006_400_000; // day-aligned
    const DAY: i64 = 86_400_000;

    fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
        r.unwrap_or_else(|e| unreachable!("{e}"))
    }

    fn value(i: i64) -> f64 {
        (i % 8) as f64 * 0.5 + (i / 600) as f64
    }

    /// Three hours of 1 Hz (every 10th sample bad) rolled up: the first hour into an hourly
    /// row, the next two into minute rows; ten raw minutes two days later stay raw.
    fn rolled_store(path: &std::path::Path) -> Store {
        let mut store = ok(Store::open(path));
        let tag = ok(store.ensure_tag(&TagInfo {
            name: "x".into(),
            unit: String::new(),
            signal: None,
        }));
        let sample = |t_ms: i64, i: i64| Sample {
            tag,
            t_ms,
            value: if i % 10 == 9 { 1e9 } else { value(i) },
            quality: if i % 10 == 9 {
                Quality::Bad
            } else {
                Quality::Good
            },
        };
        let mut s: Vec<Sample> = (0..3 * 3600).map(|i| sample(BASE + i * 1000, i)).collect();
        s.extend((0..600).map(|i| sample(BASE + 2 * DAY + i * 1000, i)));
        ok(store.insert_samples(&s));
        ok(store.store_scan(&ScanWrite {
            records: Vec::new(),
            keep_from: BASE,
            scanned_to: BASE + 2 * DAY,
            last_fuel_off_ms: None,
        }));
        let policy = RetentionPolicy {
            raw_days: 1,
            segment_margin_s: 0,
            rollup_1m_days: 10,
        };
        let done = ok(store.apply_retention(BASE + HOUR_MS + 10 * DAY, &policy));
        assert_eq!((done.samples_rolled_up, done.minutes_merged), (10_800, 60));
        store
    }

    fn export(store: &Store, from: i64, to: i64, layout: ExportLayout, r: Resolution) -> String {
        let req = ExportRequest {
            tags: vec!["x".into()],
            from_ms: from,
            to_ms: to,
            layout,
            resolution: r,
        };
        let mut out = Vec::new();
        ok(export_csv(store, &req, &mut out));
        ok(String::from_utf8(out))
    }

    /// The good samples of hour `h` (0-based from BASE) straight from the signal.
    fn truth(h: i64) -> (i64, f64, f64, f64) {
        let good: Vec<f64> = (h * 3600..(h + 1) * 3600)
            .filter(|i| i % 10 != 9)
            .map(value)
            .collect();
        let mean = good.iter().sum::<f64>() / good.len() as f64;
        let min = good.iter().copied().fold(f64::INFINITY, f64::min);
        let max = good.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (good.len() as i64, mean, min, max)
    }

    fn field(line: &str, k: usize) -> &str {
        line.split(',').nth(k).unwrap_or_default()
    }

    #[test]
    fn a_rolled_up_range_exports_its_rollups_not_nothing() {
        let dir = ok(tempfile::tempdir());
        let store = rolled_store(&dir.path().join("e.db"));
        let end = BASE + 3 * HOUR_MS - 1;

        // raw: nothing (the caller warns, from rolled_up_in_range), today's columns.
        let raw = export(&store, BASE, end, ExportLayout::Long, Resolution::Raw);
        assert_eq!(raw, "time,t_ms,tag,value,quality\n");
        assert_eq!(
            ok(rolled_up_in_range(&store, &["x".into()], BASE, end)),
            (120, 1)
        );

        // auto: the hour row, then 120 minute rows, marked.
        let auto = export(&store, BASE, end, ExportLayout::Long, Resolution::Auto);
        let lines: Vec<&str> = auto.lines().collect();
        assert_eq!(
            lines[0],
            "time,t_ms,tag,value,quality,resolution,min,max,n_good,n_all"
        );
        assert_eq!(lines.len(), 1 + 1 + 120);
        let (n_good, mean, min, max) = truth(0);
        let h0 = lines[1];
        assert_eq!(field(h0, 1), BASE.to_string());
        assert_eq!(field(h0, 5), "1h");
        assert_eq!((field(h0, 8), field(h0, 9)), (&*n_good.to_string(), "3600"));
        assert_eq!(field(h0, 6).parse::<f64>().ok(), Some(min));
        assert_eq!(field(h0, 7).parse::<f64>().ok(), Some(max));
        let got: f64 = field(h0, 3).parse().unwrap_or(f64::NAN);
        assert!((got - mean).abs() <= 1e-9 * mean.abs(), "{got} vs {mean}");
        assert!(lines[2..]
            .iter()
            .all(|l| field(l, 5) == "1m" && field(l, 4).is_empty()));
        assert_eq!(field(lines[2], 1), (BASE + HOUR_MS).to_string());

        // 1h: three hours, each equal to the raw truth, whatever tier it came from.
        let hourly = export(&store, BASE, end, ExportLayout::Long, Resolution::Hour);
        let lines: Vec<&str> = hourly.lines().skip(1).collect();
        assert_eq!(lines.len(), 3);
        for (h, l) in lines.iter().enumerate() {
            let (n_good, mean, _, _) = truth(h as i64);
            assert_eq!(field(l, 5), "1h");
            assert_eq!(field(l, 8), n_good.to_string());
            let got: f64 = field(l, 3).parse().unwrap_or(f64::NAN);
            assert!(
                (got - mean).abs() <= 1e-9 * mean.abs(),
                "hour {h}: {got} vs {mean}"
            );
        }
        // ... also from raw samples: ten raw minutes make one partial hour.
        let raw_hour = export(
            &store,
            BASE + 2 * DAY,
            BASE + 2 * DAY + 5_000,
            ExportLayout::Long,
            Resolution::Hour,
        );
        let l: Vec<&str> = raw_hour.lines().skip(1).collect();
        assert_eq!(l.len(), 1);
        assert_eq!((field(l[0], 8), field(l[0], 9)), ("540", "600"));

        // 1m: the merged hour stays hourly (its minutes are gone), the rest is minutes; the
        // raw minutes aggregate like retention's.
        let minutes = export(
            &store,
            BASE,
            BASE + 2 * DAY + DAY,
            ExportLayout::Long,
            Resolution::Minute,
        );
        let lines: Vec<&str> = minutes.lines().skip(1).collect();
        assert_eq!(lines.len(), 1 + 120 + 10);
        assert_eq!(field(lines[0], 5), "1h");
        assert!(lines[1..]
            .iter()
            .all(|l| field(l, 5) == "1m" && field(l, 9) == "60"));

        // Wide: one value column per tag (the mean for roll-ups), the row's resolution last.
        let wide = export(&store, BASE, end, ExportLayout::Wide, Resolution::Auto);
        let mut w = wide.lines();
        assert_eq!(w.next(), Some("time,t_ms,x,resolution"));
        assert!(w.next().is_some_and(|l| l.ends_with(",1h")));
        assert_eq!(w.count(), 120);
    }
}
