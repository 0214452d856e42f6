//! Tests of the wash advice: a fuel meter's step in a sequence of start-ups, named, corrected
//! and kept out of the advice.

use super::*;
use crate::diagnosis::bench::synthetic_startup;
use crate::diagnosis::transient::diagnose_transient;
use crate::diagnosis::{DiagnosisConfig, MethodResult};
use crate::gap::alias::aliases;
use crate::gap::sequence::SequenceVerdict;
use crate::health::HealthParams;
use crate::recording::Recording;
use crate::signals::Signal;
use crate::store::{NewDiagnosis, NewGapAnalysis, Store};
use crate::trend::WashDetection;
use crate::wash::WashEconomics;
use rusqlite::params;

const DAY: i64 = 86_400_000;
const T0: i64 = 1_700_000_000_000;
/// Start-ups in the sequence, and the first that the fuel meter reads high at.
const N: usize = 9;
const ONSET: usize = 4;
const METER: f64 = 1.03;

/// The unit's true health at start-up `j` (one a day): a compressor fouling at 0.25 %/day
/// (D_EC at 0.1), turbines worn a little and stable.
fn truth(j: usize) -> [f64; 6] {
    let t = j as f64;
    [0.6 + 0.25 * t, 0.3 + 0.1 * t, -0.3, 0.5, 0.2, 0.4]
}

fn cfg() -> DiagnosisConfig {
    DiagnosisConfig {
        max_model_runs: 300,
        lm_runs: 200,
        threads: Some(2),
        ..DiagnosisConfig::default()
    }
}

fn startup(engine: &Engine, j: usize, meter: f64) -> Recording {
    let h = HealthParams::from_array(truth(j));
    let mut rec = synthetic_startup(engine, &h, 100 + j as u64, true).expect("start-up");
    for k in 0..rec.len() {
        if let Some(v) = rec.value(k, Signal::FuelFlow) {
            rec.set(k, Signal::FuelFlow, v * meter).expect("set");
        }
    }
    rec
}

/// Method B's fit of start-up `j` with a correct meter. The same in every test (the engine,
/// the start-up and the settings are), so fitted once for all of them: each test fits only its
/// faulty start-ups.
fn correct_fit(j: usize) -> MethodResult {
    static FITS: std::sync::OnceLock<Vec<MethodResult>> = std::sync::OnceLock::new();
    FITS.get_or_init(|| {
        let engine = Engine::reference().expect("engine");
        (0..N)
            .map(|j| diagnose_transient(&engine, &startup(&engine, j, 1.0), &cfg()).expect("fit"))
            .collect()
    })[j]
        .clone()
}

fn store_result(store: &mut Store, j: usize, r: &MethodResult) -> i64 {
    let sigma = std::array::from_fn(|i| r.sigma.get(HEALTH_NAMES[i]).copied().unwrap_or(0.05));
    store_health(store, j, r.health.to_array(), sigma)
}

/// Stores start-up `j` (one a day from `T0`) with a Method B result of this health and 1σ.
fn store_health(store: &mut Store, j: usize, health: [f64; 6], sigma: [f64; 6]) -> i64 {
    let start = T0 + j as i64 * DAY;
    store
        .conn()
        .execute(
            "INSERT INTO segments (kind, start_ms, end_ms, outcome, status, updated_at_ms)
             VALUES ('startup', ?1, ?2, 'completed', 'closed', 0)",
            params![start, start + 900_000],
        )
        .expect("segment");
    let id = store.conn().last_insert_rowid();
    let d = NewDiagnosis {
        segment_id: id,
        method: "B".into(),
        health,
        sigma,
        objective: 1.0,
        residual_level: 1.0,
        fit_quality: "good".into(),
        model_runs: 300,
        wall_s: 1.0,
        seed: 1,
        config_hash: "h".into(),
        gtwatch_version: "test".into(),
    };
    store.insert_outcome(id, &[d], &[], "h").expect("result");
    id
}

/// Stores a gap analysis of `segment_id` that named nothing, with `report` as its JSON (the
/// daemon's analysis of a start-up that stepped against its trend: its aliases).
fn store_gap_report(store: &mut Store, segment_id: i64, report: serde_json::Value) {
    store
        .insert_gap_analysis(&NewGapAnalysis {
            segment_id,
            holdout_segment_id: None,
            effect: "none".into(),
            shrinkage: 0.0,
            confidence: 0.0,
            baseline_fit_quality: "good".into(),
            normalised_residual: 1.0,
            report_json: report.to_string(),
        })
        .expect("gap");
}

/// The fuel meter's alias signature as the reference engine gives it, per 2 %.
const FUEL_SHIFT: [f64; 6] = [0.05, 0.2, -1.28, 0.1, -0.87, 2.56];
/// An inlet-temperature signature, per 2 K.
const INLET_SHIFT: [f64; 6] = [0.6, 0.4, 0.3, -0.2, 0.5, 0.2];

/// One alias of a stored gap report: the instrument, the unit of its error, the error its
/// `shift` is given for, the largest credible error, and the shift of the six estimates.
struct Alias(&'static str, &'static str, f64, f64, [f64; 6]);

/// A stored gap report whose aliases are `aliases`.
fn report_of(aliases: &[Alias]) -> serde_json::Value {
    let list: Vec<serde_json::Value> = aliases
        .iter()
        .map(|Alias(effect, unit, nominal, max, s)| {
            serde_json::json!({"effect": effect, "unit": unit, "nominal": nominal,
                "max_magnitude": max, "health_shift": {"D_GC": s[0], "D_EC": s[1],
                "D_GT": s[2], "D_ET": s[3], "D_GP": s[4], "D_EP": s[5]}})
        })
        .collect();
    serde_json::json!({"aliases": {"aliases": list}})
}

/// The fuel meter's alias: its signature per 2 % high, credible to 6 %.
const FUEL_ALIAS: Alias = Alias("fuel_meter", "fraction", 0.02, 0.06, FUEL_SHIFT);

/// A stored gap report's aliases: the fuel meter's and the inlet temperature's signatures.
fn meter_and_inlet_report() -> serde_json::Value {
    report_of(&[
        FUEL_ALIAS,
        Alias("inlet_temperature", "K", 2.0, 6.0, INLET_SHIFT),
    ])
}

/// A wash a refresh detected just before start-up `j`, which nobody confirmed.
fn store_detected_wash(store: &mut Store, j: usize) {
    store
        .conn()
        .execute(
            "INSERT INTO washes (t_ms, kind, note) VALUES (?1, 'offline', ?2)",
            params![
                T0 + j as i64 * DAY - 1,
                format!("{DETECTED_PREFIX} D_GC recovered")
            ],
        )
        .expect("wash");
}

/// One refresh with the default economics, detection and health bounds.
fn refresh_defaults(store: &mut Store) -> AdviceReport {
    let engine = Engine::reference().expect("engine");
    refresh(
        store,
        &engine,
        &WashEconomics::default(),
        &WashDetection::default(),
        &HealthBounds::default(),
    )
    .expect("advice")
}

fn advised_days(r: &AdviceReport) -> f64 {
    r.advised_ms.expect("advice") as f64 / DAY as f64
}

/// Issue 23 item 3, on the reference engine's own start-ups with noise: a fuel meter that
/// starts reading 3 % high at the fifth of nine daily start-ups on a fouling trend. Each
/// start-up is fitted by Method B on its own (each fit within noise: the meter hides behind
/// health), the gap analysis's aliases are computed on the first stepped start-up as the
/// daemon would, and the wash advice's joint fit of the sequence must name the meter, size
/// it, correct the health of the stepped start-ups to within 0.3 points of the truth, and
/// leave the advised date within a day of the advice from the same start-ups with a
/// correct meter.
#[test]
fn a_fuel_meter_step_in_a_sequence_is_named_corrected_and_leaves_the_advice() {
    let engine = Engine::reference().expect("engine");
    let econ = WashEconomics::default();
    let dir = tempfile::tempdir().expect("dir");
    let mut faulty = Store::open(&dir.path().join("faulty.db")).expect("db");
    let mut clean = Store::open(&dir.path().join("clean.db")).expect("db");
    // The same faulty results without the gap analysis: nothing to attribute the step to.
    let mut blind = Store::open(&dir.path().join("blind.db")).expect("db");
    let mut raw_err = 0.0_f64;
    let mut fits = Vec::new();
    for j in 0..N {
        let meter = if j >= ONSET { METER } else { 1.0 };
        let rec = startup(&engine, j, meter);
        let fit = if j >= ONSET {
            diagnose_transient(&engine, &rec, &cfg()).expect("fit")
        } else {
            correct_fit(j)
        };
        let seg = store_result(&mut faulty, j, &fit);
        store_result(&mut blind, j, &fit);
        store_result(&mut clean, j, &correct_fit(j));
        if j >= ONSET {
            let t = truth(j);
            for (i, v) in fit.health.to_array().iter().enumerate() {
                raw_err = raw_err.max((v - t[i]).abs());
            }
        }
        if j == ONSET {
            let a = aliases(&engine, &rec, &cfg(), &fit).expect("aliases");
            store_gap_report(&mut faulty, seg, serde_json::json!({ "aliases": a }));
        }
        fits.push(fit);
    }
    assert!(
        raw_err > 1.0,
        "the meter must move the health (largest error {raw_err:.2})"
    );
    let det = WashDetection::default();
    let r = refresh(&mut faulty, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    let step = r.steps.first().expect("a step is found");
    assert_eq!(step.onset_segment_id, 1 + ONSET as i64);
    let SequenceVerdict::Instrument {
        effect, magnitude, ..
    } = &step.attribution.verdict
    else {
        panic!("not named: {:?}", step.attribution.verdict);
    };
    assert_eq!(effect, "fuel_meter");
    assert!((magnitude - (METER - 1.0)).abs() < 0.01, "size {magnitude}");
    // The corrected health of each stepped start-up, against the truth.
    let points: Vec<SeqPoint> = fits
        .iter()
        .enumerate()
        .map(|(j, f)| {
            SeqPoint::new(
                (T0 + j as i64 * DAY) as f64 / DAY as f64,
                f.health.to_array(),
                [0.05; 6],
                &HealthBounds::default(),
            )
        })
        .collect();
    let mut worst = 0.0_f64;
    for (j, p) in step.attribution.corrected(&points).iter().enumerate() {
        for (i, v) in p.health.iter().enumerate() {
            let err = v - truth(j)[i];
            worst = worst.max(err.abs());
            // The meter drives D_GT onto its −3 limit from the onset on (its signature says
            // −3.7): the corrected value is the trend line carried beyond the four start-ups
            // before the step, whose 1σ grows with the days it is carried (measured 0.05 at
            // the onset to 0.13 four days on, errors −0.12 to −0.29).
            if points[j].at_limit[i] {
                assert!(
                    err.abs() <= 3.0 * p.sigma[i],
                    "start-up {j} {}: {err:+.3} against 1σ {:.3}",
                    HEALTH_NAMES[i],
                    p.sigma[i]
                );
            }
        }
    }
    assert!(
        points[N - 1].at_limit[2],
        "D_GT on its limit at the newest start-up"
    );
    eprintln!("largest error: {raw_err:.2} points as fitted, {worst:.2} corrected");
    assert!(worst <= 0.3, "corrected health off by {worst:.2} points");
    // `history` shows the step as such: the stepped start-ups carry the instrument and their
    // corrected health (stored with the advice), the fitted health stays as stored.
    let shown = |store: &Store| {
        store
            .history(&HistoryFilter::default())
            .expect("history")
            .into_iter()
            .map(|r| r.instrument_step)
            .collect::<Vec<_>>()
    };
    let steps = shown(&faulty);
    assert_eq!(steps.len(), N);
    for (j, c) in steps.iter().enumerate() {
        let Some(c) = c else {
            assert!(j < ONSET, "start-up {j} not shown as corrected");
            continue;
        };
        assert!(
            j >= ONSET,
            "start-up {j} before the onset shown as corrected"
        );
        assert_eq!(c.effect, "fuel_meter");
        assert_eq!(c.onset_segment_id, 1 + ONSET as i64);
        assert_eq!(c.describe(), {
            let m = magnitude * 100.0;
            format!("fuel_meter {m:+.2} ± {:.2} %", c.magnitude_sigma * 100.0)
        });
        for (i, v) in c.health.iter().enumerate() {
            assert!(
                (v - truth(j)[i]).abs() <= 0.3,
                "start-up {j}: {} corrected {v:.2}, truth {:.2}",
                HEALTH_NAMES[i],
                truth(j)[i]
            );
        }
    }
    // A refresh that finds the same writes nothing new, and says the same.
    let again =
        refresh(&mut faulty, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    assert_eq!(again.steps, r.steps);
    assert_eq!(shown(&faulty), steps);
    let c = refresh(&mut clean, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    assert!(c.steps.is_empty(), "{:?}", c.steps);
    assert!(shown(&clean).iter().all(Option::is_none));
    eprintln!(
        "advised day {:.2} with the meter corrected, {:.2} with a correct meter",
        advised_days(&r) - T0 as f64 / DAY as f64,
        advised_days(&c) - T0 as f64 / DAY as f64
    );
    assert!((advised_days(&r) - advised_days(&c)).abs() <= 1.0);
    // Without the attribution the meter's step reads as a wash (D_GC drops by points) and
    // restarts the trend: the advice it gives is not the unit's.
    let b = refresh(&mut blind, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    assert!(
        !b.steps.iter().any(|s| s.corrected),
        "nothing to name it by"
    );
    eprintln!(
        "without the attribution: {} wash(es) detected, advised day {:.2}",
        b.detected_now.len(),
        advised_days(&b) - T0 as f64 / DAY as f64
    );
    assert!(!b.detected_now.is_empty() || (advised_days(&b) - advised_days(&c)).abs() > 1.0);
}

/// The `N` daily start-ups with the fuel meter reading `meter(j)` × the flow, each fitted by
/// Method B: stored in a faulty store (with the gap analysis's aliases of start-up `analysed`,
/// as the daemon stores them) and, fitted again with a correct meter where it was not, in a
/// clean one. Returns the directory that holds both.
fn faulty_and_clean(
    engine: &Engine,
    meter: impl Fn(usize) -> f64,
    analysed: usize,
) -> (tempfile::TempDir, Store, Store) {
    let dir = tempfile::tempdir().expect("dir");
    let mut faulty = Store::open(&dir.path().join("faulty.db")).expect("db");
    let mut clean = Store::open(&dir.path().join("clean.db")).expect("db");
    for j in 0..N {
        let rec = startup(engine, j, meter(j));
        let fit = if meter(j) == 1.0 {
            correct_fit(j)
        } else {
            diagnose_transient(engine, &rec, &cfg()).expect("fit")
        };
        let seg = store_result(&mut faulty, j, &fit);
        store_result(&mut clean, j, &correct_fit(j));
        if j == analysed {
            let a = aliases(engine, &rec, &cfg(), &fit).expect("aliases");
            store_gap_report(&mut faulty, seg, serde_json::json!({ "aliases": a }));
        }
    }
    (dir, faulty, clean)
}

/// The same meter recalibrated after three start-ups (4, 5 and 6 read 3 % high, 7 and 8 right
/// again), with the gap analysis the daemon stores for the first stepped start-up: the joint
/// fit names the meter and the start-up it read right from, `history` shows the three as
/// corrected (within 0.3 points of the truth) and the two after as measured, and the advice
/// stays within a day of the advice on a correct meter.
#[test]
fn a_fuel_meter_recalibrated_later_is_corrected_for_its_start_ups_only() {
    const BACK: usize = ONSET + 3;
    let engine = Engine::reference().expect("engine");
    let econ = WashEconomics::default();
    let meter = |j: usize| {
        if (ONSET..BACK).contains(&j) {
            METER
        } else {
            1.0
        }
    };
    let (_dir, mut faulty, mut clean) = faulty_and_clean(&engine, meter, ONSET);
    let det = WashDetection::default();
    let r = refresh(&mut faulty, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    let step = r.steps.first().expect("a step is found");
    let line = step_line(step);
    eprintln!("{line}");
    assert!(
        matches!(&step.attribution.verdict, SequenceVerdict::Instrument { effect, until: Some(m), .. }
            if effect == "fuel_meter" && *m == BACK),
        "{:?}",
        step.attribution.verdict
    );
    assert_eq!(step.until_segment_id, Some(1 + BACK as i64));
    assert!(line.contains("until start-up 8"), "{line}");
    let rows = faulty.history(&HistoryFilter::default()).expect("history");
    let mut worst = 0.0_f64;
    for (j, row) in rows.iter().enumerate() {
        match &row.instrument_step {
            Some(c) => {
                assert!((ONSET..BACK).contains(&j), "start-up {j} corrected");
                for (i, v) in c.health.iter().enumerate() {
                    worst = worst.max((v - truth(j)[i]).abs());
                }
            }
            None => assert!(!(ONSET..BACK).contains(&j), "start-up {j} not corrected"),
        }
    }
    eprintln!("corrected health off by at most {worst:.2} points");
    assert!(worst <= 0.3, "corrected health off by {worst:.2} points");
    let c = refresh(&mut clean, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    eprintln!(
        "advised day {:.2} with the meter corrected, {:.2} with a correct meter",
        advised_days(&r) - T0 as f64 / DAY as f64,
        advised_days(&c) - T0 as f64 / DAY as f64
    );
    assert!((advised_days(&r) - advised_days(&c)).abs() <= 1.0);
}

/// The same meter drifting instead of stepping: right at start-up 3, then 0.4 % further off a
/// day, 2 % high at the newest (8); no start-up steps away from the trend of those before it.
/// (Further, to 3 %, the HP turbine's estimate of the last two start-ups sits on its −3 limit,
/// the others bend with it, and the newest is seen as a step of its own, `ambiguous`.)
/// The only gap analysis is one of the newest start-up (as the daemon's schedule makes). The
/// advice names the meter's drift and the start-up it last read right at, `history` shows each
/// later start-up corrected by what the meter had drifted by then (within 0.3 points of the
/// truth), and the advice stays within a day of the advice on a correct meter. Looked for as
/// steps only, nothing was found: the health stayed as fitted, up to 2 points off.
#[test]
fn a_drifting_fuel_meter_is_named_corrected_and_leaves_the_advice() {
    const LAST_RIGHT: usize = 3;
    const NEWEST: f64 = 0.02;
    let drift =
        |j: usize| 1.0 + NEWEST * j.saturating_sub(LAST_RIGHT) as f64 / (N - 1 - LAST_RIGHT) as f64;
    let engine = Engine::reference().expect("engine");
    let econ = WashEconomics::default();
    let (_dir, mut faulty, mut clean) = faulty_and_clean(&engine, drift, N - 1);
    let det = WashDetection::default();
    let r = refresh(&mut faulty, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    let lines: Vec<String> = r.steps.iter().map(step_line).collect();
    let [step] = r.steps.as_slice() else {
        panic!("one step: {lines:#?}");
    };
    let line = step_line(step);
    eprintln!("{line}");
    let SequenceVerdict::Instrument {
        effect,
        magnitude,
        drift: Some(d),
        ..
    } = &step.attribution.verdict
    else {
        panic!("not named a drift: {:?}", step.attribution.verdict);
    };
    assert_eq!(effect, "fuel_meter");
    assert!((magnitude - NEWEST).abs() < 0.005, "size {magnitude}");
    assert!(
        (LAST_RIGHT - 1..=LAST_RIGHT + 1).contains(&d.from),
        "from {}",
        d.from
    );
    assert_eq!(step.drift_from_segment_id, Some(1 + d.from as i64));
    assert!(line.contains("drifts since start-up"), "{line}");
    let rows = faulty.history(&HistoryFilter::default()).expect("history");
    let mut worst = 0.0_f64;
    for (j, row) in rows.iter().enumerate() {
        match &row.instrument_step {
            Some(c) => {
                assert!(j > d.from, "start-up {j} corrected");
                // Each start-up's own error: what the meter had drifted by then.
                assert!(
                    (c.magnitude - (drift(j) - 1.0)).abs() < 0.005,
                    "start-up {j}: {}",
                    c.describe()
                );
                for (i, v) in c.health.iter().enumerate() {
                    worst = worst.max((v - truth(j)[i]).abs());
                }
            }
            None => assert!(j <= d.from, "start-up {j} not corrected"),
        }
    }
    eprintln!("corrected health off by at most {worst:.2} points");
    assert!(worst <= 0.3, "corrected health off by {worst:.2} points");
    let c = refresh(&mut clean, &engine, &econ, &det, &HealthBounds::default()).expect("advice");
    assert!(c.steps.is_empty(), "{:?}", c.steps);
    eprintln!(
        "advised day {:.2} with the meter corrected, {:.2} with a correct meter",
        advised_days(&r) - T0 as f64 / DAY as f64,
        advised_days(&c) - T0 as f64 / DAY as f64
    );
    assert!((advised_days(&r) - advised_days(&c)).abs() <= 1.0);
}

/// Twelve stored results with known health (no model runs): a compressor fouling at
/// 0.25 %/day, a wash the trend detected (nobody confirmed it) recovering 1.5 and 0.6 points
/// before start-up `wash`, and the fuel meter reading 3 % high from start-up `step` on (its alias
/// signature as the reference engine gives it, with a gap analysis of that start-up). Refreshes
/// the advice and checks what both tests below expect: the first step from `step` on, named the
/// fuel meter, sized within half a percent, and exactly the start-ups from `step` corrected, each
/// within 0.3 points of the truth. Returns the step's line.
fn meter_step_after_a_detected_wash(wash: usize, step: usize) -> String {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    const N: usize = 12;
    let truth = |j: usize| -> [f64; 6] {
        let t = j as f64;
        let washed = if j >= wash { 1.0 } else { 0.0 };
        [
            1.0 + 0.25 * t - 1.5 * washed,
            0.4 + 0.1 * t - 0.6 * washed,
            -0.2,
            0.4,
            0.1,
            0.3,
        ]
    };
    let dir = tempfile::tempdir().expect("dir");
    let mut store = Store::open(&dir.path().join("w.db")).expect("db");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let noise = Normal::new(0.0, 0.05).expect("normal");
    for j in 0..N {
        let h: [f64; 6] = std::array::from_fn(|i| {
            truth(j)[i] + noise.sample(&mut rng) + if j >= step { 1.5 * FUEL_SHIFT[i] } else { 0.0 }
        });
        let id = store_health(&mut store, j, h, [0.05; 6]);
        if j == wash {
            store_detected_wash(&mut store, j);
        }
        if j == step {
            store_gap_report(&mut store, id, meter_and_inlet_report());
        }
    }
    let r = refresh_defaults(&mut store);
    let first = r.steps.first().expect("a step is found");
    let line = step_line(first);
    eprintln!("{line}");
    assert_eq!(first.onset_segment_id, 1 + step as i64);
    assert_eq!(first.attribution.verdict.label(), "instrument:fuel_meter");
    let (size, _) = first
        .attribution
        .verdict
        .instrument_magnitude()
        .expect("sized");
    assert!((size - 0.03).abs() < 0.005, "size {size}");
    let rows = store.history(&HistoryFilter::default()).expect("history");
    let mut worst = 0.0_f64;
    for (j, row) in rows.iter().enumerate() {
        assert_eq!(row.instrument_step.is_some(), j >= step, "start-up {j}");
        if let Some(c) = &row.instrument_step {
            for (i, v) in c.health.iter().enumerate() {
                worst = worst.max((v - truth(j)[i]).abs());
                assert!(
                    (v - truth(j)[i]).abs() <= 0.3,
                    "start-up {j}: {} corrected {v:.2}, truth {:.2}",
                    HEALTH_NAMES[i],
                    truth(j)[i]
                );
            }
        }
    }
    eprintln!("corrected health off by at most {worst:.2} points");
    line
}

/// A wash the trend detected (not yet confirmed by the operator) and, four start-ups later, a
/// fuel meter reading 3 % high: the joint fit runs from the detected wash on, so the meter's
/// step is named and corrected (wash before start-up 4, the meter from 8). Measured: 0.21
/// points (with the trend drawn straight through the wash: 0.35 on D_GC).
#[test]
fn an_instrument_step_after_an_unconfirmed_wash_is_named() {
    let line = meter_step_after_a_detected_wash(4, 8);
    assert!(line.contains("(4 of 8 start-ups since the wash"), "{line}");
}

/// Two instruments one after the other since the last wash: a fuel meter reading 3 % high from
/// start-up 5 and the inlet temperature reading 3 K high from start-up 10 of 14. Both are
/// named, each from its own onset; `history` shows the start-ups from 5 corrected for the
/// meter and those from 10 for both (named by the newer, the older in `also`), within 0.3
/// points of the truth; the
/// stored advice says both. Stored results with known health, no model runs (the synthetic
/// draws of `gap::sequence`'s tests measure what attributing one step alone did).
#[test]
fn two_instrument_steps_one_after_the_other_are_both_named_and_corrected() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    const N: usize = 14;
    const METER: usize = 5;
    const INLET: usize = 10;
    let truth = |j: usize| -> [f64; 6] {
        let t = j as f64;
        [1.0 + 0.25 * t, 0.4 + 0.1 * t, -0.2, 0.4, 0.1, 0.3]
    };
    let dir = tempfile::tempdir().expect("dir");
    let mut store = Store::open(&dir.path().join("w.db")).expect("db");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, 0.05).expect("normal");
    for j in 0..N {
        let h: [f64; 6] = std::array::from_fn(|i| {
            truth(j)[i]
                + noise.sample(&mut rng)
                + if j >= METER { 1.5 * FUEL_SHIFT[i] } else { 0.0 }
                + if j >= INLET {
                    1.5 * INLET_SHIFT[i]
                } else {
                    0.0
                }
        });
        let id = store_health(&mut store, j, h, [0.05; 6]);
        if j == METER || j == INLET {
            store_gap_report(&mut store, id, meter_and_inlet_report());
        }
    }
    let r = refresh_defaults(&mut store);
    for s in &r.steps {
        eprintln!("{}", step_line(s));
    }
    let named: Vec<(i64, String)> = r
        .steps
        .iter()
        .map(|s| (s.onset_segment_id, s.attribution.verdict.label()))
        .collect();
    assert_eq!(
        named,
        vec![
            (1 + METER as i64, "instrument:fuel_meter".to_string()),
            (1 + INLET as i64, "instrument:inlet_temperature".to_string()),
        ]
    );
    let sizes: Vec<f64> = r
        .steps
        .iter()
        .filter_map(|s| s.attribution.verdict.instrument_magnitude().map(|m| m.0))
        .collect();
    assert!((sizes[0] - 0.03).abs() < 0.005, "meter {:.4}", sizes[0]);
    assert!((sizes[1] - 3.0).abs() < 0.5, "inlet {:.2} K", sizes[1]);
    let rows = store.history(&HistoryFilter::default()).expect("history");
    let mut worst = 0.0_f64;
    for (j, row) in rows.iter().enumerate() {
        let expect = match j {
            _ if j >= INLET => Some("inlet_temperature"),
            _ if j >= METER => Some("fuel_meter"),
            _ => None,
        };
        assert_eq!(
            row.instrument_step.as_ref().map(|c| c.effect.as_str()),
            expect,
            "start-up {j}"
        );
        if let Some(c) = &row.instrument_step {
            for (i, v) in c.health.iter().enumerate() {
                worst = worst.max((v - truth(j)[i]).abs());
            }
            // The newer step's row says the older instrument is corrected for too.
            if j >= INLET {
                assert!(
                    c.also.starts_with("fuel_meter +3.0") && c.also.ends_with("from start-up 6"),
                    "start-up {j}: {}",
                    c.describe_all()
                );
            } else {
                assert_eq!(c.also, "", "start-up {j}");
            }
        }
    }
    eprintln!(
        "{}",
        rows[N - 1]
            .instrument_step
            .as_ref()
            .map_or(String::new(), |c| c.describe_all())
    );
    eprintln!("corrected health off by at most {worst:.2} points");
    assert!(worst <= 0.3, "corrected health off by {worst:.2} points");
    let message = store
        .conn()
        .query_row(
            "SELECT message FROM recommendations ORDER BY id DESC LIMIT 1",
            [],
            |r| r.get::<_, String>(0),
        )
        .expect("advice stored");
    assert!(
        message.contains("the instrument fuel_meter is off by")
            && message.contains("the instrument inlet_temperature is off by"),
        "{message}"
    );
}

/// A wash the trend detected only two start-ups before a fuel meter began reading 3 % high
/// (before start-up 6, the meter from 8): too close for a trend after it, so the joint fit is not
/// restarted there; every hypothesis gets the wash's step in both compressor parameters beside
/// its own instead of trend lines drawn straight through it. Before, the fit restarted at the
/// wash anyway and found the step one start-up late (start-up 9, past the one whose gap analysis
/// gave the signatures): "the engine's (step:D_ET)", the meter's error left in the health.
/// Measured: 0.17 points.
#[test]
fn an_instrument_step_two_start_ups_after_a_detected_wash_is_corrected() {
    let line = meter_step_after_a_detected_wash(6, 8);
    assert!(line.contains("(4 of 12 start-ups since the wash"), "{line}");
}

mod explained;
