//! Start-up detection over the stored samples: reads what is not yet scanned, feeds the pure
//! state machine in [`machine`], and writes segments, their phases and the resume point as one
//! request ([`crate::store::ScanWrite`], one transaction) through a [`Db`].
//!
//! Same code path live (the daemon calls [`scan`] periodically from a blocking task, reading
//! through its read-only connection and writing through the daemon's one writer) and after a
//! replay (a store of its own). Resume rule: each scan restarts the machine a margin before the earliest of (the
//! start of any open segment, the last scanned time, the oldest late-arriving sample), deletes
//! the not-yet-diagnosed segments that start after that point and finds them again. The
//! machine is deterministic, so a start interrupted by a daemon restart is found whole and
//! never twice. Must not talk to Modbus or fit models.

pub mod in_memory;
pub(crate) mod machine;

pub use machine::{Frame, Machine};

use crate::config_problem::ConfigProblem;
use crate::engine::config::EngineConfig;
use crate::segment::SegmentRecord;
use crate::signals::Signal;
use crate::store::{Db, ScanWrite, Store, StoreError, TagId};
use serde::{Deserialize, Serialize};

/// `[detector]` section: start-up detection thresholds. The engine's own speeds and base load
/// default to the engine file's ([`DetectorConfig::fill_from_engine`]; the defaults written
/// here are the built-in engine's), the rest to the daemon contract.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectorConfig {
    /// Starter purge speed, rpm. Default 2300.
    pub purge_speed_rpm: f64,
    /// Light-off speed, rpm. Default 1700.
    pub light_off_speed_rpm: f64,
    /// Starter cut-out speed, rpm. Default 4500 (informational; not a boundary).
    pub starter_cutout_rpm: f64,
    /// Core idle speed, rpm. Default 6800.
    pub idle_speed_rpm: f64,
    /// Power-turbine synchronous speed, rpm. Default 3600.
    pub pt_sync_speed_rpm: f64,
    /// Base load, MW. Default 31.4.
    pub base_load_mw: f64,
    /// n1 at or below this is "at rest", rpm. Default 100.
    pub rest_speed_rpm: f64,
    /// Fuel above this is "fuel on", kg/s, once the meter's zero read at rest is taken off
    /// (`machine::Machine`). Default 0.005.
    pub fuel_on_kg_s: f64,
    /// Power above this means the breaker is closed, MW. Default 0.5.
    pub breaker_closed_mw: f64,
    /// Crank ends at this fraction of purge speed. Default 0.98.
    pub purge_entry_frac: f64,
    /// Purge band half-width as a fraction of purge speed. Default 0.02.
    pub purge_band_frac: f64,
    /// Acceleration ends at this fraction of idle speed. Default 0.99.
    pub idle_entry_frac: f64,
    /// Idle ends when n2 is within this fraction of PT sync speed. Default 0.01.
    pub sync_band_frac: f64,
    /// Steady load: power within this fraction of its level. Default 0.01.
    pub steady_band_frac: f64,
    /// ... for this long, seconds. Default 60.
    pub steady_hold_s: f64,
    /// Once steady load is found, the start-up stays open this much longer while the power
    /// holds within the band, s, so its diagnosis sees the unit settle: a hot section that
    /// soaks heat for minutes still moves fuel and exhaust temperatures a minute into the load.
    /// It closes as completed at the end of this time, or at the last steady sample when the
    /// load moves, the fuel is cut or the data stop. Unlike a longer `steady_hold_s`, a unit
    /// whose load never holds that long still completes its start-ups. Default 0 (closed where
    /// steady load is found).
    #[serde(default)]
    pub steady_extend_s: f64,
    /// A plateau below this fraction of base load is warm-up, not steady load. Default 0.2.
    pub steady_min_load_frac: f64,
    /// Fuel falling from on to off within this time is a trip (abrupt cut), s. Default 3.
    pub trip_fuel_cut_s: f64,
    /// After light-off: n1 falling this far below its peak while the fuel stays up (≥ 80 % of its
    /// value at the peak) is a flame-out, rpm. Default 1500: a commanded deceleration (the PT
    /// governor cutting fuel at synchronisation) can lose several hundred rpm; a flame-out decays
    /// towards rest.
    pub flame_out_drop_rpm: f64,
    /// During light-off (starter still turning the GG): GG speed loss below the ignition speed,
    /// with fuel on, that counts as a failed light-off / flame-out, rpm.
    #[serde(default = "default_light_off_flame_out_drop_rpm")]
    pub light_off_flame_out_drop_rpm: f64,
    /// A start within this time of the previous fuel-off is a hot restart, s. Default 1800.
    pub hot_restart_window_s: f64,
    /// Samples further apart than this mark a data gap, s. Default 10.
    pub max_sample_gap_s: f64,
    /// On resume, restart the machine this long before the resume point, s. Default 600.
    pub resume_margin_s: f64,
    /// A start-up that has not reached steady load this long after it began is closed as
    /// aborted (cause `unknown`) and not diagnosed, s: a frozen power or speed signal would
    /// otherwise leave it in progress forever. Default 3600 (a normal start takes ~15 min).
    #[serde(default = "default_max_startup_s")]
    pub max_startup_s: f64,
    /// Tag names of the inputs; default: the first tag of signal n1 / fuel_flow / power / n2.
    pub n1_tag: Option<String>,
    pub fuel_tag: Option<String>,
    pub power_tag: Option<String>,
    pub n2_tag: Option<String>,
}

fn default_light_off_flame_out_drop_rpm() -> f64 {
    300.0
}

fn default_max_startup_s() -> f64 {
    3600.0
}

impl Default for DetectorConfig {
    fn default() -> Self {
        DetectorConfig {
            purge_speed_rpm: 2300.0,
            light_off_speed_rpm: 1700.0,
            starter_cutout_rpm: 4500.0,
            idle_speed_rpm: 6800.0,
            pt_sync_speed_rpm: 3600.0,
            base_load_mw: 31.4,
            rest_speed_rpm: 100.0,
            fuel_on_kg_s: 0.005,
            breaker_closed_mw: 0.5,
            purge_entry_frac: 0.98,
            purge_band_frac: 0.02,
            idle_entry_frac: 0.99,
            sync_band_frac: 0.01,
            steady_band_frac: 0.01,
            steady_hold_s: 60.0,
            steady_extend_s: 0.0,
            steady_min_load_frac: 0.2,
            trip_fuel_cut_s: 3.0,
            flame_out_drop_rpm: 1500.0,
            light_off_flame_out_drop_rpm: 300.0,
            hot_restart_window_s: 1800.0,
            max_sample_gap_s: 10.0,
            resume_margin_s: 600.0,
            max_startup_s: default_max_startup_s(),
            n1_tag: None,
            fuel_tag: None,
            power_tag: None,
            n2_tag: None,
        }
    }
}

impl DetectorConfig {
    /// Problems with this section; keys are prefixed `detector.`.
    pub fn validate(&self) -> Vec<ConfigProblem> {
        let mut p = Vec::new();
        let positive = [
            ("purge_speed_rpm", self.purge_speed_rpm),
            ("light_off_speed_rpm", self.light_off_speed_rpm),
            ("starter_cutout_rpm", self.starter_cutout_rpm),
            ("idle_speed_rpm", self.idle_speed_rpm),
            ("pt_sync_speed_rpm", self.pt_sync_speed_rpm),
            ("base_load_mw", self.base_load_mw),
            ("rest_speed_rpm", self.rest_speed_rpm),
            ("fuel_on_kg_s", self.fuel_on_kg_s),
            ("breaker_closed_mw", self.breaker_closed_mw),
            ("steady_hold_s", self.steady_hold_s),
            ("trip_fuel_cut_s", self.trip_fuel_cut_s),
            ("flame_out_drop_rpm", self.flame_out_drop_rpm),
            (
                "light_off_flame_out_drop_rpm",
                self.light_off_flame_out_drop_rpm,
            ),
            ("max_sample_gap_s", self.max_sample_gap_s),
            ("max_startup_s", self.max_startup_s),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                p.push(ConfigProblem::new(
                    format!("detector.{k}"),
                    format!("must be a number > 0 (got {v})"),
                ));
            }
        }
        let non_negative = [
            ("steady_extend_s", self.steady_extend_s),
            ("hot_restart_window_s", self.hot_restart_window_s),
            ("resume_margin_s", self.resume_margin_s),
        ];
        for (k, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                p.push(ConfigProblem::new(
                    format!("detector.{k}"),
                    format!("must be a number >= 0 (got {v})"),
                ));
            }
        }
        let fractions = [
            ("purge_entry_frac", self.purge_entry_frac),
            ("purge_band_frac", self.purge_band_frac),
            ("idle_entry_frac", self.idle_entry_frac),
            ("sync_band_frac", self.sync_band_frac),
            ("steady_band_frac", self.steady_band_frac),
            ("steady_min_load_frac", self.steady_min_load_frac),
        ];
        for (k, v) in fractions {
            if !(v.is_finite() && v > 0.0 && v < 1.0) {
                p.push(ConfigProblem::new(
                    format!("detector.{k}"),
                    format!("must be a fraction between 0 and 1 (got {v})"),
                ));
            }
        }
        // Equal where the unit ignites at its purge speed (the engine file allows it too).
        if self.light_off_speed_rpm > self.purge_speed_rpm {
            p.push(ConfigProblem::new(
                "detector.light_off_speed_rpm",
                format!(
                    "must not be above purge_speed_rpm ({} > {})",
                    self.light_off_speed_rpm, self.purge_speed_rpm
                ),
            ));
        }
        if self.purge_speed_rpm >= self.idle_speed_rpm {
            p.push(ConfigProblem::new(
                "detector.purge_speed_rpm",
                "must be below idle_speed_rpm",
            ));
        }
        if self.rest_speed_rpm >= self.light_off_speed_rpm {
            p.push(ConfigProblem::new(
                "detector.rest_speed_rpm",
                "must be below light_off_speed_rpm",
            ));
        }
        p
    }
}

impl DetectorConfig {
    /// Sets each key that describes the engine's own start sequence and that the `[detector]`
    /// section (`section`, as written; `None` when there is none) does not set, from the engine
    /// file (`[plant] engine_model`, else the built-in engine): purge, light-off and idle speeds
    /// and base load from its `[sequence]`, the starter's cut-out speed, the PT's design speed.
    /// A unit whose speeds differ from the reference engine's was otherwise detected with the
    /// reference's numbers, and every start of it read as aborted.
    pub fn fill_from_engine(&mut self, section: Option<&toml::Value>, engine: &EngineConfig) {
        let written = |key: &str| section.and_then(|v| v.get(key)).is_some();
        let q = &engine.sequence;
        let from_engine = [
            (
                &mut self.purge_speed_rpm,
                "purge_speed_rpm",
                q.purge_speed_rpm,
            ),
            (
                &mut self.light_off_speed_rpm,
                "light_off_speed_rpm",
                q.light_off_speed_rpm,
            ),
            (
                &mut self.starter_cutout_rpm,
                "starter_cutout_rpm",
                engine.starter.cutout_rpm,
            ),
            (&mut self.idle_speed_rpm, "idle_speed_rpm", q.idle_speed_rpm),
            (
                &mut self.pt_sync_speed_rpm,
                "pt_sync_speed_rpm",
                engine.design.pt_speed_rpm,
            ),
            (&mut self.base_load_mw, "base_load_mw", q.base_load_mw),
        ];
        for (field, key, value) in from_engine {
            if !written(key) {
                *field = value;
            }
        }
    }
}

/// What one [`scan`] did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ScanReport {
    /// Frames fed to the machine (including the re-scanned margin).
    pub frames: u64,
    /// Time the scan restarted from, if there was anything to scan.
    pub resumed_from_ms: Option<i64>,
    pub scanned_to_ms: Option<i64>,
    /// Segments written (new or updated), open ones included.
    pub segments_written: u64,
    /// Segments closed in this scan.
    pub segments_closed: u64,
    /// Segments still open at the end of the scan.
    pub segments_open: u64,
    /// What the fuel meter read with the GG at rest (its zero, taken off before "fuel on" is
    /// judged), kg/s; `None` when the scan never saw the GG at rest.
    pub fuel_zero_kg_s: Option<f64>,
}

/// Detector errors.
#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    #[error("detector input '{what}': no tag found ({hint})")]
    MissingTag { what: &'static str, hint: String },
    #[error("invalid value in database: {0}")]
    Corrupt(String),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Sql(#[from] rusqlite::Error),
}

/// The tags the detector reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct InputTags {
    n1: TagId,
    fuel: TagId,
    power: TagId,
    n2: Option<TagId>,
}

fn resolve_tags(store: &Store, cfg: &DetectorConfig) -> Result<Option<InputTags>, DetectError> {
    let pick = |name: &Option<String>, sig: Signal| -> Result<Option<TagId>, DetectError> {
        match name {
            Some(n) => Ok(Some(store.tag_by_name(n)?.id)),
            None => Ok(store.tag_for_signal(sig)?.map(|t| t.id)),
        }
    };
    let n1 = pick(&cfg.n1_tag, Signal::N1)?;
    let fuel = pick(&cfg.fuel_tag, Signal::FuelFlow)?;
    let power = pick(&cfg.power_tag, Signal::Power)?;
    let n2 = pick(&cfg.n2_tag, Signal::N2)?;
    Ok(match (n1, fuel, power) {
        (Some(n1), Some(fuel), Some(power)) => Some(InputTags {
            n1,
            fuel,
            power,
            n2,
        }),
        _ => None,
    })
}

/// Carries the latest value of a secondary tag forward while n1 time stamps advance.
struct Hold {
    samples: Vec<(i64, f64)>,
    pos: usize,
    value: Option<f64>,
}

impl Hold {
    fn new(samples: Vec<(i64, f64)>, carried: Option<f64>) -> Hold {
        Hold {
            samples,
            pos: 0,
            value: carried,
        }
    }
    fn at(&mut self, t: i64) -> Option<f64> {
        while self.pos < self.samples.len() && self.samples[self.pos].0 <= t {
            self.value = Some(self.samples[self.pos].1);
            self.pos += 1;
        }
        self.value
    }
}

/// Time span read per chunk.
const CHUNK_MS: i64 = 6 * 3600 * 1000;

/// Processes the samples not yet scanned and stores/updates segments (see the module comment).
///
/// Returns an empty report when the input tags (n1, fuel flow, power) do not exist yet.
pub fn scan(db: &mut dyn Db, cfg: &DetectorConfig) -> Result<ScanReport, DetectError> {
    scan_with(db, cfg, false)
}

/// [`scan`] at the end of an input that does not go on (`gtwatch replay` of a log): a completed
/// start-up still held open for its steady load ([`DetectorConfig::steady_extend_s`]) is closed
/// at its last steady sample rather than left in progress. Live data use [`scan`].
pub fn scan_to_end(db: &mut dyn Db, cfg: &DetectorConfig) -> Result<ScanReport, DetectError> {
    scan_with(db, cfg, true)
}

fn scan_with(
    db: &mut dyn Db,
    cfg: &DetectorConfig,
    end_of_input: bool,
) -> Result<ScanReport, DetectError> {
    let (mut report, write) = plan(db.read(), cfg, end_of_input)?;
    if let Some(w) = write {
        report.segments_written = db.write_scan(w)?;
    }
    Ok(report)
}

/// Reads and runs the machine: what a scan found and what it must write (`None`: nothing
/// new). No writes.
fn plan(
    store: &Store,
    cfg: &DetectorConfig,
    end_of_input: bool,
) -> Result<(ScanReport, Option<ScanWrite>), DetectError> {
    let mut report = ScanReport::default();
    let Some(tags) = resolve_tags(store, cfg)? else {
        return Ok((report, None));
    };
    let st = store.detector_state()?;
    let margin_ms = (cfg.resume_margin_s * 1000.0) as i64;
    let (first, last) = store.tag_time_range(tags.n1)?;
    let (Some(first), Some(last)) = (first, last) else {
        return Ok((report, None));
    };
    if st.rescan_from_ms.is_none() && st.scanned_to_ms.is_some_and(|s| s >= last) {
        return Ok((report, None)); // nothing new
    }
    // Segments starting before `resume` are stored already and stay as they are; the machine
    // starts earlier (at `from`) only to have context.
    let resume = store.detector_resume_point(&st)?;
    let from = match resume {
        Some(r) => store.detector_warm_point(r, margin_ms)?.max(first),
        None => first,
    };
    let keep_from = resume.unwrap_or(first).max(from);
    report.resumed_from_ms = Some(from);

    let hot_window_ms = (cfg.hot_restart_window_s * 1000.0) as i64;
    let fuel_off_before =
        store.last_fuel_off_before(tags.fuel, from, hot_window_ms, cfg.fuel_on_kg_s)?;
    let mut machine = Machine::new(cfg.clone(), fuel_off_before);
    let mut finished = Vec::new();
    let mut carried: [Option<f64>; 3] = [None; 3];
    let mut chunk_from = from;
    let mut scanned_to = None;
    while chunk_from <= last {
        let chunk_to = chunk_from.saturating_add(CHUNK_MS);
        let n1 = store.good_samples(tags.n1, chunk_from, chunk_to)?;
        let mut fuel = Hold::new(
            store.good_samples(tags.fuel, chunk_from, chunk_to)?,
            carried[0],
        );
        let mut power = Hold::new(
            store.good_samples(tags.power, chunk_from, chunk_to)?,
            carried[1],
        );
        let mut n2 = match tags.n2 {
            Some(t) => Some(Hold::new(
                store.good_samples(t, chunk_from, chunk_to)?,
                carried[2],
            )),
            None => None,
        };
        for (t, v) in n1 {
            let (Some(fv), Some(pv)) = (fuel.at(t), power.at(t)) else {
                continue;
            };
            let n2v = n2.as_mut().and_then(|h| h.at(t));
            machine.push(Frame {
                t_ms: t,
                n1: v,
                fuel: fv,
                power: pv,
                n2: n2v,
            });
            report.frames += 1;
            scanned_to = Some(t);
        }
        carried = [fuel.value, power.value, n2.as_ref().and_then(|h| h.value)];
        finished.extend(machine.take_finished());
        if chunk_to == i64::MAX {
            break; // the last possible chunk (a sample stamped near i64::MAX)
        }
        chunk_from = chunk_to;
        // Skip empty stretches in one step instead of walking 6-hour chunks up to a far-away
        // sample (a bogus year-3000 stamp took minutes, i64::MAX forever). Held fuel/power
        // values are not carried across the jump.
        let next = store.next_good_sample_ms(tags.n1, chunk_from)?;
        match next {
            None => break,
            Some(t) if t >= chunk_from.saturating_add(CHUNK_MS) => {
                chunk_from = t;
                carried = [None; 3];
            }
            Some(_) => {}
        }
    }
    if end_of_input {
        machine.end_of_input();
        finished.extend(machine.take_finished());
    }
    // A start's onset is placed back in time once the rise is seen (the knee of n1, the
    // coast-down minimum), so a scan that stopped between the onset and the rise left that
    // start undetected before the resume point. It is kept when it begins after every stored
    // segment there; one that overlaps a stored segment is that segment, found again.
    let stored_end = store.last_segment_end_before(keep_from)?;
    let is_new = |r: &SegmentRecord| {
        r.start_ms >= keep_from || stored_end.is_none_or(|end| r.start_ms > end)
    };
    finished.retain(is_new);
    let open = machine.open_segment().filter(is_new);
    let keep_from = finished
        .iter()
        .chain(&open)
        .map(|r| r.start_ms)
        .fold(keep_from, i64::min);
    report.segments_closed = finished.len() as u64;
    report.segments_open = u64::from(open.is_some());
    report.scanned_to_ms = scanned_to;
    report.fuel_zero_kg_s = machine.fuel_zero_kg_s();

    let write = ScanWrite {
        records: finished.into_iter().chain(open).collect(),
        keep_from,
        scanned_to: scanned_to.unwrap_or(last),
        last_fuel_off_ms: machine.last_fuel_off_ms().or(st.last_fuel_off_ms),
    };
    Ok((report, Some(write)))
}

#[cfg(test)]
mod tests;
